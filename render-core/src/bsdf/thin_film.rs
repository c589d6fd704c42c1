//! Thin-film interference (iridescence), the third of Imageworks' coatings (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks",
//! "Coatings": clearcoat, sheen, thin film; the slides leave the film model to the reader).
//!
//! One film between air and a dielectric substrate reflects by the Airy summation of the
//! waves bouncing inside it (Born & Wolf, *Principles of Optics*, section 7.6). Its colour is
//! that reflectance integrated over the visible spectrum against the colour-matching functions,
//! which Belcour & Barla ("A Practical Extension to Microfacet Theory for the Modeling of
//! Varying Iridescence", SIGGRAPH 2017, section 4 and their supplemental code) do in Fourier
//! space: each term of the summation is a cosine of the optical path difference, and its
//! integral against a Gaussian fit of the CIE XYZ curves is closed form. The sum stops after
//! three orders (the next weighs r12·r23 less again), and films under 30 nm fade into the bare
//! substrate, where the wave-optics summation stops describing them (as their code and
//! Cycles do). XYZ under the equal-energy illuminant is taken to linear Rec. 709 with E's
//! white mapped to D65's, so a film that does not interfere is grey. Cycles' Principled BSDF
//! uses the same method (its Thin Film), which is why the Blender add-on can carry it.
//!
//! Over a conductor ([`airy_conductor`]) the bottom interface's Fresnel amplitude is complex:
//! its reflectance and its phase, neither 0 nor π, come from the metal's n + ik (Born & Wolf,
//! section 14.4.1), one index per channel as Belcour & Barla's code and Cycles do for metals.
//!
//! As a coat, its directional albedo E(μ) is tabulated per material when it is built (16 √μ
//! nodes of the coat lobe's own quadrature), and the layers beneath keep what it lets through
//! as under the other coats (`coat.rs`).

use std::f32::consts::PI;

use glam::Vec3;
use num_complex::Complex32;

/// Thickest film accepted, in nanometres: the interference terms have faded well before.
pub const MAX_THICKNESS_NM: f32 = 10_000.0;

/// Below this thickness (nm) the film fades into the bare substrate.
const FADE_NM: f32 = 30.0;

/// Reflectance (s, p) from medium `n1` into `n2` at incidence cosine `c1`, the phase (0 or π)
/// each reflection adds, and the transmitted cosine; None past the critical angle.
fn polarized(n1: f32, n2: f32, c1: f32) -> Option<([f32; 2], [f32; 2], f32)> {
    let s1 = (1.0 - c1 * c1).max(0.0).sqrt();
    let s2 = n1 / n2 * s1;
    if s2 >= 1.0 {
        return None;
    }
    let c2 = (1.0 - s2 * s2).sqrt();
    let rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
    let rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    let phase = |r: f32| if r < 0.0 { PI } else { 0.0 };
    Some(([rs * rs, rp * rp], [phase(rs), phase(rp)], c2))
}

/// The Fourier transform of the CIE XYZ curves (Belcour & Barla's Gaussian fit) at optical
/// path difference `opd` (nm) and phase `shift`, normalised to 1 at zero difference.
fn sensitivity(opd: f32, shift: f32) -> Vec3 {
    let phase = 2.0 * PI * opd * 1e-9;
    let gauss = |[v, p, s]: [f32; 3]| v * (2.0 * PI * s).sqrt() * (p * phase + shift).cos() * (-phase * phase * s).exp();
    let [x, y, z, x_blue] = GAUSSIANS.map(gauss);
    Vec3::new(x + x_blue, y, z) / SENSITIVITY_NORM
}

/// Belcour & Barla's fit of the CIE x, y and z curves in Fourier space: (amplitude, position,
/// variance) of one Gaussian each, and the x curve's second (blue) lobe last.
const GAUSSIANS: [[f32; 3]; 4] = [
    [5.4856e-13, 1.6810e6, 4.3278e9],
    [4.4201e-13, 1.7953e6, 9.3046e9],
    [5.2481e-13, 2.2084e6, 6.6121e9],
    [9.7470e-14, 2.2399e6, 4.5282e9],
];

/// [`sensitivity`]'s value at zero difference, which it is divided by.
const SENSITIVITY_NORM: f32 = 1.0685e-7;

/// [`sensitivity_rgb`] at m·`opd` for m = 1..=N, by recurrences in m: each Gaussian's phase
/// turns by the same angle from one order to the next, and its envelope exp(−φ²m²s) grows by
/// q^(2m+1) with q = exp(−φ²s). N orders cost four sin_cos and four exp, where evaluating each
/// order afresh cost 8N cos and exp (about 80% of a filmed metal's Fresnel term).
fn sensitivity_orders<const N: usize>(opd: f32) -> [(Vec3, Vec3); N] {
    let phase = 2.0 * PI * opd * 1e-9;
    // Per Gaussian: its weight, the turn (cos, sin) and q, and the running values.
    let mut state = GAUSSIANS.map(|[v, p, s]| {
        let (sin, cos) = (p * phase).sin_cos();
        let q = (-phase * phase * s).exp();
        (v * (2.0 * PI * s).sqrt(), (cos, sin), q, (cos, sin), q, q * q * q)
    });
    std::array::from_fn(|_| {
        let [x, y, z, x_blue] = state.map(|(w, _, _, (cos, sin), envelope, _)| (w * envelope * cos, w * envelope * sin));
        let part = |k: fn((f32, f32)) -> f32| rec709(Vec3::new(k(x) + k(x_blue), k(y), k(z)) / SENSITIVITY_NORM);
        for (_, (c1, s1), q, (cos, sin), envelope, growth) in state.iter_mut() {
            (*cos, *sin) = (*cos * *c1 - *sin * *s1, *sin * *c1 + *cos * *s1);
            *envelope *= *growth;
            *growth *= *q * *q;
        }
        (part(|(c, _)| c), part(|(_, s)| s))
    })
}

