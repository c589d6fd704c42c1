//! The uber-material every front-end resolves to, and the parameter blending that layers
//! materials (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2: "parameter resolution, then closure creation").
//!
//! Parameters live in families, as Imageworks' shaders track them (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Putting it all
//! together": Metal, Plastic, Glass, "parameter blending within each lobe ... avoids
//! contamination in cases like dirt on glass"), plus the DreamWorks fabric as a fourth family.
//! Each family has a weight (the weights sum to at most 1) and its own parameters; blending
//! two materials interpolates each family's weight linearly and its parameters weighted by
//! how much of the family each side holds, so a family one side lacks does not pull the
//! other's parameters towards zero. Coats (clearcoat, sheen) blend the same way by coverage.
//! Then [`Uber::bsdf`] builds one [`Bsdf`] holding only the non-zero lobes.

use glam::Vec3;

use super::glitter::GlitterParams;
pub use super::mix::Mix;
use crate::bsdf::{
    Bsdf, CharlieSheen, Clearcoat, Coat, Dielectric, DielectricCoat, DiffuseTransmission, DisneyDiffuse, Fabric, Fuzz, GgxReflection, Hair,
    Lobe, OrenNayar, Sheen, SpecularFresnel, ThinDielectric, ThinFilmCoat,
};

/// Share of `wb` in `wa + wb` (0 when both are 0).
fn share(wa: f32, wb: f32) -> f32 {
    if wa + wb > 0.0 { wb / (wa + wb) } else { 0.0 }
}

// (1 − t)·a + t·b rather than a + t(b − a): exactly b at t = 1, so a mask of 1 gives A's
// parameters bit for bit.
impl Mix for f32 {
    fn mix(&self, wa: f32, other: &Self, wb: f32) -> Self {
        let t = share(wa, wb);
        self * (1.0 - t) + other * t
    }
}

impl Mix for Vec3 {
    fn mix(&self, wa: f32, other: &Self, wb: f32) -> Self {
        let t = share(wa, wb);
        *self * (1.0 - t) + *other * t
    }
}

/// A discrete choice (a flag, a Fresnel model, a coat kind): the side that holds more.
fn pick<T>(a: T, wa: f32, b: T, wb: f32) -> T {
    if share(wa, wb) > 0.5 { b } else { a }
}

impl Mix for bool {
    fn mix(&self, wa: f32, other: &Self, wb: f32) -> Self {
        pick(*self, wa, *other, wb)
    }
}

impl Mix for SpecularFresnel {
    fn mix(&self, wa: f32, other: &Self, wb: f32) -> Self {
        use SpecularFresnel as F;
        match (*self, *other) {
            (F::Gulbrandsen { r, g }, F::Gulbrandsen { r: r2, g: g2 }) => F::Gulbrandsen { r: r.mix(wa, &r2, wb), g: g.mix(wa, &g2, wb) },
            (F::Schlick { f0 }, F::Schlick { f0: f2 }) => F::Schlick { f0: f0.mix(wa, &f2, wb) },
            (F::Dielectric { eta }, F::Dielectric { eta: e2 }) => F::Dielectric { eta: eta.mix(wa, &e2, wb) },
            // A plain dielectric is a tinted one of white tint.
            (F::Dielectric { eta } | F::TintedDielectric { eta, .. }, F::Dielectric { eta: e2 } | F::TintedDielectric { eta: e2, .. }) => {
                let tint = |f: SpecularFresnel| if let F::TintedDielectric { tint, .. } = f { tint } else { Vec3::ONE };
                F::tinted_dielectric(eta.mix(wa, &e2, wb), tint(*self).mix(wa, &tint(*other), wb))
            }
            (F::F82Tint { f0, b }, F::F82Tint { f0: f2, b: b2 }) => F::F82Tint { f0: f0.mix(wa, &f2, wb), b: b.mix(wa, &b2, wb) },
            (a, b) => pick(a, wa, b, wb),
        }
    }
}

/// A weight or scale clamped to [0, 1]; 0 where it is not finite.
fn unit(x: f32) -> f32 {
    if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 }
}

/// A dielectric specular whose Fresnel is a surface film's (`tessera:SolidDielectric`'s
/// `filmThickness`): built as a [`ThinFilmCoat`] over the diffuse, isotropic.
#[derive(Clone, Copy, Debug)]
struct FilmSpecular {
    roughness: f32,
    film: f32,
    thickness: f32,
    substrate: f32,
}

impl FilmSpecular {
    fn weighted(&self, weight: f32, compensate: bool) -> ThinFilmCoat {
        ThinFilmCoat::new(weight, self.roughness, self.film, self.thickness, self.substrate, compensate)
    }
}

