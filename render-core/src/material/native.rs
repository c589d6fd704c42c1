//! Tessera's own shaders, reachable from any USD file by `info:id`: the DreamWorks-style
//! specialized materials (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.3) `tessera:Metal`, `tessera:Refractive`,
//! `tessera:SolidDielectric`, and `tessera:Fabric` (section 4), and `tessera:Hair` (Chiang et al.
//! 2016, [`crate::bsdf::hair`]). Each is declared once here,
//! inputs with types, defaults and ranges, and that declaration both reads a node and writes
//! the reference table in docs/materials.md (a test checks the two agree; an ignored test
//! rewrites the table: `cargo test -p render-core write_shader_reference -- --ignored`).

use glam::Vec3;

use super::desc::ParamValue;
use super::glitter::GlitterParams;
use super::inputs::{Inputs, ResolveReport};
use super::uber::{ClearcoatParams, FabricParams, Glass, HairParams, Plastic, SheenParams, Specular, ThinFilmParams, Uber, Weighted};
use super::{Material, Tangent};
use crate::bsdf::SpecularFresnel;

/// An input's type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `float`.
    Float,
    /// `color3f`.
    Color,
    /// `bool`.
    Bool,
    /// `vector3f`: a direction, any length.
    Vector,
}

/// One declared input.
#[derive(Clone, Copy, Debug)]
pub struct Input {
    /// Name without `inputs:`.
    pub name: &'static str,
    /// Type.
    pub kind: Kind,
    /// Default (a float or bool in `.0[0]`).
    pub default: [f32; 3],
    /// Valid range; values outside are clamped.
    pub range: (f32, f32),
    /// What it does.
    pub doc: &'static str,
}

const fn float(name: &'static str, default: f32, range: (f32, f32), doc: &'static str) -> Input {
    Input { name, kind: Kind::Float, default: [default, default, default], range, doc }
}

const fn color(name: &'static str, default: f32, doc: &'static str) -> Input {
    Input { name, kind: Kind::Color, default: [default, default, default], range: (0.0, 1.0), doc }
}

/// A colour with no upper bound, 0 by default (radiance, absorption).
const fn unbounded_color(name: &'static str, doc: &'static str) -> Input {
    Input { name, kind: Kind::Color, default: [0.0; 3], range: (0.0, f32::MAX), doc }
}

const fn flag(name: &'static str, doc: &'static str) -> Input {
    Input { name, kind: Kind::Bool, default: [0.0; 3], range: (0.0, 1.0), doc }
}

/// One declared shader.
#[derive(Clone, Copy, Debug)]
pub struct Shader {
    /// `info:id`.
    pub id: &'static str,
    /// What it is.
    pub doc: &'static str,
    /// Its own inputs.
    pub inputs: &'static [Input],
    /// Whether it takes the shared coat / emission / specularControl inputs.
    pub shared: bool,
    /// Inputs that take another material (a connection to its surface output), with what
    /// each does.
    pub materials: &'static [(&'static str, &'static str)],
}

impl Shader {
    /// Every input it declares: its own, then the shared ones if it takes them.
    fn declared(&self) -> impl Iterator<Item = &'static Input> + Clone {
        let shared: &'static [Input] = if self.shared { SHARED } else { &[] };
        self.inputs.iter().chain(shared)
    }
}

/// Inputs every specialized material takes (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.3 "additional features"; the
/// sheen coat and double specular from Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings" and "Double specular").
pub const SHARED: &[Input] = &[
    float("clearcoat", 0.0, (0.0, 1.0), "coverage of a dielectric clearcoat over the material"),
    float("clearcoatRefractiveIndex", 1.5, (1.0, 3.0), "the coat's refractive index"),
    float("clearcoatRoughness", 0.0, (0.0, 1.0), "the coat's roughness"),
    float("clearcoatThickness", 0.0, (0.0, 100.0), "absorbing thickness; 1 tints a head-on round trip by exactly the attenuation colour"),
    color("clearcoatAttenuationColor", 1.0, "colour the coat absorbs towards"),
    float("sheen", 0.0, (0.0, 1.0), "coverage of a Charlie sheen coat (microfibres) over everything"),
    color("sheenColor", 1.0, "sheen colour"),
    float("sheenRoughness", 0.3, (0.07, 1.0), "sheen roughness (clamped at 0.07, where the slides' Λ fit stops conserving energy)"),
    float(
        "fuzz",
        0.0,
        (0.0, 1.0),
        "coverage of a fuzz coat over everything, the sheen included: Zeltner et al.'s multiple-scattering sheen (OpenPBR's fuzz, Cycles' sheen)",
    ),
    color("fuzzColor", 1.0, "fuzz colour"),
    float("fuzzRoughness", 0.5, (0.01, 1.0), "fuzz roughness α (clamped at 0.01, where the fits stop)"),
    float("iridescence", 0.0, (0.0, 1.0), "coverage of a thin film (soap, oil, anodized) over the material and its clearcoat"),
    float("iridescenceThickness", 400.0, (0.0, 10000.0), "film thickness in nanometres: its colours"),
    float("iridescenceRefractiveIndex", 1.33, (1.0, 3.0), "the film's refractive index"),
    float("iridescenceRoughness", 0.1, (0.0, 1.0), "the film's roughness"),
    float("roughness2", 0.5, (0.0, 1.0), "double specular: the second roughness"),
    float("doubleSpecularMix", 0.0, (0.0, 1.0), "double specular: the second roughness's share"),
    unbounded_color("emission", "emitted radiance, in UsdLux units"),
    float("specularControl", 1.0, (0.0, 1.0), "scales every specular lobe; 0 kills specular in pits and gaps"),
    Input {
        name: "normal",
        kind: Kind::Color,
        default: [0.0, 0.0, 1.0],
        range: (-1.0, 1.0),
        doc: "tangent-space normal map, read where a texture is connected (as UsdPreviewSurface's `normal`); a constant changes nothing",
    },
    Input {
        name: "tangent",
        kind: Kind::Vector,
        default: [0.0; 3],
        range: (-f32::MAX, f32::MAX),
        doc: "object-space direction of the anisotropic lobes' first axis (GGX's αx, the rougher one where `anisotropy` is positive), made perpendicular to the normal; usually a mesh's per-vertex tangents through a UsdPrimvarReader_float3; zero runs it around the object's up axis",
    },
    float(
        "anisotropyRotation",
        0.0,
        (-1.0, 1.0),
        "turn of `tangent` about the normal, counter-clockwise, in fractions of a full turn (Cycles' Anisotropic Rotation, Standard Surface's specular_rotation)",
    ),
    float(
        "stTangent",
        0.0,
        (0.0, 1.0),
        "1: without a `tangent`, the first axis runs where the mesh's texture coordinate s grows (dP/ds, MaterialX's default tangent); 0: around the object's up axis",
    ),
];

