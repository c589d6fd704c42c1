//! One render on a session: its settings validated into a job, run on a render thread until
//! done, cancelled, disconnected or stalled, restarting on scene edits, with every event sent
//! under a bound on how long a client that stops reading can hold the thread.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use render_core::camera::Camera;
use render_core::film::{Aov, TileFilm};
use render_core::integrator::IntegratorSettings;
use render_core::render::{MAX_COARSE_START, PassStats, RenderSettings, RenderSink, StopReason, pass_schedule, render};
use tessera_proto::v1 as pb;
use tokio::sync::mpsc::{self, error::TrySendError};
use tonic::Status;

use crate::budget::Reservation;
use crate::convert;
use crate::limits::Limits;
use crate::session::Session;

/// Events buffered per render before sending waits for the client.
pub const EVENT_BUFFER: usize = 256;

/// A render event and the restart it was sent in (0 before the first restart).
pub struct Queued {
    /// How many times the render had restarted when the event was sent.
    pub restart: u64,
    /// The event, or the status that ends the stream.
    pub item: Result<pb::RenderEvent, Status>,
}

impl Queued {
    /// Whether the client still wants this event once the render has restarted `now` times:
    /// tiles and progress of a superseded scene version are dropped rather than sent ahead of
    /// the new image (a 1080p pass fills the whole event buffer, 16 MiB of stale tiles);
    /// everything else is always delivered.
    pub fn is_current(&self, now: u64) -> bool {
        let stale_kind = matches!(
            &self.item,
            Ok(pb::RenderEvent {
                event: Some(pb::render_event::Event::Tile(_) | pb::render_event::Event::Progress(_) | pb::render_event::Event::Film(_))
            })
        );
        self.restart == now || !stale_kind
    }
}

/// The sending end of a render's event stream.
pub type EventSender = mpsc::Sender<Queued>;

/// A validated render request.
pub struct RenderJob {
    /// What the renderer is asked for.
    pub settings: RenderSettings,
    /// Width over height of a pixel.
    pixel_aspect: f32,
    aovs: Vec<Aov>,
    camera_path: String,
    progressive_format: pb::PixelFormat,
    threads: usize,
    /// Send each tile's pass sums (FilmTile) instead of its resolved pixels.
    stream_film: bool,
}

impl RenderJob {
    /// What these settings will do badly on this scene, and the setting that would not.
    fn scene_hints(&self, scene: &render_core::scene::CommittedScene) -> Vec<String> {
        let full = self.settings.integrator.caustics == render_core::caustics::CausticMode::Full;
        let mut w = Vec::new();
        if full && !scene.smooth_subsurface.is_empty() {
            w.push(format!(
                "{}: subsurface behind a smooth boundary is lit only where a random walk happens to leave towards a light (fireflies); --caustics avoid lights the medium from inside (biased, far less noisy)",
                scene.smooth_subsurface.join(", ")
            ));
        }
        w
    }

