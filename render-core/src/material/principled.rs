//! The Disney principled parameters (Burley 2012, "Physically Based Shading at Disney", section 5.1 plus the 2015
//! `specTrans`, `diffTrans`, `flatness`, `thin`, as Schutte 2018, "Rendering the Moana Island Scene Part 1: Implementing the Disney BSDF", implements them)
//! as the front-end of UsdPreviewSurface and `tessera:Principled`, mapped onto the uber-material.

use glam::Vec3;

use super::uber::{ClearcoatParams, Glass, Plastic, Specular, Uber, Weighted};
use crate::bsdf::thin_film::MAX_THICKNESS_NM;
use crate::bsdf::{Bsdf, Sheen, SpecularFresnel};

/// Principled parameters; defaults are Disney's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Principled {
    /// `baseColor`.
    pub base_color: Vec3,
    /// `metallic`.
    pub metallic: f32,
    /// `specular`: F0 = 0.08·specular for dielectrics (0.5 ↔ IOR 1.5).
    pub specular: f32,
    /// `specularTint`.
    pub specular_tint: f32,
    /// `roughness` (α = roughness²).
    pub roughness: f32,
    /// `anisotropic`.
    pub anisotropic: f32,
    /// `sheen`.
    pub sheen: f32,
    /// `sheenTint`.
    pub sheen_tint: f32,
    /// `clearcoat`.
    pub clearcoat: f32,
    /// `clearcoatGloss`.
    pub clearcoat_gloss: f32,
    /// `specTrans`: share of glass-like transmission.
    pub spec_trans: f32,
    /// `diffTrans`: share of the diffuse that transmits.
    pub diff_trans: f32,
    /// `flatness` (thin surfaces).
    pub flatness: f32,
    /// `thin`.
    pub thin: bool,
    /// `ior` of the transmissive part.
    pub ior: f32,
    /// Lambertian diffuse instead of Disney's (front-ends whose diffuse is Lambertian, such
    /// as UsdPreviewSurface).
    pub lambert: bool,
    /// A dielectric specular whose normal-incidence reflectance is this colour, going to white
    /// at grazing angles (Schlick), instead of the one `specular` sets: UsdPreviewSurface's
    /// specular workflow.
    pub specular_color: Option<Vec3>,
    /// Roughness of the glass lobe when it differs from `roughness` (UsdPreviewSurface's
    /// opacity transmission is smooth).
    pub transmission_roughness: Option<f32>,
    /// Tint of the glass lobe's transmission when it is not `baseColor` (UsdPreviewSurface's
    /// opacity transmission is clear).
    pub transmission_color: Option<Vec3>,
    /// `filmThickness`: a thin film (nm) on the dielectric specular and the glass, whose
    /// interference replaces their Fresnel term (Cycles' Principled Thin Film); 0: none.
    pub film_thickness: f32,
    /// `filmRefractiveIndex`: the film's index.
    pub film_ior: f32,
}

impl Default for Principled {
    fn default() -> Self {
        Principled {
            base_color: Vec3::splat(0.18),
            metallic: 0.0,
            specular: 0.5,
            specular_tint: 0.0,
            roughness: 0.5,
            anisotropic: 0.0,
            sheen: 0.0,
            sheen_tint: 0.5,
            clearcoat: 0.0,
            clearcoat_gloss: 1.0,
            spec_trans: 0.0,
            diff_trans: 0.0,
            flatness: 0.0,
            thin: false,
            ior: 1.5,
            lambert: false,
            specular_color: None,
            transmission_roughness: None,
            transmission_color: None,
            film_thickness: 0.0,
            film_ior: 1.33,
        }
    }
}

