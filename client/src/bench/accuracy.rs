//! `tessera bench accuracy`: what each quality knob buys and what it costs, measured.
//!
//! Renders fixtures in-process (no server: the timings are the renderer's own) under each
//! knob, compares every image with a reference of the same scene rendered by this renderer in
//! `reference` mode (all approximations off, many samples) or with the closed form where the
//! scene has one, and writes `docs/accuracy-vs-time.md` with tables and an SVG plot.
//! Errors are relative MSE (Rousselle et al.'s ε = 0.01) and mean absolute error; the
//! reference's own noise is measured by rendering it twice with different seeds.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use render_core::integrator::LightStrategy;
use render_core::sampling::SamplerKind;
use render_core::scene::{BlasCache, CommittedScene, commit};

use super::harness::{Knobs, Row, load, machine_description, mean, mean_abs, reference_image, rel_mse, render, today};
use crate::quality::Quality;

/// Where denoising's price lives: Open Image Denoise is an optional run-time library, so
/// its bench is separate from this report's.
const DENOISING: &str = "\n## Denoising\n\nRaw against denoised relMSE and time at 4 to 1024 spp on the Cornell box, the showcase and a glass scene, the bias floor, and Open Image Denoise's own time per megapixel on 1 and 2 threads: `cargo bench -p tessera --bench denoise`, reported in `docs/denoising.md` (the library is optional, so its bench stands apart from this one).\n";

/// Options of `tessera bench accuracy`.
#[derive(Clone, Debug)]
pub struct AccuracyBench {
    /// `fixtures/` directory.
    pub fixtures: PathBuf,
    /// Markdown report to write; the SVG goes beside it.
    pub out: PathBuf,
    /// Image size of the Cornell box renders.
    pub size: u32,
    /// Samples per pixel of the reference.
    pub reference_spp: u32,
}

/// (spp, seconds, relMSE) of one sampler at each sample count of the sweep.
pub type SppCurve = Vec<(u32, f64, f64)>;

/// The measured numbers behind the report, for tests.
#[derive(Clone, Debug, Default)]
pub struct AccuracySummary {
    /// Per sampler: its points over the spp sweep.
    pub spp_curves: Vec<(String, SppCurve)>,
    /// (max depth, relMSE).
    pub depth: Vec<(u32, f64)>,
    /// (fixture, compensation on, image mean) in the furnace.
    pub furnace: Vec<(String, bool, f64)>,
    /// The reference's own relMSE.
    pub reference_noise: f64,
    /// (setting, seconds, relMSE) with adaptive sampling at several targets and uniform.
    pub adaptive: Vec<(String, f64, f64)>,
    /// (setting, seconds, relMSE) with caustics full and avoided.
    pub caustics: Vec<(String, f64, f64)>,
    /// (setting, seconds, relMSE) with the subsurface random walk (caustics full and
    /// avoided) and its diffuse fallback.
    pub subsurface: Vec<(String, f64, f64)>,
    /// (setting, seconds, relMSE) behind a smooth boundary, caustics full and avoided,
    /// against the avoided walk's own reference.
    pub subsurface_smooth: Vec<(String, f64, f64)>,
    /// The smooth-boundary medium under the white dome: mean of the avoided render over the
    /// full one's, per channel (avoidance's bias where full path tracing converges).
    pub subsurface_smooth_bias: [f64; 3],
    /// 10 000 lights against each one-light scene at equal time, for split budgets 8, 4, 2
    /// and 1 (no splitting).
    pub many_lights: Vec<super::lights::LightsRow>,
    /// (setting, seconds, relMSE) with texture filtering on and off.
    pub texture_filtering: Vec<(String, f64, f64)>,
}

