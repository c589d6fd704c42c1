//! The front-ends that speak Disney's parameters: UsdPreviewSurface (mapped as
//! docs/materials.md explains) and `tessera:Principled` (Burley 2012, "Physically Based Shading at Disney", section 5.1 and
//! the 2015 additions, with Disney's defaults).

use glam::Vec3;

use super::desc::ParamValue;
use super::inputs::{Inputs, ResolveReport};
use super::uber::ClearcoatParams;
use super::{Material, Principled};

/// UsdPreviewSurface inputs that are known but not yet mapped.
const PREVIEW_SURFACE_KNOWN: &[&str] = &["useSpecularWorkflow", "specularColor", "opacity", "opacityThreshold", "occlusion"];

/// What a Disney-parameter front-end resolves to.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// The parameters.
    pub principled: Principled,
    /// Emission.
    pub emission: Vec3,
    /// Cut out.
    pub cut_out: bool,
    /// Share of rays passing unbent (`opacityMode` `presence`).
    pub pass_through: f32,
}

/// The material of a UsdPreviewSurface or `tessera:Principled` node.
pub(crate) fn resolve(node: Inputs, report: &mut ResolveReport) -> Material {
    let r = principled_of(node, report);
    let mut surface = r.principled.uber();
    if node.node_type_id == "UsdPreviewSurface" {
        // The specification's clearcoat is a white dielectric coat of roughness
        // clearcoatRoughness whose index is the material's `ior` (used "for all specular
        // lobes"), not Disney's fixed-index GTR1 coat.
        let p = r.principled.sanitized();
        surface.clearcoat.params =
            ClearcoatParams::Dielectric { ior: p.ior, roughness: 1.0 - p.clearcoat_gloss, color: Vec3::ONE, thickness: 0.0 };
    }
    Material { surface, emission: r.emission, cut_out: r.cut_out, pass_through: r.pass_through, tangent: Default::default() }
}