/// True when shader `id` perturbs its shading normal by a connected `normal` input.
pub fn takes_normal_map(id: &str) -> bool {
    matches!(id, "UsdPreviewSurface" | "tessera:Principled") || SHADERS.iter().any(|s| s.id == id && s.shared)
}

/// The specialized shaders.
pub const SHADERS: &[Shader] = &[
    Shader {
        id: "tessera:Metal",
        doc: "A conductor: anisotropic GGX with Gulbrandsen's reflectivity and edge tint, or the F82 tint (DreamWorks use Beckmann; GGX carries our energy tables).",
        inputs: &[
            color("reflectivity", 0.9, "normal-incidence colour (Gulbrandsen r)"),
            color("edgeTint", 1.0, "colour towards grazing angles (Gulbrandsen g)"),
            flag(
                "f82",
                "read edgeTint as an F82 tint (OpenPBR's specular_color, Cycles' Specular Tint): Schlick's curve from reflectivity, its dip near 82° scaled by edgeTint; white is Schlick",
            ),
            float("roughness", 0.3, (0.0, 1.0), "roughness (α = roughness²)"),
            float("anisotropy", 0.0, (-1.0, 1.0), "stretch along the tangent (−1) or bitangent (1)"),
            float(
                "filmThickness",
                0.0,
                (0.0, 10000.0),
                "a thin film on the metal, in nanometres: its interference over the metal's complex index (from reflectivity and edge tint, as Gulbrandsen inverts them) replaces the Fresnel (Cycles' Thin Film on a metal, OpenPBR's thin_film); 0: none",
            ),
            float("filmRefractiveIndex", 1.33, (1.0, 3.0), "the film's refractive index"),
        ],
        shared: true,
        materials: &[],
    },
    Shader {
        id: "tessera:Refractive",
        doc: "Glass: one roughness for reflection and transmission, exact dielectric Fresnel; `thin` makes it a sheet (Imageworks' thin surface).",
        inputs: &[
            float(
                "refractiveIndex",
                1.5,
                (1.0, 3.0),
                "index of refraction (1: the surface vanishes, or under a film is a soap bubble's wall)",
            ),
            float("roughness", 0.0, (0.0, 1.0), "roughness of reflection and transmission"),
            float("anisotropy", 0.0, (-1.0, 1.0), "anisotropy"),
            color("transmissionColor", 1.0, "tint of transmitted light (a sheet: of one crossing)"),
            float(
                "transmissionRefractiveIndex",
                0.0,
                (0.0, 3.0),
                "the index light bends by, decoupled from the reflectance (0: refractiveIndex); not physical, so not reciprocal and not energy-compensated; thin sheets do not bend",
            ),
            flag("thin", "a thin sheet: light crosses undeflected"),
            float(
                "filmThickness",
                0.0,
                (0.0, 10000.0),
                "a thin film on the boundary, in nanometres: its interference replaces the Fresnel, reflecting R and transmitting 1 − R per channel (Cycles' Thin Film on glass, OpenPBR's thin_film); with refractiveIndex 1, a soap bubble's wall; the boundary then goes uncompensated; sheets take none; 0: none",
            ),
            float("filmRefractiveIndex", 1.33, (1.0, 3.0), "the film's refractive index"),
        ],
        shared: true,
        materials: &[],
    },
    Shader {
        id: "tessera:SolidDielectric",
        doc: "An opaque dielectric: a Lambertian or rough (Oren-Nayar) albedo under the dielectric specular, optional diffuse transmission.",
        inputs: &[
            color("albedo", 0.8, "diffuse colour"),
            float(
                "diffuseRoughness",
                0.0,
                (0.0, 1.0),
                "Oren-Nayar roughness σ of the diffuse, energy-preserving (EON, as OpenPBR's base_diffuse_roughness and Cycles'); 0 is Lambertian",
            ),
            float("refractiveIndex", 1.5, (1.0, 3.0), "index of refraction of the specular"),
            color(
                "specularColor",
                1.0,
                "tint of the specular's head-on reflectance, grazing staying white (Cycles' Specular Tint, OpenPBR's specular_color)",
            ),
            float("roughness", 0.3, (0.0, 1.0), "specular roughness"),
            float("anisotropy", 0.0, (-1.0, 1.0), "specular anisotropy"),
            float(
                "filmThickness",
                0.0,
                (0.0, 10000.0),
                "a thin film on the surface itself, in nanometres: its interference replaces the specular's Fresnel (Cycles' Thin Film, OpenPBR's thin_film), the tint with it, and it takes from the diffuse as a coat does (isotropic, one roughness); 0: none. The shared `iridescence` is a film coat over everything instead",
            ),
            float("filmRefractiveIndex", 1.33, (1.0, 3.0), "the surface film's refractive index"),
            color("diffuseTransmission", 0.0, "colour of light diffusely transmitted (taken from the diffuse reflection)"),
            float(
                "scatteringRadius",
                0.0,
                (0.0, 1e6),
                "mean free path of a subsurface medium behind a dielectric boundary (0: Lambertian); `albedo` is then the colour the medium shows",
            ),
            color("scatteringColor", 1.0, "per-channel scale of scatteringRadius: how far each colour travels"),
            float(
                "scatteringWeight",
                1.0,
                (0.0, 1.0),
                "share of the diffuse base that is the medium when scatteringRadius > 0; the rest stays a Lambertian reflection under the specular",
            ),
            float(
                "scatteringAnisotropy",
                0.0,
                (-0.9, 0.9),
                "Henyey-Greenstein eccentricity of the medium (the albedo inversion accounts for it)",
            ),
        ],
        shared: true,
        materials: &[],
    },
    Shader {
        id: "tessera:Fabric",
        doc: "DreamWorks fabric: the normalised specular cone around the thread over a Lambertian base.",
        inputs: &[
            color("color", 1.0, "thread (cone) colour"),
            float("roughness", 0.3, (0.0, 1.0), "fabric roughness α; the cone exponent is ceil(1 + 29(1 − α)²)"),
            float("threadRotation", 0.0, (-360.0, 360.0), "thread direction, degrees from the surface tangent"),
            float("specular", 0.5, (0.0, 1.0), "share of the cone; the rest is the diffuse base"),
            color("diffuseColor", 0.5, "diffuse base colour"),
        ],
        shared: false,
        materials: &[],
    },
    Shader {
        id: "tessera:Glitter",
        doc: "DreamWorks glitter: flakes (Worley feature spheres in object space) covering the material beneath, up to four GGX flake lobes per shading point weighted by coverage plus one lobe for the rest.",
        inputs: &[
            color("flakeColor", 0.9, "flake colour (Schlick F0)"),
            float("flakeRandomColor", 0.0, (0.0, 1.0), "how much of a random hue each flake takes"),
            float("flakeRoughness", 0.3, (0.0, 1.0), "spread of the flake normals around the surface normal (GGX roughness)"),
            float(
                "flakeSurfaceRoughness",
                0.1,
                (crate::bsdf::flake::MIN_FLAKE_ROUGHNESS, 1.0),
                "each flake's own roughness (glossy at least, so small lights glint)",
            ),
            float(
                "flakeDensity",
                4000.0,
                crate::material::glitter::DENSITY_RANGE,
                "flakes per unit of object-space volume (cells of side density^(-1/3))",
            ),
            float("flakeSize", 1.0, (0.0, 2.0), "flake sphere radius in half cells; 1 covers about a third of the surface"),
            color("baseColor", 0.1, "Lambertian colour between the flakes when `base` is not connected"),
        ],
        shared: false,
        materials: &[("base", "the material between and beneath the flakes (any material's surface output)")],
    },
    Shader {
        id: "tessera:Hair",
        doc: "Hair and fur fibres for BasisCurves: Chiang et al. 2016's model with Cycles' Principled Hair inputs (absorption from melanin, plus a tint and a coefficient added to it).",
        inputs: &[
            float("melanin", 0.8, (0.0, 1.0), "melanin amount: 0 white, 1 black (concentration −ln(1 − melanin))"),
            float("melaninRedness", 1.0, (0.0, 1.0), "share of pheomelanin (red) in the melanin"),
            color("tint", 1.0, "a colour the fibre takes on top of the melanin's (absorption by Chiang's fit; white adds none)"),
            unbounded_color("absorptionCoefficient", "absorption per unit of fibre radius, added to the rest"),
            float("roughness", 0.3, (0.0, 1.0), "longitudinal roughness βm: the highlights' width along the fibre"),
            float("radialRoughness", 0.3, (0.0, 1.0), "azimuthal roughness βn: how far light spreads around the fibre"),
            float("ior", 1.55, (1.0, 3.0), "refractive index of the fibre"),
            float("offset", 2.0, (-45.0, 45.0), "tilt of the cuticle scales in degrees: shifts the highlights along the fibre"),
            color("tintR", 1.0, "tint of the light reflected off the cuticle (R), as MaterialX's chiang_hair_bsdf has it"),
            color("tintTT", 1.0, "tint of the light through the fibre (TT)"),
            color("tintTRT", 1.0, "tint of the light reflected inside the fibre (TRT and longer paths)"),
            float("roughnessScaleTT", 0.5, (0.1, 4.0), "TT's longitudinal roughness relative to `roughness`"),
            float("roughnessScaleTRT", 2.0, (0.1, 4.0), "TRT's longitudinal roughness relative to `roughness`"),
            float(
                "radialRoughnessScaleTT",
                1.0,
                (0.1, 10.0),
                "TT's azimuthal roughness (the logistic's scale) relative to `radialRoughness`'s",
            ),
            float("radialRoughnessScaleTRT", 1.0, (0.1, 10.0), "TRT's azimuthal roughness relative to `radialRoughness`'s"),
        ],
        shared: false,
        materials: &[],
    },
];

