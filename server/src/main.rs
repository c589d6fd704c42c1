//! `tessera-server`: the render server binary.

use clap::Parser;

/// Tessera render server.
#[derive(Parser)]
#[command(version, about)]
struct Args {
    /// Address to listen on. Loopback by default; other addresses are not yet guarded by a
    /// token, so bind them only on trusted networks.
    #[arg(long, default_value = "127.0.0.1:50051")]
    listen: std::net::SocketAddr,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .init();
    let args = Args::parse();
    let listener = tokio::net::TcpListener::bind(args.listen).await?;
    tracing::info!(addr = %listener.local_addr()?, "tessera-server listening");
    tessera_server::serve(listener, async {
        let _ = tokio::signal::ctrl_c().await;
        tracing::info!("shutting down");
    })
    .await
}