impl Principled {
    /// Every parameter clamped to its range, NaN replaced by the default.
    pub fn sanitized(&self) -> Self {
        let d = Principled::default();
        let u = |x: f32, def: f32| if x.is_finite() { x.clamp(0.0, 1.0) } else { def };
        Principled {
            base_color: if self.base_color.is_finite() { self.base_color.clamp(Vec3::ZERO, Vec3::ONE) } else { d.base_color },
            metallic: u(self.metallic, d.metallic),
            specular: u(self.specular, d.specular),
            specular_tint: u(self.specular_tint, d.specular_tint),
            roughness: u(self.roughness, d.roughness),
            anisotropic: if self.anisotropic.is_finite() { self.anisotropic.clamp(-1.0, 1.0) } else { 0.0 },
            sheen: u(self.sheen, d.sheen),
            sheen_tint: u(self.sheen_tint, d.sheen_tint),
            clearcoat: u(self.clearcoat, d.clearcoat),
            clearcoat_gloss: u(self.clearcoat_gloss, d.clearcoat_gloss),
            spec_trans: u(self.spec_trans, d.spec_trans),
            diff_trans: u(self.diff_trans, d.diff_trans),
            flatness: u(self.flatness, d.flatness),
            thin: self.thin,
            ior: if self.ior.is_finite() && self.ior > 0.0 { self.ior.clamp(1.0 / 3.0, 3.0) } else { d.ior },
            lambert: self.lambert,
            specular_color: self.specular_color.map(|c| if c.is_finite() { c.clamp(Vec3::ZERO, Vec3::ONE) } else { Vec3::splat(0.04) }),
            transmission_roughness: self.transmission_roughness.map(|r| u(r, 0.0)),
            transmission_color: self.transmission_color.map(|c| if c.is_finite() { c.clamp(Vec3::ZERO, Vec3::ONE) } else { Vec3::ONE }),
            film_thickness: if self.film_thickness.is_finite() { self.film_thickness.clamp(0.0, MAX_THICKNESS_NM) } else { 0.0 },
            film_ior: if self.film_ior.is_finite() { self.film_ior.clamp(1.0, 3.0) } else { d.film_ior },
        }
    }

    /// UsdPreviewSurface's defaults in these terms: Lambertian diffuse 0.18, roughness 0.5,
    /// specular from IOR 1.5.
    pub fn preview_surface_default() -> Self {
        Principled { lambert: true, base_color: Vec3::splat(0.18), roughness: 0.5, specular: 0.5, ..Default::default() }
    }

    /// The uber-material. Family weights follow Schutte's "Bringing it all together": plastic
    /// (diffuse and dielectric specular) (1 − metallic)(1 − specTrans), metal metallic, glass
    /// (1 − metallic)·specTrans; Disney's sheen rides on the plastic and the clearcoat on top.
    pub fn uber(&self) -> Uber {
        let p = self.sanitized();
        let tint = Sheen::tint(p.base_color);

        // Dielectric specular: η from `specular` (F0 = 0.08·specular), or Schlick when tinted
        // or given a specular colour (whose largest component then sets the diffuse's
        // coupling η: the most energy the specular can take).
        let f0 = p.specular_color.map_or(0.08 * p.specular, |c| c.max_element());
        let eta = ((1.0 + f0.sqrt()) / (1.0 - f0.sqrt()).max(1e-3)).clamp(1.0, 3.0);
        let fresnel = if p.film_thickness > 0.0 {
            // The film's interference is the whole Fresnel term, tint and colour included.
            SpecularFresnel::thin_film(p.film_ior, p.film_thickness, eta)
        } else if let Some(f0) = p.specular_color {
            SpecularFresnel::Schlick { f0 }
        } else if p.specular_tint > 0.0 {
            SpecularFresnel::Schlick { f0: f0 * Vec3::ONE.lerp(tint, p.specular_tint) }
        } else {
            SpecularFresnel::Dielectric { eta }
        };
        // A specular colour brighter than a dielectric of η = 3 (F0 = 0.25, the coupling
        // table's limit) takes more than the coupling leaves out: scale the diffuse by what
        // the excess takes at normal incidence, (1 − F0)/(1 − F0(η)). A white specular colour
        // over a white diffuse reflected 1.76 without it. (Applied only with compensation.)
        let diffuse_scale = match p.specular_color {
            Some(_) => ((1.0 - f0) / (1.0 - crate::bsdf::fresnel::f0_from_ior(eta)).max(1e-6)).clamp(0.0, 1.0),
            None => 1.0,
        };
        let specular =
            |fresnel| Specular { fresnel, roughness: p.roughness, anisotropic: p.anisotropic, roughness2: p.roughness, mix2: 0.0 };
        let plastic = Plastic {
            diffuse: p.base_color,
            diffuse_roughness: p.roughness,
            lambert: p.lambert,
            flatness: if p.thin { p.flatness } else { 0.0 },
            diffuse_transmission: p.diff_trans,
            transmission_color: if p.thin { p.base_color.powf(0.5) } else { p.base_color },
            specular: (f0 > 0.0).then(|| specular(fresnel)),
            coupling_eta: eta,
            diffuse_scale,
            disney_sheen: if p.sheen > 0.0 { p.sheen * Vec3::ONE.lerp(tint, p.sheen_tint) } else { Vec3::ZERO },
            ..Plastic::default()
        };
        // Thin glass is Imageworks' thin sheet (light crosses undeflected), Disney's sqrt
        // colour one crossing's tint.
        let tint = p.transmission_color.unwrap_or(p.base_color);
        let glass = Glass {
            roughness: p.transmission_roughness.unwrap_or(p.roughness),
            anisotropic: p.anisotropic,
            ior: p.ior,
            bend_ior: p.ior,
            color: if p.thin { tint.powf(0.5) } else { tint },
            thin: p.thin,
            film_thickness: p.film_thickness,
            film_ior: p.film_ior,
        };
        Uber {
            metal: Weighted { weight: p.metallic, params: specular(SpecularFresnel::Schlick { f0: p.base_color }) },
            plastic: Weighted { weight: (1.0 - p.metallic) * (1.0 - p.spec_trans), params: plastic },
            glass: Weighted { weight: (1.0 - p.metallic) * p.spec_trans, params: glass },
            clearcoat: Weighted { weight: p.clearcoat, params: ClearcoatParams::Disney { gloss: p.clearcoat_gloss } },
            ..Uber::default()
        }
    }

