//! Scattering functions in the local shading frame.
//!
//! Every lobe has the same shape: `eval(wo, wi)` (f without the cosine), `sample(wo, uc, u)`
//! (pbrt's shape: `uc` chooses among a lobe's discrete options, `u` warps) and `pdf(wo, wi)`
//! (solid angle), plus `albedo(wo)`, an estimate used to choose among
//! lobes. Directions point away from the surface; +Z is the shading normal.
//!
//! [`Bsdf`] holds only the lobes a material instance needs (a material with no
//! transmission carries no transmission lobe) and picks one to sample in proportion to its
//! albedo weight, as Cycles does with `sample_weight`; evaluation and pdf are the weighted
//! sums over all lobes, so MIS sees the one-sample mixture density.

pub mod charlie;
mod coat;
mod dielectric;
pub mod disney;
pub mod energy;
pub mod fabric;
pub mod flake;
pub mod fresnel;
pub mod fuzz;
pub mod hair;
mod lambert;
mod lazy_rows;
pub mod microfacet;
pub mod oren_nayar;
mod reflection;
mod thin;
pub mod thin_film;
mod view_cache;

pub use charlie::CharlieSheen;
pub use coat::{Coat, DielectricCoat};
use coat::{CoatScale, DiffuseProfile};
pub use dielectric::{Dielectric, GlassFilm};
pub use disney::{Clearcoat, DiffuseTransmission, DisneyDiffuse, Sheen};
pub use fabric::Fabric;
pub use flake::Flake;
pub use fuzz::Fuzz;
pub use hair::Hair;
pub use lambert::Lambert;
pub use oren_nayar::OrenNayar;
pub use reflection::{GgxReflection, SpecularFresnel};
pub use thin::{ThinDielectric, sheet_series};
pub use thin_film::ThinFilmCoat;

use glam::{Vec2, Vec3};

use view_cache::ViewCache;

/// Properties of a lobe that the integrator must know.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LobeFlags {
    /// Scatters into the hemisphere of `wo`.
    pub reflection: bool,
    /// Scatters into the opposite hemisphere.
    pub transmission: bool,
    /// A Dirac delta: cannot be evaluated, only sampled.
    pub delta: bool,
}

/// A sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct LobeSample {
    /// Sampled incident direction (local frame).
    pub wi: Vec3,
    /// f(wo, wi)·|cos θi| / pdf, the path throughput factor.
    pub weight: Vec3,
    /// Density of `wi` in solid angle (meaningless for delta lobes, where it is 1).
    pub pdf: f32,
    /// Flags of the lobe that produced the sample.
    pub flags: LobeFlags,
    /// Relative IOR η' crossed by a transmitted sample (1 for reflection): radiance weights
    /// carry 1/η'², energy does not.
    pub eta: f32,
}

/// One scattering lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lobe {
    /// Ideal diffuse reflection.
    Lambert(Lambert),
    /// Rough or smooth microfacet reflection (metals; dielectric specular) with optional
    /// energy compensation.
    GgxReflection(GgxReflection),
    /// Rough or smooth dielectric interface: reflection and refraction.
    Dielectric(Dielectric),
    /// Disney diffuse with retro-reflection (and the thin-surface blend).
    DisneyDiffuse(DisneyDiffuse),
    /// Rough diffuse: energy-preserving Oren-Nayar (OpenPBR's, Cycles').
    OrenNayar(OrenNayar),
    /// Lambertian transmission.
    DiffuseTransmission(DiffuseTransmission),
    /// Disney sheen.
    Sheen(Sheen),
    /// Disney clearcoat.
    Clearcoat(Clearcoat),
    /// Imageworks' "Charlie" sheen.
    CharlieSheen(CharlieSheen),
    /// Zeltner et al.'s multiple-scattering sheen (OpenPBR fuzz, Cycles' sheen).
    Fuzz(Fuzz),
    /// A thin dielectric sheet: reflection and undeflected transmission.
    ThinDielectric(ThinDielectric),
    /// The DreamWorks fabric cone.
    Fabric(Fabric),
    /// One DreamWorks glitter flake.
    Flake(Flake),
    /// A hair or fur fibre (Chiang et al. 2016); its frame's x runs along the fibre.
    Hair(Hair),
}