/// A microfacet specular: Fresnel, roughness, anisotropy, and Imageworks' double specular
/// (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Double specular": a second roughness and its share, a linear combination of
/// energy-preserving lobes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Specular {
    /// Reflectance.
    pub fresnel: SpecularFresnel,
    /// Roughness (α = roughness²).
    pub roughness: f32,
    /// Anisotropy in [−1, 1].
    pub anisotropic: f32,
    /// Second roughness.
    pub roughness2: f32,
    /// Share of the second roughness in [0, 1].
    pub mix2: f32,
}

impl Default for Specular {
    fn default() -> Self {
        Specular { fresnel: SpecularFresnel::Dielectric { eta: 1.5 }, roughness: 0.5, anisotropic: 0.0, roughness2: 0.5, mix2: 0.0 }
    }
}

impl Mix for Specular {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        Specular {
            fresnel: self.fresnel.mix(wa, &o.fresnel, wb),
            roughness: self.roughness.mix(wa, &o.roughness, wb),
            anisotropic: self.anisotropic.mix(wa, &o.anisotropic, wb),
            roughness2: self.roughness2.mix(wa, &o.roughness2, wb),
            mix2: self.mix2.mix(wa, &o.mix2, wb),
        }
    }
}

impl Specular {
    /// A specular whose Fresnel is a thin film's, as the coat that carries it (full weight).
    fn film(&self) -> Option<FilmSpecular> {
        match self.fresnel {
            SpecularFresnel::ThinFilm { film, thickness, substrate, .. } => {
                Some(FilmSpecular { roughness: self.roughness, film, thickness, substrate })
            }
            _ => None,
        }
    }

    /// The lobes, weighted (one, or two for a double specular), scaled by `weight`.
    fn push(&self, bsdf: &mut Bsdf, weight: f32, compensate: bool) {
        let m = self.mix2.clamp(0.0, 1.0);
        bsdf.push_weighted(
            Lobe::GgxReflection(GgxReflection::new(self.roughness, self.anisotropic, self.fresnel, compensate)),
            weight * (1.0 - m),
        );
        bsdf.push_weighted(
            Lobe::GgxReflection(GgxReflection::new(self.roughness2, self.anisotropic, self.fresnel, compensate)),
            weight * m,
        );
    }
}

/// The opaque dielectric family: a diffuse base under a dielectric specular.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plastic {
    /// Diffuse albedo.
    pub diffuse: Vec3,
    /// Disney diffuse roughness (retro-reflection); ignored when `lambert`.
    pub diffuse_roughness: f32,
    /// Lambertian diffuse instead of Disney's.
    pub lambert: bool,
    /// Oren-Nayar roughness σ of the Lambertian base (energy-preserving, OpenPBR's
    /// `base_diffuse_roughness`); 0 keeps it Lambertian. Thin surfaces keep Disney's flatness.
    pub oren_nayar: f32,
    /// Disney thin-surface flatness.
    pub flatness: f32,
    /// Share of the diffuse that transmits, and its colour.
    pub diffuse_transmission: f32,
    /// Colour of the diffuse transmission.
    pub transmission_color: Vec3,
    /// The specular, absent for `specular` 0.
    pub specular: Option<Specular>,
    /// The η the diffuse couples to (the most energy the specular can take).
    pub coupling_eta: f32,
    /// Diffuse scale for specular colours brighter than the coupling table covers.
    pub diffuse_scale: f32,
    /// Disney's sheen colour (`tessera:Principled`), added on top.
    pub disney_sheen: Vec3,
    /// DreamWorks `scatteringRadius`: when positive, the diffuse base becomes a scattering
    /// medium behind a dielectric boundary ([`crate::subsurface`]), whose visible colour is
    /// `diffuse`.
    pub scattering_radius: f32,
    /// Per-channel scale of the mean free path (`scatteringColor`).
    pub scattering_color: Vec3,
    /// Share of the diffuse base that is the medium (`scatteringWeight`); the rest stays a
    /// diffuse reflection under the specular, as a mix of closures weighs them.
    pub scattering_weight: f32,
    /// Phase function eccentricity of the medium.
    pub scattering_anisotropy: f32,
}

impl Default for Plastic {
    fn default() -> Self {
        Plastic {
            diffuse: Vec3::splat(0.18),
            diffuse_roughness: 0.5,
            lambert: true,
            oren_nayar: 0.0,
            flatness: 0.0,
            diffuse_transmission: 0.0,
            transmission_color: Vec3::ONE,
            specular: Some(Specular::default()),
            coupling_eta: 1.5,
            diffuse_scale: 1.0,
            disney_sheen: Vec3::ZERO,
            scattering_radius: 0.0,
            scattering_color: Vec3::ONE,
            scattering_weight: 1.0,
            scattering_anisotropy: 0.0,
        }
    }
}

