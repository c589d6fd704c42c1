//! Progressive rendering: passes over tiles ordered from the centre out, each tile owned by
//! one worker at a time, every pixel's samples drawn from (seed, pixel, sample index).

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

use crate::camera::Camera;
use crate::film::{Aov, Rect, TileFilm, tiles_centre_out};
use crate::integrator::{CameraPath, IntegratorSettings, PathCounters, WaveBuffers, trace_path, trace_wave};
use crate::sampling::{PathSampler, SamplerKind};
use crate::scene::CommittedScene;

/// What one render does.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel in total.
    pub spp: u32,
    /// Seed of every pixel's random stream.
    pub seed: u64,
    /// Tile edge in pixels.
    pub tile_size: u32,
    /// Path tracing settings.
    pub integrator: IntegratorSettings,
    /// The numbers paths draw.
    pub sampler: SamplerKind,
    /// Adaptive sampling: a pixel stops receiving samples once the relative standard error of
    /// its mean (worst over its neighbourhood) is below this; 0 = off.
    pub noise_threshold: f32,
    /// Block edge of the first coarse pass (a power of two; 0 or 1 = off): see
    /// [`coarse_schedule`].
    pub coarse_start: u32,
    /// The first sample index rendered: samples `first_sample..spp` of every pixel are taken
    /// (a slice of a render split across machines, or the rest of one resumed from a
    /// checkpoint). Must be a pass boundary of `spp` ([`is_pass_boundary`]); 0 renders all.
    pub first_sample: u32,
}

/// Camera samples a worker traces between two polls of [`RenderSink::should_stop`]. A
/// Cornell-box path costs about 1 µs and the worst a client can ask (depth 1024 through
/// glass and media) about 1 ms, so a stop is seen within milliseconds whatever the tile
/// costs, for an atomic load or two per 64 paths.
pub const STOP_POLL_SAMPLES: u32 = 64;

/// Camera samples traced together as one wave ([`trace_wave`]): a poll comes before each.
const WAVE: usize = STOP_POLL_SAMPLES as usize;

/// Samples every pixel takes before adaptive sampling may retire it: fewer make the
/// variance estimate itself too noisy to trust.
pub const ADAPTIVE_MIN_SPP: u32 = 16;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 256,
            height: 256,
            spp: 64,
            seed: 0,
            tile_size: 32,
            integrator: IntegratorSettings::default(),
            sampler: SamplerKind::default(),
            noise_threshold: 0.0,
            coarse_start: 0,
            first_sample: 0,
        }
    }
}

/// The largest pass. Passes are where sample ranges may start and end (a film is built one
/// whole pass at a time, see [`TileFilm::absorb`]), so capping them makes every multiple of
/// this a boundary: 1024 spp splits into slices of 64, 128, 256, … at any such multiple.
pub const MAX_PASS_SPP: u32 = 64;

/// Samples per pass: 1, 1, 2, 4, … up to [`MAX_PASS_SPP`], then that many per pass, so the
/// first image arrives fast and the early passes double the total; trimmed so the passes
/// add up to `spp`.
pub fn pass_schedule(spp: u32) -> Vec<u32> {
    let mut passes = Vec::new();
    let mut total = 0u32;
    let mut next = 1u32;
    while total < spp {
        let n = next.min(spp - total);
        passes.push(n);
        total += n;
        if passes.len() > 1 {
            next = next.saturating_mul(2).min(MAX_PASS_SPP);
        }
    }
    passes
}

/// True when sample index `k` starts a pass of a `spp`-sample render (or ends it): the
/// places a sample range may begin or end.
pub fn is_pass_boundary(k: u32, spp: u32) -> bool {
    k == spp || pass_ranges(spp).iter().any(|r| r.start == k)
}

/// The sample ranges of the passes of a `spp`-sample render, in order.
pub fn pass_ranges(spp: u32) -> Vec<std::ops::Range<u32>> {
    let mut start = 0;
    pass_schedule(spp)
        .into_iter()
        .map(|n| {
            start += n;
            start - n..start
        })
        .collect()
}