impl Lobe {
    /// f(wo, wi), without the cosine.
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            Lobe::Lambert(l) => l.eval(wo, wi),
            Lobe::GgxReflection(l) => l.eval(wo, wi),
            Lobe::Dielectric(l) => l.eval(wo, wi),
            Lobe::DisneyDiffuse(l) => l.eval(wo, wi),
            Lobe::OrenNayar(l) => l.eval(wo, wi),
            Lobe::DiffuseTransmission(l) => l.eval(wo, wi),
            Lobe::Sheen(l) => l.eval(wo, wi),
            Lobe::Clearcoat(l) => l.eval(wo, wi),
            Lobe::CharlieSheen(l) => l.eval(wo, wi),
            Lobe::Fuzz(l) => l.eval(wo, wi),
            Lobe::ThinDielectric(l) => l.eval(wo, wi),
            Lobe::Fabric(l) => l.eval(wo, wi),
            Lobe::Flake(l) => l.eval(wo, wi),
            Lobe::Hair(l) => l.eval(wo, wi),
        }
    }

    /// Samples an incident direction.
    #[inline]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<LobeSample> {
        match self {
            Lobe::Lambert(l) => l.sample(wo, uc, u),
            Lobe::GgxReflection(l) => l.sample(wo, uc, u),
            Lobe::Dielectric(l) => l.sample(wo, uc, u),
            Lobe::DisneyDiffuse(l) => l.sample(wo, uc, u),
            Lobe::OrenNayar(l) => l.sample(wo, uc, u),
            Lobe::DiffuseTransmission(l) => l.sample(wo, uc, u),
            Lobe::Sheen(l) => l.sample(wo, uc, u),
            Lobe::Clearcoat(l) => l.sample(wo, uc, u),
            Lobe::CharlieSheen(l) => l.sample(wo, uc, u),
            Lobe::Fuzz(l) => l.sample(wo, uc, u),
            Lobe::ThinDielectric(l) => l.sample(wo, uc, u),
            Lobe::Fabric(l) => l.sample(wo, uc, u),
            Lobe::Flake(l) => l.sample(wo, uc, u),
            Lobe::Hair(l) => l.sample(wo, uc, u),
        }
    }

    /// Density of [`Lobe::sample`] choosing `wi`.
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Lobe::Lambert(l) => l.pdf(wo, wi),
            Lobe::GgxReflection(l) => l.pdf(wo, wi),
            Lobe::Dielectric(l) => l.pdf(wo, wi),
            Lobe::DisneyDiffuse(l) => l.pdf(wo, wi),
            Lobe::OrenNayar(l) => l.pdf(wo, wi),
            Lobe::DiffuseTransmission(l) => l.pdf(wo, wi),
            Lobe::Sheen(l) => l.pdf(wo, wi),
            Lobe::Clearcoat(l) => l.pdf(wo, wi),
            Lobe::CharlieSheen(l) => l.pdf(wo, wi),
            Lobe::Fuzz(l) => l.pdf(wo, wi),
            Lobe::ThinDielectric(l) => l.pdf(wo, wi),
            Lobe::Fabric(l) => l.pdf(wo, wi),
            Lobe::Flake(l) => l.pdf(wo, wi),
            Lobe::Hair(l) => l.pdf(wo, wi),
        }
    }

    /// `(eval, pdf)` in one call, the same bits as the two; lobes whose two share work
    /// compute it once.
    #[inline]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        match self {
            Lobe::GgxReflection(l) => l.eval_pdf(wo, wi),
            Lobe::Dielectric(l) => l.eval_pdf(wo, wi),
            Lobe::Clearcoat(l) => l.eval_pdf(wo, wi),
            // The diffuse lobes directly: through `self.eval` and `self.pdf` they were two
            // more dispatches, each a call, at every light sample of a diffuse surface.
            Lobe::DisneyDiffuse(l) => (l.eval(wo, wi), l.pdf(wo, wi)),
            Lobe::OrenNayar(l) => (l.eval(wo, wi), l.pdf(wo, wi)),
            Lobe::Fuzz(l) => l.eval_pdf(wo, wi),
            Lobe::Lambert(l) => (l.eval(wo, wi), l.pdf(wo, wi)),
            _ => (self.eval(wo, wi), self.pdf(wo, wi)),
        }
    }

    /// Looks up once what the lobe's evaluations at this view share (E(μo) of the energy
    /// tables, see `view_cache`); evaluating without it gives the same values, slower.
    #[inline]
    pub fn prepare(&mut self, wo: Vec3) {
        match self {
            Lobe::GgxReflection(l) => l.prepare(wo),
            Lobe::Dielectric(l) => l.prepare(wo),
            Lobe::DisneyDiffuse(l) => l.prepare(wo),
            Lobe::OrenNayar(l) => l.prepare(wo),
            _ => {}
        }
    }

    /// True when [`Lobe::prepare`] stores something for the view: the lobes that read energy
    /// tables at the viewing angle.
    #[inline]
    fn reads_view(&self) -> bool {
        match self {
            Lobe::GgxReflection(_) | Lobe::Dielectric(_) | Lobe::OrenNayar(_) => true,
            Lobe::DisneyDiffuse(l) => l.reads_tables(),
            _ => false,
        }
    }

    /// Directional albedo estimate, used for lobe selection and the albedo AOV.
    #[inline]
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        match self {
            Lobe::Lambert(l) => l.albedo(wo),
            Lobe::GgxReflection(l) => l.albedo(wo),
            Lobe::Dielectric(l) => l.albedo(wo),
            Lobe::DisneyDiffuse(l) => l.albedo(wo),
            Lobe::OrenNayar(l) => l.albedo(wo),
            Lobe::DiffuseTransmission(l) => l.albedo(wo),
            Lobe::Sheen(l) => l.albedo(wo),
            Lobe::Clearcoat(l) => l.albedo(wo),
            Lobe::CharlieSheen(l) => l.albedo(wo),
            Lobe::Fuzz(l) => l.albedo(wo),
            Lobe::ThinDielectric(l) => l.albedo(wo),
            Lobe::Fabric(l) => l.albedo(wo),
            Lobe::Flake(l) => l.albedo(wo),
            Lobe::Hair(l) => l.albedo(wo),
        }
    }

    /// True when `sample`'s weight is `eval · |cos θi| / pdf`, computed in that order, with
    /// `pdf` what [`Lobe::pdf`] gives: a BSDF of this lobe alone at weight 1 may then take the
    /// sample as it is, to the bit, rather than evaluate it a second time (`Bsdf::sample`).
    #[inline]
    fn sample_is_own_estimate(&self) -> bool {
        matches!(self, Lobe::DisneyDiffuse(_) | Lobe::OrenNayar(_) | Lobe::Sheen(_))
    }

    /// The lobe's flags.
    #[inline]
    pub fn flags(&self) -> LobeFlags {
        match self {
            Lobe::Lambert(_) => Lambert::FLAGS,
            Lobe::GgxReflection(c) => c.flags(),
            Lobe::Dielectric(d) => d.flags(),
            Lobe::DisneyDiffuse(_) => DisneyDiffuse::FLAGS,
            Lobe::OrenNayar(_) => OrenNayar::FLAGS,
            Lobe::DiffuseTransmission(_) => DiffuseTransmission::FLAGS,
            Lobe::Sheen(_) => Sheen::FLAGS,
            Lobe::Clearcoat(_) => Clearcoat::FLAGS,
            Lobe::CharlieSheen(_) => CharlieSheen::FLAGS,
            Lobe::Fuzz(_) => Fuzz::FLAGS,
            Lobe::ThinDielectric(t) => t.flags(),
            Lobe::Fabric(_) => Fabric::FLAGS,
            Lobe::Flake(_) => Flake::FLAGS,
            Lobe::Hair(_) => Hair::FLAGS,
        }
    }

    /// How rough the lobe is, in [0, 1]: its microfacet roughness (the larger axis), 1 for
    /// diffuse-like lobes. Caustic avoidance compares roughness along a path.
    pub fn roughness(&self) -> f32 {
        let r = |a: f32| a.max(0.0).sqrt().min(1.0);
        match self {
            Lobe::Lambert(_)
            | Lobe::DisneyDiffuse(_)
            | Lobe::OrenNayar(_)
            | Lobe::DiffuseTransmission(_)
            | Lobe::Sheen(_)
            | Lobe::CharlieSheen(_)
            | Lobe::Fuzz(_)
            | Lobe::Fabric(_) => 1.0,
            Lobe::GgxReflection(g) => r(g.ggx.ax.max(g.ggx.ay)),
            Lobe::Dielectric(d) => r(d.ggx.ax.max(d.ggx.ay)),
            Lobe::ThinDielectric(t) => r(t.reflect.ax.max(t.reflect.ay)),
            Lobe::Clearcoat(c) => r(c.alpha),
            Lobe::Flake(f) => r(f.alpha),
            Lobe::Hair(h) => h.roughness(),
        }
    }

    /// What the lobe does to light going from `wi` to `wo`, for the light-path AOVs.
    pub fn kind(&self, wo: Vec3, wi: Vec3) -> PathKind {
        match self {
            Lobe::Lambert(_) | Lobe::DisneyDiffuse(_) | Lobe::OrenNayar(_) | Lobe::Sheen(_) | Lobe::CharlieSheen(_) | Lobe::Fuzz(_) => {
                PathKind::Diffuse
            }
            Lobe::GgxReflection(_) | Lobe::Clearcoat(_) | Lobe::Fabric(_) | Lobe::Flake(_) => PathKind::Specular,
            Lobe::DiffuseTransmission(_) => PathKind::Transmission,
            Lobe::Dielectric(_) | Lobe::ThinDielectric(_) | Lobe::Hair(_) if wo.z * wi.z > 0.0 => PathKind::Specular,
            Lobe::Dielectric(_) | Lobe::ThinDielectric(_) | Lobe::Hair(_) => PathKind::Transmission,
        }
    }

    /// How f varies with μi where it is c(μo)·g(μi) (a Lambertian lobe, UsdPreviewSurface's
    /// coupled diffuse), so a coat over it can be renormalised ([`DiffuseProfile`]).
    fn diffuse_profile(&self) -> Option<DiffuseProfile> {
        match self {
            Lobe::Lambert(_) => Some(DiffuseProfile::Flat),
            Lobe::DisneyDiffuse(d) if d.lambert => {
                Some(d.coupling.map_or(DiffuseProfile::Flat, |(eta, r)| DiffuseProfile::Coupled(eta, r)))
            }
            _ => None,
        }
    }
}