impl Plastic {
    /// The diffuse base: Oren-Nayar where a Lambertian base is rough, Disney's otherwise.
    fn diffuse_lobe(&self, coupling: Option<(f32, f32)>) -> Lobe {
        if self.lambert && self.oren_nayar > 0.0 && self.flatness == 0.0 {
            return Lobe::OrenNayar(OrenNayar::new(self.diffuse, self.oren_nayar, coupling));
        }
        Lobe::DisneyDiffuse(DisneyDiffuse::new(self.diffuse, self.diffuse_roughness, self.flatness, coupling, self.lambert))
    }
}

impl Mix for Plastic {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        let specular = match (self.specular, o.specular) {
            (Some(a), Some(b)) => Some(a.mix(wa, &b, wb)),
            (a, b) => pick(a, wa, b, wb),
        };
        Plastic {
            diffuse: self.diffuse.mix(wa, &o.diffuse, wb),
            diffuse_roughness: self.diffuse_roughness.mix(wa, &o.diffuse_roughness, wb),
            lambert: self.lambert.mix(wa, &o.lambert, wb),
            oren_nayar: self.oren_nayar.mix(wa, &o.oren_nayar, wb),
            flatness: self.flatness.mix(wa, &o.flatness, wb),
            diffuse_transmission: self.diffuse_transmission.mix(wa, &o.diffuse_transmission, wb),
            transmission_color: self.transmission_color.mix(wa, &o.transmission_color, wb),
            specular,
            coupling_eta: self.coupling_eta.mix(wa, &o.coupling_eta, wb),
            diffuse_scale: self.diffuse_scale.mix(wa, &o.diffuse_scale, wb),
            disney_sheen: self.disney_sheen.mix(wa, &o.disney_sheen, wb),
            scattering_radius: self.scattering_radius.mix(wa, &o.scattering_radius, wb),
            scattering_color: self.scattering_color.mix(wa, &o.scattering_color, wb),
            scattering_weight: self.scattering_weight.mix(wa, &o.scattering_weight, wb),
            scattering_anisotropy: self.scattering_anisotropy.mix(wa, &o.scattering_anisotropy, wb),
        }
    }
}

/// The glass family: a rough dielectric interface, or a thin sheet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glass {
    /// Roughness of reflection and transmission.
    pub roughness: f32,
    /// Anisotropy.
    pub anisotropic: f32,
    /// Refractive index: how much reflects.
    pub ior: f32,
    /// The index light bends by: `ior` for real glass; DreamWorks' `transmissionRefractiveIndex`
    /// decouples it (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.3).
    pub bend_ior: f32,
    /// Transmission tint (for a thin sheet, one crossing's colour).
    pub color: Vec3,
    /// A thin sheet rather than a solid's boundary.
    pub thin: bool,
    /// Thickness in nanometres of a thin film on the boundary, whose interference replaces
    /// its Fresnel term ([`crate::bsdf::GlassFilm`]); 0: none. Sheets take none.
    pub film_thickness: f32,
    /// The film's refractive index.
    pub film_ior: f32,
}

impl Default for Glass {
    fn default() -> Self {
        Glass {
            roughness: 0.0,
            anisotropic: 0.0,
            ior: 1.5,
            bend_ior: 1.5,
            color: Vec3::ONE,
            thin: false,
            film_thickness: 0.0,
            film_ior: 1.33,
        }
    }
}

impl Mix for Glass {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        Glass {
            roughness: self.roughness.mix(wa, &o.roughness, wb),
            anisotropic: self.anisotropic.mix(wa, &o.anisotropic, wb),
            ior: self.ior.mix(wa, &o.ior, wb),
            bend_ior: self.bend_ior.mix(wa, &o.bend_ior, wb),
            color: self.color.mix(wa, &o.color, wb),
            thin: self.thin.mix(wa, &o.thin, wb),
            film_thickness: self.film_thickness.mix(wa, &o.film_thickness, wb),
            film_ior: self.film_ior.mix(wa, &o.film_ior, wb),
        }
    }
}

/// The hair family: a fibre of Chiang et al. 2016 (`tessera:Hair`), for curves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HairParams {
    /// Absorption inside the fibre, per unit of its radius.
    pub sigma_a: Vec3,
    /// Refractive index.
    pub ior: f32,
    /// Longitudinal roughness βm.
    pub roughness: f32,
    /// Azimuthal roughness βn.
    pub radial_roughness: f32,
    /// Cuticle tilt, degrees.
    pub tilt: f32,
    /// TT's and TRT's longitudinal roughness relative to R's.
    pub scale_tt: f32,
    /// See [`Self::scale_tt`].
    pub scale_trt: f32,
    /// TT's and TRT's azimuthal roughness relative to R's.
    pub radial_scale_tt: f32,
    /// See [`Self::radial_scale_tt`].
    pub radial_scale_trt: f32,
    /// Tints of R, TT and TRT.
    pub tint: [Vec3; 3],
}