/// A node's values by input name, defaults filled in, ranges applied: (name, value) in the
/// order the shader declares them. A textured material reads them at every shading point, where
/// a `BTreeMap` built each time (sorted, deduplicated, allocated node by node) was a third of a
/// textured metal's render.
struct Values(Vec<(&'static str, [f32; 3])>);

impl Values {
    fn read(shader: &Shader, node: Inputs, report: &mut ResolveReport) -> Values {
        let mut v: Vec<(&'static str, [f32; 3])> = shader.declared().map(|i| (i.name, i.default)).collect();
        for (name, value) in node.iter() {
            if shader.materials.iter().any(|(m, _)| *m == name) {
                continue;
            }
            let Some((k, input)) = shader.declared().enumerate().find(|(_, i)| i.name == name) else {
                report.warnings.push(format!("{}: unknown {} input '{name}'", node.path, shader.id));
                continue;
            };
            let (lo, hi) = input.range;
            let clamp = |x: f32| if x.is_finite() { x.clamp(lo, hi) } else { input.default[0] };
            let got = match (input.kind, value) {
                (Kind::Float, ParamValue::Float(x)) => Some([clamp(*x); 3]),
                (Kind::Float, ParamValue::Int(x)) => Some([clamp(*x as f32); 3]),
                (Kind::Color, ParamValue::Float3(c)) => Some([clamp(c.x), clamp(c.y), clamp(c.z)]),
                (Kind::Color, ParamValue::Float(x)) => Some([clamp(*x); 3]),
                (Kind::Vector, ParamValue::Float3(c)) if c.is_finite() => Some(c.to_array()),
                (Kind::Vector, ParamValue::Float3(_)) => {
                    report.warnings.push(format!("{}: input '{name}' is not finite; using its default", node.path));
                    Some(input.default)
                }
                (Kind::Bool, ParamValue::Bool(b)) => Some([*b as u8 as f32; 3]),
                (Kind::Bool, ParamValue::Int(i)) => Some([(*i != 0) as u8 as f32; 3]),
                _ => None,
            };
            match got {
                Some(x) => v[k].1 = x,
                None => report.warnings.push(format!("{}: input '{name}' has the wrong type {value:?}; using its default", node.path)),
            }
        }
        Values(v)
    }

    /// The value of the declared input `name`.
    fn get(&self, name: &str) -> [f32; 3] {
        self.0.iter().find(|(n, _)| *n == name).map(|(_, v)| *v).expect("a declared input")
    }

    fn f(&self, name: &str) -> f32 {
        self.get(name)[0]
    }

    fn c(&self, name: &str) -> Vec3 {
        Vec3::from_array(self.get(name))
    }

    fn b(&self, name: &str) -> bool {
        self.get(name)[0] != 0.0
    }
}

/// The uber-material of a specialized shader node, or None for an id this module does not
/// declare.
pub(crate) fn resolve(node: Inputs, report: &mut ResolveReport) -> Option<Material> {
    let shader = SHADERS.iter().find(|s| s.id == node.node_type_id)?;
    let v = Values::read(shader, node, report);
    let mut u = Uber { plastic: Weighted { weight: 0.0, params: Plastic::default() }, ..Uber::default() };
    match shader.id {
        "tessera:Metal" => {
            let (r, g) = (v.c("reflectivity"), v.c("edgeTint"));
            let fresnel = if v.b("f82") { SpecularFresnel::f82_tint(r, g) } else { SpecularFresnel::Gulbrandsen { r, g } };
            let fresnel = match v.f("filmThickness") > 0.0 {
                true => fresnel.under_film(v.f("filmRefractiveIndex"), v.f("filmThickness"), node.film_averages()).unwrap_or(fresnel),
                false => fresnel,
            };
            u.metal = Weighted { weight: 1.0, params: specular(shader, &v, fresnel) };
        }
        "tessera:Refractive" => {
            let bend = v.f("transmissionRefractiveIndex");
            let glass = Glass {
                roughness: v.f("roughness"),
                anisotropic: v.f("anisotropy"),
                ior: v.f("refractiveIndex"),
                bend_ior: if bend > 0.0 { bend } else { v.f("refractiveIndex") },
                color: v.c("transmissionColor"),
                thin: v.b("thin"),
                film_thickness: v.f("filmThickness"),
                film_ior: v.f("filmRefractiveIndex"),
            };
            if glass.thin && glass.film_thickness > 0.0 {
                report.warnings.push(format!("{}: a thin sheet takes no film; 'filmThickness' has no effect", node.path));
            }
            u.glass = Weighted { weight: 1.0, params: glass };
        }
        "tessera:SolidDielectric" => {
            if v.f("filmThickness") > 0.0 && (v.f("anisotropy") != 0.0 || v.f("doubleSpecularMix") > 0.0) {
                report.warnings.push(format!("{}: the specular under a surface film is isotropic and of one roughness", node.path));
            }
            u.plastic = Weighted { weight: 1.0, params: solid_dielectric(shader, &v) };
        }
        "tessera:Fabric" => {
            let fabric = FabricParams {
                color: v.c("color"),
                roughness: v.f("roughness"),
                angle: v.f("threadRotation").to_radians(),
                specular: v.f("specular"),
                diffuse: v.c("diffuseColor"),
            };
            u.fabric = Weighted { weight: 1.0, params: fabric };
        }
        "tessera:Glitter" => {
            let base = Plastic { diffuse: v.c("baseColor"), lambert: true, specular: None, ..Plastic::default() };
            u.plastic = Weighted { weight: 1.0, params: base };
            u.glitter = Weighted {
                weight: 1.0,
                params: GlitterParams {
                    color: v.c("flakeColor"),
                    random_color: v.f("flakeRandomColor"),
                    spread: v.f("flakeRoughness"),
                    roughness: v.f("flakeSurfaceRoughness"),
                    density: v.f("flakeDensity"),
                    size: v.f("flakeSize"),
                },
            };
        }
        "tessera:Hair" => u.hair = Weighted { weight: 1.0, params: hair(&v) },
        _ => unreachable!("every declared shader is mapped"),
    }
    let emission = if shader.shared { shared_layers(&v, &mut u) } else { Vec3::ZERO };
    let tangent = match shader.shared {
        true => Tangent { direction: v.c("tangent"), rotation: v.f("anisotropyRotation"), along_st: v.f("stTangent") >= 0.5 },
        false => Tangent::default(),
    };
    Some(Material { surface: u, emission, cut_out: false, pass_through: 0.0, tangent })
}

/// The specular of a shader's `roughness` and `anisotropy` with `fresnel`, and the shared
/// double specular where the shader takes it.
fn specular(shader: &Shader, v: &Values, fresnel: SpecularFresnel) -> Specular {
    let roughness = v.f("roughness");
    Specular {
        fresnel,
        roughness,
        anisotropic: v.f("anisotropy"),
        roughness2: if shader.shared { v.f("roughness2") } else { roughness },
        mix2: if shader.shared { v.f("doubleSpecularMix") } else { 0.0 },
    }
}

/// `tessera:SolidDielectric`'s plastic: a Lambertian or Oren-Nayar albedo under the dielectric
/// (or film) specular, diffuse transmission, and a scattering medium behind it.
fn solid_dielectric(shader: &Shader, v: &Values) -> Plastic {
    let eta = v.f("refractiveIndex");
    let dt = v.c("diffuseTransmission");
    let share = dt.max_element();
    Plastic {
        diffuse: v.c("albedo"),
        lambert: true,
        oren_nayar: v.f("diffuseRoughness"),
        diffuse_transmission: share,
        transmission_color: if share > 0.0 { dt / share } else { Vec3::ONE },
        specular: (eta > 1.0).then(|| specular(shader, v, surface_fresnel(v, eta))),
        coupling_eta: eta,
        scattering_radius: v.f("scatteringRadius"),
        scattering_color: v.c("scatteringColor"),
        scattering_weight: v.f("scatteringWeight"),
        scattering_anisotropy: v.f("scatteringAnisotropy"),
        ..Plastic::default()
    }
}

/// `tessera:Hair`'s fibre: absorption from melanin, the tint and the coefficient, summed.
fn hair(v: &Values) -> HairParams {
    let bn = v.f("radialRoughness");
    let sigma_a = crate::bsdf::hair::sigma_a_from_melanin(v.f("melanin"), v.f("melaninRedness"))
        + crate::bsdf::hair::sigma_a_from_color(v.c("tint"), bn)
        + v.c("absorptionCoefficient");
    HairParams {
        sigma_a,
        ior: v.f("ior"),
        roughness: v.f("roughness"),
        radial_roughness: bn,
        tilt: v.f("offset"),
        scale_tt: v.f("roughnessScaleTT"),
        scale_trt: v.f("roughnessScaleTRT"),
        radial_scale_tt: v.f("radialRoughnessScaleTT"),
        radial_scale_trt: v.f("radialRoughnessScaleTRT"),
        tint: [v.c("tintR"), v.c("tintTT"), v.c("tintTRT")],
    }
}

/// A solid dielectric's specular Fresnel: its surface film's interference where it has one,
/// else the dielectric's, tinted.
fn surface_fresnel(v: &Values, eta: f32) -> SpecularFresnel {
    match v.f("filmThickness") > 0.0 {
        true => SpecularFresnel::thin_film(v.f("filmRefractiveIndex"), v.f("filmThickness"), eta),
        false => SpecularFresnel::tinted_dielectric(eta, v.c("specularColor")),
    }
}

/// The coats, film, sheen, specular control and emission every shared-input shader takes,
/// set on `u`; returns the emission.
fn shared_layers(v: &Values, u: &mut Uber) -> Vec3 {
    u.clearcoat = Weighted {
        weight: v.f("clearcoat"),
        params: ClearcoatParams::Dielectric {
            ior: v.f("clearcoatRefractiveIndex"),
            roughness: v.f("clearcoatRoughness"),
            color: v.c("clearcoatAttenuationColor"),
            thickness: v.f("clearcoatThickness"),
        },
    };
    u.thin_film = Weighted {
        weight: v.f("iridescence"),
        params: ThinFilmParams {
            ior: v.f("iridescenceRefractiveIndex"),
            thickness: v.f("iridescenceThickness"),
            roughness: v.f("iridescenceRoughness"),
        },
    };
    u.sheen = Weighted { weight: v.f("sheen"), params: SheenParams { color: v.c("sheenColor"), roughness: v.f("sheenRoughness") } };
    u.fuzz = Weighted { weight: v.f("fuzz"), params: SheenParams { color: v.c("fuzzColor"), roughness: v.f("fuzzRoughness") } };
    u.specular_control = v.f("specularControl");
    v.c("emission")
}

/// The reference table of every declared shader, as docs/materials.md holds it.
pub fn markdown_reference() -> String {
    let mut out = String::new();
    let row = |i: &Input| {
        let default = match i.kind {
            Kind::Float => format!("{}", i.default[0]),
            Kind::Color => format!("({}, {}, {})", i.default[0], i.default[1], i.default[2]),
            Kind::Bool => "false".to_string(),
            Kind::Vector => format!("({}, {}, {})", i.default[0], i.default[1], i.default[2]),
        };
        let range = match i.kind {
            Kind::Bool | Kind::Vector => "-".to_string(),
            _ if i.range.1 == f32::MAX => format!("≥ {}", i.range.0),
            _ => format!("[{}, {}]", i.range.0, i.range.1),
        };
        let kind = match i.kind {
            Kind::Float => "float",
            Kind::Color => "color3f",
            Kind::Bool => "bool",
            Kind::Vector => "vector3f",
        };
        format!("| `{}` | {kind} | {default} | {range} | {} |\n", i.name, i.doc)
    };
    for s in SHADERS {
        out += &format!("### `{}`\n\n{}\n\n| input | type | default | range | meaning |\n|---|---|---|---|---|\n", s.id, s.doc);
        for i in s.inputs {
            out += &row(i);
        }
        for (name, doc) in s.materials {
            out += &format!("| `{name}` | material | - | - | {doc} |\n");
        }
        if s.shared {
            out += "| *(the shared inputs below)* | | | | |\n";
        }
        out += "\n";
    }
    out += "### Shared by `tessera:Metal`, `tessera:Refractive`, `tessera:SolidDielectric`\n\n| input | type | default | range | meaning |\n|---|---|---|---|---|\n";
    for i in SHARED {
        out += &row(i);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing;

    const DOC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/materials.md");
    const BEGIN: &str = "<!-- shader reference: generated from render-core/src/material/native.rs -->\n";
    const END: &str = "<!-- end of shader reference -->";

    fn node(id: &str, params: &[(&str, ParamValue)]) -> crate::material::MaterialNode {
        crate::material::MaterialNode {
            path: "/M/S".into(),
            node_type_id: id.into(),
            parameters: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
        }
    }

    fn resolved(id: &str, params: &[(&str, ParamValue)]) -> (Material, ResolveReport) {
        let mut r = ResolveReport::default();
        (resolve(Inputs::authored(&node(id, params)), &mut r).expect("declared shader"), r)
    }

    #[test]
    fn every_shader_resolves_with_defaults_and_conserves_energy_when_white() {
        let white = ParamValue::Float3(Vec3::ONE);
        let film = |index: f32, nm: f32| {
            vec![
                ("albedo", ParamValue::Float3(Vec3::ONE)),
                ("filmRefractiveIndex", ParamValue::Float(index)),
                ("filmThickness", ParamValue::Float(nm)),
                ("roughness", ParamValue::Float(0.3)),
            ]
        };
        let metal_film = |f82: bool| {
            vec![
                ("reflectivity", white.clone()),
                ("f82", ParamValue::Bool(f82)),
                ("filmRefractiveIndex", ParamValue::Float(2.0)),
                ("filmThickness", ParamValue::Float(300.0)),
                ("roughness", ParamValue::Float(0.3)),
            ]
        };
        let cases: [(&str, Vec<(&str, ParamValue)>); 16] = [
            ("tessera:Metal", vec![("reflectivity", white.clone()), ("edgeTint", white.clone()), ("roughness", ParamValue::Float(0.6))]),
            ("tessera:Refractive", vec![("roughness", ParamValue::Float(0.4))]),
            ("tessera:Refractive", vec![("roughness", ParamValue::Float(0.4)), ("thin", ParamValue::Bool(true))]),
            (
                "tessera:SolidDielectric",
                vec![("albedo", white.clone()), ("clearcoat", ParamValue::Float(1.0)), ("sheen", ParamValue::Float(0.5))],
            ),
            ("tessera:SolidDielectric", vec![("albedo", white.clone()), ("diffuseTransmission", ParamValue::Float3(Vec3::splat(0.4)))]),
            ("tessera:SolidDielectric", vec![("albedo", white.clone()), ("diffuseRoughness", ParamValue::Float(1.0))]),
            (
                "tessera:SolidDielectric",
                vec![("albedo", white.clone()), ("fuzz", ParamValue::Float(1.0)), ("fuzzRoughness", ParamValue::Float(0.3))],
            ),
            (
                "tessera:SolidDielectric",
                vec![
                    ("albedo", white.clone()),
                    ("specularColor", ParamValue::Float3(Vec3::new(1.0, 0.3, 0.0))),
                    ("roughness", ParamValue::Float(0.4)),
                ],
            ),
            // A film of higher index than the substrate reflects more than the bare dielectric
            // (up to a quarter head-on at 2.4); one of lower index, less.
            ("tessera:SolidDielectric", film(2.4, 120.0)),
            ("tessera:SolidDielectric", film(1.33, 500.0)),
            // A film over a white metal (Gulbrandsen's, and the F82 tint's).
            ("tessera:Metal", metal_film(false)),
            ("tessera:Metal", metal_film(true)),
            ("tessera:Fabric", vec![("color", white.clone()), ("diffuseColor", white.clone())]),
            ("tessera:Glitter", vec![("flakeColor", white.clone()), ("baseColor", white.clone()), ("flakeSize", ParamValue::Float(2.0))]),
            ("tessera:Hair", vec![("melanin", ParamValue::Float(0.0)), ("roughness", ParamValue::Float(0.5))]),
            (
                "tessera:Metal",
                vec![("reflectivity", white.clone()), ("iridescence", ParamValue::Float(1.0)), ("clearcoat", ParamValue::Float(1.0))],
            ),
        ];
        for (id, params) in cases {
            let (defaults, r) = resolved(id, &[]);
            assert!(r.warnings.is_empty() && !defaults.bsdf(true).is_empty(), "{id}: {:?}", r.warnings);
            let (m, r) = resolved(id, &params);
            assert!(r.warnings.is_empty(), "{id}: {:?}", r.warnings);
            let bsdf = m.bsdf(true);
            for wo in testing::probe_directions() {
                for wo in if bsdf.transmits() { vec![wo, -wo] } else { vec![wo] } {
                    let a = testing::albedo_estimate(&bsdf, wo, 20_000);
                    assert!(a.max_element() <= 1.0 + 1e-3 + 0.02, "{id} {params:?} at {wo:?}: {a:?}");
                }
            }
            let sides = if bsdf.transmits() { testing::Sides::Both } else { testing::Sides::Above };
            testing::assert_eval_pdf_is_both(&bsdf, sides);
            // Refraction scales radiance by 1/η'², so only its energy form is reciprocal; Chiang's
            // hair model is not reciprocal at all (crate::bsdf::hair), nor is the fuzz's LTC.
            if !m.surface.has_refraction() && m.surface.hair.weight == 0.0 && m.surface.fuzz.weight == 0.0 {
                testing::assert_reciprocal(&bsdf);
            }
        }
    }

    /// `diffuseRoughness` makes the base Oren-Nayar: without a specular (refractive index 1) a
    /// white one reflects everything (EON's point; 200 000 samples hold the estimate to 3e-3),
    /// and it flattens a lit surface by sending light back towards its source.
    #[test]
    fn a_rough_solid_dielectric_keeps_its_energy_and_scatters_back() {
        let rough = |sigma: f32| {
            let params = [
                ("albedo", ParamValue::Float3(Vec3::ONE)),
                ("refractiveIndex", ParamValue::Float(1.0)),
                ("diffuseRoughness", ParamValue::Float(sigma)),
            ];
            resolved("tessera:SolidDielectric", &params).0.bsdf(true)
        };
        let bsdf = rough(1.0);
        for mu in [1.0f32, 0.5, 0.1] {
            let a = testing::albedo_estimate(&bsdf, Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu), 200_000);
            assert!((a - Vec3::ONE).abs().max_element() < 3e-3, "μ {mu}: {a:?}");
        }
        let wo = Vec3::new(0.8, 0.0, 0.6);
        let back = bsdf.eval(wo, wo).x;
        let lambert = rough(0.0).eval(wo, wo).x;
        assert_eq!(lambert, std::f32::consts::FRAC_1_PI);
        assert!(back > 1.5 * lambert, "retro-reflection {back} against Lambert's {lambert}");
    }

    /// `f82` reads the edge tint as an F82 tint: head-on the reflectivity, near 82° the tint
    /// times Schlick's there (the same metal with a white tint, which is Schlick's curve).
    #[test]
    fn an_f82_metal_dips_near_82_degrees() {
        let gold = ParamValue::Float3(Vec3::new(0.944, 0.776, 0.373));
        let metal = |tint: Vec3| {
            let params = [
                ("reflectivity", gold.clone()),
                ("edgeTint", ParamValue::Float3(tint)),
                ("f82", ParamValue::Bool(true)),
                ("roughness", ParamValue::Float(0.0)),
            ];
            resolved("tessera:Metal", &params).0.bsdf(true)
        };
        let (tinted, plain) = (metal(Vec3::new(1.0, 0.5, 0.2)), metal(Vec3::ONE));
        let head_on = testing::albedo_estimate(&tinted, Vec3::Z, 64);
        assert!((head_on - Vec3::new(0.944, 0.776, 0.373)).abs().max_element() < 1e-4, "{head_on:?}");
        let mu = 1.0f32 / 7.0;
        let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
        let ratio = testing::albedo_estimate(&tinted, wo, 64) / testing::albedo_estimate(&plain, wo, 64);
        assert!((ratio - Vec3::new(1.0, 0.5, 0.2)).abs().max_element() < 1e-3, "{ratio:?}");
    }

    /// `specularColor` tints the specular's head-on reflectance: a smooth one over black
    /// reflects F0·tint head-on (0.04 at index 1.5), white at grazing.
    #[test]
    fn a_specular_colour_tints_the_head_on_reflection() {
        let tint = Vec3::new(1.0, 0.5, 0.25);
        let params = [
            ("albedo", ParamValue::Float3(Vec3::ZERO)),
            ("roughness", ParamValue::Float(0.0)),
            ("specularColor", ParamValue::Float3(tint)),
        ];
        let bsdf = resolved("tessera:SolidDielectric", &params).0.bsdf(true);
        let a = testing::albedo_estimate(&bsdf, Vec3::Z, 256);
        assert!((a - 0.04 * tint).abs().max_element() < 1e-4, "{a:?}");
        let grazing = testing::albedo_estimate(&bsdf, Vec3::new(1.0, 0.0, 1e-3).normalize(), 256);
        assert!(grazing.min_element() > 0.98, "{grazing:?}");
    }

    /// A surface film's specular is the film coat's lobe, isotropic and of one roughness:
    /// anisotropy or a double specular under it is reported, not dropped in silence.
    #[test]
    fn what_a_surface_film_does_not_keep_is_reported() {
        let film = [("filmThickness", ParamValue::Float(400.0)), ("anisotropy", ParamValue::Float(0.5))];
        let (_, r) = resolved("tessera:SolidDielectric", &film);
        assert_eq!(r.warnings, ["/M/S: the specular under a surface film is isotropic and of one roughness"]);
        let (_, r) = resolved("tessera:SolidDielectric", &film[..1]);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }

    /// A film on tessera:Refractive reaches its glass; at index 1 it keeps the surface in the
    /// scene (a soap bubble's wall), where bare index-1 glass is left out; a thin sheet takes
    /// none, said.
    #[test]
    fn a_film_on_glass_reaches_the_glass_and_keeps_a_bubble_in_the_scene() {
        let film = [("filmThickness", ParamValue::Float(500.0)), ("refractiveIndex", ParamValue::Float(1.0))];
        let (m, r) = resolved("tessera:Refractive", &film);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!((m.surface.glass.params.film_thickness, m.surface.glass.params.film_ior), (500.0, 1.33));
        assert!(!m.is_invisible());
        assert!(resolved("tessera:Refractive", &film[1..]).0.is_invisible());
        let (_, r) = resolved("tessera:Refractive", &[film[0].clone(), ("thin", ParamValue::Bool(true))]);
        assert_eq!(r.warnings, ["/M/S: a thin sheet takes no film; 'filmThickness' has no effect"]);
    }

    /// No shader declares an input twice, its own or shared: a node's values are found by
    /// name, the first of the name.
    #[test]
    fn no_shader_declares_an_input_twice() {
        for s in SHADERS {
            let names: Vec<_> = s.declared().map(|i| i.name).collect();
            for (k, n) in names.iter().enumerate() {
                assert!(!names[..k].contains(n), "{}: '{n}' declared twice", s.id);
            }
        }
    }

    #[test]
    fn metal_uses_gulbrandsen_and_reflects_its_reflectivity_head_on() {
        let gold = ParamValue::Float3(Vec3::new(0.944, 0.776, 0.373));
        let (m, _) = resolved("tessera:Metal", &[("reflectivity", gold), ("roughness", ParamValue::Float(0.0))]);
        let a = testing::albedo_estimate(&m.bsdf(true), Vec3::Z, 256);
        assert!((a - Vec3::new(0.944, 0.776, 0.373)).abs().max_element() < 1e-3, "{a:?}");
    }

    #[test]
    fn bad_and_unsupported_inputs_are_reported_by_name() {
        let (m, r) = resolved(
            "tessera:Refractive",
            &[
                ("refractiveIndex", ParamValue::Float(9.0)),
                ("roughness", ParamValue::Bool(true)),
                ("bogus", ParamValue::Float(1.0)),
                ("transmissionRefractiveIndex", ParamValue::Float(1.2)),
            ],
        );
        assert_eq!(m.surface.glass.params.ior, 3.0, "clamped to the declared range");
        assert_eq!(m.surface.glass.params.bend_ior, 1.2, "transmissionRefractiveIndex bends");
        for needle in ["'roughness' has the wrong type", "unknown tessera:Refractive input 'bogus'"] {
            assert!(r.warnings.iter().any(|w| w.contains(needle) && w.contains("/M/S")), "{needle}: {:?}", r.warnings);
        }
        let (m, r) = resolved("tessera:SolidDielectric", &[("scatteringRadius", ParamValue::Float(0.1))]);
        assert!(r.warnings.is_empty() && m.medium().is_some(), "{:?}", r.warnings);
    }

    #[test]
    fn docs_hold_the_current_shader_reference() {
        let doc = std::fs::read_to_string(DOC).expect("docs/materials.md");
        let expected = format!("{BEGIN}{}{END}", markdown_reference());
        assert!(
            doc.contains(&expected),
            "docs/materials.md's shader reference is stale: run `cargo test -p render-core write_shader_reference -- --ignored`"
        );
    }

    #[test]
    #[ignore = "rewrites docs/materials.md"]
    fn write_shader_reference() {
        let doc = std::fs::read_to_string(DOC).expect("docs/materials.md");
        let table = format!("{BEGIN}{}{END}", markdown_reference());
        let new = match (doc.find(BEGIN), doc.find(END)) {
            (Some(a), Some(b)) => format!("{}{table}{}", &doc[..a], &doc[b + END.len()..]),
            _ => format!("{doc}\n## Tessera's own shaders\n\n{table}\n"),
        };
        std::fs::write(DOC, new).unwrap();
    }
}