/// The light-path AOV a scattering event belongs to (`film::Aov::COMPONENTS` order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKind {
    /// Diffuse reflection.
    Diffuse = 0,
    /// Glossy or mirror reflection.
    Specular = 1,
    /// Transmission.
    Transmission = 2,
}

/// Most lobes one material instance may hold.
pub const MAX_LOBES: usize = 16;
/// Most coats one material instance may stack.
pub const MAX_COATS: usize = 3;

/// The weighted lobes of one shading point, with selection probabilities.
#[derive(Debug, Default)]
pub struct Bsdf {
    lobes: [Option<Lobe>; MAX_LOBES],
    weights: [f32; MAX_LOBES],
    select: [f32; MAX_LOBES],
    count: usize,
    /// Coats over the lobes before them, with the index of their own lobe (see
    /// [`Bsdf::coat_with`]).
    coats: [Option<(usize, Coat)>; MAX_COATS],
    /// Each coat's `through` at the shading point's view ([`Bsdf::prepare`]).
    coats_at_view: [ViewCache<f32>; MAX_COATS],
    /// Per lobe under a coat whose shape in μi is known ([`DiffuseProfile`]), the coats'
    /// renormalisation 1/K; 0 for lobes the min rule scales.
    coat_norms: [f32; MAX_LOBES],
    /// Keep lobes of weight 0 (the `force_all_effects` benchmark's uber-shader that pays for
    /// every lobe whether or not the material uses it).
    keep_zero: bool,
}

/// `clone_from` copies only the lobes in use. The integrator copies a material's BSDF at
/// every path vertex (`prepare` fills it in for the viewer) into one buffer per path, and a
/// material fills two or three of the sixteen slots: copying all of them moved 2.3 KB per
/// vertex, 13% of a Cornell box render. Slots past `count` are never read.
impl Clone for Bsdf {
    fn clone(&self) -> Self {
        let mut b = Bsdf::default();
        b.clone_from(self);
        b
    }

