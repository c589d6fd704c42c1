//! `tessera bench effects`: what the render plan saves. Each fixture renders twice in-process
//! at equal settings: as planned, and with every effect forced on (`force_all_effects`: every
//! lobe the uber-material can build at weight 0 with its energy tables, tangent frames,
//! closest-hit shadow rays, the light-path AOVs). The images must agree within noise (forcing
//! changes the sampling pattern, not the expectation); the times show the price of
//! simulating effects a scene does not call for. A fourth render at the planned render's seed
//! runs the general path loop: the image must be bit-identical, and the time shows what the
//! specialised loop buys. Writes `docs/render-plan.md`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};

use super::harness::{Knobs, load, rel_mse, render};

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
    /// Seconds of the planned render in the general path loop, and whether the scene runs the
    /// specialised loop at all.
    pub general_seconds: f64,
    /// The scene runs the specialised path loop (no media, cut-outs or glitter).
    pub specialised: bool,
    /// relMSE between the planned and the forced image.
    pub difference: f64,
    /// relMSE between two planned images of different seeds: the noise level.
    pub noise: f64,
}

/// Runs the benchmark; returns the report and its rows.
pub fn effects(b: &EffectsBench) -> Result<(String, Vec<EffectsRow>)> {
    let mut rows = Vec::new();
    for name in &b.names {
        eprintln!("{name} ...");
        let scene = load(&b.fixtures, name)?;
        let res = (b.size, b.size);
        let knobs = Knobs { spp: b.spp, max_depth: 8, ..Knobs::default() };
        let planned = render(&scene, res, knobs, 1);
        let other_seed = render(&scene, res, knobs, 2);
        // A third seed: the forced image is an independent estimate, so "equal within noise"
        // means it differs from the planned one as much as another planned seed does.
        let forced = render(&scene, res, Knobs { force_all_effects: true, ..knobs }, 3);
        // The same seed in the general loop: the same random numbers in the same order, so
        // the same image to the bit; only the time may differ.
        let general = render(&scene, res, Knobs { general_loop: true, ..knobs }, 1);
        anyhow::ensure!(general.rgb == planned.rgb, "{name}: the general path loop changed the image");
        let specialised = !render_core::integrator::needs_full_loop(scene.plan.features, &Default::default());
        rows.push(EffectsRow {
            fixture: name.clone(),
            plan: scene.plan.features.iter().map(|f| f.name().to_string()).collect(),
            seconds: (planned.seconds, forced.seconds),
            general_seconds: general.seconds,
            specialised,
            difference: rel_mse(&forced.rgb, &planned.rgb),
            noise: rel_mse(&other_seed.rgb, &planned.rgb),
        });
    }
    let mut md = String::new();
    writeln!(md, "# What the render plan saves\n")?;
    writeln!(
        md,
        "Written by `tessera bench effects` on {} ({}). Each fixture renders at {}x{}, {} spp, max depth 8, in-process: as planned; in the general path loop at the same seed (which must give the same image to the bit); and with every effect forced on (every lobe at weight 0 with its energy tables, tangent frames, closest-hit shadow rays, light-path AOVs). The forced render is no renderer anyone runs: read it as an upper bound on what planning saves. The comparison that matters is the path loop: a scene without media, cut-outs or glitter (and a render without light-path AOVs or caustic avoidance) runs the specialised loop, compiled without that machinery. Forced and planned use different seeds, and their difference is compared with the difference between two planned renders of different seeds.\n",
        super::harness::today(),
        super::harness::machine_description(),
        b.size,
        b.size,
        b.spp
    )?;
    writeln!(
        md,
        "| fixture | plan | planned s | path loop | general loop s | loop speed-up | forced s | speed-up | relMSE planned vs forced | relMSE between seeds |\n| --- | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"
    )?;
    for r in &rows {
        writeln!(
            md,
            "| `{}` | {} | {:.3} | {} | {:.3} | {:.2}x | {:.3} | {:.2}x | {:.2e} | {:.2e} |",
            r.fixture,
            r.plan.join(", "),
            r.seconds.0,
            if r.specialised { "specialised" } else { "general" },
            r.general_seconds,
            r.general_seconds / r.seconds.0.max(1e-9),
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