/// Runs the benchmark, writes the report and returns its text and numbers.
/// Runs the benchmark, writes the report and returns its text and numbers.
pub fn accuracy(b: &AccuracyBench) -> Result<(String, AccuracySummary)> {
    if let Some(dir) = b.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let mut r = Report { b, res: (b.size, b.size), base: Knobs::default(), md: String::new(), summary: AccuracySummary::default() };
    writeln!(r.md, "# What accuracy costs in time\n")?;
    writeln!(
        r.md,
        "Written by `tessera bench accuracy` on {} ({}, {} render threads). Regenerate with\n`cargo run --release -p tessera -- bench accuracy`; the numbers below are this run's.\n",
        today(),
        machine_description(),
        rayon::current_num_threads()
    )?;
    r.cornell()?;
    r.energy_compensation()?;
    r.caustics()?;
    r.subsurface()?;
    r.smooth_subsurface()?;
    r.texture_filtering()?;
    r.motion_samples()?;
    r.curve_samples()?;
    r.volume_depth()?;
    r.many_lights()?;
    r.md.push_str(DENOISING);
    std::fs::write(&b.out, &r.md).with_context(|| format!("cannot write {}", b.out.display()))?;
    Ok((r.md, r.summary))
}

/// The accuracy report being written: each section renders its scene and appends a table.
struct Report<'b> {
    b: &'b AccuracyBench,
    /// Image size of the Cornell box sections (others derive theirs from it).
    res: (u32, u32),
    /// The knobs every row starts from.
    base: Knobs,
    md: String,
    summary: AccuracySummary,
}