/// The Disney parameters of a UsdPreviewSurface or `tessera:Principled` node.
pub(crate) fn principled_of(node: Inputs, report: &mut ResolveReport) -> Resolved {
    if node.node_type_id == "tessera:Principled" {
        return native_principled(node, report);
    }
    let mut m = Resolved { principled: Principled::preview_surface_default(), emission: Vec3::ZERO, cut_out: false, pass_through: 0.0 };
    let p = &mut m.principled;
    // UsdPreviewSurface: Lambertian diffuse under a dielectric specular whose F0 comes from
    // `ior` (default 1.5); `ior` 1 means no specular.
    let float = |n: &str| node.get(n).and_then(|v| if let ParamValue::Float(x) = v { Some(*x) } else { None });
    let int = |n: &str| {
        node.get(n).and_then(|v| match v {
            ParamValue::Int(i) => Some(*i),
            ParamValue::Bool(b) => Some(*b as i32),
            _ => None,
        })
    };
    let specular_workflow = int("useSpecularWorkflow").unwrap_or(0) != 0;
    let opacity = float("opacity").unwrap_or(1.0);
    let threshold = float("opacityThreshold").unwrap_or(0.0);
    let presence = match node.get("opacityMode") {
        Some(ParamValue::String(mode)) if mode == "presence" => true,
        Some(ParamValue::String(mode)) if mode == "transparent" => false,
        Some(v) => {
            report
                .warnings
                .push(format!("{}: input 'opacityMode' is {v:?}, not 'transparent' or 'presence'; using 'transparent'", node.path));
            false
        }
        None => false,
    };
    if threshold > 0.0 {
        // A cut-out: present where opacity ≥ threshold, absent elsewhere.
        m.cut_out = opacity < threshold;
    } else if presence {
        // Partial presence: the surface covers a share `opacity` of each point's
        // neighbourhood; the rest lets rays through unbent.
        m.pass_through = if opacity.is_finite() { 1.0 - opacity.clamp(0.0, 1.0) } else { 0.0 };
    } else if opacity < 1.0 {
        // "Transparent but lit, like clear glass": a smooth dielectric transmission of
        // weight 1 − opacity with the material's ior.
        p.spec_trans = (1.0 - opacity).clamp(0.0, 1.0);
        p.transmission_roughness = Some(0.0);
        p.transmission_color = Some(Vec3::ONE);
    }
    for (name, value) in node.iter() {
        match (name.as_str(), value) {
            ("useSpecularWorkflow", ParamValue::Int(_) | ParamValue::Bool(_)) => {}
            ("specularColor", ParamValue::Float3(c)) if specular_workflow => p.specular_color = Some(*c),
            // The metallic workflow ignores specularColor, the specular one metallic.
            ("specularColor", ParamValue::Float3(_)) => {}
            ("metallic", ParamValue::Float(_)) if specular_workflow => {}
            ("opacity" | "opacityThreshold", ParamValue::Float(_)) => {}
            // Read (and, if malformed, reported) above.
            ("opacityMode", _) => {}
            // A tangent-space normal map, applied at shading time when the input is connected
            // (graph.rs); an unconnected (0, 0, 1) is the unperturbed normal.
            ("normal", ParamValue::Float3(n)) if *n == Vec3::Z => {}
            ("normal", ParamValue::Float3(_)) if node.is_overridden("normal") => {}
            // Ambient occlusion is for rasterisers: a path tracer computes it.
            ("occlusion", ParamValue::Float(_)) => {}
            ("diffuseColor", ParamValue::Float3(c)) => p.base_color = *c,
            ("emissiveColor", ParamValue::Float3(c)) => m.emission = c.max(Vec3::ZERO),
            ("metallic", ParamValue::Float(x)) => p.metallic = *x,
            ("roughness", ParamValue::Float(x)) => p.roughness = *x,
            ("clearcoat", ParamValue::Float(x)) => p.clearcoat = *x,
            ("clearcoatRoughness", ParamValue::Float(x)) => p.clearcoat_gloss = 1.0 - x,
            // The IOR sets the dielectric specular: F0 = ((η − 1)/(η + 1))² = 0.08·specular.
            ("ior", ParamValue::Float(x)) => {
                p.ior = *x;
                p.specular = (crate::bsdf::fresnel::f0_from_ior(*x) / 0.08).clamp(0.0, 1.0);
            }
            // Moves the mesh's vertices at commit (scene/displace.rs), not its shading.
            ("displacement", ParamValue::Float(_)) => {}
            (
                n @ ("diffuseColor" | "emissiveColor" | "metallic" | "roughness" | "clearcoat" | "clearcoatRoughness" | "ior"
                | "displacement"),
                v,
            ) => report.warnings.push(format!("{}: input '{n}' has the wrong type {v:?}; using its default", node.path)),
            (n, _) if PREVIEW_SURFACE_KNOWN.contains(&n) => {
                report.warnings.push(format!("{}: input '{n}' is not supported yet and has no effect", node.path))
            }
            (n, _) => report.warnings.push(format!("{}: unknown UsdPreviewSurface input '{n}'", node.path)),
        }
    }
    m
}

