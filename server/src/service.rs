//! The `tessera.v1.Render` service: sessions, sync transactions and progressive renders
//! streamed to the client. Rendering runs on rayon threads, never on the async runtime.

use std::collections::HashMap;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use render_core::camera::Camera;
use render_core::film::{Aov, TileFilm};
use render_core::integrator::IntegratorSettings;
use render_core::render::{PassStats, RenderSettings, RenderSink, StopReason, pass_schedule, render};
use tessera_proto::v1 as pb;
use tokio::sync::mpsc;
use tokio_stream::{Stream, StreamExt, wrappers::ReceiverStream};
use tonic::{Request, Response, Status, Streaming};

use crate::convert;
use crate::limits::Limits;
use crate::session::Session;
use crate::textures::TextureStore;

/// The service state shared by all connections.
#[derive(Clone)]
pub struct RenderService {
    sessions: Arc<Mutex<HashMap<String, Arc<Session>>>>,
    limits: Limits,
    next_id: Arc<std::sync::atomic::AtomicU64>,
    textures: Arc<TextureStore>,
}

impl Default for RenderService {
    fn default() -> Self {
        Self::new(Limits::default())
    }
}

impl RenderService {
    /// A service with the given limits.
    pub fn new(limits: Limits) -> Self {
        RenderService {
            sessions: Arc::default(),
            limits,
            next_id: Arc::new(std::sync::atomic::AtomicU64::new(1)),
            textures: Arc::new(TextureStore::new(usize::try_from(limits.texture_cache_bytes).unwrap_or(usize::MAX))),
        }
    }

    fn session(&self, id: &str) -> Result<Arc<Session>, Status> {
        self.sessions
            .lock()
            .unwrap()
            .get(id)
            .cloned()
            .ok_or_else(|| Status::not_found(format!("session '{id}' does not exist (closed, or never created)")))
    }
}

/// The AOVs and node types this build supports, for `GetCapabilities`.
pub fn capabilities(limits: &Limits) -> pb::Capabilities {
    pb::Capabilities {
        version: env!("CARGO_PKG_VERSION").into(),
        prim_kinds: ["mesh", "instancer", "material", "light", "camera", "texture", "remove"].map(String::from).to_vec(),
        node_types: [
            "UsdPreviewSurface",
            "UsdUVTexture",
            "UsdPrimvarReader_float2",
            "UsdTransform2d",
            "tessera:Principled",
            "tessera:Layer",
        ]
        .into_iter()
        .chain(render_core::material::native::SHADERS.iter().map(|s| s.id))
        .map(String::from)
        .collect(),
        aovs: Aov::ALL.iter().map(|a| a.name().to_string()).collect(),
        limits: Some(limits.to_wire()),
    }
}

type EventStream = Pin<Box<dyn Stream<Item = Result<pb::RenderEvent, Status>> + Send>>;

#[tonic::async_trait]
impl pb::render_server::Render for RenderService {
    async fn get_capabilities(&self, _: Request<pb::GetCapabilitiesRequest>) -> Result<Response<pb::Capabilities>, Status> {
        Ok(Response::new(capabilities(&self.limits)))
    }

    async fn create_session(&self, req: Request<pb::CreateSessionRequest>) -> Result<Response<pb::CreateSessionResponse>, Status> {
        let mut sessions = self.sessions.lock().unwrap();
        if sessions.len() >= self.limits.max_sessions as usize {
            return Err(Status::resource_exhausted(format!("{} sessions are open, the limit", sessions.len())));
        }
        let id = format!("s{}", self.next_id.fetch_add(1, Ordering::Relaxed));
        tracing::info!(session = %id, client = %req.get_ref().client_name, "session created");
        sessions.insert(id.clone(), Arc::new(Session::new(id.clone())));
        Ok(Response::new(pb::CreateSessionResponse { session_id: id }))
    }

    async fn close_session(&self, req: Request<pb::CloseSessionRequest>) -> Result<Response<pb::CloseSessionResponse>, Status> {
        let id = &req.get_ref().session_id;
        let session =
            self.sessions.lock().unwrap().remove(id).ok_or_else(|| Status::not_found(format!("session '{id}' does not exist")))?;
        session.cancel_render();
        tracing::info!(session = %id, "session closed");
        Ok(Response::new(pb::CloseSessionResponse {}))
    }