/// One polarisation's Airy summation in XYZ: top reflectance `r12`, bottom `r23`, optical path
/// difference `opd` and the round trip's phase `phi`.
fn summation(r12: f32, r23: f32, opd: f32, phi: f32) -> Vec3 {
    let t121 = 1.0 - r12;
    let r123 = r12 * r23;
    if r123 >= 1.0 {
        return Vec3::ONE;
    }
    let rs = t121 * t121 * r23 / (1.0 - r123);
    let mut xyz = Vec3::splat(r12 + rs);
    let mut cm = rs - t121;
    for m in 1..=3 {
        cm *= r123.sqrt();
        xyz += cm * 2.0 * sensitivity(m as f32 * opd, m as f32 * phi);
    }
    xyz
}

/// XYZ under the equal-energy illuminant to linear Rec. 709, E's white to D65's.
fn rec709(xyz: Vec3) -> Vec3 {
    let w = xyz * Vec3::new(0.950_47, 1.0, 1.088_83);
    Vec3::new(
        3.240_454_2 * w.x - 1.537_138_5 * w.y - 0.498_531_4 * w.z,
        -0.969_266 * w.x + 1.876_010_8 * w.y + 0.041_556 * w.z,
        0.055_643_4 * w.x - 0.204_025_9 * w.y + 1.057_225_2 * w.z,
    )
}

/// Reflectance of a film of index `film` and thickness `nm` on a substrate of index
/// `substrate`, seen from air at cosine `cos`, as linear Rec. 709 RGB.
pub fn airy(cos: f32, film: f32, nm: f32, substrate: f32) -> Vec3 {
    let Some(Top { film, r12, phi12, cos_film, opd }) = top(cos, film, nm) else { return Vec3::ONE };
    // Total reflection at the substrate: the film's bottom reflects everything.
    let Some((r23, phi23, _)) = polarized(film, fixed(substrate, 1.0, 3.0, 1.5), cos_film) else { return Vec3::ONE };
    // The round trip reflects once inside the top interface (its phase from below) and once at the bottom.
    let pol = |k: usize| summation(r12[k], r23[k], opd, PI - phi12[k] + phi23[k]);
    rec709(0.5 * (pol(0) + pol(1))).clamp(Vec3::ZERO, Vec3::ONE)
}

/// `x` clamped to [`lo`, `hi`], or `default` where it is not finite.
fn fixed(x: f32, lo: f32, hi: f32, default: f32) -> f32 {
    if x.is_finite() { x.clamp(lo, hi) } else { default }
}

/// What both sums read of a film's top: its index (faded below [`FADE_NM`]), reflectance and
/// phase per polarisation, the cosine inside it and the round trip's optical path difference.
struct Top {
    film: f32,
    r12: [f32; 2],
    phi12: [f32; 2],
    cos_film: f32,
    opd: f32,
}

/// The [`Top`] of a film of index `film` and thickness `nm` seen from air at cosine `cos`, the
/// three made finite and in range; None where light cannot enter it.
fn top(cos: f32, film: f32, nm: f32) -> Option<Top> {
    let (cos, nm) = (fixed(cos, 0.0, 1.0, 0.0), fixed(nm, 0.0, MAX_THICKNESS_NM, 0.0));
    let film = faded(fixed(film, 1.0, 3.0, 1.33), nm);
    let (r12, phi12, cos_film) = polarized(1.0, film, cos)?;
    Some(Top { film, r12, phi12, cos_film, opd: 2.0 * film * nm * cos_film })
}

/// The film's index faded towards air below [`FADE_NM`], where the wave-optics summation stops
/// describing it.
fn faded(film: f32, nm: f32) -> f32 {
    match nm < FADE_NM {
        true => {
            let t = nm / FADE_NM;
            1.0 + (film - 1.0) * t * t * (3.0 - 2.0 * t)
        }
        false => film,
    }
}

/// A conductor under a film: its complex refractive index n + ik, one per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// Refractive index.
    pub n: Vec3,
    /// Extinction coefficient.
    pub k: Vec3,
}

impl Conductor {
    /// The n and k of reflectivity `r` and edge colour `g` (Gulbrandsen, "Artist Friendly
    /// Metallic Fresnel", JCGT 2014: [`super::fresnel::gulbrandsen_nk`]).
    pub fn gulbrandsen(r: Vec3, g: Vec3) -> Self {
        let [x, y, z] = [0, 1, 2].map(|c| super::fresnel::gulbrandsen_nk(r[c], g[c]));
        Conductor { n: Vec3::new(x.0, y.0, z.0), k: Vec3::new(x.1, y.1, z.1) }
    }

    /// Channel `c`'s index, finite, n not below a hundredth and neither above a thousand.
    fn eta(&self, c: usize) -> Complex32 {
        Complex32::new(fixed(self.n[c], 0.01, 1e3, 1.0), fixed(self.k[c], 0.0, 1e3, 0.0))
    }
}

