//! The `tessera.v1.Render` service: sessions, sync transactions and progressive renders
//! streamed to the client. Rendering runs on its own threads, never on the async runtime.
//! Every call is made as the tenant the interceptor ([`crate::auth`]) found for it.

use std::collections::HashMap;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use render_core::film::Aov;
use tessera_proto::v1 as pb;
use tokio::sync::mpsc;
use tokio_stream::{Stream, StreamExt, wrappers::ReceiverStream};
use tonic::{Request, Response, Status, Streaming};

use crate::auth::tenant_of;
use crate::budget::{Budget, Reservation};
use crate::config::ServerConfig;
use crate::registry::Registry;
use crate::render_job::{EVENT_BUFFER, RenderJob, RunContext};
use crate::session::Session;
use crate::textures::TextureStore;

/// The service state shared by all connections.
#[derive(Clone)]
pub struct RenderService {
    registry: Arc<Registry>,
    config: Arc<ServerConfig>,
    textures: Arc<TextureStore>,
    /// Every session's memory together.
    budget: Arc<Budget>,
    /// Render thread pools by size, shared by the renders that ask for that many threads.
    pools: Arc<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>>,
    /// Set once a shutdown began: no new sessions or renders.
    draining: Arc<AtomicBool>,
}

impl Default for RenderService {
    fn default() -> Self {
        Self::new(ServerConfig::default())
    }
}

impl RenderService {
    /// A service with the given configuration.
    pub fn new(config: ServerConfig) -> Self {
        // Decoded textures kept for reuse count against the server's budget: at most a
        // quarter of it, so the cache alone cannot starve scenes and films.
        let cache = config.limits.texture_cache_bytes.min(config.memory_budget / 4);
        RenderService {
            registry: Arc::default(),
            budget: Budget::new("server", config.memory_budget),
            textures: Arc::new(TextureStore::new(usize::try_from(cache).unwrap_or(usize::MAX))),
            config: Arc::new(config),
            pools: Arc::default(),
            draining: Arc::default(),
        }
    }

    /// The configuration it serves with.
    pub fn config(&self) -> &ServerConfig {
        &self.config
    }

    /// The open sessions.
    pub fn registry(&self) -> &Arc<Registry> {
        &self.registry
    }

    /// Stops taking new sessions and renders and tells every running render to finish
    /// (each ends with `Finished { cancelled }`); returns how many were running.
    pub fn begin_shutdown(&self) -> usize {
        self.draining.store(true, Ordering::Release);
        self.registry.cancel_all()
    }

    /// Render threads still running.
    pub fn renders_running(&self) -> usize {
        RENDERS_RUNNING.load(Ordering::Acquire)
    }

    #[allow(clippy::result_large_err)]
    fn session<T>(&self, req: &Request<T>, id: &str) -> Result<Arc<Session>, Status> {
        self.registry.get(id, &tenant_of(req))
    }

    #[allow(clippy::result_large_err)]
    fn refuse_if_draining(&self) -> Result<(), Status> {
        if self.draining.load(Ordering::Acquire) {
            return Err(Status::unavailable("the server is shutting down"));
        }
        Ok(())
    }