    fn clone_from(&mut self, source: &Self) {
        self.lobes[..source.count].copy_from_slice(&source.lobes[..source.count]);
        self.weights = source.weights;
        self.select = source.select;
        self.count = source.count;
        // Most materials have no coat, and the coat slots (and their views) are a third of
        // what is left to copy: skipped when neither side has one.
        if self.coats[0].is_some() || source.coats[0].is_some() {
            self.coats = source.coats;
            self.coats_at_view = source.coats_at_view;
            self.coat_norms = source.coat_norms;
        }
        self.keep_zero = source.keep_zero;
    }
}

impl Bsdf {
    /// Adds a lobe of weight 1.
    pub fn push(&mut self, lobe: Lobe) {
        self.push_weighted(lobe, 1.0);
    }

    /// Adds a lobe scaled by `weight`; zero-weight lobes are not added, and lobes past
    /// [`MAX_LOBES`] are ignored (a material never builds that many).
    pub fn push_weighted(&mut self, lobe: Lobe, weight: f32) {
        if self.count < MAX_LOBES && (weight > 0.0 || (self.keep_zero && weight == 0.0)) && weight.is_finite() {
            self.lobes[self.count] = Some(lobe);
            self.weights[self.count] = weight;
            self.count += 1;
        }
    }

    /// Puts `coat` over every lobe added so far (coats included, so coats stack), layered as
    /// Imageworks combines coats (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings"): the lobes beneath are scaled by
    /// [`Coat::over`], so coat plus base never reflects more than 1 and the product stays
    /// reciprocal; diffuse lobes of known shape are renormalised under the coats so far
    /// ([`DiffuseProfile`]). `compensate` switches the coat lobe's own energy compensation.
    pub fn coat_with(&mut self, coat: Coat, compensate: bool) {
        let (lobe, weight) = coat.lobe(compensate);
        let Some(slot) = self.coats.iter_mut().find(|c| c.is_none()) else { return };
        if (weight > 0.0 || self.keep_zero) && self.count < MAX_LOBES {
            *slot = Some((self.count, coat));
            self.push_weighted(lobe, weight);
            self.renormalise_diffuse_under_coats();
        }
    }

    /// Sets [`Bsdf::coat_norms`] for every lobe of known diffuse shape under the coats so far.
    fn renormalise_diffuse_under_coats(&mut self) {
        for i in 0..self.count {
            let Some(profile) = self.lobes[i].as_ref().and_then(Lobe::diffuse_profile) else { continue };
            let above = self.coats.iter().flatten().filter(|(k, _)| *k > i).map(|(_, c)| c);
            self.coat_norms[i] = profile.coat_norm(above);
        }
    }

    /// Covers a share `coverage` of the surface with something opaque (glitter flakes): every
    /// lobe so far, coats included, keeps the uncovered rest. The lobes of the cover are
    /// pushed after this call, with weights that sum to at most `coverage`.
    pub fn cover(&mut self, coverage: f32) {
        let keep = if coverage.is_finite() { 1.0 - coverage.clamp(0.0, 1.0) } else { 1.0 };
        self.weights[..self.count].iter_mut().for_each(|w| *w *= keep);
    }

    /// Each coat's attenuation of the lobes beneath it for (wo, wi), by coat slot: found once
    /// for all the lobes of an evaluation.
    #[inline]
    fn coat_scales(&self, wo: Vec3, wi: Vec3) -> [CoatScale; MAX_COATS] {
        let mut scales = [CoatScale::NONE; MAX_COATS];
        if self.coats[0].is_none() {
            return scales; // coats fill the slots in order: none at all
        }
        for (slot, (coat, at_view)) in self.coats.iter().zip(&self.coats_at_view).enumerate() {
            if let Some((_, c)) = coat {
                scales[slot] = c.over(at_view.get(wo, || c.through(wo.z)), wo, wi);
            }
        }
        scales
    }

    /// The scale of lobe `i` in f(wo, wi): the attenuation of every coat above it, from
    /// [`Bsdf::coat_scales`] at (wo, wi); renormalised for a lobe of known diffuse shape.
    #[inline]
    fn under_coat(&self, i: usize, scales: &[CoatScale; MAX_COATS]) -> Vec3 {
        if self.coats[0].is_none() {
            return Vec3::ONE;
        }
        let norm = self.coat_norms[i];
        if norm > 0.0 { norm * self.coats_over(i, scales, |s| s.diffuse) } else { self.coats_over(i, scales, |s| s.any) }
    }

    /// The share of lobe `i`'s albedo at `wo` the coats above it leave, from
    /// [`Bsdf::coat_scales`] at (wo, wo): 1 − E(μo) for every lobe (the renormalised product
    /// leaves a diffuse lobe exactly that, the min rule at most that).
    #[inline]
    fn albedo_under_coat(&self, i: usize, scales: &[CoatScale; MAX_COATS]) -> Vec3 {
        if self.coats[0].is_none() {
            return Vec3::ONE;
        }
        self.coats_over(i, scales, |s| s.any)
    }

    /// The product of `part` of the scales of the coats over lobe `i`.
    #[inline]
    fn coats_over(&self, i: usize, scales: &[CoatScale; MAX_COATS], part: impl Fn(&CoatScale) -> Vec3) -> Vec3 {
        let mut scale = Vec3::ONE;
        for (coat, s) in self.coats.iter().zip(scales) {
            if let Some((k, _)) = coat
                && *k > i
            {
                scale *= part(s);
            }
        }
        scale
    }

    /// A BSDF that keeps zero-weight lobes (see `keep_zero`).
    pub fn keeping_zero_lobes() -> Self {
        Bsdf { keep_zero: true, ..Default::default() }
    }