/// The principal square root of `z` without its angle (num-complex's goes through atan2 and
/// sin_cos, a tenth of a filmed metal's render): the stable half-angle form, each part from
/// the sum of |z| and |Re z|, so nothing cancels.
fn principal_sqrt(z: Complex32) -> Complex32 {
    let t = ((z.re.abs() + z.norm()) * 0.5).sqrt();
    if t == 0.0 {
        Complex32::new(0.0, 0.0)
    } else if z.re >= 0.0 {
        Complex32::new(t, z.im / (2.0 * t))
    } else {
        Complex32::new(z.im.abs() / (2.0 * t), t.copysign(z.im))
    }
}

/// Reflectance (s, p) from a dielectric of index `n1` into a conductor of index `eta` at
/// incidence cosine `c1`, and the phase each reflection adds as a unit complex number e^{iφ}
/// (no angle taken: the sum turns by it order by order). The transmitted side is taken as
/// η·cos θt = √(η² − n1² sin² θi) on the principal branch (a wave that decays into the metal);
/// with no absorption these are [`polarized`]'s amplitudes, of phase 0 or π.
fn conductor_polarized(n1: f32, eta: Complex32, c1: f32) -> ([f32; 2], [Complex32; 2]) {
    let eta2 = eta * eta;
    let eta_ct = principal_sqrt(eta2 - n1 * n1 * (1.0 - c1 * c1).max(0.0));
    let rs = (n1 * c1 - eta_ct) / (n1 * c1 + eta_ct);
    let rp = (eta2 * c1 - n1 * eta_ct) / (eta2 * c1 + n1 * eta_ct);
    let fine = |r: Complex32| if r.is_finite() { r } else { Complex32::new(1.0, 0.0) };
    let (rs, rp) = (fine(rs), fine(rp));
    let phasor = |r: Complex32| if r.norm_sqr() > 0.0 { r / r.norm() } else { Complex32::new(1.0, 0.0) };
    ([rs.norm_sqr().min(1.0), rp.norm_sqr().min(1.0)], [phasor(rs), phasor(rp)])
}

/// The cosine and sine parts of [`sensitivity`] at `opd`, each in linear Rec. 709:
/// sensitivity(opd, φ) = cos φ·C − sin φ·S, and the map to RGB is linear, so each channel can
/// take its own phase afterwards.
#[cfg(test)]
fn sensitivity_rgb(opd: f32) -> (Vec3, Vec3) {
    (rec709(sensitivity(opd, 0.0)), rec709(sensitivity(opd, -0.5 * PI)))
}

/// Orders of the summation over a conductor. A metal reflects most of what reaches the film's
/// bottom, so the terms fall slowly (as (r12·r23)^(m/2)): three orders, enough over glass, missed
/// the spectral integral by 0.049 for thin films at grazing angles, eight by 0.014.
const CONDUCTOR_ORDERS: usize = 8;

/// [`summation`] for channel `c` of a bottom interface whose phase differs per channel: the
/// round trip's phase e^{iφ} (`turn`) applied to the RGB sensitivities `parts` of orders 1
/// and up. `white` is channel `c` of the order-0 term's colour, grey: the equal-energy white's.
fn summation_channel(r12: f32, r23: f32, turn: Complex32, parts: &[(Vec3, Vec3); CONDUCTOR_ORDERS], c: usize, white: f32) -> f32 {
    let t121 = 1.0 - r12;
    let r123 = r12 * r23;
    if r123 >= 1.0 {
        return 1.0;
    }
    let rs = t121 * t121 * r23 / (1.0 - r123);
    let mut total = (r12 + rs) * white;
    let mut cm = rs - t121;
    // The phase of order m is m·φ: turned one φ an order.
    let mut phase = turn;
    for (cos_part, sin_part) in parts {
        cm *= r123.sqrt();
        total += cm * 2.0 * (phase.re * cos_part[c] - phase.im * sin_part[c]);
        phase *= turn;
    }
    total
}

/// Reflectance of a film of index `film` and thickness `nm` on the conductor `metal`, seen
/// from air at cosine `cos`, as linear Rec. 709 RGB: [`airy`]'s summation, the film's bottom
/// reflecting by the metal's complex Fresnel amplitude in each channel.
pub fn airy_conductor(cos: f32, film: f32, nm: f32, metal: &Conductor) -> Vec3 {
    let Some(Top { film, r12, phi12, cos_film, opd }) = top(cos, film, nm) else { return Vec3::ONE };
    let parts: [(Vec3, Vec3); CONDUCTOR_ORDERS] = sensitivity_orders(opd);
    let white = rec709(Vec3::ONE);
    let channel = |c: usize| {
        let (r23, turn23) = conductor_polarized(film, metal.eta(c), cos_film);
        // e^{i(π − φ12 + φ23)}, φ12 being 0 or π.
        let turn = |p: usize| turn23[p] * -phi12[p].cos();
        (0..2).map(|p| 0.5 * summation_channel(r12[p], r23[p], turn(p), &parts, c, white[c])).sum::<f32>()
    };
    Vec3::new(channel(0), channel(1), channel(2)).clamp(Vec3::ZERO, Vec3::ONE)
}

/// What a thread keeps of a film's tables: the last few, by their parameters' bits.
type Kept<K, V> = std::cell::RefCell<Vec<(K, V)>>;

