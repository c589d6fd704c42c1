//! MaterialX's hair (`surface` over `chiang_hair_bsdf`, with its `chiang_hair_roughness`,
//! `chiang_hair_absorption_from_color` and `deon_hair_absorption_from_melanin` helpers, as the
//! MaterialX 1.39 specification's "PBR Shading Nodes" define them) onto `tessera:Hair`, which
//! holds the same model: MaterialX's per-path roughness is given as Mp's variance v and the
//! logistic's scale s, so Chiang et al.'s fits are inverted to the βm and βn the shader takes,
//! and TT's and TRT's pairs become its per-path scales.

use glam::{Vec3, Vec4};
use render_core::material::{MaterialNetwork, MaterialNode};

/// `tessera:Hair`'s inputs for the hair under `surface` (an `ND_surface` node), or why not.
pub(super) fn hair_inputs(net: &MaterialNetwork, surface: &str, warnings: &mut Vec<String>) -> Result<Vec<(&'static str, Vec4)>, String> {
    let bsdf = upstream(net, surface, "bsdf").ok_or_else(|| format!("{surface}: MaterialX surface has no bsdf connected"))?;
    if !bsdf.node_type_id.starts_with("ND_chiang_hair_bsdf") {
        return Err(format!(
            "{}: MaterialX BSDF '{}' under a surface is not supported (chiang_hair_bsdf is)",
            bsdf.path, bsdf.node_type_id
        ));
    }
    let h = &bsdf.path;
    let mut warn = |w: String| {
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    };
    let Roughness { beta_m, beta_n, scale_tt, scale_trt, radial_tt, radial_trt } = roughness(net, h, &mut warn);
    let cuticle = constant(net, h, "cuticle_angle", Vec4::splat(0.5), &mut warn).x;
    let absorption = absorption(net, h, &mut warn);
    let ior = constant(net, h, "ior", Vec4::splat(1.55), &mut warn);
    let [tint_r, tint_tt, tint_trt] = ["tint_R", "tint_TT", "tint_TRT"].map(|name| constant(net, h, name, Vec4::ONE, &mut warn));
    Ok(vec![
        ("melanin", Vec4::ZERO),
        ("absorptionCoefficient", absorption.extend(1.0)),
        ("roughness", Vec4::splat(beta_m)),
        ("radialRoughness", Vec4::splat(beta_n)),
        ("roughnessScaleTT", Vec4::splat(scale_tt)),
        ("roughnessScaleTRT", Vec4::splat(scale_trt)),
        ("radialRoughnessScaleTT", Vec4::splat(radial_tt)),
        ("radialRoughnessScaleTRT", Vec4::splat(radial_trt)),
        ("ior", ior),
        // cuticle_angle maps [0, 1] onto [−90°, 90°] (0.5: no tilt).
        ("offset", Vec4::splat(cuticle * 180.0 - 90.0)),
        ("tintR", tint_r),
        ("tintTT", tint_tt),
        ("tintTRT", tint_trt),
    ])
}

/// The node feeding `node.input`, if any.
fn upstream<'n>(net: &'n MaterialNetwork, node: &str, input: &str) -> Option<&'n MaterialNode> {
    let c = net.connections.iter().find(|c| c.downstream_node == node && c.downstream_input == input)?;
    net.nodes.iter().find(|n| n.path == c.upstream_node)
}

/// `node.input` as authored (or `default`); a connection to anything else is reported.
fn constant(net: &MaterialNetwork, node: &str, input: &str, default: Vec4, warn: &mut impl FnMut(String)) -> Vec4 {
    if let Some(up) = upstream(net, node, input) {
        warn(format!(
            "{}: MaterialX node '{}' feeding {node}.{input} is not supported; the input keeps its value",
            up.path, up.node_type_id
        ));
    }
    net.nodes.iter().find(|n| n.path == node).and_then(|n| n.parameters.get(input)).and_then(super::materialx::vec4_of).unwrap_or(default)
}

/// `tessera:Hair`'s roughness inputs: βm and βn (R's), and TT's and TRT's longitudinal and
/// azimuthal scales relative to R's.
struct Roughness {
    beta_m: f32,
    beta_n: f32,
    scale_tt: f32,
    scale_trt: f32,
    radial_tt: f32,
    radial_trt: f32,
}