    /// Number of lobes.
    pub fn len(&self) -> usize {
        self.count
    }

    /// True when the lobes depend on the direction of the tangent (anisotropic microfacets,
    /// fabric threads), so the shading frame must be a continuous tangent field.
    pub fn is_anisotropic(&self) -> bool {
        self.lobes().any(|(_, l)| match l {
            Lobe::GgxReflection(g) => g.ggx.ax != g.ggx.ay,
            Lobe::Dielectric(d) => d.ggx.ax != d.ggx.ay,
            Lobe::ThinDielectric(t) => t.reflect.ax != t.reflect.ay,
            Lobe::Fabric(_) => true,
            _ => false,
        })
    }

    /// True when a lobe is a fibre's: the shading frame's x must run along the fibre.
    pub fn is_fibre(&self) -> bool {
        self.lobes().any(|(i, l)| matches!(l, Lobe::Hair(_)) && self.weights[i] > 0.0)
    }

    /// True when any lobe transmits.
    pub fn transmits(&self) -> bool {
        self.lobes().any(|(_, l)| l.flags().transmission)
    }

    /// Builds the energy tables this BSDF's lobes read (each is computed once per process),
    /// so a scene commit pays for them rather than the first tiles, and only for lobes that
    /// use them: evaluating every lobe once in reflection and transmission touches exactly
    /// its tables.
    pub fn build_tables(&self) {
        for (_, l) in self.lobes() {
            l.eval(Vec3::Z, Vec3::Z);
            l.eval(Vec3::Z, -Vec3::Z);
        }
        self.coats.iter().flatten().for_each(|(_, c)| {
            c.through(1.0);
        });
    }

    /// True when [`Bsdf::prepare`] gives the same BSDF at every view: one lobe, no coat, and
    /// nothing read at the viewing angle (a plain diffuse material). Such a BSDF, prepared
    /// once, can be shaded with as it is ([`Bsdf::settle`]).
    #[inline]
    pub fn is_view_independent(&self) -> bool {
        self.count == 1 && self.coats[0].is_none() && self.lobes[0].as_ref().is_some_and(|l| !l.reads_view())
    }

    /// Prepares a view-independent BSDF for every view at once (a material's own, when the
    /// scene builds it), so shading points can share it instead of copying and preparing it.
    pub fn settle(&mut self) {
        if self.is_view_independent() {
            self.prepare(Vec3::Z);
        }
    }