/// `compute()` for `key`, or what this thread kept of it. A textured material builds its BSDF
/// at every shading point, so a film that does not vary is computed once a thread, not once a
/// vertex. Every value is a pure function of its key: keeping it changes no bit.
fn kept<K: PartialEq + Copy, V: Copy>(cache: &'static std::thread::LocalKey<Kept<K, V>>, key: K, compute: impl FnOnce() -> V) -> V {
    const KEPT: usize = 8;
    if let Some(v) = cache.with_borrow(|t| t.iter().find(|(k, _)| *k == key).map(|(_, v)| *v)) {
        return v;
    }
    let v = compute();
    cache.with_borrow_mut(|t| {
        if t.len() == KEPT {
            t.remove(0);
        }
        t.push((key, v));
    });
    v
}

/// The film's cosine-weighted average reflectance, by the midpoint rule on 64 cosines
/// (17 µs to compute).
pub(super) fn average(film: f32, thickness: f32, substrate: f32) -> Vec3 {
    thread_local! {
        static AVERAGES: Kept<[u32; 3], Vec3> = const { std::cell::RefCell::new(Vec::new()) };
    }
    kept(&AVERAGES, [film.to_bits(), thickness.to_bits(), substrate.to_bits()], || {
        cosine_average(64, |mu| airy(mu, film, thickness, substrate))
    })
}

/// 2∫f(μ)μ dμ over [0, 1] by the midpoint rule on `count` cosines.
fn cosine_average(count: usize, f: impl Fn(f32) -> Vec3) -> Vec3 {
    (0..count).map(|k| (k as f32 + 0.5) / count as f32).map(|mu| f(mu) * (2.0 * mu / count as f32)).sum()
}

/// [`average`] of a film over the conductor `metal`, on 16 cosines: it only sets the size of
/// the energy compensation (7 µs on the Zen 4 host; the test that checks it prints it). A
/// metal whose colours are textured reads it from [`ConductorAverages`] instead.
pub(super) fn average_conductor(film: f32, thickness: f32, metal: &Conductor) -> Vec3 {
    thread_local! {
        static AVERAGES: Kept<[u32; 8], Vec3> = const { std::cell::RefCell::new(Vec::new()) };
    }
    let (n, k) = (metal.n.to_array().map(f32::to_bits), metal.k.to_array().map(f32::to_bits));
    kept(&AVERAGES, [film.to_bits(), thickness.to_bits(), n[0], n[1], n[2], k[0], k[1], k[2]], || {
        cosine_average(16, |mu| airy_conductor(mu, film, thickness, metal))
    })
}

/// A film's [`average_conductor`] over every metal Gulbrandsen's reflectivity r and edge colour
/// g describe, for a metal whose colours vary over its surface. A channel's average depends on
/// that channel's (r, g) alone ([`airy_conductor`] reads `metal.eta(c)` only), so one grid of
/// grey metals over [0, 1]² holds each channel's, read bilinearly per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ConductorAverages {
    /// Film refractive index.
    pub film: f32,
    /// Thickness in nanometres.
    pub thickness: f32,
    /// The grey metal (r_i, g_j)'s average at `nodes[i * CONDUCTOR_GRID + j]`.
    nodes: Vec<Vec3>,
}

/// Nodes a side of [`ConductorAverages`]' grid: 625 averages, about 5 ms to build. They lie
/// evenly in asin(√r) and in 1 − √(1 − g), dense where n and k change fastest: r near 0 or
/// 1, g near 1.
const CONDUCTOR_GRID: usize = 25;

impl ConductorAverages {
    /// The grid of a film of index `film` and `thickness` nanometres.
    pub fn new(film: f32, thickness: f32) -> Self {
        let at = |i: usize| i as f32 / (CONDUCTOR_GRID - 1) as f32;
        let nodes = (0..CONDUCTOR_GRID * CONDUCTOR_GRID)
            .map(|ij| {
                let (r, g) =
                    ((at(ij / CONDUCTOR_GRID) * std::f32::consts::FRAC_PI_2).sin().powi(2), 1.0 - (1.0 - at(ij % CONDUCTOR_GRID)).powi(2));
                let metal = Conductor::gulbrandsen(Vec3::splat(r), Vec3::splat(g));
                cosine_average(16, |mu| airy_conductor(mu, film, thickness, &metal))
            })
            .collect();
        ConductorAverages { film, thickness, nodes }
    }

    /// The average over the metal of reflectivity `r` and edge colour `g`, channel by channel.
    pub fn at(&self, r: Vec3, g: Vec3) -> Vec3 {
        let last = (CONDUCTOR_GRID - 1) as f32;
        let cell = |x: f32| {
            let f = x.clamp(0.0, 1.0) * last;
            let i = (f as usize).min(CONDUCTOR_GRID - 2);
            (i, f - i as f32)
        };
        let channel = |c: usize| {
            let ((i, s), (j, t)) =
                (cell(r[c].clamp(0.0, 1.0).sqrt().asin() / std::f32::consts::FRAC_PI_2), cell(1.0 - (1.0 - g[c].min(1.0)).max(0.0).sqrt()));
            let node = |a: usize, b: usize| self.nodes[(i + a) * CONDUCTOR_GRID + j + b][c];
            (1.0 - s) * ((1.0 - t) * node(0, 0) + t * node(0, 1)) + s * ((1.0 - t) * node(1, 0) + t * node(1, 1))
        };
        Vec3::new(channel(0), channel(1), channel(2))
    }
}