/// Why a render stopped before its last pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The client cancelled or went away.
    Cancelled,
    /// The scene changed; the caller recommits and restarts.
    SceneChanged,
}

/// A finished pass's figures.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Pass index.
    pub pass: u32,
    /// Samples per pixel accumulated so far.
    pub spp: u32,
    /// Seconds since the render started.
    pub elapsed: f64,
    /// Rays traced so far.
    pub rays: u64,
    /// Relative standard error of the image's mean luminance (RMS over pixels).
    pub noise: f32,
    /// Pixels still receiving samples after this pass (all of them without adaptive sampling).
    pub active_pixels: u64,
    /// Camera samples taken so far over the whole image.
    pub samples_taken: u64,
}

/// Where a render sends its results. Called from worker threads.
pub trait RenderSink: Sync {
    /// A tile finished a pass.
    fn tile(&self, tile: &TileFilm, pass: u32);
    /// A pass finished.
    fn pass_done(&self, stats: &PassStats);
    /// A coarse pass finished a tile: `film` holds one sample per `pixel_size`² block of the
    /// image rect `covers` (its own rect counts blocks from 0). Only sent when asked for.
    fn coarse_tile(&self, _covers: Rect, _pixel_size: u32, _film: &TileFilm) {}
    /// True when the sink wants [`Self::pass_film`] calls.
    fn wants_pass_films(&self) -> bool {
        false
    }
    /// A tile finished a pass: `film` holds that pass's sums alone (samples `samples` of
    /// each active pixel), before they were added to the tile's totals. Only called when
    /// [`Self::wants_pass_films`]; for clients that keep exact films (slices, checkpoints).
    fn pass_film(&self, _film: &TileFilm, _pass: u32, _samples: std::ops::Range<u32>) {}
    /// Polled before every tile and every [`STOP_POLL_SAMPLES`] samples within one: `Some`
    /// stops the render (a tile stopped part-way is dropped, never sent). Keep it cheap.
    fn should_stop(&self) -> Option<StopReason>;
}

/// Camera samples one region of the image (a tile) took.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RegionSamples {
    /// The region.
    pub rect: Rect,
    /// Camera samples taken over all its pixels.
    pub samples: u64,
}

/// How a render ended.
#[derive(Clone, Debug)]
pub struct RenderOutcome {
    /// Last completed pass's figures.
    pub stats: PassStats,
    /// Camera samples taken.
    pub paths: u64,
    /// Samples dropped for non-finite radiance.
    pub non_finite: u64,
    /// `Some` when the render stopped early.
    pub stopped: Option<StopReason>,
    /// Samples per tile, for the final stats (where adaptive sampling spent its budget).
    pub regions: Vec<RegionSamples>,
}