    /// True when nothing scatters.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    fn lobes(&self) -> impl Iterator<Item = (usize, &Lobe)> {
        self.lobes[..self.count].iter().enumerate().filter_map(|(i, l)| l.as_ref().map(|l| (i, l)))
    }

    /// Prepares the lobes for the view `wo` ([`Lobe::prepare`]) and sets lobe selection
    /// probabilities from albedo estimates there. Call once per shading point before sampling.
    pub fn prepare(&mut self, wo: Vec3) {
        self.lobes[..self.count].iter_mut().flatten().for_each(|l| l.prepare(wo));
        for (coat, at_view) in self.coats.iter().zip(&mut self.coats_at_view) {
            if let Some((_, c)) = coat {
                at_view.store(wo, c.through(wo.z));
            }
        }
        if self.count == 1 {
            // One lobe is always the one chosen: its albedo estimate would only divide itself.
            self.select[0] = 1.0;
            return;
        }
        let mut total = 0.0;
        let coats = self.coat_scales(wo, wo);
        for i in 0..self.count {
            let w = self.weights[i]
                * self.lobes[i].map_or(0.0, |l| crate::math::luminance(self.albedo_under_coat(i, &coats) * l.albedo(wo)).max(0.0));
            self.select[i] = w;
            total += w;
        }
        for i in 0..self.count {
            self.select[i] = if total > 0.0 { self.select[i] / total } else { 1.0 / self.count as f32 };
        }
    }

    /// The lone lobe of a BSDF with one lobe and no coat, where every mixture sum has one term
    /// (most diffuse surfaces): its sums skip the loops and give the same bits.
    #[inline(always)]
    fn lone_lobe(&self) -> Option<&Lobe> {
        if self.count == 1 && self.coats[0].is_none() { self.lobes[0].as_ref() } else { None }
    }

    /// Weighted sum of the lobes' f(wo, wi).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if let Some(l) = self.lone_lobe() {
            return self.weights[0] * l.eval(wo, wi);
        }
        let coats = self.coat_scales(wo, wi);
        self.lobes().map(|(i, l)| self.weights[i] * self.under_coat(i, &coats) * l.eval(wo, wi)).sum()
    }

    /// The mixture density of [`Bsdf::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if let Some(l) = self.lone_lobe() {
            return self.select[0] * l.pdf(wo, wi);
        }
        self.lobes().map(|(i, l)| self.select[i] * l.pdf(wo, wi)).sum()
    }

    /// `(eval, pdf)` in one pass over the lobes, the same bits as the two calls (each lobe's
    /// pair from [`Lobe::eval_pdf`]; the sums in the same order, the density's from −0 as
    /// `Iterator::sum` starts it).
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if let Some(l) = self.lone_lobe() {
            let (f, pdf) = l.eval_pdf(wo, wi);
            return (self.weights[0] * f, self.select[0] * pdf);
        }
        let coats = self.coat_scales(wo, wi);
        self.lobes().fold((Vec3::ZERO, -0.0), |(f, pdf), (i, l)| {
            let (lf, lp) = l.eval_pdf(wo, wi);
            (f + self.weights[i] * self.under_coat(i, &coats) * lf, pdf + self.select[i] * lp)
        })
    }

    /// Weighted sum of the lobes' albedo estimates.
    pub fn albedo(&self, wo: Vec3) -> Vec3 {
        let coats = self.coat_scales(wo, wo);
        self.lobes().map(|(i, l)| self.weights[i] * self.albedo_under_coat(i, &coats) * l.albedo(wo)).sum()
    }

    /// [`Bsdf::eval`] split by [`PathKind`]: the three parts sum to `eval`.
    pub fn eval_by_kind(&self, wo: Vec3, wi: Vec3) -> [Vec3; 3] {
        let mut out = [Vec3::ZERO; 3];
        let coats = self.coat_scales(wo, wi);
        for (i, l) in self.lobes() {
            out[l.kind(wo, wi) as usize] += self.weights[i] * self.under_coat(i, &coats) * l.eval(wo, wi);
        }
        out
    }

    /// [`Bsdf::sample`], also saying which kind of lobe produced the sample and how rough
    /// that lobe is.
    pub fn sample_kind(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<(LobeSample, PathKind, f32)> {
        let (s, i) = self.sample_lobe(wo, u_lobe, u)?;
        let lobe = self.lobes[i].as_ref()?;
        Some((s, lobe.kind(wo, s.wi), lobe.roughness()))
    }

    /// The roughest lobe's roughness (0 for an empty BSDF).
    pub fn roughness(&self) -> f32 {
        self.lobes().map(|(_, l)| l.roughness()).fold(0.0, f32::max)
    }

    /// Picks a lobe with `u_lobe`, samples it with `u`, and returns the one-sample MIS
    /// estimate of the whole BSDF (f and pdf summed over all non-delta lobes). Reflection and
    /// transmission lobes are evaluated on their own side: the cosine is |cos θi|.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<LobeSample> {
        self.sample_lobe(wo, u_lobe, u).map(|(s, _)| s)
    }

    /// [`Bsdf::sample`] and the index of the lobe chosen.
    fn sample_lobe(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<(LobeSample, usize)> {
        if let Some(l) = self.lone_lobe().filter(|l| self.weights[0] == 1.0 && self.select[0] == 1.0 && l.sample_is_own_estimate()) {
            // The mixture is the lobe itself: its sample already holds f·cos/pdf.
            return l.sample(wo, u_lobe.clamp(0.0, 1.0 - f32::EPSILON), u).map(|s| (s, 0));
        }
        let mut acc = 0.0;
        let mut chosen = None;
        for (i, _) in self.lobes() {
            if u_lobe < acc + self.select[i] || i + 1 == self.count {
                chosen = Some((i, acc));
                break;
            }
            acc += self.select[i];
        }
        let (i, lo) = chosen?;
        let lobe = self.lobes[i].as_ref()?;
        // Reuse the selection number inside the lobe, rescaled (Cycles' trick, which keeps
        // its stratification).
        let uc = if self.select[i] > 0.0 { ((u_lobe - lo) / self.select[i]).clamp(0.0, 1.0 - f32::EPSILON) } else { 0.5 };
        let s = lobe.sample(wo, uc, u)?;
        if s.flags.delta {
            let p = self.select[i];
            let scale = self.weights[i] * self.under_coat(i, &self.coat_scales(wo, s.wi)) / p;
            return (p > 0.0).then(|| (LobeSample { weight: s.weight * scale, pdf: p * s.pdf, ..s }, i));
        }
        // f and the density in one pass: lobes whose two share work (GGX's D and G) do it once.
        let (f, pdf) = self.eval_pdf(wo, s.wi);
        if !(pdf > 0.0) {
            return None;
        }
        Some((LobeSample { weight: f * s.wi.z.abs() / pdf, pdf, ..s }, i))
    }
}

#[cfg(test)]
pub(crate) mod testing;

#[cfg(test)]
mod finite_everywhere {
    use super::*;
    use proptest::prelude::*;

    fn dir() -> impl Strategy<Value = Vec3> {
        // Any direction, including below the horizon, exactly grazing and unnormalised.
        (-1.0f32..1.0, -1.0f32..1.0, prop_oneof![Just(0.0f32), Just(1e-6f32), Just(-1e-6f32), -1.0f32..1.0])
            .prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    fn lobe() -> impl Strategy<Value = Lobe> {
        let r = prop_oneof![Just(0.0f32), Just(1e-7f32), Just(1e-4f32), Just(1.0f32), 0.0f32..1.0];
        let a = prop_oneof![Just(-1.0f32), Just(0.0f32), Just(1.0f32), -1.0f32..1.0];
        let c = (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z));
        prop_oneof![
            c.clone().prop_map(|r| Lobe::Lambert(Lambert { r })),
            (r.clone(), a.clone(), c.clone(), c.clone(), any::<bool>()).prop_map(|(r, a, f, g, comp)| Lobe::GgxReflection(
                GgxReflection::new(r, a, SpecularFresnel::Gulbrandsen { r: f, g }, comp)
            )),
            (r.clone(), a.clone(), c.clone(), c.clone(), 0.01f32..10.0, any::<bool>()).prop_map(|(r, a, f, g, p, comp)| {
                Lobe::GgxReflection(GgxReflection::new(r, a, SpecularFresnel::Artistic { r: f, g, p }, comp))
            }),
            (r.clone(), a.clone(), prop_oneof![Just(1.0f32), Just(1.0001f32), Just(3.0f32), 0.3f32..3.0], c.clone(), any::<bool>())
                .prop_map(|(r, a, eta, c, comp)| Lobe::ThinDielectric(ThinDielectric::new(r, a, eta, c, comp))),
            (c.clone(), r.clone()).prop_map(|(c, r)| Lobe::CharlieSheen(CharlieSheen::new(c, r))),
            (c.clone(), r.clone()).prop_map(|(c, r)| Lobe::Fuzz(Fuzz::new(c, r))),
            (c.clone(), r.clone()).prop_map(|(c, r)| Lobe::OrenNayar(OrenNayar::new(c, r, None))),
            (c.clone(), r.clone(), a).prop_map(|(c, r, a)| Lobe::Fabric(Fabric::new(c, r, a * 3.0))),
            (dir(), r.clone(), c.clone()).prop_map(|(n, r, c)| Lobe::Flake(Flake::new(n, r, c))),
            (c, r.clone(), r, prop_oneof![Just(1.0f32), 1.0f32..3.0], -10.0f32..10.0)
                .prop_map(|(s, bm, bn, eta, a)| Lobe::Hair(Hair::new(s * 10.0, eta, bm, bn, a))),
        ]
    }