impl Default for HairParams {
    fn default() -> Self {
        HairParams {
            sigma_a: Vec3::ZERO,
            ior: 1.55,
            roughness: 0.3,
            radial_roughness: 0.3,
            tilt: 2.0,
            scale_tt: 0.5,
            scale_trt: 2.0,
            radial_scale_tt: 1.0,
            radial_scale_trt: 1.0,
            tint: [Vec3::ONE; 3],
        }
    }
}

impl Mix for HairParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        HairParams {
            sigma_a: self.sigma_a.mix(wa, &o.sigma_a, wb),
            ior: self.ior.mix(wa, &o.ior, wb),
            roughness: self.roughness.mix(wa, &o.roughness, wb),
            radial_roughness: self.radial_roughness.mix(wa, &o.radial_roughness, wb),
            tilt: self.tilt.mix(wa, &o.tilt, wb),
            scale_tt: self.scale_tt.mix(wa, &o.scale_tt, wb),
            scale_trt: self.scale_trt.mix(wa, &o.scale_trt, wb),
            radial_scale_tt: self.radial_scale_tt.mix(wa, &o.radial_scale_tt, wb),
            radial_scale_trt: self.radial_scale_trt.mix(wa, &o.radial_scale_trt, wb),
            tint: [0, 1, 2].map(|k| self.tint[k].mix(wa, &o.tint[k], wb)),
        }
    }
}

/// The fabric family: the DreamWorks cone over a Lambertian base, in proportion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FabricParams {
    /// Thread (specular) colour.
    pub color: Vec3,
    /// Fabric roughness α.
    pub roughness: f32,
    /// Thread direction, radians from the tangent.
    pub angle: f32,
    /// Share of the cone; the rest is the diffuse base.
    pub specular: f32,
    /// Diffuse colour of the base.
    pub diffuse: Vec3,
}

impl Default for FabricParams {
    fn default() -> Self {
        FabricParams { color: Vec3::ONE, roughness: 0.3, angle: 0.0, specular: 0.5, diffuse: Vec3::splat(0.5) }
    }
}

impl Mix for FabricParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        FabricParams {
            color: self.color.mix(wa, &o.color, wb),
            roughness: self.roughness.mix(wa, &o.roughness, wb),
            angle: self.angle.mix(wa, &o.angle, wb),
            specular: self.specular.mix(wa, &o.specular, wb),
            diffuse: self.diffuse.mix(wa, &o.diffuse, wb),
        }
    }
}

/// A clearcoat: Disney's GTR1 or the dielectric layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClearcoatParams {
    /// Disney: `clearcoat` and `clearcoatGloss`.
    Disney {
        /// Gloss in [0, 1].
        gloss: f32,
    },
    /// Imageworks / DreamWorks: refractive index, roughness, attenuation colour and thickness.
    Dielectric {
        /// Refractive index.
        ior: f32,
        /// Roughness.
        roughness: f32,
        /// Colour of a head-on round trip through thickness 1.
        color: Vec3,
        /// Thickness.
        thickness: f32,
    },
}

impl Mix for ClearcoatParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        use ClearcoatParams as C;
        match (*self, *o) {
            (C::Disney { gloss }, C::Disney { gloss: g2 }) => C::Disney { gloss: gloss.mix(wa, &g2, wb) },
            (C::Dielectric { ior, roughness, color, thickness }, C::Dielectric { ior: i2, roughness: r2, color: c2, thickness: t2 }) => {
                C::Dielectric {
                    ior: ior.mix(wa, &i2, wb),
                    roughness: roughness.mix(wa, &r2, wb),
                    color: color.mix(wa, &c2, wb),
                    thickness: thickness.mix(wa, &t2, wb),
                }
            }
            (a, b) => pick(a, wa, b, wb),
        }
    }
}

/// A thin-film coat (iridescence); the substrate's index is the material's own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilmParams {
    /// Film refractive index.
    pub ior: f32,
    /// Thickness in nanometres.
    pub thickness: f32,
    /// Roughness.
    pub roughness: f32,
}

impl Mix for ThinFilmParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        ThinFilmParams {
            ior: self.ior.mix(wa, &o.ior, wb),
            thickness: self.thickness.mix(wa, &o.thickness, wb),
            roughness: self.roughness.mix(wa, &o.roughness, wb),
        }
    }
}