/// Renders `scene` through `camera` progressively on the current rayon pool.
pub fn render(scene: &CommittedScene, camera: &Camera, settings: &RenderSettings, sink: &dyn RenderSink) -> RenderOutcome {
    let start = Instant::now();
    scene.prepare_bsdfs(settings.integrator.energy_compensation);
    // Built here, not lazily inside a tile: a rayon worker waiting on its own build could
    // take another tile that waits on the same cell.
    scene.prepare_inside_medium_bsdfs(settings.integrator.energy_compensation);
    if settings.integrator.force_all_effects {
        scene.bsdf_with_every_lobe(0, settings.integrator.energy_compensation);
    }
    if settings.integrator.caustics == crate::caustics::CausticMode::Avoid {
        scene.prepare_floored_bsdfs(settings.integrator.energy_compensation);
    }
    let extra = settings.integrator.light_path_aovs || settings.integrator.force_all_effects;
    let tiles: Vec<LazyTile> =
        tiles_centre_out(settings.width, settings.height, settings.tile_size).into_iter().map(|rect| LazyTile::new(rect, extra)).collect();
    if let Some(reason) = coarse_passes(scene, camera, settings, &tiles, sink) {
        return RenderOutcome { stats: PassStats::default(), paths: 0, non_finite: 0, stopped: Some(reason), regions: Vec::new() };
    }
    let totals = Totals::default();
    let mut last = PassStats::default();
    let passes = pass_ranges(settings.spp).into_iter().enumerate().filter(|(_, r)| r.start >= settings.first_sample);
    for (pass, samples) in passes {
        let _span = tracing::debug_span!("pass", pass, spp = samples.len()).entered();
        if let Some(reason) = run_pass(scene, camera, settings, &tiles, pass as u32, samples.clone(), &totals, sink) {
            let regions = regions_of(&tiles);
            return RenderOutcome {
                stats: last,
                paths: totals.paths.into_inner(),
                non_finite: totals.non_finite.into_inner(),
                stopped: Some(reason),
                regions,
            };
        }
        let spp_done = samples.end;
        let (var, mean, active, taken) = settle_pass(&tiles, settings, spp_done);
        let pixels = (settings.width * settings.height).max(1) as f64;
        let noise = relative_noise(var, mean, pixels) as f32;
        last = PassStats {
            pass: pass as u32,
            spp: spp_done,
            elapsed: start.elapsed().as_secs_f64(),
            rays: totals.rays.load(Ordering::Relaxed),
            noise,
            active_pixels: active,
            samples_taken: taken,
        };
        sink.pass_done(&last);
        if active == 0 {
            // Every pixel converged: the render is done early.
            break;
        }
    }
    let regions = regions_of(&tiles);
    RenderOutcome { stats: last, paths: totals.paths.into_inner(), non_finite: totals.non_finite.into_inner(), stopped: None, regions }
}

/// Rays, dropped samples and camera samples of a render so far, summed over its workers.
#[derive(Default)]
struct Totals {
    rays: AtomicU64,
    non_finite: AtomicU64,
    paths: AtomicU64,
}

/// One pass over every tile on the pool's workers, each taking the next tile; `Some` when
/// the sink stopped it.
#[allow(clippy::too_many_arguments)]
fn run_pass(
    scene: &CommittedScene,
    camera: &Camera,
    settings: &RenderSettings,
    tiles: &[LazyTile],
    pass: u32,
    samples: std::ops::Range<u32>,
    totals: &Totals,
    sink: &dyn RenderSink,
) -> Option<StopReason> {
    let next = AtomicUsize::new(0);
    let stopped: Mutex<Option<StopReason>> = Mutex::new(None);
    let stop = |reason| *stopped.lock().unwrap() = Some(reason);
    rayon::scope(|s| {
        for _ in 0..rayon::current_num_threads().max(1) {
            s.spawn(|_| {
                // This worker's pass sums of its current tile, reused from tile to tile.
                let mut scratch = TileFilm::new(Rect { x: 0, y: 0, width: 0, height: 0 }, false);
                loop {
                    if let Some(reason) = sink.should_stop() {
                        return stop(reason);
                    }
                    let Some(tile) = tiles.get(next.fetch_add(1, Ordering::Relaxed)) else { return };
                    let mut tile = tile.film().lock().unwrap();
                    let mut counters = PathCounters::default();
                    let before = tile.sample_totals().1;
                    let interrupted = render_tile(scene, camera, settings, &mut tile, &mut scratch, samples.clone(), &mut counters, sink);
                    totals.rays.fetch_add(counters.rays, Ordering::Relaxed);
                    totals.non_finite.fetch_add(counters.non_finite, Ordering::Relaxed);
                    totals.paths.fetch_add(tile.sample_totals().1 - before, Ordering::Relaxed);
                    if let Some(reason) = interrupted {
                        return stop(reason);
                    }
                    if sink.wants_pass_films() {
                        sink.pass_film(&scratch, pass, samples.clone());
                    }
                    sink.tile(&tile, pass);
                }
            });
        }
    });
    stopped.into_inner().unwrap()
}

/// The image's noise estimate from the summed per-pixel terms of [`TileFilm::noise_terms`]:
/// the RMS standard error of the pixels' mean luminance over the mean luminance.
pub fn relative_noise(var: f64, mean: f64, pixels: f64) -> f64 {
    if mean > 0.0 { (var / pixels).sqrt() / (mean / pixels) } else { 0.0 }
}