/// The fibre's roughness: from a `chiang_hair_roughness` node (one azimuthal roughness for
/// every path, as that node has), or from the constant (v, s) pairs of each path, R's
/// inverted through Chiang's fits, TT's and TRT's taken as ratios of R's (Mp's variance goes
/// as the square of the roughness, the logistic's scale linearly).
fn roughness(net: &MaterialNetwork, h: &str, warn: &mut impl FnMut(String)) -> Roughness {
    if let Some(r) = upstream(net, h, "roughness_R").filter(|n| n.node_type_id.starts_with("ND_chiang_hair_roughness")) {
        let p = &r.path;
        let get = |name: &str, default: f32, warn: &mut dyn FnMut(String)| constant(net, p, name, Vec4::splat(default), &mut |w| warn(w)).x;
        return Roughness {
            beta_m: get("longitudinal", 0.1, warn),
            beta_n: get("azimuthal", 0.2, warn),
            scale_tt: get("scale_TT", 0.5, warn),
            scale_trt: get("scale_TRT", 2.0, warn),
            radial_tt: 1.0,
            radial_trt: 1.0,
        };
    }
    // chiang_hair_bsdf's own defaults.
    let pair = |name: &str, default: f32, warn: &mut dyn FnMut(String)| constant(net, h, name, Vec4::splat(default), &mut |w| warn(w));
    let (r, tt, trt) = (pair("roughness_R", 0.1, warn), pair("roughness_TT", 0.05, warn), pair("roughness_TRT", 0.2, warn));
    let variance_ratio = |v: f32| if r.x > 0.0 { (v / r.x).max(0.0).sqrt() } else { 1.0 };
    let scale_ratio = |s: f32| if r.y > 0.0 { (s / r.y).max(0.0) } else { 1.0 };
    Roughness {
        beta_m: invert(|b| (0.726 * b + 0.812 * b * b + 3.7 * b.powi(20)).powi(2), r.x),
        beta_n: invert(|b| 0.265 * b + 1.194 * b * b + 5.372 * b.powi(22), r.y),
        scale_tt: variance_ratio(tt.x),
        scale_trt: variance_ratio(trt.x),
        radial_tt: scale_ratio(tt.y),
        radial_trt: scale_ratio(trt.y),
    }
}

/// The β in [0, 1] where the increasing fit `f` reaches `target` (bisection; the ends beyond).
fn invert(f: impl Fn(f32) -> f32, target: f32) -> f32 {
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < target { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// σa inside the fibre: authored, or computed from `deon_hair_absorption_from_melanin` or
/// `chiang_hair_absorption_from_color` with their (constant) inputs, as MaterialX defines them.
fn absorption(net: &MaterialNetwork, h: &str, warn: &mut impl FnMut(String)) -> Vec3 {
    let Some(up) = upstream(net, h, "absorption_coefficient") else {
        return constant(net, h, "absorption_coefficient", Vec4::ZERO, warn).truncate();
    };
    let p = up.path.clone();
    let mut get = |name: &str, default: Vec4| constant(net, &p, name, default, &mut *warn);
    if up.node_type_id.starts_with("ND_deon_hair_absorption_from_melanin") {
        let concentration = get("melanin_concentration", Vec4::splat(0.25)).x;
        let redness = get("melanin_redness", Vec4::splat(0.5)).x;
        let eu = get("eumelanin_color", (-Vec3::new(0.419, 0.697, 1.37)).exp().extend(1.0)).truncate();
        let pheo = get("pheomelanin_color", (-Vec3::new(0.187, 0.4, 1.05)).exp().extend(1.0)).truncate();
        let melanin = -(1.0 - concentration).max(1e-4).ln();
        let ln = |c: Vec3| Vec3::new(c.x.max(1e-4).ln(), c.y.max(1e-4).ln(), c.z.max(1e-4).ln());
        return (-(melanin * (1.0 - redness)) * ln(eu) - melanin * redness * ln(pheo)).max(Vec3::ZERO);
    }
    if up.node_type_id.starts_with("ND_chiang_hair_absorption_from_color") {
        let color = get("color", Vec4::ONE).truncate();
        let beta_n = get("azimuthal_roughness", Vec4::splat(0.2)).x;
        return render_core::bsdf::hair::sigma_a_from_color(color, beta_n);
    }
    warn(format!("{}: MaterialX node '{}' feeding {h}.absorption_coefficient is not supported; no absorption", up.path, up.node_type_id));
    Vec3::ZERO
}