/// A sheen coat (Charlie's or the fuzz's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SheenParams {
    /// Colour.
    pub color: Vec3,
    /// Roughness.
    pub roughness: f32,
}

impl Mix for SheenParams {
    fn mix(&self, wa: f32, o: &Self, wb: f32) -> Self {
        SheenParams { color: self.color.mix(wa, &o.color, wb), roughness: self.roughness.mix(wa, &o.roughness, wb) }
    }
}

/// A family or coat with its weight.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Weighted<T> {
    /// Weight (families) or coverage (coats) in [0, 1].
    pub weight: f32,
    /// Parameters.
    pub params: T,
}

impl<T: Mix> Weighted<T> {
    /// A over B: `self` is B, `a` is A, `mask` A's coverage.
    fn over(&self, a: &Self, mask: f32) -> Self {
        let (wb, wa) = ((1.0 - mask) * self.weight, mask * a.weight);
        Weighted { weight: wb + wa, params: self.params.mix(wb, &a.params, wa) }
    }
}

/// The resolved parameters of one material instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Uber {
    /// Conductors.
    pub metal: Weighted<Specular>,
    /// Opaque dielectrics.
    pub plastic: Weighted<Plastic>,
    /// Glass.
    pub glass: Weighted<Glass>,
    /// Fabric.
    pub fabric: Weighted<FabricParams>,
    /// Hair fibres.
    pub hair: Weighted<HairParams>,
    /// Clearcoat over everything.
    pub clearcoat: Weighted<ClearcoatParams>,
    /// Thin film over the clearcoat and everything beneath.
    pub thin_film: Weighted<ThinFilmParams>,
    /// Charlie sheen over everything (and over the clearcoat).
    pub sheen: Weighted<SheenParams>,
    /// Zeltner et al.'s fuzz over everything, the Charlie sheen included (OpenPBR's `fuzz`,
    /// Cycles' Principled sheen): the topmost layer, as both specify it.
    pub fuzz: Weighted<SheenParams>,
    /// Glitter flakes over everything, sheen included; the weight scales their coverage.
    pub glitter: Weighted<GlitterParams>,
    /// DreamWorks `specularControl` in [0, 1]: scales every specular lobe (1: untouched).
    pub specular_control: f32,
}

impl Default for Uber {
    /// UsdPreviewSurface's defaults: an opaque dielectric.
    fn default() -> Self {
        Uber {
            metal: Weighted { weight: 0.0, params: Specular::default() },
            plastic: Weighted { weight: 1.0, params: Plastic::default() },
            glass: Weighted { weight: 0.0, params: Glass::default() },
            fabric: Weighted { weight: 0.0, params: FabricParams::default() },
            hair: Weighted { weight: 0.0, params: HairParams::default() },
            clearcoat: Weighted { weight: 0.0, params: ClearcoatParams::Disney { gloss: 1.0 } },
            thin_film: Weighted { weight: 0.0, params: ThinFilmParams { ior: 1.33, thickness: 400.0, roughness: 0.1 } },
            sheen: Weighted { weight: 0.0, params: SheenParams { color: Vec3::ONE, roughness: 0.3 } },
            fuzz: Weighted { weight: 0.0, params: SheenParams { color: Vec3::ONE, roughness: 0.5 } },
            glitter: Weighted { weight: 0.0, params: GlitterParams::default() },
            specular_control: 1.0,
        }
    }
}

impl Uber {
    /// "A over B" with one mask (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 2.2): `self` is B.
    pub fn layered_under(&self, a: &Uber, mask: f32) -> Uber {
        let m = unit(mask);
        Uber {
            metal: self.metal.over(&a.metal, m),
            plastic: self.plastic.over(&a.plastic, m),
            glass: self.glass.over(&a.glass, m),
            fabric: self.fabric.over(&a.fabric, m),
            hair: self.hair.over(&a.hair, m),
            clearcoat: self.clearcoat.over(&a.clearcoat, m),
            thin_film: self.thin_film.over(&a.thin_film, m),
            sheen: self.sheen.over(&a.sheen, m),
            fuzz: self.fuzz.over(&a.fuzz, m),
            glitter: self.glitter.over(&a.glitter, m),
            specular_control: self.specular_control.mix(1.0 - m, &a.specular_control, m),
        }
    }