    /// What the settings cost in accuracy, said where every client sees it.
    fn settings_warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if let Some(c) = self.settings.integrator.clamp_indirect {
            w.push(format!("firefly clamp on: indirect contributions above {c} are scaled down (biased, darker)"));
        }
        if self.settings.integrator.caustics == render_core::caustics::CausticMode::Avoid {
            w.push("caustics avoided: light through smooth glass and smooth subsurface boundaries arrives unfocused and unbent (biased, far less noisy)".into());
        }
        if !self.settings.integrator.energy_compensation {
            w.push("energy compensation off: rough surfaces lose the energy of multiple scattering".into());
        }
        if !self.settings.integrator.texture_filtering {
            w.push("texture filtering off: textures alias unless many samples per pixel average them".into());
        }
        if self.settings.integrator.light_split_budget == 1 {
            w.push("light splitting off: one light per shading point from the light tree (cheaper samples, more noise)".into());
        }
        w
    }

    /// Validates the settings of a Render request, naming the field at fault.
    #[allow(clippy::result_large_err)]
    pub fn new(s: &pb::RenderSettings, limits: &Limits) -> Result<Self, Status> {
        let bad = |field: &str, why: String| Status::invalid_argument(format!("render settings: {field}: {why}"));
        let (w, h) = (if s.width == 0 { 256 } else { s.width }, if s.height == 0 { 256 } else { s.height });
        if w > limits.max_resolution || h > limits.max_resolution {
            return Err(bad("resolution", format!("{w}x{h} exceeds {}", limits.max_resolution)));
        }
        let spp = if s.spp == 0 { 64 } else { s.spp };
        if spp > limits.max_spp {
            return Err(bad("spp", format!("{spp} exceeds {}", limits.max_spp)));
        }
        if s.max_depth > 1024 {
            return Err(bad("max_depth", format!("{} exceeds 1024", s.max_depth)));
        }
        let tile = if s.tile_size == 0 { 64 } else { s.tile_size };
        if !(8..=512).contains(&tile) {
            return Err(bad("tile_size", format!("{tile} is outside 8..=512")));
        }
        let mut aovs = vec![Aov::Beauty];
        for name in &s.aovs {
            let aov = Aov::from_name(name).ok_or_else(|| {
                let known: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
                bad("aovs", format!("unknown AOV '{name}' (known: {})", known.join(", ")))
            })?;
            if !aovs.contains(&aov) {
                aovs.push(aov);
            }
        }
        // More threads than cores only adds switching; the pools are shared per count.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = (s.threads as usize).min(cores);
        let first_sample = first_sample(s, spp)?;
        let pixel_aspect = match s.pixel_aspect {
            0.0 => 1.0,
            a if a.is_finite() && (1e-3..=1e3).contains(&a) => a,
            a => return Err(bad("pixel_aspect", format!("{a} must be within [0.001, 1000] (0 = square)"))),
        };
        Ok(RenderJob {
            pixel_aspect,
            settings: RenderSettings {
                width: w,
                height: h,
                spp,
                seed: s.seed,
                tile_size: tile,
                integrator: IntegratorSettings {
                    max_depth: if s.max_depth == 0 { 8 } else { s.max_depth },
                    energy_compensation: !s.disable_energy_compensation,
                    light_path_aovs: aovs.iter().any(|a| a.is_extra()),
                    clamp_indirect: match s.clamp_indirect {
                        0.0 => None,
                        x if x.is_finite() && x > 0.0 => Some(x),
                        x => return Err(bad("clamp_indirect", format!("{x} must be positive and finite (0 = off)"))),
                    },
                    caustics: match pb::Caustics::try_from(s.caustics) {
                        Ok(pb::Caustics::Full) => render_core::caustics::CausticMode::Full,
                        Ok(pb::Caustics::Avoid) => render_core::caustics::CausticMode::Avoid,
                        Err(_) => return Err(bad("caustics", format!("unknown caustics mode {}", s.caustics))),
                    },
                    force_all_effects: s.force_all_effects,
                    texture_filtering: !s.disable_texture_filtering,
                    light_split_budget: match (s.disable_light_splitting, s.light_split_budget) {
                        (true, _) => 1,
                        (false, 0) => render_core::light::tree::SPLIT_BUDGET,
                        (false, b) if b as usize <= render_core::light::tree::SPLIT_BUDGET => b as usize,
                        (false, b) => {
                            return Err(bad(
                                "light_split_budget",
                                format!("{b} exceeds {} (0 = the default)", render_core::light::tree::SPLIT_BUDGET),
                            ));
                        }
                    },
                    ..Default::default()
                },
                noise_threshold: match s.noise_threshold {
                    x if x.is_finite() && x >= 0.0 => x,
                    x => return Err(bad("noise_threshold", format!("{x} must be finite and not negative (0 = off)"))),
                },
                coarse_start: match s.coarse_start {
                    0 | 1 => 0,
                    b if b.is_power_of_two() && b <= MAX_COARSE_START => b,
                    b => return Err(bad("coarse_start", format!("{b} must be a power of two from 2 to {MAX_COARSE_START} (0 = off)"))),
                },
                first_sample,
                sampler: match pb::Sampler::try_from(s.sampler) {
                    Ok(pb::Sampler::Sobol) => render_core::sampling::SamplerKind::Sobol,
                    Ok(pb::Sampler::Independent) => render_core::sampling::SamplerKind::Independent,
                    Err(_) => return Err(bad("sampler", format!("unknown sampler {}", s.sampler))),
                },
            },
            aovs,
            camera_path: s.camera_path.clone(),
            progressive_format: if s.noise_threshold > 0.0 {
                pb::PixelFormat::F32
            } else {
                pb::PixelFormat::try_from(s.progressive_format).unwrap_or(pb::PixelFormat::F32)
            },
            threads,
            stream_film: s.stream_film,
        })
    }

    /// Threads the render asked for (0: the server's shared pool).
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// The memory this render's film holds: every pixel's sums, the adaptive error map, and the
    /// tiles the event buffer can hold.
    pub fn film_bytes(&self) -> u64 {
        let s = &self.settings;
        let pixels = u64::from(s.width) * u64::from(s.height);
        let extra = s.integrator.light_path_aovs || s.integrator.force_all_effects;
        let adaptive = if s.noise_threshold > 0.0 { 4 } else { 0 };
        let channels: u64 = self.aovs.iter().map(|a| a.channels() as u64).sum();
        let tile = u64::from(s.tile_size).pow(2).min(pixels);
        let event = match self.stream_film {
            true => tile * TileFilm::encoded_bytes_per_pixel(extra) as u64,
            false => tile * 4 * channels.max(1) / self.aovs.len() as u64,
        };
        pixels * (TileFilm::bytes_per_pixel(extra) + adaptive) + EVENT_BUFFER as u64 * event
    }

    /// What the film reservation refuses with, naming the render.
    pub fn film_name(&self) -> String {
        format!("a {}x{} film with {} AOVs", self.settings.width, self.settings.height, self.aovs.len())
    }

    /// Renders until done, cancelled, disconnected or stalled, restarting on scene edits.
    /// `pool` runs the tiles (`None`: rayon's global pool). `film` is the reservation of the
    /// film's memory, held until the render ends.
    pub fn run(&self, session: &Session, run: &RunContext, pool: Option<&rayon::ThreadPool>, film: Reservation) {
        let out = Outbox { tx: &run.tx, cancel: &run.cancel, stall: run.stall, restarts: &run.restarts };
        let start = Instant::now();
        let mut first = true;
        loop {
            let Some((scene, version)) = session.current() else {
                return;
            };
            let camera = match scene.camera(&self.camera_path) {
                Ok(c) => Camera::with_pixel_aspect(&c, self.settings.width, self.settings.height, self.pixel_aspect),
                Err(e) => {
                    out.error(Status::invalid_argument(e.to_string()));
                    return;
                }
            };
            let event = if first {
                pb::render_event::Event::Started(self.started(&scene, version))
            } else {
                pb::render_event::Event::Restarted(pb::Restarted { scene_version: version })
            };
            first = false;
            out.send(event);
            let sink = StreamSink { job: self, out: &out, session, version, passes: pass_schedule(self.settings.spp).len() as u32 };
            let outcome = match pool {
                Some(p) => p.install(|| render(&scene, &camera, &self.settings, &sink)),
                None => render(&scene, &camera, &self.settings, &sink),
            };
            session.counters.samples.fetch_add(outcome.paths, Ordering::Relaxed);
            if outcome.non_finite > 0 {
                tracing::warn!(samples = outcome.non_finite, "non-finite radiance samples were dropped");
            }
            if outcome.stopped == Some(StopReason::SceneChanged) {
                run.restarts.fetch_add(1, Ordering::AcqRel);
                out.wait_for_commit(session);
                continue;
            }
            let secs = start.elapsed().as_secs_f64().max(1e-9);
            session.counters.render_micros.fetch_add((secs * 1e6) as u64, Ordering::Relaxed);
            let s = outcome.stats;
            let cancelled = outcome.stopped.is_some();
            tracing::info!(seconds = secs, spp = s.spp, rays = s.rays, cancelled, "render finished");
            out.finish(self.finished(&outcome, secs));
            drop(film);
            return;
        }
    }

    fn started(&self, scene: &render_core::scene::CommittedScene, version: u64) -> pb::Started {
        pb::Started {
            width: self.settings.width,
            height: self.settings.height,
            pass_spp: pass_schedule(self.settings.spp),
            plan: scene.plan.entries().into_iter().map(|e| pb::PlanEntry { effect: e.effect, reason: e.reason, prims: e.prims }).collect(),
            aovs: self.aovs.iter().map(|a| a.name().to_string()).collect(),
            scene_version: version,
            warnings: scene.warnings.iter().cloned().chain(self.settings_warnings()).chain(self.scene_hints(scene)).collect(),
            prim_paths: if self.aovs.contains(&Aov::PrimId) { scene.prim_paths.clone() } else { Vec::new() },
        }
    }

    fn finished(&self, outcome: &render_core::render::RenderOutcome, secs: f64) -> pb::Finished {
        let s = outcome.stats;
        pb::Finished {
            seconds: secs,
            spp: s.spp,
            rays: s.rays,
            paths: outcome.paths,
            rays_per_second: s.rays as f64 / secs,
            paths_per_second: outcome.paths as f64 / secs,
            estimated_noise: s.noise,
            cancelled: outcome.stopped.is_some(),
            skipped_prims: Vec::new(),
            mean_spp: s.samples_taken as f64 / (self.settings.width as f64 * self.settings.height as f64).max(1.0),
            regions: outcome
                .regions
                .iter()
                .map(|r| pb::RegionSamples {
                    x: r.rect.x,
                    y: r.rect.y,
                    width: r.rect.width,
                    height: r.rect.height,
                    mean_spp: r.samples as f64 / (r.rect.width as f64 * r.rect.height as f64).max(1.0),
                })
                .collect(),
        }
    }
}