/// The coat lobe's directional albedo at √μ = k/15, by stratified quadrature of the lobe (4 ms
/// to compute).
fn albedo_table(c: &ThinFilmCoat, compensate: bool) -> [f32; 16] {
    thread_local! {
        static TABLES: Kept<[u32; 5], [f32; 16]> = const { std::cell::RefCell::new(Vec::new()) };
    }
    let key = [c.roughness.to_bits(), c.film.to_bits(), c.thickness.to_bits(), c.substrate.to_bits(), compensate as u32];
    kept(&TABLES, key, || {
        let lobe = c.lobe(compensate);
        std::array::from_fn(|k| {
            let mu = ((k as f32 / 15.0).powi(2)).max(1e-4);
            super::energy::grid_albedo(|wo, uc, u| lobe.sample(wo, uc, u), mu, 24).min(1.0)
        })
    })
}

/// A thin-film coat: a GGX reflection whose Fresnel is the film's interference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilmCoat {
    /// Coverage.
    pub weight: f32,
    /// Roughness of the film's surface.
    pub roughness: f32,
    /// Film refractive index.
    pub film: f32,
    /// Thickness in nanometres.
    pub thickness: f32,
    /// Refractive index under the film.
    pub substrate: f32,
    /// The coat lobe's directional albedo at √μ = k/15 (largest channel).
    pub e: [f32; 16],
}

impl ThinFilmCoat {
    /// A coat, its albedo table computed by stratified quadrature of its own lobe.
    pub fn new(weight: f32, roughness: f32, film: f32, thickness: f32, substrate: f32, compensate: bool) -> Self {
        let mut c = ThinFilmCoat {
            weight: fixed(weight, 0.0, 1.0, 0.0),
            roughness: fixed(roughness, 0.0, 1.0, 0.0),
            film: fixed(film, 1.0, 3.0, 1.33),
            thickness: fixed(thickness, 0.0, MAX_THICKNESS_NM, 0.0),
            substrate: fixed(substrate, 1.0, 3.0, 1.5),
            e: [0.0; 16],
        };
        c.e = albedo_table(&c, compensate);
        c
    }

    /// The coat's own lobe.
    pub fn lobe(&self, compensate: bool) -> super::GgxReflection {
        let fresnel = super::SpecularFresnel::thin_film(self.film, self.thickness, self.substrate);
        super::GgxReflection::new(self.roughness, 0.0, fresnel, compensate)
    }

    /// E(μ) from the table.
    pub fn e(&self, mu: f32) -> f32 {
        super::energy::split_axis(mu.abs().min(1.0).sqrt(), 16).iter().map(|&(k, w)| w * self.e[k]).sum()
    }
}

/// The reference the Fourier-space integration is checked against: the Airy formula at single
/// wavelengths, integrated over the spectrum.
#[cfg(test)]
pub(crate) mod spectral {
    use super::rec709;
    use glam::Vec3;

    /// The exact reflectance of the film at one wavelength (nm), the Airy formula in the
    /// amplitudes of the two interfaces (Born & Wolf 7.6), seen from a medium of index
    /// `ambient` at cosine `cos`.
    fn airy_at(ambient: f64, cos: f32, film: f64, nm: f64, substrate: f64, lambda: f64) -> f64 {
        let amplitudes = |n1: f64, n2: f64, c1: f64| {
            let c2 = (1.0 - (n1 / n2).powi(2) * (1.0 - c1 * c1)).sqrt();
            ([(n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2), (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)], c2)
        };
        let (r01, cf) = amplitudes(ambient, film, cos as f64);
        let (r12, _) = amplitudes(film, substrate, cf);
        let delta = 2.0 * std::f64::consts::PI / lambda * 2.0 * film * nm * cf;
        let r = |a: f64, b: f64| {
            let c = 2.0 * a * b * delta.cos();
            (a * a + b * b + c) / (1.0 + a * a * b * b + c)
        };
        0.5 * (r(r01[0], r12[0]) + r(r01[1], r12[1]))
    }

    /// [`airy_at`] integrated over 360-830 nm against the CIE 1931 curves (Wyman et al.'s fit,
    /// not Belcour & Barla's) under the equal-energy illuminant, to Rec. 709 as
    /// [`super::airy`] does.
    pub(crate) fn airy_by_wavelength(ambient: f32, cos: f32, film: f32, nm: f32, substrate: f32) -> Vec3 {
        let (mut xyz, mut norm) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for l in 360..=830 {
            let cmf = crate::light::blackbody::cie_1931(l as f64);
            xyz += airy_at(ambient as f64, cos, film as f64, nm as f64, substrate as f64, l as f64) * cmf;
            norm += cmf;
        }
        rec709((xyz / norm).as_vec3())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Bsdf, Coat, Lambert, Lobe, fresnel, testing};
    use crate::sampling::Pcg32;

    #[test]
    fn a_film_of_no_thickness_is_the_bare_substrate() {
        for cos in [1.0f32, 0.7, 0.3, 0.05] {
            let r = airy(cos, 1.33, 0.0, 1.5);
            let bare = fresnel::dielectric(cos, 1.5);
            assert!((r - Vec3::splat(bare)).abs().max_element() < 1e-4, "cos {cos}: {r:?} vs {bare}");
        }
    }

