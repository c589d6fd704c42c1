//! Material networks as a session syncs them, in the shape of Hydra's `HdMaterialNetwork`:
//! nodes with parameters, and connections from outputs to inputs.

use std::collections::BTreeMap;

use glam::Vec3;

/// A parameter value on a node.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// A float.
    Float(f32),
    /// A colour or vector.
    Float3(Vec3),
    /// An integer.
    Int(i32),
    /// A boolean.
    Bool(bool),
    /// A string or token.
    String(String),
    /// An asset path, already resolved by the client.
    Asset(String),
    /// A texture coordinate or other pair.
    Float2(glam::Vec2),
    /// Four components (UsdUVTexture `scale`, `bias`, `fallback`).
    Float4(glam::Vec4),
    /// A texture file by content: its hash and where the client found it.
    Texture {
        /// `sha256:` and 64 hex digits.
        hash: String,
        /// The authored file, for messages.
        source: String,
    },
    /// A UDIM texture set: one file per unit square of texture space, the square at
    /// (u, v) (0 to 9 each) in tile `1001 + u + 10·v`.
    Udim {
        /// Each tile present, by its number ([`UDIM_TILES`]), in increasing order, with
        /// its file's content hash.
        tiles: Vec<(u16, String)>,
        /// The authored path, with `<UDIM>` where the tile number goes, for messages.
        source: String,
    },
}

/// The UDIM tiles read: ten columns by ten rows of texture space, as USD's
/// `UsdShadeUdimUtils` reads them.
pub const UDIM_TILES: std::ops::RangeInclusive<u16> = 1001..=1100;

impl ParamValue {
    /// The texture files the value names: (content hash, the authored path), none for a
    /// value that is not a texture.
    pub fn texture_files(&self) -> Vec<(&str, &str)> {
        match self {
            ParamValue::Texture { hash, source } => vec![(hash.as_str(), source.as_str())],
            ParamValue::Udim { tiles, source } => tiles.iter().map(|(_, hash)| (hash.as_str(), source.as_str())).collect(),
            _ => Vec::new(),
        }
    }
}

/// One shader node.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialNode {
    /// The node's USD path.
    pub path: String,
    /// Shader id, e.g. `UsdPreviewSurface`.
    pub node_type_id: String,
    /// Authored input values by input name (without the `inputs:` prefix).
    pub parameters: BTreeMap<String, ParamValue>,
}

/// An edge from an upstream output to a downstream input.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialConnection {
    /// Downstream node path.
    pub downstream_node: String,
    /// Downstream input name.
    pub downstream_input: String,
    /// Upstream node path.
    pub upstream_node: String,
    /// Upstream output name.
    pub upstream_output: String,
}

/// A whole material network.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialNetwork {
    /// Nodes.
    pub nodes: Vec<MaterialNode>,
    /// Connections between node inputs and outputs.
    pub connections: Vec<MaterialConnection>,
    /// Path of the node connected to the material's surface terminal.
    pub surface_node: String,
}
