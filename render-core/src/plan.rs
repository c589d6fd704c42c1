//! The render plan: the typed set of [`Feature`]s a committed scene calls for, with the prims
//! that call for each.
//!
//! Commit derives the set once (the scene's features step); the machinery reads it (which
//! caches are built, which tests a ray makes, which path loop runs), and the plan a user reads
//! (`Started.plan`, `--explain-plan`) is printed from the same set, so the two cannot drift.

use std::collections::BTreeMap;

macro_rules! features {
    ($($variant:ident = $name:literal : $reason:literal,)*) => {
        /// One effect the renderer can simulate.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Feature {
            $(
                #[doc = $reason]
                $variant,
            )*
        }

        impl Feature {
            /// Every feature, in the order plans list them.
            pub const ALL: &'static [Feature] = &[$(Feature::$variant),*];

            /// The short name plans print, e.g. `normal-maps`.
            pub fn name(self) -> &'static str {
                match self { $(Feature::$variant => $name,)* }
            }

            /// What the renderer does for it.
            pub fn reason(self) -> &'static str {
                match self { $(Feature::$variant => $reason,)* }
            }
        }
    };
}

features! {
    Lights = "lights": "UsdLux lights, chosen through a light tree with adaptive splitting, MIS (power heuristic)",
    EnvironmentMap = "environment-map": "DomeLight texture, importance-sampled by luminance × sin θ (bilinear, as looked up) with MIS",
    Textures = "textures": "material inputs from textures, resolved per shading point and mip-mapped by ray cones",
    NormalMaps = "normal-maps": "tangent-space normal maps (MikkTSpace tangents built for the meshes that use them)",
    BumpMaps = "bump-maps": "tessera:Bump heights: the shading normal tilted by the height's slope, read by central differences one texel apart",
    Displacement = "displacement": "UsdPreviewSurface displacement: the meshes it is bound to diced to their texture's texels (2M triangles a scene at most) and moved along their vertex normals before their BVHs are built",
    TexturedCutouts = "textured-cutouts": "opacity textures cut surfaces out per point, for every ray",
    TexturedEmission = "textured-emission": "emission looked up per texel where light sampling lands",
    EmissiveMeshes = "emissive-meshes": "emissive triangles sampled by solid angle (by area when small or far) with MIS",
    Diffuse = "diffuse": "diffuse reflection (Lambertian, energy-preserving Oren-Nayar where rough; Disney's for tessera:Principled)",
    Metal = "metal": "GGX conductor reflection",
    Transmission = "transmission": "rough dielectric refraction (glass)",
    ThinTransmission = "thin-transmission": "thin dielectric sheets (Imageworks' double-refraction series)",
    DiffuseTransmission = "diffuse-transmission": "Lambertian transmission",
    Clearcoat = "clearcoat": "a clearcoat layered over the base",
    Sheen = "sheen": "sheen (Charlie coat, Zeltner's fuzz coat, or Disney's for tessera:Principled)",
    Fabric = "fabric": "the DreamWorks fabric cone",
    Hair = "hair": "hair fibres (Chiang et al. 2016): the shading frame along each curve, tube insides skipped by rays leaving a fibre",
    Glitter = "glitter": "DreamWorks glitter: object-space Worley flakes found per shading point, GGX lobe per flake",
    ThinFilm = "thin-film": "thin-film interference (Airy, integrated over the spectrum): a film coat, or a film replacing a specular's or a glass's Fresnel",
    DoubleSpecular = "double-specular": "two GGX roughnesses blended",
    Anisotropy = "anisotropy": "anisotropic GGX",
    Instancing = "instancing": "instances share one BLAS per prototype under a TLAS",
    PartialPresence = "partial-presence": "opacityMode presence: rays pass the surface unbent in proportion to 1 - opacity, shadow rays too",
    Subsurface = "subsurface": "random walk in a homogeneous medium behind a dielectric boundary (van de Hulst albedo)",
    DepthOfField = "depth-of-field": "thin-lens cameras (fStop, focusDistance): rays from points on the lens",
    Volumes = "volumes": "UsdVol volumes: delta tracking through a majorant grid, ratio-tracked shadows, Henyey-Greenstein scattering, emission and black-body fire",
    LightLinking = "light-linking": "lights that illuminate only the prims of their collection:lightLink, checked per light sample and per light a path finds",
    ShadowLinking = "shadow-linking": "lights whose shadows only the prims of their collection:shadowLink cast: shadow rays pass the others, and those lights are found by light sampling alone",
    MotionBlur = "motion-blur": "motion over the shutter: each camera sample at its own time, moving instances, lights and volumes placed and deforming meshes shaped per ray",
}

/// A set of [`Feature`]s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Features(u32);

const _: () = assert!(Feature::ALL.len() <= 32, "Features holds at most 32 features");

impl Features {
    /// True when `f` is in the set.
    #[inline]
    pub fn has(self, f: Feature) -> bool {
        self.0 & (1 << f as u32) != 0
    }

