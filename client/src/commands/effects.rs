//! `tessera bench effects`: what the render plan saves. Each fixture renders twice in-process
//! at equal settings: as planned, and with every effect forced on (`force_all_effects`: every
//! lobe the uber-material can build at weight 0 with its energy tables, tangent frames,
//! closest-hit shadow rays, the light-path AOVs). The images must agree within noise (forcing
//! changes the sampling pattern, not the expectation); the times show the price of
//! simulating effects a scene does not call for. Writes `docs/render-plan.md`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};

/// The fixtures the benchmark renders by default.
pub const FIXTURES: &[&str] =
    &["cornell_box.usda", "materials/showcase.usda", "caustics/glass_on_floor.usda", "hard/many_lights.usdc", "furnace_rough_glass.usda"];

/// What to run.
pub struct EffectsBench {
    /// `fixtures/` directory.
    pub fixtures: PathBuf,
    /// Fixtures, relative to it.
    pub names: Vec<String>,
    /// Image edge.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Report to write, if any.
    pub out: Option<PathBuf>,
}

/// One fixture's measurements.
#[derive(Clone, Debug)]
pub struct EffectsRow {
    /// Fixture.
    pub fixture: String,
    /// The plan's effects.
    pub plan: Vec<String>,
    /// Seconds as planned and forced.
    pub seconds: (f64, f64),
    /// relMSE between the planned and the forced image.
    pub difference: f64,
    /// relMSE between two planned images of different seeds: the noise level.
    pub noise: f64,
}

fn rgb(scene: &CommittedScene, size: u32, spp: u32, seed: u64, force: bool) -> (Vec<f64>, f64) {
    let settings = RenderSettings {
        width: size,
        height: size,
        spp,
        seed,
        tile_size: 16,
        integrator: IntegratorSettings { max_depth: 8, force_all_effects: force, ..Default::default() },
        ..Default::default()
    };
    let camera = Camera::new(&scene.camera("").expect("the fixture has a camera"), size, size);
    // Table builds are a load cost: pay them before timing.
    scene.prepare_bsdfs(true);
    if force {
        scene.bsdf_with_every_lobe(0, true);
    }
    let t = Instant::now();
    let (fb, _) = render_to_framebuffer(scene, &camera, &settings);
    let seconds = t.elapsed().as_secs_f64();
    (fb.layers[&Aov::Beauty].chunks(4).flat_map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect(), seconds)
}

/// Relative MSE of `a` against `b` (Rousselle's ε = 0.01), symmetric in its use here.
fn rel_mse(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2) / (0.25 * (x + y).powi(2) + 0.01)).sum::<f64>() / a.len() as f64
}

fn load(fixtures: &Path, name: &str) -> Result<CommittedScene> {
    let t = crate::usd::load(&fixtures.join(name)).with_context(|| format!("cannot read {name}"))?;
    commit(&t.to_scene_desc(), &mut BlasCache::default()).with_context(|| format!("{name} does not commit"))
}

/// Runs the benchmark; returns the report and its rows.
pub fn effects(b: &EffectsBench) -> Result<(String, Vec<EffectsRow>)> {
    let mut rows = Vec::new();
    for name in &b.names {
        eprintln!("{name} ...");
        let scene = load(&b.fixtures, name)?;
        let (planned, t_plan) = rgb(&scene, b.size, b.spp, 1, false);
        let (other_seed, _) = rgb(&scene, b.size, b.spp, 2, false);
        // A third seed: the forced image is an independent estimate, so "equal within noise"
        // means it differs from the planned one as much as another planned seed does.
        let (forced, t_forced) = rgb(&scene, b.size, b.spp, 3, true);
        rows.push(EffectsRow {
            fixture: name.clone(),
            plan: scene.plan.entries.iter().map(|e| e.effect.clone()).collect(),
            seconds: (t_plan, t_forced),
            difference: rel_mse(&planned, &forced),
            noise: rel_mse(&planned, &other_seed),
        });
    }
    let mut md = String::new();
    writeln!(md, "# What the render plan saves\n")?;
    writeln!(
        md,
        "Written by `tessera bench effects` on {} ({}). Each fixture renders at {}x{}, {} spp, max depth 8, in-process, as planned and with every effect forced on (every lobe at weight 0 with its energy tables, tangent frames, closest-hit shadow rays, light-path AOVs). The images agree within noise: forced and planned use different seeds, and their difference is compared with the difference between two planned renders of different seeds.\n",
        crate::commands::bench::today(),
        crate::commands::bench::machine_description(),
        b.size,
        b.size,
        b.spp
    )?;
    writeln!(
        md,
        "| fixture | plan | planned s | forced s | speed-up | relMSE planned vs forced | relMSE between seeds |\n| --- | --- | ---: | ---: | ---: | ---: | ---: |"
    )?;
    for r in &rows {
        writeln!(
            md,
            "| `{}` | {} | {:.3} | {:.3} | {:.2}x | {:.2e} | {:.2e} |",
            r.fixture,
            r.plan.join(", "),
            r.seconds.0,
            r.seconds.1,
            r.seconds.1 / r.seconds.0.max(1e-9),
            r.difference,
            r.noise
        )?;
    }
    if let Some(out) = &b.out {
        std::fs::write(out, &md).with_context(|| format!("cannot write {}", out.display()))?;
    }
    Ok((md, rows))
}
