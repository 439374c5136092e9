//! `rtd serve` and `rtd worker`: options to a [`ServiceConfig`], a tokio runtime, and the
//! service's library calls.

use std::sync::Arc;

use rtd_denoise::Denoiser;
use rtd_service::{redact, run_worker, shutdown_signal, sqlite_url, start_server, Database, ServiceConfig};

use crate::service_args::{NodeArgs, ServeArgs, WorkerArgs};

/// Logs to standard error, at `info` unless `RUST_LOG` says otherwise.
fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,sqlx=warn"));
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_multi_thread().enable_all().build()?)
}

impl NodeArgs {
    fn denoiser(&self) -> anyhow::Result<Arc<Denoiser>> {
        Ok(Arc::new(match &self.model {
            Some(p) => Denoiser::load(p)?,
            None => Denoiser::builtin()?,
        }))
    }
    fn config(&self) -> ServiceConfig {
        ServiceConfig::default().lease(self.lease).threads(self.threads.map(|t| t as usize))
    }
}

/// Runs `rtd serve` until Ctrl-C or SIGTERM.
pub fn serve(args: &ServeArgs) -> anyhow::Result<()> {
    init_logging();
    let denoiser = args.node.denoiser()?;
    let config = args
        .node
        .config()
        .max_upload(args.max_upload)
        .max_queued(args.max_queued)
        .keep(args.keep)
        .uploads_per_minute(args.rate_limit)
        .upload_timeout(args.upload_timeout)
        .render_chunk_spp(args.render_chunk_spp);
    let (url, workers) = match &args.database {
        Some(url) => (url.clone(), args.workers.unwrap_or(0)),
        None => {
            std::fs::create_dir_all(&args.data)
                .map_err(|e| anyhow::anyhow!("{}: cannot create the data folder: {e}", args.data.display()))?;
            (sqlite_url(&args.data), args.workers.unwrap_or(1))
        }
    };
    runtime()?.block_on(async move {
        let db = Database::connect(&url).await?;
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .map_err(|e| anyhow::anyhow!("cannot listen on {}: {e}", args.listen))?;
        let server = start_server(listener, db, workers, denoiser, config, shutdown_signal()).await?;
        crate::print_line(&format!(
            "rtd serve: open http://{}/ (database {}, {workers} in-process worker{})",
            server.addr,
            redact(&url),
            if workers == 1 { "" } else { "s" }
        ))?;
        server.wait().await?;
        Ok(())
    })
}

/// Runs `rtd worker` until Ctrl-C or SIGTERM.
pub fn worker(args: &WorkerArgs) -> anyhow::Result<()> {
    init_logging();
    let denoiser = args.node.denoiser()?;
    let config = args.node.config();
    runtime()?.block_on(async move {
        let db = Database::connect(&args.database).await?;
        run_worker(db, denoiser, config, shutdown_signal()).await?;
        Ok(())
    })
}