    /// The closed-form spectral integral against a brute-force one, over thicknesses of soap
    /// and oil films and anti-reflective coatings, head-on to grazing. 0.012: the two fits of
    /// the colour-matching functions and the sum's truncation after three orders (measured
    /// largest difference 0.011; three single wavelengths, this module's model until 2026-12-07,
    /// missed by up to 0.067).
    #[test]
    fn the_fourier_integral_is_the_spectrum_integrated_wavelength_by_wavelength() {
        let mut worst: f32 = 0.0;
        for (film, substrate) in [(1.33, 1.5), (1.45, 1.5), (1.8, 1.5), (1.2, 1.6)] {
            for nm in [50.0, 120.0, 250.0, 400.0, 500.0, 700.0, 1000.0] {
                for cos in [1.0f32, 0.7, 0.4, 0.1] {
                    let d =
                        (airy(cos, film, nm, substrate) - spectral::airy_by_wavelength(1.0, cos, film, nm, substrate)).abs().max_element();
                    worst = worst.max(d);
                    assert!(
                        d < 0.012,
                        "film {film} on {substrate}, {nm} nm, cos {cos}: {:?} vs {:?}",
                        airy(cos, film, nm, substrate),
                        spectral::airy_by_wavelength(1.0, cos, film, nm, substrate)
                    );
                }
            }
        }
        assert!(worst > 1e-4, "the two integrals are independent: {worst}");
    }