impl Report<'_> {
    /// The Cornell box: spp and sampler, max depth, clamp, adaptive sampling, light strategies, presets.
    fn cornell(&mut self) -> Result<()> {
        let cornell = load(&self.b.fixtures, "cornell_box.usda")?;
        let reference_knobs = Knobs::from_quality(Quality::Reference);
        let reference_knobs = Knobs { spp: self.b.reference_spp, ..reference_knobs };
        eprintln!("cornell reference: {} spp at {}x{} ...", self.b.reference_spp, self.res.0, self.res.1);
        let r1 = render(&cornell, self.res, reference_knobs, 1_000_001);
        let r2 = render(&cornell, self.res, reference_knobs, 2_000_002);
        // Each reference's own relMSE is half that between two independent ones; their average
        // halves it again.
        let reference: Vec<f64> = r1.rgb.iter().zip(&r2.rgb).map(|(a, b)| 0.5 * (a + b)).collect();
        let reference_noise = rel_mse(&r1.rgb, &r2.rgb) / 4.0;
        self.summary.reference_noise = reference_noise;
        writeln!(
            self.md,
            "## Cornell box ({}x{}, `fixtures/cornell_box.usda`)\n\nReference: `reference` mode (no clamp, max depth {}, Sobol), two renders of {} spp averaged ({:.1} s each). Its own remaining noise is relMSE {:.2e}, below every error reported here.\n",
            self.res.0, self.res.1, reference_knobs.max_depth, self.b.reference_spp, r1.seconds, reference_noise
        )?;

        let measure = |label: String, k: Knobs| -> Row {
            let r = render(&cornell, self.res, k, 7);
            Row::of(label, &r, &reference)
        };

        // Samples per pixel and sampler: the convergence curves.
        let spps = [1u32, 4, 16, 64, 256];
        let mut curves: Vec<(&str, Vec<Row>)> = Vec::new();
        for (name, sampler) in [("Sobol", SamplerKind::Sobol), ("independent", SamplerKind::Independent)] {
            eprintln!("cornell spp sweep, {name} ...");
            curves.push((name, spps.iter().map(|&spp| measure(format!("{spp} spp"), Knobs { spp, sampler, ..self.base })).collect()));
        }
        writeln!(self.md, "### Samples per pixel and sampler (max depth 7)\n")?;
        writeln!(self.md, "| spp | Sobol s | Sobol relMSE | independent s | independent relMSE |\n| ---: | ---: | ---: | ---: | ---: |")?;
        for (i, spp) in spps.iter().enumerate() {
            let (s, r) = (&curves[0].1[i], &curves[1].1[i]);
            writeln!(self.md, "| {spp} | {:.3} | {:.2e} | {:.3} | {:.2e} |", s.seconds, s.rel_mse, r.seconds, r.rel_mse)?;
        }
        for (name, rows) in &curves {
            let slope = log_slope(rows.iter().map(|r| (r.seconds, r.rel_mse)).collect());
            writeln!(self.md, "\n{name}: relMSE falls as time^{slope:.2} (Monte Carlo alone would give -1).")?;
        }
        self.summary.spp_curves = curves
            .iter()
            .map(|(name, rows)| (name.to_string(), rows.iter().zip(spps).map(|(r, spp)| (spp, r.seconds, r.rel_mse)).collect()))
            .collect();
        let svg = self.b.out.with_extension("svg");
        plot_curves(&svg, &curves)?;
        writeln!(self.md, "\n![relMSE against render time]({})\n", svg.file_name().unwrap().to_string_lossy())?;

        // Max depth: bias against time.
        eprintln!("cornell depth sweep ...");
        let depths = [1u32, 2, 3, 5, 7, 12];
        let depth_rows: Vec<Row> = depths.iter().map(|&d| measure(format!("max depth {d}"), Knobs { max_depth: d, ..self.base })).collect();
        self.summary.depth = depths.iter().zip(&depth_rows).map(|(&d, r)| (d, r.rel_mse)).collect();
        table(&mut self.md, "Max depth (64 spp, Sobol): light lost to truncated paths is bias", &depth_rows)?;

        // Firefly clamp.
        eprintln!("cornell clamp sweep ...");
        let clamp_rows: Vec<Row> = [None, Some(10.0f32), Some(1.0), Some(0.2)]
            .iter()
            .map(|&c| measure(c.map_or("clamp off".to_string(), |c| format!("clamp {c}")), Knobs { clamp: c, ..self.base }))
            .collect();
        table(&mut self.md, "Firefly clamp (64 spp, max depth 7): variance traded for bias", &clamp_rows)?;

        // Adaptive sampling: time to an error, against uniform sampling of the same budget.
        eprintln!("cornell adaptive sampling ...");
        let adaptive_rows: Vec<Row> = [0.0f32, 0.05, 0.02, 0.01]
            .iter()
            .map(|&t| {
                let label = if t == 0.0 { "uniform 256 spp".to_string() } else { format!("`--noise-threshold {t}`, 256 spp at most") };
                measure(label, Knobs { spp: 256, noise_threshold: t, ..self.base })
            })
            .collect();
        self.summary.adaptive = adaptive_rows.iter().map(|r| (r.label.clone(), r.seconds, r.rel_mse)).collect();
        table(
            &mut self.md,
            "Adaptive sampling (max depth 7): pixels stop once their relative error is below the target; compare the time and error with the spp sweep above",
            &adaptive_rows,
        )?;

        self.cornell_strategies_and_presets(&cornell, &reference)
    }

    /// The Cornell box's light strategies and quality presets, against its reference.
    fn cornell_strategies_and_presets(&mut self, cornell: &CommittedScene, reference: &[f64]) -> Result<()> {
        let measure = |label: String, k: Knobs| -> Row {
            let r = render(cornell, self.res, k, 7);
            Row::of(label, &r, reference)
        };
        // Light strategies.
        eprintln!("cornell light strategies ...");
        let strategy_rows: Vec<Row> = [LightStrategy::Mis, LightStrategy::LightOnly, LightStrategy::BsdfOnly]
            .iter()
            .map(|&s| measure(format!("{s:?}"), Knobs { strategy: s, ..self.base }))
            .collect();
        table(
            &mut self.md,
            "How paths find light (64 spp, max depth 7): next-event estimation and BSDF sampling, alone and by MIS",
            &strategy_rows,
        )?;

        // Quality presets on the Cornell box.
        eprintln!("cornell presets ...");
        let preset_rows: Vec<Row> = [Quality::Draft, Quality::Preview, Quality::Final]
            .iter()
            .map(|&q| measure(format!("`--quality {}`", q.name()), Knobs::from_quality(q)))
            .collect();
        table(&mut self.md, "Quality presets (`--quality`)", &preset_rows)?;
        writeln!(self.md, "{}", Quality::table())?;

        Ok(())
    }

    /// Energy compensation in the furnace and on the roughness grid.
    fn energy_compensation(&mut self) -> Result<()> {
        writeln!(
            self.md,
            "## Energy compensation (furnace: the closed form is 1 everywhere)\n\nA rough (roughness 1) white metal sphere and a rough (0.7) clear glass sphere in a unit white dome, {}x{}, 64 spp, max depth 64. Error is the mean absolute difference from 1 over the whole image; time per sample shows what the compensation lobes cost.\n",
            self.res.0 / 2,
            self.res.1 / 2
        )?;
        writeln!(self.md, "| scene | compensation | seconds | mean | mean abs error vs 1 |\n| --- | --- | ---: | ---: | ---: |")?;
        for name in ["furnace_rough_metal.usda", "furnace_rough_glass.usda"] {
            eprintln!("{name} ...");
            let scene = load(&self.b.fixtures, name)?;
            for on in [true, false] {
                let k = Knobs { max_depth: 64, energy_compensation: on, ..Knobs::default() };
                let r = render(&scene, (self.res.0 / 2, self.res.1 / 2), k, 3);
                let ones = vec![1.0; r.rgb.len()];
                self.summary.furnace.push((name.to_string(), on, mean(&r.rgb)));
                writeln!(
                    self.md,
                    "| {name} | {} | {:.3} | {:.4} | {:.4} |",
                    if on { "on" } else { "off" },
                    r.seconds,
                    mean(&r.rgb),
                    mean_abs(&r.rgb, &ones)
                )?;
            }
        }
        // The same knob in a shaded scene: the roughness grid (metal, glass, plastic, sheen, fabric
        // and glitter from smooth to rough) under its key light. Its reference keeps compensation
        // on; compensation off converges to another image, and that difference is its bias.
        let grid = load(&self.b.fixtures, "materials/roughness_grid.usda")?;
        let gres = (self.res.0 / 2, self.res.1 / 2);
        let gknobs = Knobs { max_depth: 16, ..self.base };
        let grid_ref = reference_image("roughness grid", &grid, gres, Knobs { spp: self.b.reference_spp / 4, ..gknobs }, 13);
        writeln!(
            self.md,
            "\n### Energy compensation in a shaded scene (`fixtures/materials/roughness_grid.usda`, {}x{}, max depth 16)\n\nAgainst a {}-spp reference with compensation on. Off at the reference's spp is the bias that more samples do not remove.\n",
            gres.0,
            gres.1,
            self.b.reference_spp / 4
        )?;
        let mut grid_rows = Vec::new();
        for (spp, on) in [(64, true), (64, false), (self.b.reference_spp / 4, false)] {
            let r = render(&grid, gres, Knobs { spp, energy_compensation: on, ..gknobs }, 17);
            grid_rows.push(Row::of(format!("{spp} spp, compensation {}", if on { "on" } else { "off" }), &r, &grid_ref));
        }
        table(&mut self.md, "Energy compensation, roughness grid", &grid_rows)?;

        Ok(())
    }

    /// Caustic avoidance on glass over a floor.
    fn caustics(&mut self) -> Result<()> {
        let scene = load(&self.b.fixtures, "caustics/glass_on_floor.usda")?;
        let cres = (self.res.0, self.res.1 * 3 / 4);
        let full = Knobs { spp: self.b.reference_spp, max_depth: 12, ..self.base };
        let reference = reference_image("caustics", &scene, cres, full, 11);
        writeln!(
            self.md,
            "## Caustics: full path tracing against avoidance (`fixtures/caustics/glass_on_floor.usda`, {}x{})\n\nA smooth glass ball on a white floor under a small sphere light. The reference is full path tracing at {} spp (max depth 12); its own noise in the shadow is large, since the focused caustic is exactly what unidirectional path tracing finds rarely, so part of avoidance's error below is the reference's.\n",
            cres.0, cres.1, self.b.reference_spp
        )?;
        let mut caustic_rows = Vec::new();
        for spp in [16u32, 64] {
            for avoid in [false, true] {
                let r = render(&scene, cres, Knobs { spp, max_depth: 12, avoid_caustics: avoid, ..self.base }, 5);
                caustic_rows.push(Row::of(format!("{} spp, caustics {}", spp, if avoid { "avoid" } else { "full" }), &r, &reference));
            }
        }
        self.summary.caustics = caustic_rows.iter().map(|r| (r.label.clone(), r.seconds, r.rel_mse)).collect();
        table(&mut self.md, "Caustics (max depth 12)", &caustic_rows)?;

        Ok(())
    }

    /// The subsurface random walk against its diffuse fallback.
    fn subsurface(&mut self) -> Result<()> {
        let lit = crate::usd::load(&self.b.fixtures.join("materials/subsurface_lit.usda"))
            .context("cannot read materials/subsurface_lit.usda")?;
        let walk_scene = commit(&lit.to_scene_desc(), &mut BlasCache::default())?;
        let mut fallback_desc = lit.to_scene_desc();
        for net in fallback_desc.materials.values_mut() {
            for node in &mut net.nodes {
                if let Some(r) = node.parameters.get_mut("scatteringRadius") {
                    *r = render_core::material::ParamValue::Float(0.0);
                }
            }
        }
        let fallback_scene = commit(&fallback_desc, &mut BlasCache::default())?;
        let sres = (self.res.0, self.res.1 * 3 / 4);
        let reference = reference_image("subsurface", &walk_scene, sres, Knobs { spp: self.b.reference_spp / 4, ..self.base }, 17);
        writeln!(
            self.md,
            "\n## Subsurface: random walk against its diffuse fallback (`fixtures/materials/subsurface_lit.usda`, {}x{})\n\nA translucent sphere (scatteringRadius 0.1 of its radius, boundary roughness 0.4) lit from the upper left. The reference is the random walk at {} spp, caustics full. The fallback renders the same material with scatteringRadius 0, a Lambertian of the same albedo: faster, and biased by exactly what translucency adds (softened shading, light bled into the shadowed side); its error stays at that bias however many samples it takes. The full walk's error is noise: light reaches the medium only where a walk leaves it towards the light, through a glossy boundary from a random direction. With caustics avoided, every scattering event inside also connects to the light through a transparent shadow, weighted by the slides' roughness heuristic against the walks that leave (at roughness 0.4, shadows take 69%): less noise for more shadow rays per sample, and a bias small next to the reference's own noise (the next section measures it where full path tracing converges).\n",
            sres.0,
            sres.1,
            self.b.reference_spp / 4
        )?;
        let mut sss_rows = Vec::new();
        for spp in [16u32, 64] {
            for (label, scene, avoid) in [
                ("random walk", &walk_scene, false),
                ("random walk, caustics avoid", &walk_scene, true),
                ("diffuse fallback", &fallback_scene, false),
            ] {
                let r = render(scene, sres, Knobs { spp, avoid_caustics: avoid, ..self.base }, 9);
                sss_rows.push(Row::of(format!("{spp} spp, {label}"), &r, &reference));
            }
        }
        self.summary.subsurface = sss_rows.iter().map(|r| (r.label.clone(), r.seconds, r.rel_mse)).collect();
        table(&mut self.md, "Subsurface (max depth 7)", &sss_rows)?;

        Ok(())
    }

    /// Subsurface behind a smooth boundary, with and without caustic avoidance.
    fn smooth_subsurface(&mut self) -> Result<()> {
        let sres = (self.res.0, self.res.1 * 3 / 4);
        let smooth = load(&self.b.fixtures, "materials/subsurface_smooth.usda")?;
        let avoided = Knobs { avoid_caustics: true, ..self.base };
        let reference = reference_image("smooth subsurface", &smooth, sres, Knobs { spp: self.b.reference_spp / 4, ..avoided }, 17);
        // Avoidance's bias where full path tracing converges: the same medium under the white dome.
        let dome = load(&self.b.fixtures, "materials/furnace_subsurface_smooth.usda")?;
        let dome_spp = Knobs { spp: (self.b.reference_spp / 16).max(16), max_depth: 64, ..self.base };
        let dome_full = render(&dome, sres, dome_spp, 21).rgb;
        let dome_avoid = render(&dome, sres, Knobs { avoid_caustics: true, ..dome_spp }, 21).rgb;
        // The sphere's pixels: the dome behind it is exactly 1.
        let sphere_mean = |img: &[f64]| {
            let covered = dome_full.chunks(3).map(|p| p.iter().any(|&c| c < 0.999));
            let (sum, n) = img
                .chunks(3)
                .zip(covered)
                .filter(|(_, c)| *c)
                .fold(([0.0; 3], 0), |(s, n), (p, _)| ([s[0] + p[0], s[1] + p[1], s[2] + p[2]], n + 1));
            sum.map(|x| x / n.max(1) as f64)
        };
        let (full_mean, avoid_mean) = (sphere_mean(&dome_full), sphere_mean(&dome_avoid));
        self.summary.subsurface_smooth_bias = [0, 1, 2].map(|c| avoid_mean[c] / full_mean[c]);
        let bias = self.summary.subsurface_smooth_bias.map(|r| format!("{:+.1}%", 100.0 * (r - 1.0)));
        writeln!(
            self.md,
            "\n## Subsurface behind a smooth boundary (`fixtures/materials/subsurface_smooth.usda`, {}x{})\n\nThe same sphere with boundary roughness 0: full path tracing lights the medium only where a walk happens to leave through the mirror-smooth boundary towards the small light, so its error is almost all fireflies. Caustic avoidance lights every scattering event inside through a transparent shadow, and weights the leaving walks' direct light down to nothing (\"Brute-force subsurface scattering\" in Kulla & Conty 2017, \"Revisiting Physically Based Shading at Imageworks\"). The reference is the avoided walk at {} spp, so the avoided rows measure its noise alone and the full rows their noise plus avoidance's bias. That bias, measured where full path tracing converges (the same medium under the white dome, `fixtures/materials/furnace_subsurface_smooth.usda`, {} spp each, the sphere's mean with avoidance over without): {} in r, g, b. Unbent light reaches the medium from every direction, bent light only from within the critical angle.\n",
            sres.0,
            sres.1,
            self.b.reference_spp / 4,
            dome_spp.spp,
            bias.join(", ")
        )?;
        let mut smooth_rows = Vec::new();
        for spp in [16u32, 64] {
            for avoid in [false, true] {
                let r = render(&smooth, sres, Knobs { spp, avoid_caustics: avoid, ..self.base }, 9);
                smooth_rows.push(Row::of(format!("{spp} spp, caustics {}", if avoid { "avoid" } else { "full" }), &r, &reference));
            }
        }
        self.summary.subsurface_smooth = smooth_rows.iter().map(|r| (r.label.clone(), r.seconds, r.rel_mse)).collect();
        table(&mut self.md, "Subsurface behind a smooth boundary (max depth 7)", &smooth_rows)?;

        Ok(())
    }

    /// Texture filtering by ray cones on a checker to the horizon.
    fn texture_filtering(&mut self) -> Result<()> {
        let cres = (self.res.0, self.res.1 * 3 / 4);
        let scene = load(&self.b.fixtures, "textures/checker_plane.usda")?;
        let reference =
            render(&scene, cres, Knobs { spp: self.b.reference_spp, max_depth: 2, texture_filtering: false, ..self.base }, 13).rgb;
        writeln!(
            self.md,
            "\n## Texture filtering (`fixtures/textures/checker_plane.usda`, {}x{})\n\nA one-texel checker repeated to the horizon of a grazing view. The reference supersamples the finest level at {} spp (the pixel's true average); filtering by ray cones reads coarser mips where a pixel covers many texels: less noise (aliasing) at few samples, some blur (bias) at many. The last row renders the plane with no texture at all (the material's default grey), for the time a textured material costs per sample.\n",
            cres.0, cres.1, self.b.reference_spp
        )?;
        let mut filter_rows = Vec::new();
        for spp in [1u32, 4, 16, 64] {
            for filtering in [false, true] {
                let r = render(&scene, cres, Knobs { spp, max_depth: 2, texture_filtering: filtering, ..self.base }, 7);
                filter_rows.push(Row::of(format!("{spp} spp, filtering {}", if filtering { "on" } else { "off" }), &r, &reference));
            }
        }
        // What per-point texture evaluation costs: the same scene with each texture replaced by
        // its mean (the inputs' connections cut), at 16 spp.
        let mut flat = crate::usd::load(&self.b.fixtures.join("textures/checker_plane.usda"))?.to_scene_desc();
        flat.materials.values_mut().for_each(|net| net.connections.clear());
        let flat_scene = commit(&flat, &mut BlasCache::default())?;
        let r = render(&flat_scene, cres, Knobs { spp: 16, max_depth: 2, ..self.base }, 7);
        filter_rows.push(Row::of("16 spp, untextured (constant grey)".into(), &r, &reference));
        self.summary.texture_filtering = filter_rows.iter().map(|r| (r.label.clone(), r.seconds, r.rel_mse)).collect();
        table(&mut self.md, "Texture filtering (max depth 2)", &filter_rows)?;

        Ok(())
    }

    /// Transform samples over the shutter, on the turntable of `usd/motion_blur.usda` at frame 6
    /// (a cube turning 15° and a ball sliding 0.27 units within the shutter).
    fn motion_samples(&mut self) -> Result<()> {
        let res = (self.res.0, self.res.1 * 3 / 4);
        let path = self.b.fixtures.join("usd/motion_blur.usda");
        let at = |options: crate::usd::LoadOptions| -> Result<CommittedScene> {
            let t = crate::usd::load_with(&path, crate::usd::LoadOptions { frame: Some(6.0), ..options })?;
            Ok(commit(&t.to_scene_desc(), &mut BlasCache::default())?)
        };
        let (spp, seed) = (64, 17);
        let samples = |n: usize| crate::usd::LoadOptions { motion_samples: n, ..Default::default() };
        let most = render_core::motion::MAX_MOTION_SAMPLES;
        let reference = render(&at(samples(most))?, res, Knobs { spp, ..self.base }, seed).rgb;
        writeln!(
            self.md,
            "\n## Motion samples (`fixtures/usd/motion_blur.usda` at frame 6, {}x{})\n\nEach prim that moves over the shutter is placed at `--motion-samples` evenly spaced times and interpolated linearly between them, so a rotation follows chords of its arc. The reference takes {most} samples (the most a motion holds); every row renders {spp} spp with the reference's seed, so their sampling noise is shared and the error left is the interpolation's (and, for the closed shutter, the blur itself).\n",
            res.0, res.1
        )?;
        let mut rows = Vec::new();
        for n in [2usize, 3, 5, 9, 17] {
            let r = render(&at(samples(n))?, res, Knobs { spp, ..self.base }, seed);
            rows.push(Row::of(
                format!("{n} samples{}", if n == crate::usd::DEFAULT_MOTION_SAMPLES { " (default)" } else { "" }),
                &r,
                &reference,
            ));
        }
        let closed = at(crate::usd::LoadOptions { shutter: Some((0.0, 0.0)), ..Default::default() })?;
        rows.push(Row::of("shutter closed (no blur)".into(), &render(&closed, res, Knobs { spp, ..self.base }, seed), &reference));
        table(&mut self.md, "Motion samples (64 spp)", &rows)
    }

    /// Samples per cubic span of the tubes of `usd/curves.usda` (every kind of curve).
    fn curve_samples(&mut self) -> Result<()> {
        let res = (self.res.0, self.res.1 / 2);
        let path = self.b.fixtures.join("usd/curves.usda");
        let at = |n: usize| -> Result<(CommittedScene, usize)> {
            let t = crate::usd::load_with(&path, crate::usd::LoadOptions { curve_samples: n, ..Default::default() })?;
            let triangles = t.meshes.iter().map(|(_, m)| m.mesh.indices.len()).sum();
            Ok((commit(&t.to_scene_desc(), &mut BlasCache::default())?, triangles))
        };
        let (spp, seed) = (64, 19);
        let most = crate::usd::curves::MAX_CURVE_SAMPLES;
        let reference = render(&at(most)?.0, res, Knobs { spp, ..self.base }, seed).rgb;
        writeln!(
            self.md,
            "\n## Curve samples (`fixtures/usd/curves.usda`, {}x{})\n\nBasisCurves render as tubes swept along each cubic span at `--curve-samples` points; fewer make the tubes polylines, and the seams show at the bends. The reference takes {most} per span; every row renders {spp} spp with its seed, so the error left is the tessellation's.\n",
            res.0, res.1
        )?;
        let mut rows = Vec::new();
        for n in [1usize, 2, 4, 8, 16] {
            let (scene, triangles) = at(n)?;
            let r = render(&scene, res, Knobs { spp, ..self.base }, seed);
            let default = if n == crate::usd::curves::DEFAULT_CURVE_SAMPLES { " (default)" } else { "" };
            rows.push(Row::of(format!("{n} per span{default}, {triangles} triangles"), &r, &reference));
        }
        table(&mut self.md, "Curve samples (64 spp)", &rows)
    }

    /// Scattering orders through the smoke of `usd/volume.usda`: the depth a scattering
    /// medium needs.
    fn volume_depth(&mut self) -> Result<()> {
        let res = (self.res.0, self.res.1 * 3 / 4);
        let t = crate::usd::load(&self.b.fixtures.join("usd/volume.usda")).context("cannot read usd/volume.usda")?;
        let scene = commit(&t.to_scene_desc(), &mut BlasCache::default())?;
        let (spp, seed, deepest) = (64, 23, 64);
        let reference =
            reference_image("volume", &scene, res, Knobs { spp: self.b.reference_spp / 8, max_depth: deepest, ..self.base }, 29);
        writeln!(
            self.md,
            "\n## Volume scattering depth (`fixtures/usd/volume.usda`, {}x{})\n\nThe smoke ball (albedo 0.85, up to 2.4 extinction per unit across 1.75 units) brightens with every order of scattering it is allowed; a path stops at the max depth, and what the later orders carry is lost: bias, not noise. Delta tracking itself has no step to tune (it is unbiased whatever the majorant; the majorant grid changes only the time, `docs/benchmarks.md`). The reference is max depth {deepest} at {} spp; every row renders {spp} spp.\n",
            res.0,
            res.1,
            self.b.reference_spp / 8
        )?;
        let mut rows = Vec::new();
        for depth in [1u32, 2, 4, 7, 16] {
            let r = render(&scene, res, Knobs { spp, max_depth: depth, ..self.base }, seed);
            let default = if depth == self.base.max_depth { " (default)" } else { "" };
            rows.push(Row::of(format!("max depth {depth}{default}"), &r, &reference));
        }
        table(&mut self.md, "Volume scattering depth (64 spp)", &rows)
    }

    /// 10 000 lights against one, at equal time.
    fn many_lights(&mut self) -> Result<()> {
        let (lights_md, rows) =
            super::lights::lights(&super::lights::LightsBench::new(self.b.fixtures.clone(), 32, self.b.reference_spp / 4))?;
        writeln!(self.md, "\n{lights_md}")?;
        self.summary.many_lights = rows;
        Ok(())
    }
}