/// After a pass: retires the pixels adaptive sampling finds converged (once every pixel has
/// [`ADAPTIVE_MIN_SPP`]), and sums the noise terms and sample counts over the tiles as
/// (variance, mean, active pixels, samples taken).
fn settle_pass(tiles: &[LazyTile], settings: &RenderSettings, spp_done: u32) -> (f64, f64, u64, u64) {
    // A slice lacks the samples before it, so it cannot judge convergence.
    let adaptive = settings.noise_threshold > 0.0 && settings.first_sample == 0 && spp_done >= ADAPTIVE_MIN_SPP;
    // Every pixel's relative error over the whole image, so neighbourhoods cross tiles.
    let errors = adaptive.then(|| {
        let mut errors = vec![0.0f32; (settings.width * settings.height) as usize];
        for t in tiles {
            let t = t.film().lock().unwrap();
            let r = t.rect;
            for (i, e) in t.relative_errors().into_iter().enumerate() {
                let (x, y) = (r.x + i as u32 % r.width, r.y + i as u32 / r.width);
                errors[(y * settings.width + x) as usize] = e;
            }
        }
        errors
    });
    let (mut var, mut mean, mut active, mut taken) = (0.0, 0.0, 0u64, 0u64);
    for t in tiles {
        let mut t = t.film().lock().unwrap();
        if let Some(errors) = &errors {
            t.retire_converged(errors, settings.width, settings.noise_threshold);
        }
        let (v, m) = t.noise_terms();
        var += v;
        mean += m;
        let (a, n) = t.sample_totals();
        active += a as u64;
        taken += n;
    }
    (var, mean, active, taken)
}

fn regions_of(tiles: &[LazyTile]) -> Vec<RegionSamples> {
    tiles.iter().map(|t| RegionSamples { rect: t.rect, samples: t.film.get().map_or(0, |f| f.lock().unwrap().sample_totals().1) }).collect()
}

/// Largest block edge a coarse pass may use (`RenderSettings::coarse_start`).
pub const MAX_COARSE_START: u32 = 64;

/// Block edges of the coarse passes that start a render: `start`, `start/2`, … down to 2
/// (Cycles' viewport "start resolution" and Arras' progressive refinement do the same). A
/// whole frame at 8×8 costs a 64th of a one-sample pass, so a viewport sees every pixel
/// change within a frame time of an edit. Empty for 0 or 1.
pub fn coarse_schedule(start: u32) -> Vec<u32> {
    std::iter::successors(Some(start), |b| Some(b / 2)).take_while(|&b| b >= 2).collect()
}

/// The coarse passes, each over every tile in parallel; `Some` when the sink stopped them.
/// Their samples go to throw-away films, so the passes after them are unchanged.
fn coarse_passes(
    scene: &CommittedScene,
    camera: &Camera,
    settings: &RenderSettings,
    tiles: &[LazyTile],
    sink: &dyn RenderSink,
) -> Option<StopReason> {
    use rayon::prelude::*;
    coarse_schedule(settings.coarse_start)
        .into_iter()
        .find_map(|block| tiles.par_iter().find_map_any(|t| coarse_tile(scene, camera, settings, t, block, sink)))
}

/// One sample per `block`² block of `rect`, at the block's centre pixel (clamped into the
/// rect), with the sample index 0 that pixel's first full pass also draws.
fn coarse_tile(
    scene: &CommittedScene,
    camera: &Camera,
    settings: &RenderSettings,
    tile: &LazyTile,
    block: u32,
    sink: &dyn RenderSink,
) -> Option<StopReason> {
    if let Some(reason) = sink.should_stop() {
        return Some(reason);
    }
    let rect = tile.rect;
    let blocks = Rect { x: 0, y: 0, width: rect.width.div_ceil(block), height: rect.height.div_ceil(block) };
    let mut film = TileFilm::new(blocks, tile.extra);
    let integrator = integrator_for(camera, settings);
    let mut counters = PathCounters::default();
    for by in 0..blocks.height {
        for bx in 0..blocks.width {
            let x = (rect.x + bx * block + block / 2).min(rect.x + rect.width - 1);
            let y = (rect.y + by * block + block / 2).min(rect.y + rect.height - 1);
            let sample = trace_camera_sample(scene, camera, settings, &integrator, x, y, 0, &mut counters);
            film.add((by * blocks.width + bx) as usize, &sample);
        }
    }
    film.samples = 1;
    sink.coarse_tile(rect, block, &film);
    None
}