    /// [`airy_at`] over a conductor of index n + ik: the bottom amplitudes complex, the film's
    /// reflectance |r01 + r12·e^{iδ}|² / |1 + r01·r12·e^{iδ}|² (Born & Wolf 7.6 with 14.4.1).
    fn airy_conductor_at(cos: f64, film: f64, nm: f64, n: f64, k: f64, lambda: f64) -> f64 {
        use num_complex::Complex64;
        let cf = (1.0 - (1.0 - cos * cos) / (film * film)).sqrt();
        let r01 = [(cos - film * cf) / (cos + film * cf), (film * cos - cf) / (film * cos + cf)];
        let eta = Complex64::new(n, k);
        let eta_ct = (eta * eta - film * film * (1.0 - cf * cf)).sqrt();
        let r12 = [(film * cf - eta_ct) / (film * cf + eta_ct), (eta * eta * cf - film * eta_ct) / (eta * eta * cf + film * eta_ct)];
        let phase = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI / lambda * 2.0 * film * nm * cf);
        let r = |a: f64, b: Complex64| ((a + b * phase) / (1.0 + a * b * phase)).norm_sqr();
        0.5 * (r(r01[0], r12[0]) + r(r01[1], r12[1]))
    }

    /// A film over a grey conductor (one n + ik for every wavelength, so that one spectral
    /// integral is the reference) against the same film integrated wavelength by wavelength:
    /// silver-, nickel- and titanium-like indices, soap to titania films, head-on to grazing.
    /// 0.04: the Gaussian fit of the colour-matching functions errs in proportion to the
    /// interference's amplitude, which a metal's strong bottom reflection makes large (measured
    /// 0.037, 500 nm of index 2.2 head-on; over glass the same fit errs by 0.011). Summed to three
    /// orders, as over glass, thin films at grazing angles missed by 0.049: hence
    /// [`CONDUCTOR_ORDERS`].
    #[test]
    fn a_film_over_a_conductor_is_its_spectrum_integrated() {
        let mut worst: f32 = 0.0;
        for (n, k) in [(0.15f32, 3.5f32), (1.9, 3.4), (2.9, 3.1)] {
            let metal = Conductor { n: Vec3::splat(n), k: Vec3::splat(k) };
            for film in [1.33f32, 1.5, 2.2] {
                for nm in [80.0f32, 250.0, 500.0] {
                    for cos in [1.0f32, 0.6, 0.2] {
                        let (mut xyz, mut norm) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
                        for l in 360..=830 {
                            let cmf = crate::light::blackbody::cie_1931(l as f64);
                            xyz += airy_conductor_at(cos as f64, film as f64, nm as f64, n as f64, k as f64, l as f64) * cmf;
                            norm += cmf;
                        }
                        let reference = rec709((xyz / norm).as_vec3()).clamp(Vec3::ZERO, Vec3::ONE);
                        worst = worst.max((airy_conductor(cos, film, nm, &metal) - reference).abs().max_element());
                    }
                }
            }
        }
        assert!(worst < 0.04, "largest difference {worst}");
    }

    /// With no absorption the conductor's path is the dielectric film's (the same summation
    /// with real amplitudes, phases 0 or π), but for its orders beyond the dielectric's three
    /// (measured up to 4e-4, at grazing angles where the film's top reflects most).
    #[test]
    fn a_conductor_that_does_not_absorb_is_the_dielectric_film() {
        for (film, substrate) in [(1.33, 1.5), (1.45, 2.0)] {
            let metal = Conductor { n: Vec3::splat(substrate), k: Vec3::ZERO };
            for nm in [0.0, 100.0, 300.0, 700.0] {
                for cos in [1.0, 0.6, 0.2] {
                    let d = (airy_conductor(cos, film, nm, &metal) - airy(cos, film, nm, substrate)).abs().max_element();
                    assert!(d < 1e-3, "film {film} on {substrate}, {nm} nm, cos {cos}: {d}");
                }
            }
        }
    }

    /// A film of no thickness leaves the bare metal: head-on, Gulbrandsen's reflectivity
    /// exactly (his n and k are chosen for it), and at every angle the conductor's Fresnel.
    #[test]
    fn a_film_of_no_thickness_leaves_the_bare_conductor() {
        let (r, g) = (Vec3::new(0.95, 0.64, 0.54), Vec3::new(1.0, 0.98, 0.6));
        let metal = Conductor::gulbrandsen(r, g);
        assert!((airy_conductor(1.0, 1.5, 0.0, &metal) - r).abs().max_element() < 1e-4);
        for cos in [0.8f32, 0.4, 0.1] {
            let bare = Vec3::from_array(std::array::from_fn(|c| {
                let (rsp, _) = conductor_polarized(1.0, metal.eta(c), cos);
                0.5 * (rsp[0] + rsp[1])
            }));
            assert!((airy_conductor(cos, 1.5, 0.0, &metal) - bare).abs().max_element() < 1e-4, "cos {cos}");
        }
    }

    /// The square root without angles is num-complex's principal one, over all four quadrants,
    /// the axes, tiny and huge magnitudes.
    #[test]
    fn the_principal_square_root_is_num_complexs() {
        for re in [-1e6f32, -3.0, -1e-3, 0.0, 1e-3, 2.0, 1e6] {
            for im in [-1e5f32, -2.0, -1e-4, 0.0, 1e-4, 0.5, 1e5] {
                let z = Complex32::new(re, im);
                let (ours, theirs) = (principal_sqrt(z), z.sqrt());
                assert!((ours - theirs).norm() <= 1e-6 * theirs.norm().max(1e-30), "{z}: {ours} against {theirs}");
            }
        }
    }

    /// The orders' sensitivities by recurrence are each order's computed afresh, to 1e-5 (the
    /// rounding of eight steps: measured up to 2.5e-6), over optical paths of a few nanometres
    /// to a thick film's (where the envelope has faded).
    #[test]
    fn sensitivities_by_recurrence_are_each_orders_own() {
        for opd in [5.0f32, 120.0, 400.0, 900.0, 2500.0, 20_000.0] {
            for (m, (cos, sin)) in sensitivity_orders::<CONDUCTOR_ORDERS>(opd).into_iter().enumerate() {
                let (c, s) = sensitivity_rgb((m + 1) as f32 * opd);
                let d = (cos - c).abs().max((sin - s).abs()).max_element();
                assert!(d < 1e-5, "opd {opd}, order {}: {cos} {sin} against {c} {s}", m + 1);
            }
        }
    }

    /// The 16-cosine average is the 64-cosine one to 0.01, and what it costs is printed.
    #[test]
    fn a_film_over_a_conductors_average_is_close_and_cheap() {
        let metal = Conductor::gulbrandsen(Vec3::new(0.95, 0.64, 0.54), Vec3::new(1.0, 0.98, 0.6));
        for nm in [100.0, 300.0, 800.0] {
            let fine: Vec3 =
                (0..256).map(|i| (i as f32 + 0.5) / 256.0).map(|mu| airy_conductor(mu, 1.5, nm, &metal) * (2.0 * mu / 256.0)).sum();
            let d = (average_conductor(1.5, nm, &metal) - fine).abs().max_element();
            assert!(d < 0.01, "{nm} nm: {d}");
        }
        let t = std::time::Instant::now();
        for i in 0..100 {
            std::hint::black_box(average_conductor(1.5, 300.0 + i as f32, &metal));
        }
        eprintln!("average over a conductor: {:.1} µs", t.elapsed().as_secs_f64() * 1e4);
    }

    /// Whatever the inputs, a reflectance in [0, 1].
    #[test]
    fn a_film_over_a_conductor_stays_finite_at_extremes() {
        let odd = [f32::NAN, f32::INFINITY, -1.0, 0.0, 1e-30, 1e30];
        for n in odd {
            for k in odd {
                let metal = Conductor { n: Vec3::splat(n), k: Vec3::splat(k) };
                for cos in [0.0, 1e-7, 1.0, f32::NAN] {
                    for nm in [0.0, 29.9, 10_000.0, f32::INFINITY] {
                        let r = airy_conductor(cos, 1.5, nm, &metal);
                        assert!(r.is_finite() && r.min_element() >= 0.0 && r.max_element() <= 1.0, "{n} {k} {cos} {nm}: {r}");
                    }
                }
            }
        }
    }

    /// A quarter-wave film of index √n_s at 550 nm, the anti-reflection coating: head-on it
    /// reflects under a twentieth of the bare substrate's luminance (measured 0.017), tinted
    /// purple (red and blue reflect, green cancels). Colour varies with thickness: iridescence.
    #[test]
    fn quarter_wave_film_is_anti_reflective() {
        let film = 1.5f32.sqrt();
        let r = airy(1.0, film, 550.0 / (4.0 * film), 1.5);
        let bare = fresnel::dielectric(1.0, 1.5);
        assert!(crate::math::luminance(r) < 0.05 * bare, "{r:?} against {bare}");
        assert!(r.y < r.x && r.y < r.z, "green cancels most: {r:?}");
        let a = airy(1.0, 1.33, 300.0, 1.5);
        let b = airy(1.0, 1.33, 400.0, 1.5);
        assert!((a - b).abs().max_element() > 0.01);
    }

    /// Limits where the film cannot interfere. A film of the substrate's own index has no
    /// bottom interface: the bare substrate. A film so thick that no two path lengths stay
    /// coherent across the spectrum reflects the incoherent sum R12 + T²R23/(1 − R12·R23).
    #[test]
    fn films_that_cannot_interfere_reflect_grey() {
        for cos in [1.0f32, 0.5, 0.1] {
            let bare = fresnel::dielectric(cos, 1.5);
            let r = airy(cos, 1.5, 400.0, 1.5);
            assert!((r - Vec3::splat(bare)).abs().max_element() < 1e-4, "cos {cos}: {r:?} vs {bare}");
            let (r12, _, cf) = polarized(1.0, 1.33, cos).unwrap();
            let (r23, _, _) = polarized(1.33, 1.5, cf).unwrap();
            let incoherent = |k: usize| r12[k] + (1.0 - r12[k]).powi(2) * r23[k] / (1.0 - r12[k] * r23[k]);
            let want = 0.5 * (incoherent(0) + incoherent(1));
            let thick = airy(cos, 1.33, MAX_THICKNESS_NM, 1.5);
            assert!((thick - Vec3::splat(want)).abs().max_element() < 1e-3, "cos {cos}: {thick:?} vs {want}");
        }
    }

    #[test]
    fn coated_white_base_conserves_energy_and_samples_its_pdf() {
        let mut b = Bsdf::default();
        b.push(Lobe::Lambert(Lambert { r: Vec3::ONE }));
        b.coat_with(Coat::ThinFilm(ThinFilmCoat::new(1.0, 0.2, 1.33, 380.0, 1.5, true)), true);
        for wo in testing::probe_directions() {
            let a = testing::albedo_estimate(&b, wo, 40_000);
            assert!(a.max_element() <= 1.0 + 1e-3 + 0.01, "{wo:?}: {a:?}");
        }
        testing::assert_reciprocal(&b);
        testing::assert_chi2_at(&b, 1200, testing::probe_directions().into_iter().filter(|w| w.z >= 1e-2).collect());
    }

    /// The grid of averages reads each channel's metal within 0.01 of its own average, for
    /// colours anywhere in [0, 1] and films thin to thick (measured worst over 200 metals:
    /// 0.004-0.009; 0.07 on an evenly spaced 17² grid, hence the spacing dense at the ends).
    /// An error of 0.01 moves a rough metal's compensation by about 2% of itself.
    #[test]
    fn conductor_averages_read_each_channels_metal() {
        let mut rng = Pcg32::new(9, 2);
        for (film, thickness) in [(1.33, 150.0), (1.5, 400.0), (2.0, 900.0)] {
            let grid = ConductorAverages::new(film, thickness);
            let mut worst = 0.0f32;
            for _ in 0..200 {
                let (r, g) =
                    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()), Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()));
                let exact = cosine_average(16, |mu| airy_conductor(mu, film, thickness, &Conductor::gulbrandsen(r, g)));
                worst = worst.max((grid.at(r, g) - exact).abs().max_element());
            }
            println!("film {film}, {thickness} nm: worst {worst}");
            assert!(worst < 0.01, "film {film}, {thickness} nm: {worst}");
        }
    }

    /// The albedo table and average kept per thread are the ones computed afresh, to the bit,
    /// on a thread that kept nothing: for the same film asked again, and for films that differ
    /// from a kept one in each parameter (a key missing one would return the kept film's).
    #[test]
    fn kept_tables_are_the_computed_ones() {
        let coat = |(roughness, film, nm, substrate): (f32, f32, f32, f32)| {
            let c = ThinFilmCoat::new(1.0, roughness, film, nm, substrate, true);
            (c.e.map(f32::to_bits), average(film, nm, substrate).to_array().map(f32::to_bits))
        };
        let fresh = |p| std::thread::spawn(move || coat(p)).join().expect("thread");
        let kept = (0.25, 1.4, 333.0, 1.5);
        let first = coat(kept);
        assert_eq!(first, coat(kept));
        assert_eq!(first, fresh(kept));
        for other in [(0.3, 1.4, 333.0, 1.5), (0.25, 1.5, 333.0, 1.5), (0.25, 1.4, 334.0, 1.5), (0.25, 1.4, 333.0, 1.6)] {
            assert_eq!(coat(other), fresh(other), "{other:?}");
            assert_ne!(coat(other), first, "{other:?}");
        }
    }

    /// The same for the average over a conductor, whose key holds both indices of each channel:
    /// films differing from a kept one in any of its eight parameters get their own.
    #[test]
    fn kept_conductor_averages_are_the_computed_ones() {
        let average = |p: [f32; 8]| {
            let metal = Conductor { n: Vec3::new(p[2], p[3], p[4]), k: Vec3::new(p[5], p[6], p[7]) };
            average_conductor(p[0], p[1], &metal).to_array().map(f32::to_bits)
        };
        let fresh = |p| std::thread::spawn(move || average(p)).join().expect("thread");
        let kept = [1.5, 300.0, 0.2, 0.4, 1.1, 3.5, 2.8, 2.3];
        let first = average(kept);
        assert_eq!(first, average(kept));
        assert_eq!(first, fresh(kept));
        for i in 0..8 {
            let mut other = kept;
            other[i] += 0.05;
            assert_eq!(average(other), fresh(other), "parameter {i}");
            assert_ne!(average(other), first, "parameter {i}");
        }
    }

    #[test]
    fn finite_at_extreme_parameters() {
        for (film, nm, sub) in [(1.0, 0.0, 1.0), (3.0, 1e9, 3.0), (f32::NAN, f32::NAN, f32::NAN), (1.2, 500.0, 3.0)] {
            for cos in [0.0f32, 1e-6, 0.5, 1.0] {
                assert!(crate::math::is_finite(airy(cos, film.clamp(1.0, 3.0), nm, sub.clamp(1.0, 3.0))));
            }
            let c = ThinFilmCoat::new(1.0, 0.0, film, nm, sub, true);
            assert!(c.e.iter().all(|e| e.is_finite()));
        }
    }
}