    /// The same material with every microfacet lobe at least `floor` rough (caustic
    /// avoidance's roughness clamping, [`crate::caustics`]); diffuse, sheen and fabric lobes
    /// have no roughness to clamp.
    pub fn with_roughness_floor(&self, floor: f32) -> Uber {
        let mut u = *self;
        let clamp = |s: &mut Specular| {
            s.roughness = s.roughness.max(floor);
            s.roughness2 = s.roughness2.max(floor);
        };
        clamp(&mut u.metal.params);
        if let Some(s) = u.plastic.params.specular.as_mut() {
            clamp(s);
        }
        u.glass.params.roughness = u.glass.params.roughness.max(floor);
        u.thin_film.params.roughness = u.thin_film.params.roughness.max(floor);
        u.glitter.params.roughness = u.glitter.params.roughness.max(floor);
        u.hair.params.roughness = u.hair.params.roughness.max(floor);
        u.clearcoat.params = match u.clearcoat.params {
            // Disney's coat: α = lerp(0.1, 0.001, gloss); roughness r ↔ α = r², so cap the gloss.
            ClearcoatParams::Disney { gloss } => {
                let max_gloss = ((0.1 - floor * floor) / 0.099).clamp(0.0, 1.0);
                ClearcoatParams::Disney { gloss: gloss.min(max_gloss) }
            }
            ClearcoatParams::Dielectric { ior, roughness, color, thickness } => {
                ClearcoatParams::Dielectric { ior, roughness: roughness.max(floor), color, thickness }
            }
        };
        u
    }

    /// The scattering medium behind the surface, when the plastic family has a positive
    /// `scatteringRadius` (subsurface scattering).
    pub fn medium(&self) -> Option<crate::subsurface::Medium> {
        let p = &self.plastic.params;
        let r = p.scattering_radius;
        (self.plastic.weight > 0.0 && r.is_finite() && r > 0.0 && p.scattering_weight > 0.0)
            .then(|| {
                let mfp = r * p.scattering_color.max(Vec3::splat(1e-3));
                crate::subsurface::Medium::new(mfp, p.diffuse, p.scattering_anisotropy, p.coupling_eta)
            })
            .flatten()
    }

    /// True when part of the diffuse base, not all of it, is a scattering medium
    /// (`scatteringWeight` between 0 and 1).
    pub fn is_partly_medium(&self) -> bool {
        self.plastic.params.scattering_weight < 1.0 && self.medium().is_some()
    }

    /// The surface as a path inside its medium meets it: the medium's boundary alone. The
    /// diffuse share beside the medium faces the outside; light walking inside only ever
    /// reaches the boundary.
    pub fn inside_medium(&self) -> Uber {
        let mut u = *self;
        u.plastic.params.scattering_weight = 1.0;
        u
    }

    /// True when a lobe transmits light through a solid's boundary (bending it).
    pub fn has_refraction(&self) -> bool {
        self.glass.weight > 0.0 && !self.glass.params.thin
    }

    /// The BSDF, holding only its non-zero lobes, in the order: plastic (diffuse, diffuse
    /// transmission, specular, Disney sheen), metal, glass, fabric, hair, then the coats. Glitter
    /// is here as seen from far away ([`GlitterParams::far_field`]); a renderer that knows the
    /// shading point uses [`Uber::base_bsdf`] and [`GlitterParams::apply`] there.
    pub fn bsdf(&self, compensate: bool) -> Bsdf {
        let mut b = self.build_bsdf(compensate, false);
        self.far_glitter(&mut b);
        b
    }

    /// The BSDF without its glitter flakes.
    pub fn base_bsdf(&self, compensate: bool, every_lobe: bool) -> Bsdf {
        self.build_bsdf(compensate, every_lobe)
    }

    /// True when glitter flakes cover part of the surface.
    pub fn has_glitter(&self) -> bool {
        self.glitter.weight > 0.0
    }

    fn far_glitter(&self, b: &mut Bsdf) {
        if self.has_glitter() {
            let g = &self.glitter.params;
            g.apply(self.glitter.weight, &g.far_field(), b, |n| n);
        }
    }

    /// The BSDF with every lobe the uber-material can build, those the material does not use
    /// at weight 0: what an uber-shader without a render plan would evaluate. The image is
    /// the same; `tessera bench effects` measures what the plan saves.
    pub fn bsdf_with_every_lobe(&self, compensate: bool) -> Bsdf {
        let mut b = self.build_bsdf(compensate, true);
        self.far_glitter(&mut b);
        b
    }

    fn build_bsdf(&self, compensate: bool, every: bool) -> Bsdf {
        let mut bsdf = if every { Bsdf::keeping_zero_lobes() } else { Bsdf::default() };
        let spec_scale = unit(self.specular_control);
        self.push_plastic(&mut bsdf, compensate, every, spec_scale);
        self.push_metal_and_glass(&mut bsdf, compensate, every, spec_scale);
        self.push_fibres(&mut bsdf, every, spec_scale);
        self.push_coats(&mut bsdf, compensate, every, spec_scale);
        bsdf
    }

