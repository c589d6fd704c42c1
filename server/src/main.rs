//! `tessera-server`: the render server binary.

use std::path::PathBuf;
use std::time::Duration;

use clap::Parser;
use tessera_server::auth::Auth;
use tessera_server::budget::{default_server_budget, parse_size};
use tessera_server::limits::Limits;
use tessera_server::{RenderService, ServerConfig, TlsFiles};

/// Tessera render server.
#[derive(Parser)]
#[command(version, about)]
struct Args {
    /// Address to listen on. Loopback by default; any other address needs `--token-file` and
    /// TLS (`--tls-cert`, `--tls-key`), or `--insecure` to serve without them.
    #[arg(long, default_value = "127.0.0.1:50051")]
    listen: std::net::SocketAddr,
    /// Bearer tokens, one tenant per line (`TOKEN` or `NAME TOKEN`); sessions belong to the
    /// tenant that created them.
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// PEM certificate chain for TLS.
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// PEM private key for TLS.
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Serve a non-loopback address without tokens or TLS (trusted networks only).
    #[arg(long)]
    insecure: bool,
    /// Memory all sessions together may hold, e.g. `8G` (default: half the machine's memory).
    #[arg(long, value_parser = parse_size)]
    memory_budget: Option<u64>,
    /// Memory one session may hold (default: the whole server budget).
    #[arg(long, value_parser = parse_size)]
    session_memory_budget: Option<u64>,
    /// Close sessions with no call and no open stream for this many seconds.
    #[arg(long, default_value_t = 600.0)]
    session_idle_timeout: f64,
    /// Drop a Render stream whose client reads nothing for this many seconds.
    #[arg(long, default_value_t = 30.0)]
    stall_timeout: f64,
    /// Seconds running renders get to finish after SIGTERM or SIGINT; a second signal exits
    /// at once.
    #[arg(long, default_value_t = 10.0)]
    shutdown_grace: f64,
    #[command(flatten)]
    limits: LimitArgs,
}

/// Every limit of `GetCapabilities`, as a flag.
#[derive(clap::Args)]
struct LimitArgs {
    /// Triangles in one mesh.
    #[arg(long, default_value_t = Limits::default().max_triangles_per_mesh)]
    max_triangles_per_mesh: u64,
    /// Triangles in one scene.
    #[arg(long, default_value_t = Limits::default().max_total_triangles)]
    max_total_triangles: u64,
    /// Image width or height.
    #[arg(long, default_value_t = Limits::default().max_resolution)]
    max_resolution: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = Limits::default().max_spp)]
    max_spp: u32,
    /// Sessions open at once, all tenants together.
    #[arg(long, default_value_t = Limits::default().max_sessions)]
    max_sessions: u32,
    /// Sessions one tenant may hold open.
    #[arg(long, default_value_t = Limits::default().max_sessions_per_tenant)]
    max_sessions_per_tenant: u32,
    /// Scalar elements in one array chunk.
    #[arg(long, default_value_t = Limits::default().max_array_chunk_elements)]
    max_array_chunk_elements: u64,
    /// Instances in one instancer.
    #[arg(long, default_value_t = Limits::default().max_instances)]
    max_instances: u64,
    /// Decoded texture bytes kept for reuse across sessions (at most a quarter of the budget).
    #[arg(long, value_parser = parse_size, default_value = "4G")]
    texture_cache: u64,
    /// Encoded bytes of one texture file.
    #[arg(long, value_parser = parse_size, default_value = "2G")]
    max_texture_file: u64,
    /// Texels of one decoded texture.
    #[arg(long, default_value_t = Limits::default().max_texture_texels)]
    max_texture_texels: u64,
}

impl LimitArgs {
    fn limits(&self) -> Limits {
        Limits {
            max_triangles_per_mesh: self.max_triangles_per_mesh,
            max_total_triangles: self.max_total_triangles,
            max_resolution: self.max_resolution,
            max_spp: self.max_spp,
            max_sessions: self.max_sessions,
            max_sessions_per_tenant: self.max_sessions_per_tenant,
            max_array_chunk_elements: self.max_array_chunk_elements,
            max_instances: self.max_instances,
            texture_cache_bytes: self.texture_cache,
            max_texture_file_bytes: self.max_texture_file,
            max_texture_texels: self.max_texture_texels,
        }
    }
}