/// A tile whose film is allocated by the first worker that renders it. A 1920×1080 film is
/// over 200 MB; allocated up front it delayed the first tile of every (re)start by ~40 ms.
struct LazyTile {
    rect: Rect,
    extra: bool,
    film: OnceLock<Mutex<TileFilm>>,
}

impl LazyTile {
    fn new(rect: Rect, extra: bool) -> Self {
        LazyTile { rect, extra, film: OnceLock::new() }
    }

    fn film(&self) -> &Mutex<TileFilm> {
        self.film.get_or_init(|| Mutex::new(TileFilm::new(self.rect, self.extra)))
    }
}

/// Adds samples `samples` to every active pixel of `tile`, or stops part-way when the sink
/// says so (then the tile is unchanged and the reason returned). The samples go to `pass`
/// first, reset to the tile's rect, and are added to the tile's totals as one pass sum
/// ([`TileFilm::absorb`]), so a pixel's total does not depend on how its passes were split
/// between renders.
#[allow(clippy::too_many_arguments)]
fn render_tile(
    scene: &CommittedScene,
    camera: &Camera,
    settings: &RenderSettings,
    tile: &mut TileFilm,
    pass: &mut TileFilm,
    samples: std::ops::Range<u32>,
    counters: &mut PathCounters,
    sink: &dyn RenderSink,
) -> Option<StopReason> {
    let r = tile.rect;
    pass.reset(r, tile.has_extra());
    let integrator = integrator_for(camera, settings);
    let mut wave = Vec::with_capacity(WAVE);
    let mut wave_pixels = Vec::with_capacity(WAVE);
    let mut buffers = WaveBuffers::default();
    // Polls for a stop, then traces the wave into the pass.
    let mut flush = |wave: &mut Vec<CameraPath>, pixels: &mut Vec<usize>, pass: &mut TileFilm, counters: &mut PathCounters| {
        if let Some(reason) = sink.should_stop() {
            return Some(reason);
        }
        let depth_of = |t, cos| camera.depth(t, cos);
        let traced = trace_wave(scene, wave, depth_of, camera.background_depth(), &integrator, counters, &mut buffers);
        // Added in the order the samples were drawn: a pixel's sum is the same to the bit.
        for (i, sample) in pixels.drain(..).zip(traced) {
            pass.add(i, sample);
        }
        wave.clear();
        None
    };
    for py in 0..r.height {
        for px in 0..r.width {
            let (x, y) = (r.x + px, r.y + py);
            let i = (py * r.width + px) as usize;
            if !tile.is_active(i) {
                continue;
            }
            for k in samples.clone() {
                wave.push(camera_path(scene, camera, settings, x, y, k));
                wave_pixels.push(i);
                if wave.len() == WAVE
                    && let Some(reason) = flush(&mut wave, &mut wave_pixels, pass, counters)
                {
                    return Some(reason);
                }
            }
        }
    }
    if !wave.is_empty()
        && let Some(reason) = flush(&mut wave, &mut wave_pixels, pass, counters)
    {
        return Some(reason);
    }
    pass.samples = samples.end;
    tile.absorb(pass);
    tile.samples = samples.end;
    None
}

/// A whole-image framebuffer, for callers that render in-process (tests, benchmarks).
pub struct Framebuffer {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels per AOV, row-major, channels interleaved.
    pub layers: std::collections::BTreeMap<Aov, Vec<f32>>,
}

impl Framebuffer {
    /// An empty framebuffer with every AOV.
    pub fn new(width: u32, height: u32) -> Self {
        let layers = Aov::ALL.iter().map(|&a| (a, vec![0.0; (width * height) as usize * a.channels()])).collect();
        Framebuffer { width, height, layers }
    }