    async fn sync(&self, req: Request<Streaming<pb::SyncRequest>>) -> Result<Response<pb::SyncResponse>, Status> {
        let mut stream = req.into_inner();
        let mut session: Option<Arc<Session>> = None;
        let mut tx = None;
        while let Some(msg) = stream.next().await {
            let msg = msg?;
            if session.is_none() {
                let s = self.session(&msg.session_id)?;
                tx = Some(s.begin(self.limits, Arc::clone(&self.textures)));
                session = Some(s);
            }
            let Some(item) = msg.item else { continue };
            tx.as_mut().expect("begun with the session").apply(item)?;
        }
        let (Some(session), Some(tx)) = (session, tx) else {
            return Err(Status::invalid_argument("empty Sync stream: the first message must carry session_id"));
        };
        let applied = tx.applied;
        let span = tracing::info_span!("sync", session = %session.id, prims = applied);
        let (version, warnings) = tokio::task::spawn_blocking(move || {
            let _e = span.enter();
            session.commit(tx)
        })
        .await
        .map_err(|e| Status::internal(format!("commit task failed: {e}")))??;
        Ok(Response::new(pb::SyncResponse { scene_version: version, prims_applied: applied, warnings }))
    }

    async fn missing_textures(&self, req: Request<pb::MissingTexturesRequest>) -> Result<Response<pb::MissingTexturesResponse>, Status> {
        let req = req.into_inner();
        if req.content_hashes.len() > 1 << 20 {
            return Err(Status::resource_exhausted("more than 2^20 texture hashes in one request"));
        }
        Ok(Response::new(pb::MissingTexturesResponse { content_hashes: self.textures.missing(&req.content_hashes) }))
    }

    type RenderStream = EventStream;

    async fn render(&self, req: Request<pb::RenderRequest>) -> Result<Response<Self::RenderStream>, Status> {
        let req = req.into_inner();
        let session = self.session(&req.session_id)?;
        let job = RenderJob::new(&req.settings.unwrap_or_default(), &self.limits)?;
        if session.current().is_none() {
            return Err(Status::failed_precondition(format!("session '{}' has no scene yet: Sync before Render", session.id)));
        }
        let cancel = Arc::new(AtomicBool::new(false));
        if let Some(previous) = session.render_cancel.lock().unwrap().replace(cancel.clone()) {
            // One render per session: a new request supersedes the old one.
            previous.store(true, Ordering::Release);
        }
        let (tx, rx) = mpsc::channel(256);
        let span =
            tracing::info_span!("render", session = %session.id, w = job.settings.width, h = job.settings.height, spp = job.settings.spp);
        std::thread::Builder::new()
            .name(format!("render-{}", session.id))
            .spawn(move || {
                let _e = span.enter();
                job.run(&session, &cancel, &tx);
                let mut slot = session.render_cancel.lock().unwrap();
                if slot.as_ref().is_some_and(|c| Arc::ptr_eq(c, &cancel)) {
                    *slot = None;
                }
            })
            .map_err(|e| Status::internal(format!("cannot start render thread: {e}")))?;
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }

    async fn cancel(&self, req: Request<pb::CancelRequest>) -> Result<Response<pb::CancelResponse>, Status> {
        let session = self.session(&req.get_ref().session_id)?;
        Ok(Response::new(pb::CancelResponse { was_rendering: session.cancel_render() }))
    }
}

/// A validated render request.
struct RenderJob {
    settings: RenderSettings,
    /// Width over height of a pixel.
    pixel_aspect: f32,
    aovs: Vec<Aov>,
    camera_path: String,
    progressive_format: pb::PixelFormat,
    threads: usize,
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