    /// The BSDF, holding only its non-zero lobes; `compensate` switches the whole
    /// Kulla-Conty energy layer.
    pub fn bsdf(&self, compensate: bool) -> Bsdf {
        self.uber().bsdf(compensate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::testing;

    /// The grid: roughness 0, 1e-4, 0.5, 1; anisotropic −1, 0, 1; IOR 1, 1.0001, 1.5,
    /// 3 and an inverse; metallic 0, 1; specTrans 0, 1; colours 0 and 1.
    fn grid() -> Vec<Principled> {
        let mut v = Vec::new();
        for roughness in [0.0, 1e-4, 0.5, 1.0] {
            for anisotropic in [-1.0, 0.0, 1.0] {
                for ior in [1.0, 1.0001, 1.5, 3.0, 1.0 / 1.5] {
                    for metallic in [0.0, 1.0] {
                        for spec_trans in [0.0, 1.0] {
                            for c in [0.0, 1.0] {
                                if metallic == 1.0 && (spec_trans == 1.0 || ior != 1.5) {
                                    continue; // metal ignores specTrans and ior
                                }
                                if spec_trans == 0.0 && ior != 1.5 {
                                    continue; // opaque dielectrics take their IOR from `specular`
                                }
                                v.push(Principled {
                                    base_color: Vec3::splat(c),
                                    metallic,
                                    roughness,
                                    anisotropic,
                                    ior,
                                    spec_trans,
                                    ..Default::default()
                                });
                            }
                        }
                    }
                }
            }
        }
        v
    }

    #[test]
    fn white_furnace_over_the_parameter_grid() {
        let (mut iso_min, mut aniso_min) = (f32::INFINITY, f32::INFINITY);
        for p in grid() {
            let bsdf = p.bsdf(true);
            // White metal and white glass, compensated, lose nothing: a conductor of F = 1
            // reflects all, clear glass reflects or transmits all (Kulla & Conty 2017,
            // "Revisiting Physically Based Shading at Imageworks", energy compensation).
            // Index-matched glass (IOR 1) is left out at cos 1e-4, where its lobe returns no
            // sample: commit removes such surfaces, so a render never evaluates it.
            let lossless = p.base_color == Vec3::ONE && (p.metallic == 1.0 || p.spec_trans == 1.0);
            for wo in testing::probe_directions() {
                for wo in if p.spec_trans > 0.0 { vec![wo, -wo] } else { vec![wo] } {
                    let a = testing::albedo_estimate(&bsdf, wo, 8_000);
                    assert!(a.max_element() <= 1.0 + 1e-3 + 0.02, "{p:?} at {wo:?}: albedo {a:?}");
                    if !lossless || (p.ior == 1.0 && wo.z.abs() < 1e-3) {
                        continue;
                    }
                    let (min, floor) = match p.anisotropic {
                        0.0 => (&mut iso_min, ISOTROPIC_FLOOR),
                        _ => (&mut aniso_min, ANISOTROPIC_FLOOR),
                    };
                    *min = min.min(a.min_element());
                    assert!(a.min_element() >= floor, "{p:?} at {wo:?}: albedo {a:?} below {floor}");
                }
            }
        }
        println!("white metal and glass over the grid: lowest albedo isotropic {iso_min}, anisotropic {aniso_min}");
    }

    /// The lowest albedo isotropic white metal and glass reach over the grid, compensated:
    /// measured 2026-12-02 at 0.987; the floor leaves 8 000 samples' noise (σ ≈ 0.5% of a rough
    /// glass's albedo, whose weights vary).
    const ISOTROPIC_FLOOR: f32 = 0.975;

    /// The same for anisotropic glass, which is not compensated (docs/materials.md: one
    /// table by mean roughness gained up to 9%; losing is the conservative failure): at
    /// roughness 0.5, anisotropy ±1 and grazing angles it loses most of its energy (0.57 at cos 0.05, IOR 1.0001; 0.068 at cos −1e-4 from
    /// inside). Measured 2026-12-02; a known gap (docs/materials.md), bounded here so it cannot
    /// grow unnoticed.
    const ANISOTROPIC_FLOOR: f32 = 0.05;

    #[test]
    fn specular_and_coupled_diffuse_never_exceed_one() {
        // White diffuse under a dielectric specular: the coupling leaves only 1 − E_s.
        for roughness in [0.05, 0.3, 0.7, 1.0] {
            let p = Principled { base_color: Vec3::ONE, roughness, ..Default::default() };
            for wo in testing::probe_directions() {
                let on = testing::albedo_estimate(&p.bsdf(true), wo, 60_000).x;
                assert!(on <= 1.0 + 1e-3 + 0.01, "roughness {roughness}, cos {}: {on}", wo.z);
            }
        }
        // Without the energy layer the sum exceeds 1 at grazing angles.
        let p = Principled { base_color: Vec3::ONE, roughness: 0.3, ..Default::default() };
        let grazing = testing::probe_directions()[5];
        assert!(testing::albedo_estimate(&p.bsdf(false), grazing, 60_000).x > 1.01);
    }

    #[test]
    fn chi_square_of_the_whole_bsdf() {
        let cases = [
            Principled { base_color: Vec3::new(0.8, 0.5, 0.2), roughness: 0.4, ..Default::default() },
            Principled { base_color: Vec3::new(0.9, 0.7, 0.3), metallic: 1.0, roughness: 0.3, anisotropic: 0.5, ..Default::default() },
            Principled { base_color: Vec3::ONE, spec_trans: 1.0, roughness: 0.5, ..Default::default() },
            Principled {
                base_color: Vec3::new(0.5, 0.6, 0.7),
                metallic: 0.3,
                spec_trans: 0.4,
                roughness: 0.6,
                sheen: 0.5,
                diff_trans: 0.3,
                ..Default::default()
            },
            Principled { base_color: Vec3::new(0.9, 0.8, 0.6), spec_trans: 1.0, thin: true, roughness: 0.4, ..Default::default() },
        ];
        let dirs: Vec<Vec3> = testing::probe_directions().into_iter().filter(|w| w.z >= 1e-3).collect();
        for (k, p) in cases.iter().enumerate() {
            testing::assert_chi2_at(&p.bsdf(true), 600 + k as u64, dirs.clone());
            if p.spec_trans > 0.0 || p.diff_trans > 0.0 {
                testing::assert_chi2_at(&p.bsdf(true), 700 + k as u64, dirs.iter().map(|w| -*w).collect());
            }
        }
    }

    #[test]
    fn a_clearcoat_takes_its_energy_from_the_layers_beneath() {
        // Added on top, Disney's coat over a white base reflects more than it receives at
        // grazing angles; layered (Kulla & Conty 2017, "Revisiting Physically Based Shading at Imageworks", "Coatings") it never does, stays reciprocal and
        // samples its pdf.
        let coated =
            Principled { base_color: Vec3::ONE, roughness: 1.0, lambert: true, clearcoat: 1.0, clearcoat_gloss: 0.5, ..Default::default() };
        let base = Principled { clearcoat: 0.0, ..coated };
        let coat = crate::bsdf::Lobe::Clearcoat(crate::bsdf::Clearcoat::new(1.0, 0.5));
        let added = testing::probe_directions()
            .into_iter()
            .map(|wo| testing::albedo_estimate(&base.bsdf(true), wo, 60_000).x + testing::albedo_estimate(&coat, wo, 60_000).x)
            .fold(0.0f32, f32::max);
        assert!(added > 1.02, "coat + base added: {added}");
        let bsdf = coated.bsdf(true);
        for wo in testing::probe_directions() {
            let a = testing::albedo_estimate(&bsdf, wo, 60_000).x;
            assert!(a <= 1.0 + 1e-3 + 0.01, "coated white base at {wo:?}: {a}");
        }
        testing::assert_reciprocal(&bsdf);
        testing::assert_chi2(&bsdf, 77);
        testing::assert_weights_consistent(&bsdf);
    }

    #[test]
    fn only_non_zero_lobes_are_built() {
        assert_eq!(Principled { metallic: 1.0, ..Default::default() }.bsdf(true).len(), 1);
        assert!(!Principled::default().bsdf(true).transmits());
        assert!(Principled { spec_trans: 1.0, ..Default::default() }.bsdf(true).transmits());
        assert_eq!(Principled { base_color: Vec3::ONE, ..Default::default() }.bsdf(true).len(), 2, "diffuse + specular");
    }
}