    /// Copies a tile's current means into the framebuffer.
    pub fn write_tile(&mut self, tile: &TileFilm) {
        for (&aov, layer) in self.layers.iter_mut() {
            let c = aov.channels();
            let data = tile.resolve(aov);
            let r = tile.rect;
            for row in 0..r.height {
                let src = (row * r.width) as usize * c;
                let dst = (((r.y + row) * self.width + r.x) as usize) * c;
                layer[dst..dst + r.width as usize * c].copy_from_slice(&data[src..src + r.width as usize * c]);
            }
        }
    }
}

/// Renders to a framebuffer in-process, with no streaming.
pub fn render_to_framebuffer(scene: &CommittedScene, camera: &Camera, settings: &RenderSettings) -> (Framebuffer, RenderOutcome) {
    struct Collect(Mutex<Framebuffer>);
    impl RenderSink for Collect {
        fn tile(&self, tile: &TileFilm, _pass: u32) {
            self.0.lock().unwrap().write_tile(tile);
        }
        fn pass_done(&self, _: &PassStats) {}
        fn should_stop(&self) -> Option<StopReason> {
            None
        }
    }
    let sink = Collect(Mutex::new(Framebuffer::new(settings.width, settings.height)));
    let outcome = render(scene, camera, settings, &sink);
    (sink.0.into_inner().unwrap(), outcome)
}

/// The render's path settings with the camera's pixel footprint (for texture filtering).
fn integrator_for(camera: &Camera, settings: &RenderSettings) -> IntegratorSettings {
    let footprint = if settings.integrator.texture_filtering { camera.pixel_footprint() } else { (0.0, 0.0) };
    IntegratorSettings { pixel_footprint: footprint, exposure_scale: camera.exposure_scale(), ..settings.integrator }
}

/// Sample `k` of pixel (`x`, `y`), traced on its own.
#[allow(clippy::too_many_arguments)]
fn trace_camera_sample(
    scene: &CommittedScene,
    camera: &Camera,
    settings: &RenderSettings,
    integrator: &IntegratorSettings,
    x: u32,
    y: u32,
    k: u32,
    counters: &mut PathCounters,
) -> crate::film::PixelSample {
    let CameraPath { ray, cos, mut rng } = camera_path(scene, camera, settings, x, y, k);
    trace_path(scene, ray, |t| camera.depth(t, cos), camera.background_depth(), &mut rng, integrator, counters)
}

/// Sample `k` of pixel (`x`, `y`) as a path to trace: its random numbers depend on nothing else.
#[inline(always)]
pub fn camera_path(scene: &CommittedScene, camera: &Camera, settings: &RenderSettings, x: u32, y: u32, k: u32) -> CameraPath {
    let mut rng = PathSampler::for_sample(settings.sampler, settings.seed, x, y, k);
    // The camera's 4D set: pixel jitter and the lens point; and, only in scenes that move
    // (so still ones draw the same numbers as ever), a set whose first dimension is the time.
    let [jx, jy, lx, ly] = rng.next_4d();
    let time = if scene.plan.has(crate::plan::Feature::MotionBlur) { rng.next_4d()[0] } else { 0.0 };
    let (ray, cos) = camera.ray_at(x as f32 + jx, y as f32 + jy, glam::Vec2::new(lx, ly), time);
    CameraPath { ray, cos, rng }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_schedule_adds_up() {
        assert_eq!(pass_schedule(64), vec![1, 1, 2, 4, 8, 16, 32]);
        assert_eq!(pass_schedule(300), vec![1, 1, 2, 4, 8, 16, 32, 64, 64, 64, 44]);
        assert!([0, 1, 2, 4, 64, 128, 192, 256, 300].iter().all(|&k| is_pass_boundary(k, 300)));
        assert!(![3, 100, 299].iter().any(|&k| is_pass_boundary(k, 300)));
        assert_eq!(pass_schedule(5), vec![1, 1, 2, 1]);
        assert_eq!(pass_schedule(1), vec![1]);
        for spp in 1..300 {
            assert_eq!(pass_schedule(spp).iter().sum::<u32>(), spp);
        }
    }
}
