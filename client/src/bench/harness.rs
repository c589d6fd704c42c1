//! What the renderer benchmarks share: the knobs, an in-process render timed after its
//! one-time table builds, relative error against a reference, and the date and machine the
//! reports record.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use render_core::camera::Camera;
use render_core::caustics::CausticMode;
use render_core::film::Aov;
use render_core::integrator::{IntegratorSettings, LightStrategy};
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::sampling::SamplerKind;
use render_core::scene::{BlasCache, CommittedScene, commit};

use crate::quality::Quality;

/// One configuration of the knobs.
#[derive(Clone, Copy, Debug)]
pub struct Knobs {
    /// Samples per pixel.
    pub spp: u32,
    /// Scattering events.
    pub max_depth: u32,
    /// Kulla-Conty energy compensation.
    pub energy_compensation: bool,
    /// Sampler.
    pub sampler: SamplerKind,
    /// Firefly clamp.
    pub clamp: Option<f32>,
    /// Adaptive sampling target (0: off).
    pub noise_threshold: f32,
    /// Caustic avoidance.
    pub avoid_caustics: bool,
    /// Which strategies find light.
    pub strategy: LightStrategy,
    /// Run every effect whether or not the scene calls for it (`tessera bench effects`).
    pub force_all_effects: bool,
    /// Run the general path loop whatever the scene's features (`tessera bench effects`).
    pub general_loop: bool,
    /// Mip-map texture lookups by the ray's footprint.
    pub texture_filtering: bool,
    /// Most lights per shading point the light tree's splitting samples (1: no splitting).
    pub light_split_budget: usize,
}

impl Default for Knobs {
    /// 64 spp, max depth 7, everything else at its unbiased default.
    fn default() -> Self {
        Knobs {
            spp: 64,
            max_depth: 7,
            energy_compensation: true,
            sampler: SamplerKind::Sobol,
            clamp: None,
            noise_threshold: 0.0,
            avoid_caustics: false,
            strategy: LightStrategy::Mis,
            force_all_effects: false,
            general_loop: false,
            texture_filtering: true,
            light_split_budget: render_core::light::tree::SPLIT_BUDGET,
        }
    }
}

impl Knobs {
    pub(crate) fn from_quality(q: Quality) -> Self {
        let p = q.preset();
        Knobs { spp: p.spp, max_depth: p.max_depth, clamp: p.clamp, ..Knobs::default() }
    }
}

/// An image and what it cost.
pub(crate) struct Rendered {
    /// RGB of the beauty, pixel by pixel.
    pub(crate) rgb: Vec<f64>,
    /// Wall time of the render alone.
    pub(crate) seconds: f64,
}

/// Renders `scene` in-process with the knobs; table builds are paid before timing.
pub(crate) fn render(scene: &CommittedScene, (w, h): (u32, u32), k: Knobs, seed: u64) -> Rendered {
    let settings = RenderSettings {
        width: w,
        height: h,
        spp: k.spp,
        seed,
        tile_size: 16,
        integrator: IntegratorSettings {
            max_depth: k.max_depth,
            energy_compensation: k.energy_compensation,
            clamp_indirect: k.clamp,
            caustics: if k.avoid_caustics { CausticMode::Avoid } else { CausticMode::Full },
            strategy: k.strategy,
            force_all_effects: k.force_all_effects,
            general_loop: k.general_loop,
            texture_filtering: k.texture_filtering,
            light_split_budget: k.light_split_budget,
            ..Default::default()
        },
        sampler: k.sampler,
        noise_threshold: k.noise_threshold,
        coarse_start: 0,
        first_sample: 0,
    };
    let camera = Camera::new(&scene.camera("").expect("the fixture has a camera"), w, h);
    // One-time energy-table builds are a load cost, not a per-render one (see
    // docs/benchmarks.md for their price): build before timing.
    scene.prepare_bsdfs(k.energy_compensation);
    if k.force_all_effects {
        scene.bsdf_with_every_lobe(0, k.energy_compensation);
    }
    let t = Instant::now();
    let (fb, _) = render_to_framebuffer(scene, &camera, &settings);
    let seconds = t.elapsed().as_secs_f64();
    let rgb = fb.layers[&Aov::Beauty].chunks(4).flat_map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect();
    Rendered { rgb, seconds }
}

/// A reference image, announced on stderr: references are the slow part of a run.
pub(crate) fn reference_image(what: &str, scene: &CommittedScene, res: (u32, u32), k: Knobs, seed: u64) -> Vec<f64> {
    eprintln!("{what} reference: {} spp ...", k.spp);
    render(scene, res, k, seed).rgb
}

/// Relative MSE against a reference, with Rousselle's ε = 0.01.
pub fn rel_mse(img: &[f64], reference: &[f64]) -> f64 {
    img.iter().zip(reference).map(|(a, r)| (a - r).powi(2) / (r * r + 0.01)).sum::<f64>() / img.len() as f64
}

pub(crate) fn mean_abs(img: &[f64], reference: &[f64]) -> f64 {
    img.iter().zip(reference).map(|(a, r)| (a - r).abs()).sum::<f64>() / img.len() as f64
}

pub(crate) fn mean(img: &[f64]) -> f64 {
    img.iter().sum::<f64>() / img.len() as f64
}

/// Reads and commits a fixture.
pub(crate) fn load(fixtures: &Path, name: &str) -> Result<CommittedScene> {
    let t = crate::usd::load(&fixtures.join(name)).with_context(|| format!("cannot read {name}"))?;
    commit(&t.to_scene_desc(), &mut BlasCache::default()).with_context(|| format!("{name} does not commit"))
}

/// A row of a results table.
pub(crate) struct Row {
    pub label: String,
    pub seconds: f64,
    pub rel_mse: f64,
    pub mae: f64,
}

impl Row {
    /// A row for render `r`, measured against `reference`.
    pub fn of(label: String, r: &Rendered, reference: &[f64]) -> Row {
        Row { label, seconds: r.seconds, rel_mse: rel_mse(&r.rgb, reference), mae: mean_abs(&r.rgb, reference) }
    }
}

pub(crate) fn today() -> String {
    std::process::Command::new("date")
        .arg("+%Y-%m-%d")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "today".into())
}

pub(crate) fn machine_description() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("model name")).map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string()))
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{cpu}, {cores} cores")
}