/// The first sample of a slice: below `spp`, at one of its pass boundaries, and without
/// adaptive sampling (a slice lacks the samples before it to judge convergence).
#[allow(clippy::result_large_err)]
fn first_sample(s: &pb::RenderSettings, spp: u32) -> Result<u32, Status> {
    let bad = |why: String| Err(Status::invalid_argument(format!("render settings: first_sample: {why}")));
    match s.first_sample {
        0 => Ok(0),
        k if k >= spp || !render_core::render::is_pass_boundary(k, spp) => {
            bad(format!("{k} must be below spp {spp} and start one of its passes (0, a power of two up to 64, or a multiple of 64)"))
        }
        _ if s.noise_threshold != 0.0 => {
            bad("a slice cannot use adaptive sampling (noise_threshold): it lacks the samples before it".into())
        }
        k => Ok(k),
    }
}

/// What a render thread shares with the service: its event stream, its cancel flag and how
/// long a client may leave the stream unread.
pub struct RunContext {
    /// Where events go.
    pub tx: EventSender,
    /// Set by Cancel, CloseSession, a superseding Render, shutdown, or a gone client.
    pub cancel: Arc<AtomicBool>,
    /// How long a full stream may stay full.
    pub stall: Duration,
    /// Restarts so far; the stream drops what was queued before the latest.
    pub restarts: Arc<AtomicU64>,
}

