//! Light linking: each light's `collection:lightLink` and `collection:shadowLink` resolved as
//! usd-core's `ComputeMembershipQuery` resolves them, and each gprim's membership in them, sent
//! as Hydra sends it: the prim lists the link collections it belongs to ("categories"), and the
//! light names its collection ([`render_core::scene::LightLinks`]).

use std::collections::HashMap;

use anyhow::Result;
use openusd::usd::{Collection, ExpansionRule, PathExpansionRuleMap, PathRule};

use super::*;

/// The lights' link collections that hold less than the whole stage.
#[derive(Default)]
pub(super) struct LinkQueries {
    /// Each such collection's id (`<light>.collection:lightLink`).
    ids: Vec<String>,
    /// Every path some collection has an opinion on, with those opinions (collection, rule):
    /// a prim's membership in each is decided by its closest ancestor with an opinion, so one
    /// walk up from the prim decides them all (asking each collection in turn cost 1.7 s for
    /// 1,000 linked lights over 10,000 cubes).
    opinions: HashMap<sdf::Path, Vec<(u32, PathRule)>>,
    /// Per light path, the ids of its light-link and shadow-link collections.
    lights: HashMap<String, [Option<String>; 2]>,
}

/// The link collections every light has, as UsdLux's LightAPI declares them.
const LINKS: [&str; 2] = ["lightLink", "shadowLink"];

/// The id of light `light`'s link collection `link` (`lightLink` or `shadowLink`): its
/// collection path, as Hydra names a category.
pub fn link_collection_id(light: &str, link: &str) -> String {
    format!("{light}.collection:{link}")
}

impl Reader<'_> {
    /// Resolves the link collections of the lights among `paths`. Called after the traversal,
    /// which loads every payload's layer, and only when some layer authors a link property.
    pub(super) fn resolve_light_links(&mut self, paths: &[sdf::Path]) {
        self.reported_names.update(self.stage);
        if !self.reported_names.links {
            return;
        }
        for path in paths {
            let prim = self.stage.prim(path.clone());
            let is_light = prim.type_name().ok().flatten().is_some_and(|t| LIGHTS.contains(&t.as_str()));
            if !is_light {
                continue;
            }
            let p = path.as_str();
            let mut ids = [None, None];
            for (k, link) in LINKS.into_iter().enumerate() {
                match self.link_query(&prim, p, link) {
                    Ok(Some(rules)) => {
                        let id = link_collection_id(p, link);
                        let index = self.links.ids.len() as u32;
                        for (path, rule) in rules {
                            self.links.opinions.entry(path).or_default().push((index, rule));
                        }
                        self.links.ids.push(id.clone());
                        ids[k] = Some(id);
                    }
                    Ok(None) => {}
                    Err(e) => {
                        self.out.warnings.push(format!("{p}: collection:{link} cannot be read ({e:#}); it is taken to hold every prim"))
                    }
                }
            }
            if ids.iter().any(Option::is_some) {
                self.links.lights.insert(p.to_string(), ids);
            }
        }
    }

    /// The rules of light `prim`'s collection `link` (its resolved membership), or None when
    /// it holds every prim. LightAPI gives the link collections an `includeRoot` fallback of
    /// true, which the crate's query (authored opinions only) does not know; usd-core then
    /// holds every prim, and evaluates a `membershipExpression` only when `includeRoot` is
    /// authored false.
    fn link_query(&mut self, prim: &Prim, p: &str, link: &str) -> Result<Option<PathExpansionRuleMap>> {
        let collection = Collection::new(prim.path().clone(), link);
        let root_authored = get(prim, &format!("collection:{link}:includeRoot"), self.time)?.is_some();
        if root_authored && collection.has_expression(self.stage)? {
            let (limits, so) = match link {
                "lightLink" => ("which prims the light illuminates", "it illuminates every prim"),
                _ => ("which prims cast the light's shadows", "every prim casts them"),
            };
            self.out
                .warnings
                .push(format!("{p}: collection:{link} limits {limits} by a membershipExpression, which is not evaluated yet, so {so}"));
            return Ok(None);
        }
        let mut rules = collection.compute_membership_query(self.stage)?.rule_map().clone();
        let expansion = collection.expansion_rule(self.stage)?;
        if !root_authored && expansion != ExpansionRule::ExplicitOnly {
            let rule = match expansion {
                ExpansionRule::ExpandPrimsAndProperties => PathRule::ExpandPrimsAndProperties,
                _ => PathRule::ExpandPrims,
            };
            rules.entry(sdf::Path::abs_root()).or_insert(rule);
        }
        // The root expanded, and nothing below it excluded or held to itself alone.
        let expands = |rule: &PathRule| matches!(rule, PathRule::ExpandPrims | PathRule::ExpandPrimsAndProperties);
        let everything = rules.get(&sdf::Path::abs_root()).is_some_and(expands) && rules.values().all(expands);
        Ok((!everything).then_some(rules))
    }

    /// The ids of the link collections that hold the prim at `path`, as usd-core's
    /// `IsPathIncluded` decides: by the closest opinion on the path or an ancestor, where an
    /// `explicitOnly` opinion holds its own path alone and is passed over for what lies below.
    pub(super) fn link_collections(&self, path: &sdf::Path) -> Vec<String> {
        if self.links.ids.is_empty() {
            return Vec::new();
        }
        let (mut decided, mut held) = (std::collections::HashSet::new(), Vec::new());
        let mut at = Some(path.clone());
        while let Some(current) = at {
            for &(index, rule) in self.links.opinions.get(&current).into_iter().flatten() {
                let holds = match rule {
                    PathRule::ExpandPrims | PathRule::ExpandPrimsAndProperties => true,
                    PathRule::ExplicitOnly if &current == path => true,
                    PathRule::ExplicitOnly => continue,
                    PathRule::Exclude => false,
                };
                if decided.insert(index) && holds {
                    held.push(index);
                }
            }
            at = current.parent().filter(|p| !p.is_empty());
        }
        held.sort_unstable();
        held.into_iter().map(|i| self.links.ids[i as usize].clone()).collect()
    }

    /// Says, once per pair, where a volume at `p` in `collections` casts a shadow-linked light's
    /// shadows though the link leaves it out: volumes attenuate every shadow ray (not yet
    /// filtered by link).
    pub(super) fn report_volume_shadow_links(&mut self, p: &str, collections: &[String]) {
        let mut left_out: Vec<&String> = self
            .links
            .lights
            .iter()
            .filter_map(|(light, [_, shadow])| shadow.as_ref().filter(|id| !collections.contains(id)).map(|_| light))
            .collect();
        left_out.sort();
        for light in left_out {
            self.out.warnings.push(format!(
                "{p}: the volume is left out of {light}'s collection:shadowLink, but volumes shadow every light (not yet linked)"
            ));
        }
    }

    /// Light `p`'s light-link and shadow-link collection ids (None: every prim).
    pub(super) fn light_links(&self, p: &str) -> [Option<String>; 2] {
        self.links.lights.get(p).cloned().unwrap_or_default()
    }
}
