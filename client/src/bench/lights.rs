//! `tessera bench lights`: 10 000 lights against one light of the same total power, at equal
//! time.
//!
//! The 10 000-light grid (`hard/many_lights.usdc`) is compared with two one-light scenes of
//! the grid's power: one sphere at the grid's centre (`hard/one_light.usda`), and one
//! RectLight covering the grid (`hard/one_rect_light.usda`), whose light arrives from the
//! same spread of directions and distances as the grid's. Per-sample cost is measured on
//! long renders (the best of five), so that fixed per-render costs do not enter it; the
//! many-light render then gets the samples that fit in the one-light render's time, and each
//! image is compared with its own reference.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use render_core::scene::CommittedScene;

use super::harness::{Knobs, load, machine_description, reference_image, rel_mse, render, today};

/// Options of `tessera bench lights`.
#[derive(Clone, Debug)]
pub struct LightsBench {
    /// `fixtures/` directory.
    pub fixtures: PathBuf,
    /// Also write the table here (None: only return it).
    pub out: Option<PathBuf>,
    /// Image edge.
    pub size: u32,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// One-light sample counts to compare at.
    pub spp: Vec<u32>,
    /// Split budgets to measure.
    pub budgets: Vec<usize>,
}

impl LightsBench {
    /// The standard comparison: one-light renders at 16 and 64 spp, split budgets 8, 4, 2
    /// and 1 (no splitting).
    pub fn new(fixtures: PathBuf, size: u32, reference_spp: u32) -> Self {
        LightsBench { fixtures, out: None, size, reference_spp, spp: vec![16, 64], budgets: vec![8, 4, 2, 1] }
    }
}

/// One row: a one-light scene and a split budget at one sample count.
#[derive(Clone, Debug)]
pub struct LightsRow {
    /// Which one-light scene.
    pub counterpart: &'static str,
    /// Split budget of the 10 000-light render.
    pub budget: usize,
    /// One-light samples per pixel.
    pub one_spp: u32,
    /// Its relative MSE.
    pub one_rel_mse: f64,
    /// 10 000-light samples per pixel at equal time.
    pub many_spp: u32,
    /// Its relative MSE.
    pub many_rel_mse: f64,
    /// Ratio of RMS errors, many / one.
    pub ratio: f64,
    /// Cost of a 10 000-light sample over a one-light one.
    pub cost_ratio: f64,
}

/// Seconds per sample per pixel: the best of five renders at `spp` (the machine is shared).
fn seconds_per_spp(scene: &CommittedScene, res: (u32, u32), k: Knobs) -> f64 {
    (0..5).map(|s| render(scene, res, k, 100 + s).seconds).fold(f64::INFINITY, f64::min) / k.spp as f64
}

/// Runs the comparison; returns the markdown and the rows.
pub fn lights(b: &LightsBench) -> Result<(String, Vec<LightsRow>)> {
    let many = load(&b.fixtures, "hard/many_lights.usdc")?;
    let counterparts = [("sphere", load(&b.fixtures, "hard/one_light.usda")?), ("rect", load(&b.fixtures, "hard/one_rect_light.usda")?)];
    let res = (b.size, b.size);
    let base = Knobs { max_depth: 2, ..Knobs::default() };
    let reference = |what: &str, scene: &CommittedScene| reference_image(what, scene, res, Knobs { spp: b.reference_spp, ..base }, 21);
    let many_ref = reference("10 000 lights", &many);
    let mut md = String::new();
    writeln!(
        md,
        "## Many lights at equal time ({}x{}, {}, {})\n\nOne-light scenes: `sphere` is one sphere of the grid's power at its centre, `rect` one RectLight covering the grid (sampled by solid angle). The panel spreads its power over the grid's extent, so its light arrives from the same spread of directions and distances: it is the one-light scene the grid's convergence is fairly compared with. The sphere subtends a few degrees: its estimator is nearly constant per pixel and the Sobol sampler converges on it at about N^-3 in MSE, which no choice among 10 000 lights can follow; its rows show that gap. Per-sample cost is the best of five renders at 256 spp (one light) or 64 spp (10 000 lights). References: {} spp.\n\n| one light | split budget | cost per sample, many / one | one light spp | one light relMSE | 10 000 lights spp | 10 000 lights relMSE | RMS error ratio |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
        b.size,
        b.size,
        today(),
        machine_description(),
        b.reference_spp
    )?;
    // The 10 000-light cost per sample depends on the budget only: measured once for both
    // one-light scenes.
    let many_costs: Vec<f64> =
        b.budgets.iter().map(|&budget| seconds_per_spp(&many, res, Knobs { spp: 64, light_split_budget: budget, ..base })).collect();
    let mut rows = Vec::new();
    for (name, one) in &counterparts {
        let one_ref = reference(name, one);
        let one_cost = seconds_per_spp(one, res, Knobs { spp: 256, ..base });
        // The one-light errors do not depend on the budget: rendered once per sample count.
        let one_errors: Vec<f64> = b.spp.iter().map(|&spp| rel_mse(&render(one, res, Knobs { spp, ..base }, 5).rgb, &one_ref)).collect();
        for (&budget, &many_cost) in b.budgets.iter().zip(&many_costs) {
            let k = Knobs { light_split_budget: budget, ..base };
            for (&spp, &eo) in b.spp.iter().zip(&one_errors) {
                let equal = ((spp as f64 * one_cost / many_cost).floor() as u32).max(1);
                let em = rel_mse(&render(&many, res, Knobs { spp: equal, ..k }, 5).rgb, &many_ref);
                let row = LightsRow {
                    counterpart: name,
                    budget,
                    one_spp: spp,
                    one_rel_mse: eo,
                    many_spp: equal,
                    many_rel_mse: em,
                    ratio: (em / eo).sqrt(),
                    cost_ratio: many_cost / one_cost,
                };
                writeln!(md, "| {name} | {budget} | {:.1} | {spp} | {eo:.2e} | {equal} | {em:.2e} | {:.2}x |", row.cost_ratio, row.ratio)?;
                rows.push(row);
            }
        }
    }
    if let Some(out) = &b.out {
        std::fs::write(out, &md)?;
    }
    Ok((md, rows))
}