    /// The lobes whose `prepare` caches table lookups, compensated or coupled or not.
    fn preparing_lobe() -> impl Strategy<Value = Lobe> {
        let r = prop_oneof![Just(0.0f32), Just(1e-4f32), Just(1.0f32), 0.0f32..1.0];
        let c = (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0).prop_map(|(x, y, z)| Vec3::new(x, y, z));
        let coupling = prop_oneof![Just(None), (1.0f32..3.0, 0.0f32..1.0).prop_map(Some)];
        prop_oneof![
            (r.clone(), -1.0f32..1.0, c.clone(), c.clone(), any::<bool>()).prop_map(|(r, a, f, g, comp)| Lobe::GgxReflection(
                GgxReflection::new(r, a, SpecularFresnel::Gulbrandsen { r: f, g }, comp)
            )),
            (r.clone(), prop_oneof![Just(1.0f32), 0.3f32..3.0], c.clone(), any::<bool>())
                .prop_map(|(r, eta, t, comp)| Lobe::Dielectric(Dielectric::new(r, 0.0, eta, t).compensated(comp))),
            (c.clone(), r.clone(), r.clone(), coupling.clone(), any::<bool>())
                .prop_map(|(c, r, fl, cp, lambert)| Lobe::DisneyDiffuse(DisneyDiffuse::new(c, r, fl, cp, lambert))),
            (c, r, coupling).prop_map(|(c, r, cp)| Lobe::OrenNayar(OrenNayar::new(c, r, cp))),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]
        /// `Lobe::prepare` only saves lookups: prepared for `wo`, a lobe gives the same bits
        /// at `wo` and at any other view as unprepared.
        #[test]
        fn a_prepared_lobe_gives_the_same_bits(l in preparing_lobe(), wo in dir(), wi in dir(), u in (0.0f32..1.0, 0.0f32..1.0)) {
            let wo = wo.normalize_or_zero();
            let mut p = l;
            p.prepare(wo);
            let bits = |l: &Lobe, wo: Vec3| {
                let s = l.sample(wo, u.0, Vec2::new(u.1, u.0)).map(|s| (s.wi, s.weight, s.pdf));
                format!("{:?}", (l.eval(wo, wi), l.pdf(wo, wi), l.albedo(wo), s))
            };
            prop_assert_eq!(bits(&p, wo), bits(&l, wo));
            prop_assert_eq!(bits(&p, Vec3::Z), bits(&l, Vec3::Z), "another view");
        }
    }