    /// True when any of `fs` is in the set.
    #[inline]
    pub fn has_any(self, fs: &[Feature]) -> bool {
        fs.iter().any(|&f| self.has(f))
    }

    /// Adds `f`.
    pub fn insert(&mut self, f: Feature) {
        self.0 |= 1 << f as u32;
    }

    /// The features in the set, in plan order.
    pub fn iter(self) -> impl Iterator<Item = Feature> {
        Feature::ALL.iter().copied().filter(move |&f| self.has(f))
    }

    /// Every feature there is.
    pub fn all() -> Features {
        let mut s = Features::default();
        Feature::ALL.iter().for_each(|&f| s.insert(f));
        s
    }
}

/// One simulated effect as a plan prints it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanEntry {
    /// The feature.
    pub feature: Feature,
    /// Short effect name, e.g. `direct-lighting`.
    pub effect: String,
    /// Why it is on (or what it costs).
    pub reason: String,
    /// Prims that call for it (possibly truncated, with a count).
    pub prims: Vec<String>,
}

/// What the renderer will simulate for a committed scene.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RenderPlan {
    /// The features the scene calls for: the switches the renderer reads.
    pub features: Features,
    /// The prims that call for each feature, and a reason that says more than the feature's
    /// own (a count), where there is one.
    calls: BTreeMap<Feature, (Vec<String>, Option<String>)>,
}

/// Prims a plan entry lists before it gives a count.
const SHOWN: usize = 8;

impl RenderPlan {
    /// Turns `f` on because `prims` call for it; an empty list leaves it off.
    pub fn call_for(&mut self, f: Feature, prims: impl IntoIterator<Item = String>) {
        let prims: Vec<String> = prims.into_iter().collect();
        if !prims.is_empty() {
            self.features.insert(f);
            self.calls.entry(f).or_default().0.extend(prims);
        }
    }

    /// As [`Self::call_for`], with a reason that says more (e.g. how many).
    pub fn call_for_because(&mut self, f: Feature, reason: String, prims: impl IntoIterator<Item = String>) {
        self.call_for(f, prims);
        if let Some(call) = self.calls.get_mut(&f) {
            call.1 = Some(reason);
        }
    }

    /// True when `f` is on.
    #[inline]
    pub fn has(&self, f: Feature) -> bool {
        self.features.has(f)
    }

    /// The prims that call for `f`.
    pub fn prims(&self, f: Feature) -> &[String] {
        self.calls.get(&f).map_or(&[], |c| &c.0)
    }

    /// The enabled effects as a plan lists them, at most a handful of prims each.
    pub fn entries(&self) -> Vec<PlanEntry> {
        self.features
            .iter()
            .map(|f| {
                let (all, reason) = &self.calls[&f];
                let mut prims: Vec<String> = all.iter().take(SHOWN).cloned().collect();
                if all.len() > SHOWN {
                    prims.push(format!("... and {} more", all.len() - SHOWN));
                }
                let reason = reason.clone().unwrap_or_else(|| f.reason().to_string());
                PlanEntry { feature: f, effect: f.name().to_string(), reason, prims }
            })
            .collect()
    }

    /// Features the renderer supports but this scene does not need, and so skips.
    pub fn skipped(&self) -> impl Iterator<Item = Feature> + '_ {
        Feature::ALL.iter().copied().filter(|&f| !self.has(f))
    }
}

impl std::fmt::Display for RenderPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for e in self.entries() {
            writeln!(f, "  + {:<18} {}", e.effect, e.reason)?;
            if !e.prims.is_empty() {
                writeln!(f, "  {:<20} {}", "", e.prims.join(", "))?;
            }
        }
        for s in self.skipped() {
            writeln!(f, "  - {}: not needed by this scene", s.name())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_the_set_holds_each_alone() {
        let names: std::collections::BTreeSet<&str> = Feature::ALL.iter().map(|f| f.name()).collect();
        assert_eq!(names.len(), Feature::ALL.len());
        for &f in Feature::ALL {
            let mut s = Features::default();
            s.insert(f);
            assert_eq!(s.iter().collect::<Vec<_>>(), vec![f]);
        }
        assert_eq!(Features::all().iter().count(), Feature::ALL.len());
    }

    #[test]
    fn a_feature_no_prim_calls_for_stays_off_and_is_listed_as_skipped() {
        let mut plan = RenderPlan::default();
        plan.call_for(Feature::Subsurface, Vec::new());
        plan.call_for(Feature::Metal, (0..10).map(|i| format!("/M{i}")));
        assert!(!plan.has(Feature::Subsurface) && plan.has(Feature::Metal));
        let e = &plan.entries()[0];
        assert_eq!(e.prims.len(), SHOWN + 1);
        assert_eq!(e.prims[SHOWN], "... and 2 more");
        let text = plan.to_string();
        assert!(text.contains("+ metal") && text.contains("- subsurface: not needed"), "{text}");
    }
}
