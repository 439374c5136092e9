//! `rtd serve` and `rtd worker`: options to a [`ServiceConfig`], a tokio runtime, and the
//! service's library calls.

use std::sync::Arc;

use rtd_denoise::Denoiser;
use rtd_image::Progress;
use rtd_service::{
    redact, run_worker, shutdown_signal, sqlite_url, start_server, Database, DatasetJob, DatasetRun, ServiceConfig,
    Worker,
};
use rtd_train::dataset::{DatasetOptions, Manifest};

use crate::exit::Interrupted;
use crate::progress::TaskBar;
use crate::service_args::{NodeArgs, ServeArgs, WorkerArgs};
use crate::train_args::DatagenArgs;

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
            rtd_image::create_dir_durably(&args.data)
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

/// Runs `rtd datagen --database URL`: queues the dataset's missing scenes, renders on
/// `--workers` in-process workers as well as any `rtd worker` nodes, and gathers the views
/// into the output directory until all are in or Ctrl-C.
pub fn datagen_on_queue(args: &DatagenArgs, url: &str, options: &DatasetOptions) -> anyhow::Result<()> {
    init_logging();
    let bar = TaskBar::new(args.quiet);
    let run = runtime()?.block_on(async {
        let db = Database::connect(url).await?;
        let (stop, stopped) = tokio::sync::watch::channel(false);
        let mut workers = Vec::new();
        if args.workers > 0 {
            let denoiser = Arc::new(Denoiser::builtin()?);
            for _ in 0..args.workers {
                let worker = Worker::new(db.clone(), denoiser.clone(), ServiceConfig::default())?;
                workers.push(tokio::spawn(worker.run(stopped.clone())));
            }
        } else {
            bar.note(&format!("queued on {}; start `rtd worker --database URL` on the render nodes", redact(url)));
        }
        let run = DatasetJob::new(db, &args.output).run(options, &bar).await;
        // In-process workers give their tasks back to the queue for the nodes.
        let _ = stop.send(true);
        for w in workers {
            let _ = w.await;
        }
        anyhow::Ok(run?)
    })?;
    bar.finish();
    let manifest = Manifest::load(&args.output)?;
    let summary = format!(
        "{}: {} views ({} validation), {} rejected",
        args.output.display(),
        manifest.views.len(),
        manifest.views.iter().filter(|v| v.validation).count(),
        manifest.rejected.len()
    );
    match run {
        DatasetRun::Complete { added, .. } => {
            eprintln!("{summary}; {added} added from the queue");
            Ok(())
        }
        DatasetRun::Interrupted { job, added } => {
            eprintln!("{summary}; {added} added from the queue");
            let kept = format!("job {job} stays queued; rerun the same command to gather the rest");
            Err(Interrupted(kept).into())
        }
    }
}