    /// The plastic family: its medium's boundary where it scatters beneath, and the rest of it
    /// as a surface.
    fn push_plastic(&self, bsdf: &mut Bsdf, compensate: bool, every: bool, spec_scale: f32) {
        let plastic_w = unit(self.plastic.weight);
        let medium_share = if plastic_w > 0.0 && self.medium().is_some() { unit(self.plastic.params.scattering_weight) } else { 0.0 };
        if medium_share > 0.0 {
            // Subsurface: the plastic's specular becomes the boundary of its medium, which the
            // integrator's random walk crosses; its diffuse colour lives in the medium.
            let p = &self.plastic.params;
            let (roughness, anisotropic) = p.specular.map_or((0.0, 0.0), |s| (s.roughness, s.anisotropic));
            let eta = p.coupling_eta.max(1.0);
            bsdf.push_weighted(
                Lobe::Dielectric(Dielectric::new(roughness, anisotropic, eta, Vec3::ONE).compensated(compensate)),
                plastic_w * medium_share,
            );
        }
        // The rest of the plastic is a surface: a mix of the medium's boundary and the plain
        // plastic, weighed as a mix of closures is (each conserves energy, so the sum does).
        let surface_w = plastic_w * (1.0 - medium_share);
        if surface_w > 0.0 || (every && medium_share == 0.0) {
            self.push_plastic_surface(bsdf, compensate, every, spec_scale, surface_w, medium_share > 0.0);
        }
    }

    /// The plastic's surface at weight `plastic_w`: diffuse (coupled to the specular), diffuse
    /// transmission unless `beside_medium`, specular, Disney sheen, and a surface film as a coat.
    fn push_plastic_surface(&self, bsdf: &mut Bsdf, compensate: bool, every: bool, spec_scale: f32, plastic_w: f32, beside_medium: bool) {
        let p = &self.plastic.params;
        let film = p.specular.and_then(|s| s.film());
        let coupling = match p.specular {
            // A surface film is layered as a coat, which scales the diffuse itself.
            Some(_) if film.is_some() => None,
            Some(s) if compensate => {
                let ggx = crate::bsdf::microfacet::Ggx::from_roughness(s.roughness, s.anisotropic);
                Some((p.coupling_eta, ggx.ax.min(ggx.ay).sqrt().min(1.0)))
            }
            _ => None,
        };
        // Beside a medium, light that crosses the surface is the medium's: a diffuse
        // transmission would enter it as if through the boundary.
        let dt = if beside_medium { 0.0 } else { unit(p.diffuse_transmission) };
        let scale = if compensate { p.diffuse_scale } else { 1.0 };
        bsdf.push_weighted(p.diffuse_lobe(coupling), plastic_w * (1.0 - dt) * scale);
        bsdf.push_weighted(Lobe::DiffuseTransmission(DiffuseTransmission { color: p.transmission_color, coupling }), plastic_w * dt);
        match p.specular {
            Some(_) if film.is_some() => {}
            Some(s) => s.push(bsdf, plastic_w * spec_scale, compensate),
            None if every => Specular::default().push(bsdf, 0.0, compensate),
            None => {}
        }
        if p.disney_sheen.max_element() > 0.0 || every {
            bsdf.push_weighted(Lobe::Sheen(Sheen { color: p.disney_sheen }), plastic_w);
        }
        if let Some(coat) = film {
            // Its interference can reflect more than the bare dielectric whose albedo the
            // diffuse coupling reads (a quarter head-on for index 2.4 over 1.5, against 4%),
            // so it takes from the diffuse as a coat does (`Bsdf::coat_with`).
            bsdf.coat_with(Coat::ThinFilm(coat.weighted(plastic_w * spec_scale, compensate)), compensate);
        }
    }

    /// The metal family and the glass family (thin sheet or refracting interface).
    fn push_metal_and_glass(&self, bsdf: &mut Bsdf, compensate: bool, every: bool, spec_scale: f32) {
        let metal_w = unit(self.metal.weight);
        if metal_w > 0.0 || every {
            self.metal.params.push(bsdf, metal_w * spec_scale, compensate);
        }
        let glass_w = unit(self.glass.weight);
        if glass_w > 0.0 || every {
            let g = &self.glass.params;
            if g.thin || every {
                let w = if g.thin { glass_w } else { 0.0 };
                bsdf.push_weighted(Lobe::ThinDielectric(ThinDielectric::new(g.roughness, g.anisotropic, g.ior, g.color, compensate)), w);
            }
            if !g.thin || every {
                let w = if g.thin { 0.0 } else { glass_w };
                let interface = Dielectric::new(g.roughness, g.anisotropic, g.bend_ior, g.color)
                    .with_fresnel_eta(g.ior)
                    .with_film(g.film_ior, g.film_thickness);
                bsdf.push_weighted(Lobe::Dielectric(interface.compensated(compensate)), w);
            }
        }
    }