    fn new(s: &pb::RenderSettings, limits: &Limits) -> Result<Self, Status> {
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
        let threads = s.threads as usize;
        if threads > 1024 {
            return Err(bad("threads", format!("{threads} is too many")));
        }
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
        })
    }

    /// Renders until done, cancelled or disconnected, restarting on scene edits.
    fn run(&self, session: &Session, cancel: &AtomicBool, tx: &mpsc::Sender<Result<pb::RenderEvent, Status>>) {
        let send = |e: pb::render_event::Event| {
            if tx.blocking_send(Ok(pb::RenderEvent { event: Some(e) })).is_err() {
                cancel.store(true, Ordering::Release);
            }
        };
        let pool = match self.threads {
            0 => None,
            n => match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
                Ok(p) => Some(p),
                Err(e) => {
                    let _ = tx.blocking_send(Err(Status::internal(format!("cannot build a {n}-thread pool: {e}"))));
                    return;
                }
            },
        };
        let start = std::time::Instant::now();
        let mut first = true;
        loop {
            let Some((scene, version)) = session.current() else {
                return;
            };
            let camera = match scene.camera(&self.camera_path) {
                Ok(c) => Camera::with_pixel_aspect(&c, self.settings.width, self.settings.height, self.pixel_aspect),
                Err(e) => {
                    let _ = tx.blocking_send(Err(Status::invalid_argument(e.to_string())));
                    return;
                }
            };
            if first {
                send(pb::render_event::Event::Started(pb::Started {
                    width: self.settings.width,
                    height: self.settings.height,
                    pass_spp: pass_schedule(self.settings.spp),
                    plan: scene
                        .plan
                        .entries
                        .iter()
                        .map(|e| pb::PlanEntry { effect: e.effect.clone(), reason: e.reason.clone(), prims: e.prims.clone() })
                        .collect(),
                    aovs: self.aovs.iter().map(|a| a.name().to_string()).collect(),
                    scene_version: version,
                    warnings: scene.warnings.iter().cloned().chain(self.settings_warnings()).chain(self.scene_hints(&scene)).collect(),
                    prim_paths: if self.aovs.contains(&Aov::PrimId) { scene.prim_paths.clone() } else { Vec::new() },
                }));
                first = false;
            } else {
                send(pb::render_event::Event::Restarted(pb::Restarted { scene_version: version }));
            }
            let sink = StreamSink { job: self, tx, cancel, session, version, passes: pass_schedule(self.settings.spp).len() as u32 };
            let outcome = match &pool {
                Some(p) => p.install(|| render(&scene, &camera, &self.settings, &sink)),
                None => render(&scene, &camera, &self.settings, &sink),
            };
            if outcome.non_finite > 0 {
                tracing::warn!(samples = outcome.non_finite, "non-finite radiance samples were dropped");
            }
            match outcome.stopped {
                Some(StopReason::SceneChanged) => continue,
                stopped => {
                    let secs = start.elapsed().as_secs_f64().max(1e-9);
                    let s = outcome.stats;
                    tracing::info!(seconds = secs, spp = s.spp, rays = s.rays, cancelled = stopped.is_some(), "render finished");
                    send(pb::render_event::Event::Finished(pb::Finished {
                        seconds: secs,
                        spp: s.spp,
                        rays: s.rays,
                        paths: outcome.paths,
                        rays_per_second: s.rays as f64 / secs,
                        paths_per_second: outcome.paths as f64 / secs,
                        estimated_noise: s.noise,
                        cancelled: stopped.is_some(),
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
                    }));
                    return;
                }
            }
        }
    }
}

struct StreamSink<'a> {
    job: &'a RenderJob,
    tx: &'a mpsc::Sender<Result<pb::RenderEvent, Status>>,
    cancel: &'a AtomicBool,
    session: &'a Session,
    version: u64,
    passes: u32,
}

impl RenderSink for StreamSink<'_> {
    fn tile(&self, tile: &TileFilm, pass: u32) {
        let format = if pass + 1 == self.passes { pb::PixelFormat::F32 } else { self.job.progressive_format };
        for &aov in &self.job.aovs {
            let t = convert::tile_to_wire(tile, aov, pass, format);
            if self.tx.blocking_send(Ok(pb::RenderEvent { event: Some(pb::render_event::Event::Tile(t)) })).is_err() {
                self.cancel.store(true, Ordering::Release);
                return;
            }
        }
    }

    fn pass_done(&self, s: &PassStats) {
        let total = self.job.settings.spp as f32;
        let progress = pb::Progress {
            pass_index: s.pass,
            spp: s.spp,
            percent: 100.0 * s.spp as f32 / total,
            rays_per_second: s.rays as f64 / s.elapsed.max(1e-9),
            estimated_noise: s.noise,
            elapsed_seconds: s.elapsed,
            active_pixels: s.active_pixels,
            samples_taken: s.samples_taken,
        };
        if self.tx.blocking_send(Ok(pb::RenderEvent { event: Some(pb::render_event::Event::Progress(progress)) })).is_err() {
            self.cancel.store(true, Ordering::Release);
        }
    }

    fn should_stop(&self) -> Option<StopReason> {
        if self.cancel.load(Ordering::Acquire) || self.tx.is_closed() {
            Some(StopReason::Cancelled)
        } else if self.session.version() != self.version {
            Some(StopReason::SceneChanged)
        } else {
            None
        }
    }
}