    /// A shared pool of `threads` threads (`None`: rayon's global pool, all cores).
    fn pool(&self, threads: usize) -> Result<Option<Arc<rayon::ThreadPool>>, Status> {
        if threads == 0 {
            return Ok(None);
        }
        let mut pools = self.pools.lock().unwrap();
        if let Some(p) = pools.get(&threads) {
            return Ok(Some(Arc::clone(p)));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(move |i| format!("render-{threads}-{i}"))
            .build()
            .map_err(|e| Status::internal(format!("cannot build a {threads}-thread pool: {e}")))?;
        let pool = Arc::new(pool);
        pools.insert(threads, Arc::clone(&pool));
        Ok(Some(pool))
    }
}

/// Render threads alive, for shutdown's wait.
static RENDERS_RUNNING: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Counts a render thread while it lives.
struct RunningRender;

impl RunningRender {
    fn start() -> Self {
        RENDERS_RUNNING.fetch_add(1, Ordering::AcqRel);
        RunningRender
    }
}

impl Drop for RunningRender {
    fn drop(&mut self) {
        RENDERS_RUNNING.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The AOVs and node types this build supports, for `GetCapabilities`.
pub fn capabilities(config: &ServerConfig) -> pb::Capabilities {
    pb::Capabilities {
        version: env!("CARGO_PKG_VERSION").into(),
        prim_kinds: ["mesh", "instancer", "material", "light", "camera", "texture", "volume", "remove"].map(String::from).to_vec(),
        node_types: [
            "UsdPreviewSurface",
            "UsdUVTexture",
            "UsdPrimvarReader_float2",
            "UsdTransform2d",
            "tessera:Principled",
            "tessera:Layer",
            render_core::material::BUMP,
        ]
        .into_iter()
        .chain(render_core::material::native::SHADERS.iter().map(|s| s.id))
        .map(String::from)
        .collect(),
        aovs: Aov::ALL.iter().map(|a| a.name().to_string()).collect(),
        limits: Some(config.limits_to_wire()),
    }
}

type EventStream = Pin<Box<dyn Stream<Item = Result<pb::RenderEvent, Status>> + Send>>;

#[tonic::async_trait]
impl pb::render_server::Render for RenderService {
    async fn get_capabilities(&self, _: Request<pb::GetCapabilitiesRequest>) -> Result<Response<pb::Capabilities>, Status> {
        Ok(Response::new(capabilities(&self.config)))
    }

    async fn create_session(&self, req: Request<pb::CreateSessionRequest>) -> Result<Response<pb::CreateSessionResponse>, Status> {
        self.refuse_if_draining()?;
        let tenant = tenant_of(&req);
        let l = &self.config.limits;
        let budget = self.config.session_memory_budget.min(self.config.memory_budget);
        let session = self.registry.create(tenant.clone(), l.max_sessions, l.max_sessions_per_tenant, budget, &self.budget)?;
        let name: String = req.get_ref().client_name.chars().take(128).collect();
        tracing::info!(session = %session.id, tenant = %tenant.0, client = %name.escape_debug(), "session created");
        Ok(Response::new(pb::CreateSessionResponse { session_id: session.id.clone() }))
    }

    async fn close_session(&self, req: Request<pb::CloseSessionRequest>) -> Result<Response<pb::CloseSessionResponse>, Status> {
        let id = &req.get_ref().session_id;
        self.registry.close(id, &tenant_of(&req))?;
        tracing::info!(session = %id, "session closed");
        Ok(Response::new(pb::CloseSessionResponse {}))
    }

    async fn sync(&self, req: Request<Streaming<pb::SyncRequest>>) -> Result<Response<pb::SyncResponse>, Status> {
        let tenant = tenant_of(&req);
        let mut stream = req.into_inner();
        let first =
            stream.next().await.ok_or_else(|| Status::invalid_argument("empty Sync stream: the first message must carry session_id"))??;
        let session = self.registry.get(&first.session_id, &tenant)?;
        let _one_at_a_time = session.claim_sync()?;
        let _alive = session.open_stream();
        let span = tracing::info_span!("sync", session = %session.id);
        let mut tx = session.begin(self.config.limits, Arc::clone(&self.textures));
        let mut next = Some(first);
        while let Some(msg) = next {
            if let Some(item) = msg.item {
                tx.apply(item).inspect_err(|e| span.in_scope(|| tracing::info!(error = %e.message(), "sync refused")))?;
            }
            next = stream.next().await.transpose()?;
        }
        let applied = tx.applied;
        let committing = Arc::clone(&session);
        let (version, warnings) = tokio::task::spawn_blocking(move || {
            let _e = span.enter();
            let out = committing.commit(tx);
            tracing::info!(prims = applied, ok = out.is_ok(), "sync committed");
            out
        })
        .await
        .map_err(|e| Status::internal(format!("commit task failed: {e}")))??;
        Ok(Response::new(pb::SyncResponse { scene_version: version, prims_applied: applied, warnings }))
    }

    async fn missing_textures(&self, req: Request<pb::MissingTexturesRequest>) -> Result<Response<pb::MissingTexturesResponse>, Status> {
        let req = req.into_inner();
        if req.content_hashes.len() > 1 << 16 {
            return Err(Status::resource_exhausted("more than 65 536 texture hashes in one request"));
        }
        Ok(Response::new(pb::MissingTexturesResponse { content_hashes: self.textures.missing(&req.content_hashes) }))
    }

    async fn get_session_stats(&self, req: Request<pb::GetSessionStatsRequest>) -> Result<Response<pb::SessionStats>, Status> {
        let s = self.session(&req, &req.get_ref().session_id)?;
        let c = &s.counters;
        let seconds = c.render_micros.load(Ordering::Relaxed) as f64 * 1e-6;
        let samples = c.samples.load(Ordering::Relaxed);
        let own = &s.budgets()[0];
        Ok(Response::new(pb::SessionStats {
            session_id: s.id.clone(),
            scene_version: s.version(),
            triangles: s.triangles(),
            scene_bytes: s.scene_bytes(),
            syncs: c.syncs.load(Ordering::Relaxed),
            renders: c.renders.load(Ordering::Relaxed),
            samples,
            render_seconds: seconds,
            samples_per_second: if seconds > 0.0 { samples as f64 / seconds } else { 0.0 },
            bytes_received: c.bytes_received.load(Ordering::Relaxed),
            rendering: s.render_cancel.lock().unwrap().is_some(),
            syncing: s.is_syncing(),
            session_memory_used: own.used(),
            session_memory_budget: own.limit(),
            server_memory_used: self.budget.used(),
            server_memory_budget: self.budget.limit(),
        }))
    }

    type RenderStream = EventStream;

    async fn render(&self, req: Request<pb::RenderRequest>) -> Result<Response<Self::RenderStream>, Status> {
        self.refuse_if_draining()?;
        let session = self.session(&req, &req.get_ref().session_id)?;
        let req = req.into_inner();
        let job = RenderJob::new(&req.settings.unwrap_or_default(), &self.config.limits)?;
        if session.current().is_none() {
            return Err(Status::failed_precondition(format!("session '{}' has no scene yet: Sync before Render", session.id)));
        }
        let cancel = Arc::new(AtomicBool::new(false));
        if let Some(previous) = session.render_cancel.lock().unwrap().replace(cancel.clone()) {
            // One render per session: a new request supersedes the old one, and its film is
            // freed before this one's is reserved.
            previous.store(true, Ordering::Release);
        }
        let film = match Reservation::take(session.budgets(), job.film_bytes(), &job.film_name()) {
            Ok(f) => f,
            Err(e) => {
                release_slot(&session, &cancel);
                return Err(e);
            }
        };
        let pool = self.pool(job.threads())?;
        let (tx, rx) = mpsc::channel(EVENT_BUFFER);
        let restarts = Arc::new(AtomicU64::new(0));
        let run = RunContext { tx, cancel, stall: self.config.stall_timeout, restarts: Arc::clone(&restarts) };
        let span =
            tracing::info_span!("render", session = %session.id, w = job.settings.width, h = job.settings.height, spp = job.settings.spp);
        session.counters.renders.fetch_add(1, Ordering::Relaxed);
        let alive = session.open_stream();
        let running = RunningRender::start();
        std::thread::Builder::new()
            .name(format!("render-{}", &session.id[..session.id.len().min(10)]))
            .spawn(move || {
                let _e = span.enter();
                job.run(&session, &run, pool.as_deref(), film);
                release_slot(&session, &run.cancel);
                drop((alive, running));
            })
            .map_err(|e| Status::internal(format!("cannot start render thread: {e}")))?;
        let current = ReceiverStream::new(rx).filter_map(move |q| q.is_current(restarts.load(Ordering::Acquire)).then_some(q.item));
        Ok(Response::new(Box::pin(current)))
    }

    async fn cancel(&self, req: Request<pb::CancelRequest>) -> Result<Response<pb::CancelResponse>, Status> {
        let session = self.session(&req, &req.get_ref().session_id)?;
        Ok(Response::new(pb::CancelResponse { was_rendering: session.cancel_render() }))
    }
}

/// Clears the session's render slot if it still holds this render's flag.
fn release_slot(session: &Session, cancel: &Arc<AtomicBool>) {
    let mut slot = session.render_cancel.lock().unwrap();
    if slot.as_ref().is_some_and(|c| Arc::ptr_eq(c, cancel)) {
        *slot = None;
    }
}
