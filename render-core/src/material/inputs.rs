//! What resolution reads of a node: its inputs, with connected ones replaced by their values
//! at the shading point, and what it reports.

use super::desc::{MaterialConnection, MaterialNetwork, MaterialNode, ParamValue};
use crate::bsdf::thin_film::ConductorAverages;

/// Node ids whose outputs are evaluated per shading point (the texture graph's nodes).
pub(super) const EVALUATED: &[&str] = &[
    "UsdUVTexture",
    "UsdPrimvarReader_float2",
    "UsdPrimvarReader_float",
    "UsdPrimvarReader_float3",
    "UsdPrimvarReader_int",
    "UsdTransform2d",
    super::graph::BUMP,
];

/// True when the upstream node of `c` is one evaluated per shading point.
pub(crate) fn evaluable(net: &MaterialNetwork, c: &MaterialConnection) -> bool {
    net.nodes.iter().any(|n| n.path == c.upstream_node && EVALUATED.contains(&n.node_type_id.as_str()))
}

/// Values of connected inputs evaluated at one shading point: `keys[i]` is (node path,
/// input name) of `values[i]`. Empty at commit time.
#[derive(Clone, Copy, Default)]
pub(crate) struct Overrides<'a> {
    pub keys: &'a [(String, String)],
    pub values: &'a [ParamValue],
    /// (node path, grid) of each filmed `tessera:Metal` whose colours vary: its film's
    /// average is read from the grid, not integrated at each point.
    pub film_averages: &'a [(String, ConductorAverages)],
}

impl<'a> Overrides<'a> {
    pub(super) fn get(&self, node: &str, input: &str) -> Option<&'a ParamValue> {
        self.keys.iter().position(|(n, i)| n == node && i == input).map(|k| &self.values[k])
    }
}

/// A node's inputs as resolution reads them: the authored values, with connected inputs
/// replaced by their values at the shading point. A connected input is always present among
/// the authored ones (compilation writes a placeholder), so iterating covers it.
#[derive(Clone, Copy)]
pub(crate) struct Inputs<'a> {
    pub(super) node: &'a MaterialNode,
    pub(super) overrides: Overrides<'a>,
}

impl<'a> Inputs<'a> {
    /// The node's authored values only.
    #[cfg(test)]
    pub fn authored(node: &'a MaterialNode) -> Self {
        Inputs { node, overrides: Overrides::default() }
    }

    /// The value of input `name`.
    pub fn get(&self, name: &str) -> Option<&'a ParamValue> {
        self.overrides.get(&self.node.path, name).or_else(|| self.node.parameters.get(name))
    }

    /// The grid this node's film reads its average from, if its colours vary.
    pub fn film_averages(&self) -> Option<&'a ConductorAverages> {
        self.overrides.film_averages.iter().find(|(n, _)| *n == self.node.path).map(|(_, grid)| grid)
    }

    /// True when `name` is a connected input evaluated at the shading point.
    pub fn is_overridden(&self, name: &str) -> bool {
        self.overrides.get(&self.node.path, name).is_some()
    }

    /// Every input with a value.
    pub fn iter(&self) -> impl Iterator<Item = (&'a String, &'a ParamValue)> + 'a {
        let (node, overrides) = (self.node, self.overrides);
        node.parameters.iter().map(move |(k, v)| (k, overrides.get(&node.path, k).unwrap_or(v)))
    }
}

impl std::ops::Deref for Inputs<'_> {
    type Target = MaterialNode;
    fn deref(&self) -> &MaterialNode {
        self.node
    }
}

/// What resolution could not honour, each naming the node and input.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ResolveReport {
    /// Human-readable warnings.
    pub warnings: Vec<String>,
}