/// Sends a render's events without letting a client that stops reading hold the thread: a
/// full stream is retried until the stall timeout (then the render is cancelled), and after a
/// cancel nothing but the final event is sent.
struct Outbox<'a> {
    tx: &'a EventSender,
    cancel: &'a AtomicBool,
    stall: Duration,
    restarts: &'a AtomicU64,
}

/// How long the final `Finished` of a cancelled render may wait for a slow reader.
const FINISH_WAIT: Duration = Duration::from_millis(500);

impl Outbox<'_> {
    /// Sends a progress event; false when the render should stop.
    fn send(&self, event: pb::render_event::Event) -> bool {
        if self.cancel.load(Ordering::Acquire) {
            return false;
        }
        self.deliver(Ok(pb::RenderEvent { event: Some(event) }), self.stall, true)
    }

    /// Sends the last event, waiting less when the render was cancelled.
    fn finish(&self, finished: pb::Finished) {
        let wait = if finished.cancelled { FINISH_WAIT.min(self.stall) } else { self.stall };
        let event = pb::RenderEvent { event: Some(pb::render_event::Event::Finished(finished)) };
        self.deliver(Ok(event), wait, false);
    }

    /// Waits while the session commits a new scene version (the render stopped its pass for
    /// it), or until the render is cancelled or its client leaves.
    fn wait_for_commit(&self, session: &Session) {
        while session.is_committing() && !self.cancel.load(Ordering::Acquire) && !self.tx.is_closed() {
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Ends the stream with an error status.
    fn error(&self, status: Status) {
        self.deliver(Err(status), FINISH_WAIT, false);
    }

    fn deliver(&self, item: Result<pb::RenderEvent, Status>, wait: Duration, stop_on_cancel: bool) -> bool {
        let deadline = Instant::now() + wait;
        let mut queued = Queued { restart: self.restarts.load(Ordering::Acquire), item };
        loop {
            match self.tx.try_send(queued) {
                Ok(()) => return true,
                Err(TrySendError::Closed(_)) => break,
                Err(TrySendError::Full(back)) => {
                    if stop_on_cancel && self.cancel.load(Ordering::Acquire) {
                        return false;
                    }
                    if Instant::now() >= deadline {
                        if stop_on_cancel {
                            tracing::warn!(
                                stall_seconds = wait.as_secs_f64(),
                                "the client stopped reading its render stream; render dropped"
                            );
                        }
                        break;
                    }
                    queued = back;
                    std::thread::sleep(Duration::from_millis(2));
                }
            }
        }
        self.cancel.store(true, Ordering::Release);
        false
    }
}

struct StreamSink<'a> {
    job: &'a RenderJob,
    out: &'a Outbox<'a>,
    session: &'a Session,
    version: u64,
    passes: u32,
}