    /// The coats over everything, bottom to top: clearcoat, thin film, sheen, fuzz.
    fn push_coats(&self, bsdf: &mut Bsdf, compensate: bool, every: bool, spec_scale: f32) {
        let coat_w = unit(self.clearcoat.weight) * spec_scale;
        if coat_w > 0.0 || every {
            let coat = match self.clearcoat.params {
                ClearcoatParams::Disney { gloss } => Coat::Disney(Clearcoat::new(coat_w, gloss)),
                ClearcoatParams::Dielectric { ior, roughness, color, thickness } => {
                    Coat::Dielectric(DielectricCoat::new(coat_w, ior, roughness, color, thickness))
                }
            };
            bsdf.coat_with(coat, compensate);
        }
        let film_w = unit(self.thin_film.weight) * spec_scale;
        if film_w > 0.0 || every {
            let f = &self.thin_film.params;
            // The film lies on the material itself: its index is the glass's, else the
            // dielectric specular's.
            let substrate = if self.glass.weight > 0.0 { self.glass.params.ior } else { self.plastic.params.coupling_eta };
            bsdf.coat_with(
                Coat::ThinFilm(ThinFilmCoat::new(film_w, f.roughness, f.ior, f.thickness, substrate.max(1.0), compensate)),
                compensate,
            );
        }
        let sheen_w = unit(self.sheen.weight);
        if sheen_w > 0.0 || every {
            let s = &self.sheen.params;
            bsdf.coat_with(Coat::Sheen(CharlieSheen::new(sheen_w * s.color.clamp(Vec3::ZERO, Vec3::ONE), s.roughness)), compensate);
        }
        let fuzz_w = unit(self.fuzz.weight);
        if fuzz_w > 0.0 || every {
            let f = &self.fuzz.params;
            bsdf.coat_with(Coat::Fuzz(Fuzz::new(fuzz_w * f.color.clamp(Vec3::ZERO, Vec3::ONE), f.roughness)), compensate);
        }
    }

    /// The fibre families' lobes: fabric (its cone over a Lambertian base) and hair.
    fn push_fibres(&self, bsdf: &mut Bsdf, every: bool, spec_scale: f32) {
        let fabric_w = unit(self.fabric.weight);
        if fabric_w > 0.0 || every {
            // The normalised cone reflects at most 1 and the base is a Lambertian of albedo ≤ 1,
            // so their convex combination conserves energy.
            let f = &self.fabric.params;
            let s = unit(f.specular);
            bsdf.push_weighted(Lobe::Fabric(Fabric::new(f.color, f.roughness, f.angle)), fabric_w * s * spec_scale);
            bsdf.push_weighted(Lobe::Lambert(crate::bsdf::Lambert { r: f.diffuse.clamp(Vec3::ZERO, Vec3::ONE) }), fabric_w * (1.0 - s));
        }
        let hair_w = unit(self.hair.weight);
        if hair_w > 0.0 || every {
            let h = &self.hair.params;
            let fibre = Hair::new(h.sigma_a, h.ior, h.roughness, h.radial_roughness, h.tilt)
                .with_lobes(h.scale_tt, h.scale_trt, h.tint)
                .with_radial_scales(h.radial_scale_tt, h.radial_scale_trt);
            bsdf.push_weighted(Lobe::Hair(fibre), hair_w);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bsdf_with_every_lobe` really builds every lobe (so the render-plan benchmark measures
    /// something) and changes nothing the material reflects.
    #[test]
    fn every_lobe_bsdf_holds_more_lobes_and_the_same_function() {
        let u = Uber::default();
        let (planned, every) = (u.bsdf(true), u.bsdf_with_every_lobe(true));
        assert_eq!(planned.len(), 2, "diffuse and specular");
        assert!(every.len() >= 12, "{} lobes", every.len());
        let mut rng = crate::sampling::Pcg32::new(3, 7);
        for _ in 0..200 {
            let wo = crate::sampling::uniform_sphere(rng.next_2d());
            let wi = crate::sampling::uniform_sphere(rng.next_2d());
            let (a, b) = (planned.eval(wo, wi), every.eval(wo, wi));
            assert!((a - b).abs().max_element() <= 1e-6 * a.max_element().max(1.0), "{a:?} vs {b:?}");
        }
    }
}