/// `tessera:Principled`: Disney's names and defaults, not UsdPreviewSurface's.
fn native_principled(node: Inputs, report: &mut ResolveReport) -> Resolved {
    let mut m = Resolved { principled: Principled::default(), emission: Vec3::ZERO, cut_out: false, pass_through: 0.0 };
    let p = &mut m.principled;
    for (name, value) in node.iter() {
        let f = |v: &ParamValue| if let ParamValue::Float(x) = v { Some(*x) } else { None };
        let ok = match name.as_str() {
            "baseColor" => matches!(value, ParamValue::Float3(c) if { p.base_color = *c; true }),
            "emission" => matches!(value, ParamValue::Float3(c) if { m.emission = c.max(Vec3::ZERO); true }),
            "thin" => matches!(value, ParamValue::Bool(b) if { p.thin = *b; true }),
            // A tangent-space normal map, read where a texture is connected (graph.rs).
            "normal" => matches!(value, ParamValue::Float3(_)),
            other => {
                let slot = match other {
                    "metallic" => &mut p.metallic,
                    "specular" => &mut p.specular,
                    "specularTint" => &mut p.specular_tint,
                    "roughness" => &mut p.roughness,
                    "anisotropic" => &mut p.anisotropic,
                    "sheen" => &mut p.sheen,
                    "sheenTint" => &mut p.sheen_tint,
                    "clearcoat" => &mut p.clearcoat,
                    "clearcoatGloss" => &mut p.clearcoat_gloss,
                    "specTrans" => &mut p.spec_trans,
                    "diffTrans" => &mut p.diff_trans,
                    "flatness" => &mut p.flatness,
                    "ior" => &mut p.ior,
                    "filmThickness" => &mut p.film_thickness,
                    "filmRefractiveIndex" => &mut p.film_ior,
                    unknown => {
                        report.warnings.push(format!("{}: unknown tessera:Principled input '{unknown}'", node.path));
                        continue;
                    }
                };
                f(value).map(|x| *slot = x).is_some()
            }
        };
        if !ok {
            report.warnings.push(format!("{}: input '{name}' has the wrong type {value:?}; using its default", node.path));
        }
    }
    if p.film_thickness > 0.0 && p.specular_tint > 0.0 {
        report
            .warnings
            .push(format!("{}: the film's interference replaces the specular's Fresnel; 'specularTint' has no effect", node.path));
    }
    m
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::material::{MaterialNetwork, MaterialNode, Principled};

    /// The Disney parameters the surface node resolves to.
    fn params(n: &MaterialNetwork) -> Principled {
        principled_of(Inputs::authored(&n.nodes[0]), &mut ResolveReport::default()).principled
    }

    /// tessera:Principled's film lies on its glass and replaces its dielectric specular's
    /// Fresnel (Cycles' Principled Thin Film); a specular tint under it is said to do nothing.
    #[test]
    fn a_principled_film_lies_on_the_glass_and_the_specular() {
        let node = MaterialNode {
            path: "/M/S".into(),
            node_type_id: "tessera:Principled".into(),
            parameters: [("specTrans", 0.5), ("filmThickness", 400.0), ("filmRefractiveIndex", 1.4), ("specularTint", 0.5)]
                .iter()
                .map(|(k, v)| (k.to_string(), ParamValue::Float(*v)))
                .collect(),
        };
        let mut report = ResolveReport::default();
        let u = principled_of(Inputs::authored(&node), &mut report).principled.uber();
        assert_eq!((u.glass.params.film_thickness, u.glass.params.film_ior), (400.0, 1.4));
        let fresnel = u.plastic.params.specular.map(|s| s.fresnel);
        assert!(matches!(fresnel, Some(crate::bsdf::SpecularFresnel::ThinFilm { film: 1.4, thickness: 400.0, .. })), "{fresnel:?}");
        assert_eq!(report.warnings, ["/M/S: the film's interference replaces the specular's Fresnel; 'specularTint' has no effect"]);
    }

    pub(crate) fn preview(params: &[(&str, ParamValue)]) -> MaterialNetwork {
        MaterialNetwork {
            nodes: vec![MaterialNode {
                path: "/M/S".into(),
                node_type_id: "UsdPreviewSurface".into(),
                parameters: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
            }],
            connections: vec![],
            surface_node: "/M/S".into(),
        }
    }

    /// The metallic workflow is the layering, literally: `metallic` m resolves to the
    /// same uber-material as a `tessera:Layer` of the fully metallic surface (a conductor with
    /// F0 = diffuseColor) over the fully dielectric one with mask m, for opaque and
    /// "transparent but lit" surfaces, clearcoated or not.
    #[test]
    fn metallic_is_a_metal_layered_over_the_dielectric_with_mask_metallic() {
        let base = |metallic: f32, opacity: f32, coat: f32| {
            let n = preview(&[
                ("diffuseColor", ParamValue::Float3(Vec3::new(0.9, 0.6, 0.2))),
                ("roughness", ParamValue::Float(0.35)),
                ("ior", ParamValue::Float(1.7)),
                ("clearcoat", ParamValue::Float(coat)),
                ("opacity", ParamValue::Float(opacity)),
                ("metallic", ParamValue::Float(metallic)),
            ]);
            n.resolve("/M").0.surface
        };
        for (opacity, coat) in [(1.0, 0.0), (0.4, 0.0), (1.0, 1.0)] {
            for m in [0.0, 0.25, 0.5, 0.9, 1.0] {
                let layered = base(0.0, opacity, coat).layered_under(&base(1.0, opacity, coat), m);
                let direct = base(m, opacity, coat);
                let (a, b) = (format!("{direct:?}"), format!("{layered:?}"));
                let close = |x: &crate::material::Uber, y: &crate::material::Uber| {
                    (x.metal.weight - y.metal.weight).abs() < 1e-6
                        && (x.plastic.weight - y.plastic.weight).abs() < 1e-6
                        && (x.glass.weight - y.glass.weight).abs() < 1e-6
                        && x.metal.params == y.metal.params
                        && x.glass.params == y.glass.params
                        && x.clearcoat == y.clearcoat
                };
                assert!(close(&direct, &layered) && (m == 0.0 || direct.plastic.params == layered.plastic.params), "m = {m}:\n{a}\n{b}");
            }
        }
    }

    #[test]
    fn maps_preview_surface_inputs_and_reports_the_rest() {
        let n = preview(&[
            ("diffuseColor", ParamValue::Float3(Vec3::new(0.5, 2.0, -1.0))),
            ("emissiveColor", ParamValue::Float3(Vec3::splat(3.0))),
            ("metallic", ParamValue::Float(1.0)),
            ("roughness", ParamValue::Float(0.25)),
            ("ior", ParamValue::Float(1.5)),
            ("displacement", ParamValue::Float(0.1)),
            ("occlusion", ParamValue::Float(0.5)),
            ("bogus", ParamValue::Float(1.0)),
        ]);
        let (m, r) = n.resolve("/M");
        let p = params(&n).sanitized();
        assert_eq!(p.base_color, Vec3::new(0.5, 1.0, 0.0));
        assert_eq!((p.metallic, p.roughness), (1.0, 0.25));
        assert!((p.specular - 0.5).abs() < 1e-5, "IOR 1.5 is Disney's specular 0.5");
        assert_eq!(m.emission, Vec3::splat(3.0));
        assert!(!r.warnings.iter().any(|w| w.contains("'displacement'")), "displacement moves the mesh at commit: {:?}", r.warnings);
        assert!(!r.warnings.iter().any(|w| w.contains("'occlusion'")), "occlusion is meaningless to a path tracer, not unsupported");
        assert!(r.warnings.iter().any(|w| w.contains("unknown UsdPreviewSurface input 'bogus'")));
        let (_, r) = preview(&[("displacement", ParamValue::Float3(Vec3::ONE))]).resolve("/M");
        assert!(r.warnings.iter().any(|w| w.contains("'displacement' has the wrong type")), "{:?}", r.warnings);
    }

    #[test]
    fn preview_surface_opacity_is_clear_transmission_or_a_cut_out() {
        // opacityThreshold 0: transparent but lit, like clear glass.
        let n = preview(&[("opacity", ParamValue::Float(0.3)), ("diffuseColor", ParamValue::Float3(Vec3::X))]);
        let (m, r) = n.resolve("/M");
        let p = params(&n).sanitized();
        assert!((p.spec_trans - 0.7).abs() < 1e-6 && !m.cut_out && r.warnings.is_empty());
        assert_eq!((p.transmission_roughness, p.transmission_color), (Some(0.0), Some(Vec3::ONE)));
        assert!(m.bsdf(true).transmits());
        // A positive threshold makes opacity binary.
        for (opacity, gone) in [(0.2, true), (0.5, false), (0.8, false)] {
            let (m, _) = preview(&[("opacity", ParamValue::Float(opacity)), ("opacityThreshold", ParamValue::Float(0.5))]).resolve("/M");
            assert_eq!(m.cut_out, gone, "opacity {opacity}");
            assert!(!m.bsdf(true).transmits());
        }
        // Presence: no transmission lobe, a share 1 − opacity of rays passes unbent; a
        // threshold still cuts out; an unknown mode is reported and read as transparent.
        let mode = |m: &str| ("opacityMode", ParamValue::String(m.into()));
        let (m, r) = preview(&[("opacity", ParamValue::Float(0.3)), mode("presence")]).resolve("/M");
        assert!((m.pass_through - 0.7).abs() < 1e-6 && !m.cut_out && !m.bsdf(true).transmits() && r.warnings.is_empty(), "{r:?}");
        let (m, _) =
            preview(&[("opacity", ParamValue::Float(0.3)), ("opacityThreshold", ParamValue::Float(0.5)), mode("presence")]).resolve("/M");
        assert!(m.cut_out && m.pass_through == 0.0);
        let (m, _) = preview(&[("opacity", ParamValue::Float(0.0)), mode("presence")]).resolve("/M");
        assert!(m.is_invisible(), "opacity 0 presence leaves nothing to render");
        let (m, r) = preview(&[("opacity", ParamValue::Float(0.3)), mode("stencil")]).resolve("/M");
        assert!(m.pass_through == 0.0 && m.bsdf(true).transmits());
        assert!(r.warnings.iter().any(|w| w.contains("opacityMode") && w.contains("stencil")), "{r:?}");
    }

    #[test]
    fn preview_surface_specular_workflow_uses_specular_color_and_ignores_metallic() {
        let red = ParamValue::Float3(Vec3::new(0.9, 0.0, 0.0));
        let n =
            preview(&[("useSpecularWorkflow", ParamValue::Int(1)), ("specularColor", red.clone()), ("metallic", ParamValue::Float(1.0))]);
        let (_, r) = n.resolve("/M");
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        let p = params(&n);
        assert_eq!((p.metallic, p.specular_color), (0.0, Some(Vec3::new(0.9, 0.0, 0.0))));
        // Seen head-on, a smooth specular-workflow surface reflects its specular colour.
        let smooth = Material::principled(Principled { roughness: 0.0, base_color: Vec3::ZERO, ..p });
        let spec = crate::bsdf::testing::albedo_estimate(&smooth.bsdf(true), Vec3::Z, 4096);
        assert!((spec.x - 0.9).abs() < 0.02 && spec.y.abs() < 1e-3, "head-on specular {spec:?}");
        // The metallic workflow ignores specularColor.
        let p = params(&preview(&[("specularColor", red), ("metallic", ParamValue::Float(1.0))]));
        assert_eq!((p.metallic, p.specular_color), (1.0, None));
    }

    #[test]
    fn preview_surface_variants_conserve_energy() {
        use crate::bsdf::testing;
        let white = ParamValue::Float3(Vec3::ONE);
        let cases = [
            vec![("diffuseColor", white.clone()), ("opacity", ParamValue::Float(0.5)), ("roughness", ParamValue::Float(0.4))],
            vec![("diffuseColor", white.clone()), ("useSpecularWorkflow", ParamValue::Int(1)), ("specularColor", white.clone())],
            vec![("diffuseColor", white.clone()), ("clearcoat", ParamValue::Float(1.0)), ("roughness", ParamValue::Float(1.0))],
        ];
        for params in cases {
            let (m, _) = preview(&params).resolve("/M");
            let bsdf = m.bsdf(true);
            for wo in testing::probe_directions() {
                for wo in [wo, -wo] {
                    let a = testing::albedo_estimate(&bsdf, wo, 20_000);
                    assert!(a.max_element() <= 1.0 + 1e-3 + 0.02, "{params:?} at {wo:?}: {a:?}");
                }
            }
        }
    }

    #[test]
    fn native_principled_shader_takes_disney_names() {
        let mut n = preview(&[
            ("baseColor", ParamValue::Float3(Vec3::ONE)),
            ("specTrans", ParamValue::Float(1.0)),
            ("thin", ParamValue::Bool(true)),
            ("sheenn", ParamValue::Float(1.0)),
        ]);
        n.nodes[0].node_type_id = "tessera:Principled".into();
        let (_, r) = n.resolve("/M");
        let p = params(&n);
        assert_eq!((p.spec_trans, p.thin, p.base_color), (1.0, true, Vec3::ONE));
        assert!(r.warnings.iter().any(|w| w.contains("unknown tessera:Principled input 'sheenn'")));
    }
}