impl RenderSink for StreamSink<'_> {
    fn wants_pass_films(&self) -> bool {
        self.job.stream_film
    }

    fn pass_film(&self, film: &TileFilm, pass: u32, samples: std::ops::Range<u32>) {
        let r = film.rect;
        self.out.send(pb::render_event::Event::Film(pb::FilmTile {
            x: r.x,
            y: r.y,
            width: r.width,
            height: r.height,
            pass_index: pass,
            first_sample: samples.start,
            end_sample: samples.end,
            extra: film.has_extra(),
            sums: film.encode(),
        }));
    }

    fn tile(&self, tile: &TileFilm, pass: u32) {
        if self.job.stream_film {
            return;
        }
        let format = if pass + 1 == self.passes { pb::PixelFormat::F32 } else { self.job.progressive_format };
        for &aov in &self.job.aovs {
            if !self.out.send(pb::render_event::Event::Tile(convert::tile_to_wire(tile, aov, pass, format))) {
                return;
            }
        }
    }

    fn coarse_tile(&self, covers: render_core::film::Rect, pixel_size: u32, film: &TileFilm) {
        for &aov in &self.job.aovs {
            let mut tile = convert::tile_to_wire(film, aov, 0, self.job.progressive_format);
            (tile.x, tile.y, tile.width, tile.height, tile.pixel_size) = (covers.x, covers.y, covers.width, covers.height, pixel_size);
            if !self.out.send(pb::render_event::Event::Tile(tile)) {
                return;
            }
        }
    }

    fn pass_done(&self, s: &PassStats) {
        // A slice's share: its own samples against the ones it was asked for.
        let first = self.job.settings.first_sample;
        let total = (self.job.settings.spp - first).max(1) as f32;
        self.out.send(pb::render_event::Event::Progress(pb::Progress {
            pass_index: s.pass,
            spp: s.spp,
            percent: 100.0 * (s.spp - first) as f32 / total,
            rays_per_second: s.rays as f64 / s.elapsed.max(1e-9),
            estimated_noise: s.noise,
            elapsed_seconds: s.elapsed,
            active_pixels: s.active_pixels,
            samples_taken: s.samples_taken,
        }));
    }

    fn should_stop(&self) -> Option<StopReason> {
        if self.out.cancel.load(Ordering::Acquire) || self.out.tx.is_closed() {
            Some(StopReason::Cancelled)
        } else if self.session.version() != self.version || self.session.is_committing() {
            Some(StopReason::SceneChanged)
        } else {
            None
        }
    }
}