    /// Two of [`preparing_lobe`]'s lobes under up to two coats of any kind.
    fn coated_bsdf() -> impl Strategy<Value = Bsdf> {
        let coat = prop_oneof![
            (0.0f32..1.0, 0.0f32..1.0).prop_map(|(w, g)| Coat::Disney(Clearcoat::new(w, g))),
            (0.0f32..1.0, 1.0f32..3.0, 0.0f32..1.0, 0.0f32..1.0, 0.0f32..2.0)
                .prop_map(|(w, eta, r, c, t)| Coat::Dielectric(DielectricCoat::new(w, eta, r, Vec3::new(c, 0.5, 1.0), t))),
            (0.0f32..1.0, 0.0f32..1.0).prop_map(|(c, r)| Coat::Sheen(CharlieSheen::new(Vec3::splat(c), r))),
            (0.0f32..1.0, 0.0f32..1.0).prop_map(|(c, r)| Coat::Fuzz(Fuzz::new(Vec3::splat(c), r))),
        ];
        (preparing_lobe(), preparing_lobe(), proptest::collection::vec((coat, any::<bool>()), 0..=2)).prop_map(|(a, b, coats)| {
            let mut bsdf = Bsdf::default();
            bsdf.push_weighted(a, 0.5);
            bsdf.push_weighted(b, 0.5);
            coats.into_iter().for_each(|(c, comp)| bsdf.coat_with(c, comp));
            bsdf
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]
        /// The same for a whole BSDF, coats included: prepared for `wo`, or prepared for
        /// another view with the same lobe choice, it gives the same bits at `wo`.
        #[test]
        fn a_prepared_bsdf_gives_the_same_bits(b in coated_bsdf(), wo in dir(), wi in dir(), u in (0.0f32..1.0, 0.0f32..1.0)) {
            let wo = wo.normalize_or_zero();
            let mut here = b.clone();
            here.prepare(wo);
            let mut elsewhere = b.clone();
            elsewhere.prepare(Vec3::new(0.0, 0.6, 0.8));
            elsewhere.select = here.select;
            let bits = |b: &Bsdf| {
                let s = b.sample(wo, u.0, Vec2::new(u.1, u.0)).map(|s| (s.wi, s.weight, s.pdf));
                format!("{:?}", (b.eval(wo, wi), b.pdf(wo, wi), b.albedo(wo), b.eval_by_kind(wo, wi), s))
            };
            prop_assert_eq!(bits(&here), bits(&elsewhere));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]
        /// `Bsdf::eval_pdf` is `Bsdf::eval` and `Bsdf::pdf` called apart, to the bit, for
        /// mixtures under coats too: `sample` takes its estimate's f and density from it.
        #[test]
        fn a_bsdfs_eval_pdf_is_its_eval_and_pdf(b in coated_bsdf(), wo in dir(), wi in dir()) {
            let wo = wo.normalize_or_zero();
            let mut b = b;
            b.prepare(wo);
            prop_assert_eq!(format!("{:?}", b.eval_pdf(wo, wi)), format!("{:?}", (b.eval(wo, wi), b.pdf(wo, wi))));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// A BSDF that calls itself view-independent, settled once, is what preparing a copy
        /// for any view gives, to the bit: shading points share it instead of preparing a copy
        /// (`integrator::shading`). Lobes of every kind, alone or two, at weight 1 or less,
        /// coated or not.
        #[test]
        fn a_settled_bsdf_is_every_views_prepared_bsdf(
            a in prop_oneof![lobe(), preparing_lobe()],
            b in proptest::option::of(lobe()),
            weight in prop_oneof![Just(1.0f32), 0.0f32..1.0],
            coat in any::<bool>(),
            wo in dir(),
            wi in dir(),
            u in (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0),
        ) {
            let mut bsdf = Bsdf::default();
            bsdf.push_weighted(a, weight);
            b.into_iter().for_each(|b| bsdf.push(b));
            if coat {
                bsdf.coat_with(Coat::Disney(Clearcoat::new(0.5, 0.5)), true);
            }
            let mut settled = bsdf.clone();
            settled.settle();
            if !settled.is_view_independent() {
                // Left as it is, to be copied and prepared at each shading point.
                prop_assert_eq!(format!("{settled:?}"), format!("{bsdf:?}"));
                return Ok(());
            }
            prop_assert!(bsdf.len() == 1 && !coat);
            let wo = wo.normalize_or_zero();
            let mut here = bsdf.clone();
            here.prepare(wo);
            let bits = |b: &Bsdf| {
                let s = b.sample_kind(wo, u.0, Vec2::new(u.1, u.2)).map(|(s, k, r)| (s.wi, s.weight, s.pdf, s.flags.delta, k, r));
                format!("{:?}", (b.eval(wo, wi), b.pdf(wo, wi), b.eval_pdf(wo, wi), b.albedo(wo), b.eval_by_kind(wo, wi), s))
            };
            prop_assert_eq!(bits(&settled), bits(&here));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]
        /// A lone lobe whose sample is its own estimate (`Lobe::sample_is_own_estimate`) is
        /// sampled without the mixture's second evaluation, and gives the bits the mixture
        /// gives: `eval · |cos θi| / pdf` of the whole BSDF at the sampled direction.
        #[test]
        fn a_lone_lobe_sample_is_the_mixture_estimate(
            c in (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0),
            r in prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..1.0],
            coupling in prop_oneof![Just(None), (1.0f32..3.0, 0.0f32..1.0).prop_map(Some)],
            lambert in any::<bool>(),
            sheen in any::<bool>(),
            wo in dir(),
            u in (0.0f32..1.0, 0.0f32..1.0, 0.0f32..1.0),
        ) {
            let color = Vec3::new(c.0, c.1, c.2);
            let lobe = match sheen {
                true => Lobe::Sheen(Sheen { color }),
                false => Lobe::DisneyDiffuse(DisneyDiffuse::new(color, r, r, coupling, lambert)),
            };
            prop_assert!(lobe.sample_is_own_estimate());
            let wo = wo.normalize_or_zero();
            let mut bsdf = Bsdf::default();
            bsdf.push(lobe);
            bsdf.prepare(wo);
            let s = bsdf.sample(wo, u.0, Vec2::new(u.1, u.2));
            // What `sample_lobe`'s general path computes from the lobe's direction.
            let general = s.and_then(|s| {
                let pdf = bsdf.pdf(wo, s.wi);
                (pdf > 0.0).then(|| (s.wi, bsdf.eval(wo, s.wi) * s.wi.z.abs() / pdf, pdf))
            });
            prop_assert_eq!(format!("{:?}", s.map(|s| (s.wi, s.weight, s.pdf))), format!("{general:?}"));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        #[test]
        fn eval_pdf_and_sample_are_finite_and_non_negative(l in lobe(), wo in dir(), wi in dir(), u in (0.0f32..1.0, 0.0f32..1.0)) {
            let (wo_n, wi_n) = (wo.normalize_or_zero(), wi.normalize_or_zero());
            for (a, b) in [(wo, wi), (wo_n, wi_n)] {
                let f = l.eval(a, b);
                prop_assert!(crate::math::is_finite(f) && f.min_element() >= 0.0, "eval {f:?}");
                let p = l.pdf(a, b);
                prop_assert!(p.is_finite() && p >= 0.0, "pdf {p}");
            }
            if let Some(s) = l.sample(wo_n, u.0, Vec2::new(u.1, u.0)) {
                prop_assert!(crate::math::is_finite(s.weight) && s.weight.min_element() >= 0.0, "weight {:?}", s.weight);
                prop_assert!(s.pdf.is_finite() && s.pdf > 0.0, "pdf {}", s.pdf);
                prop_assert!(crate::math::is_finite(s.wi));
            }
        }
    }
}