fn table(md: &mut String, title: &str, rows: &[Row]) -> Result<()> {
    writeln!(md, "### {title}\n\n| setting | seconds | relMSE | mean abs error |\n| --- | ---: | ---: | ---: |")?;
    for r in rows {
        writeln!(md, "| {} | {:.3} | {:.2e} | {:.4} |", r.label, r.seconds, r.rel_mse, r.mae)?;
    }
    writeln!(md)?;
    Ok(())
}

/// Least-squares slope of log(error) against log(time).
fn log_slope(points: Vec<(f64, f64)>) -> f64 {
    let pts: Vec<(f64, f64)> = points.into_iter().filter(|(t, e)| *t > 0.0 && *e > 0.0).map(|(t, e)| (t.ln(), e.ln())).collect();
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let cov: f64 = pts.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let var: f64 = pts.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    if var > 0.0 { cov / var } else { f64::NAN }
}

fn plot_curves(path: &Path, curves: &[(&str, Vec<Row>)]) -> Result<()> {
    use plotters::prelude::*;
    let pts = curves.iter().flat_map(|(_, rows)| rows.iter().map(|r| (r.seconds, r.rel_mse)));
    let (tmin, tmax, emin, emax) =
        pts.fold((f64::MAX, 0.0f64, f64::MAX, 0.0f64), |(a, b, c, d), (t, e)| (a.min(t), b.max(t), c.min(e), d.max(e)));
    let root = SVGBackend::new(path, (640, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Cornell box: relMSE against render time", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((tmin * 0.7..tmax * 1.4).log_scale(), (emin * 0.7..emax * 1.4).log_scale())?;
    chart.configure_mesh().x_desc("seconds").y_desc("relMSE").draw()?;
    for (i, (name, rows)) in curves.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let series: Vec<(f64, f64)> = rows.iter().map(|r| (r.seconds, r.rel_mse)).collect();
        chart
            .draw_series(LineSeries::new(series.clone(), colour.stroke_width(2)))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2)));
        chart.draw_series(series.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
    }
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE.mix(0.8)).draw()?;
    root.present()?;
    Ok(())
}