fn seconds(flag: &str, s: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s).map_err(|_| anyhow::anyhow!("--{flag} {s}: must be a non-negative number of seconds"))
}

fn config(args: &Args) -> anyhow::Result<(ServerConfig, Option<TlsFiles>)> {
    let read = |p: &PathBuf| std::fs::read(p).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()));
    let auth = match &args.token_file {
        Some(p) => Auth::from_file_contents(&String::from_utf8_lossy(&read(p)?)).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?,
        None => Auth::open(),
    };
    let tls = match (&args.tls_cert, &args.tls_key) {
        (Some(c), Some(k)) => Some(TlsFiles { cert: read(c)?, key: read(k)? }),
        _ => None,
    };
    if !args.listen.ip().is_loopback() && !args.insecure && (!auth.required() || tls.is_none()) {
        anyhow::bail!(
            "refusing to serve {} without tokens and TLS: anyone who can reach it could render on it and read what others send. Give --token-file, --tls-cert and --tls-key, or --insecure on a trusted network",
            args.listen
        );
    }
    let memory_budget = args.memory_budget.unwrap_or_else(default_server_budget);
    let config = ServerConfig {
        limits: args.limits.limits(),
        memory_budget,
        session_memory_budget: args.session_memory_budget.unwrap_or(memory_budget).min(memory_budget),
        auth,
        session_idle_timeout: seconds("session-idle-timeout", args.session_idle_timeout)?,
        stall_timeout: seconds("stall-timeout", args.stall_timeout)?,
        shutdown_grace: seconds("shutdown-grace", args.shutdown_grace)?,
    };
    Ok((config, tls))
}

/// Resolves at the first SIGINT or SIGTERM.
async fn signal() {
    #[cfg(unix)]
    {
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).expect("SIGTERM handler");
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    let _ = tokio::signal::ctrl_c().await;
}

/// Drains on the first signal: no new work, running renders told to finish, then waits up to
/// the grace period for them. A second signal exits at once.
async fn drain(service: RenderService) {
    signal().await;
    let running = service.begin_shutdown();
    let grace = service.config().shutdown_grace;
    tracing::info!(renders = running, grace_seconds = grace.as_secs_f64(), "shutting down: renders finish, then exit");
    tokio::spawn(async {
        signal().await;
        tracing::warn!("second signal: exiting now");
        std::process::exit(130);
    });
    let deadline = tokio::time::Instant::now() + grace;
    while service.renders_running() > 0 && tokio::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    if service.renders_running() > 0 {
        tracing::warn!(renders = service.renders_running(), "grace period over with renders still running; exiting");
    }
    // tonic now waits for open connections to close; a client keeping one open must not hold
    // the process past a short last delay.
    tokio::spawn(async {
        tokio::time::sleep(Duration::from_secs(1)).await;
        std::process::exit(0);
    });
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .init();
    let args = Args::parse();
    let (config, tls) = config(&args)?;
    let listener = tokio::net::TcpListener::bind(args.listen).await?;
    tracing::info!(
        addr = %listener.local_addr()?,
        tokens = config.auth.required(),
        tls = tls.is_some(),
        memory_budget = %tessera_server::budget::human(config.memory_budget),
        "tessera-server listening"
    );
    // A long-running server builds every row of the energy tables now, in the background on
    // one core (8 s), so that no render waits for one: a render builds the rows its materials
    // read when it first reads them (3-9 ms each; a scene sweeping every roughness, as the
    // principled grid does, waited 0.7 s for them on two cores). An embedded server (the CLI)
    // builds only the rows its scenes read.
    std::thread::Builder::new().name("energy-tables".into()).spawn(render_core::bsdf::energy::warm_up)?;
    let service = RenderService::new(config);
    tessera_server::serve_with(listener, service.clone(), tls, drain(service)).await?;
    // Render threads still running past the grace period end with the process.
    std::process::exit(0);
}
