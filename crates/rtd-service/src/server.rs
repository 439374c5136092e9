//! `rtd serve` and `rtd worker` as library calls: the HTTP server with its in-process workers
//! and retention sweep, or a worker alone, each stopped by a shutdown signal.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::ConnectInfo;
use axum::http::Request;
use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioExecutor, TokioIo, TokioTimer};
use hyper_util::server::conn::auto::Builder;
use hyper_util::server::graceful::GracefulShutdown;
use hyper_util::service::TowerToHyperService;
use rtd_denoise::Denoiser;
use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tower::ServiceExt;

use crate::api::{router, AppState};
use crate::database::now_ms;
use crate::jobs::JobStore;
use crate::{Database, ServiceConfig, ServiceError, Worker};

/// How often finished jobs past their keeping time are deleted.
const RETENTION_SWEEP: Duration = Duration::from_secs(60);

/// A server that is running: its address, and the handle that stops it.
pub struct RunningServer {
    /// The address it listens on.
    pub addr: SocketAddr,
    stop: watch::Sender<bool>,
    task: JoinHandle<Result<(), ServiceError>>,
}

impl RunningServer {
    /// Stops taking requests, lets those in flight finish, gives running tasks back to the
    /// queue and waits for it all.
    pub async fn shutdown(self) -> Result<(), ServiceError> {
        let _ = self.stop.send(true);
        self.wait().await
    }

    /// Waits until the server stops (on its shutdown signal).
    pub async fn wait(self) -> Result<(), ServiceError> {
        self.task.await.map_err(|e| ServiceError::Config(format!("the server task failed: {e}")))?
    }
}

/// Serves the API and pages on `listener` from `db`, with `workers` in-process workers using
/// `denoiser`, until [`RunningServer::shutdown`] or until `signal` completes.
pub async fn start_server(
    listener: TcpListener,
    db: Database,
    workers: usize,
    denoiser: Arc<Denoiser>,
    config: ServiceConfig,
    signal: impl Future<Output = ()> + Send + 'static,
) -> Result<RunningServer, ServiceError> {
    let addr = listener.local_addr().map_err(|e| ServiceError::io("cannot read the listening address", e))?;
    let (stop, stopped) = watch::channel(false);
    let state = AppState::new(JobStore::new(db.clone()), config.clone());
    let mut handles = Vec::new();
    for _ in 0..workers {
        let worker = Worker::new(db.clone(), denoiser.clone(), config.clone())?;
        handles.push(tokio::spawn(worker.run(stopped.clone())));
    }
    handles.push(tokio::spawn(retention(JobStore::new(db), config.keep, stopped.clone())));
    {
        let (state, mut stopped) = (state.clone(), stopped.clone());
        handles.push(tokio::spawn(async move {
            loop {
                tokio::select! {
                    _ = tokio::time::sleep(RETENTION_SWEEP) => state.forget_idle_clients(),
                    _ = stopped.wait_for(|s| *s) => return,
                }
            }
        }));
    }
    let stop_on_signal = stop.clone();
    tokio::spawn(async move {
        signal.await;
        let _ = stop_on_signal.send(true);
    });
    let app = router(state.clone());
    let mut http_stopped = stopped.clone();
    let task = tokio::spawn(async move {
        let stop = async move {
            let _ = http_stopped.wait_for(|s| *s).await;
            state.stop_accepting();
        };
        serve_http(listener, app, config.upload_timeout, stop).await;
        for h in handles {
            let _ = h.await;
        }
        Ok(())
    });
    Ok(RunningServer { addr, stop, task })
}

/// Serves `app` on `listener` until `stop` completes, then lets the requests in flight
/// finish. Each connection is HTTP/1.1 through hyper, with `header_timeout` to send a
/// request's headers (a client that trickles them in, as in slowloris, is cut off); the
/// router sees the peer's address as [`ConnectInfo`].
async fn serve_http(listener: TcpListener, app: Router, header_timeout: Duration, stop: impl Future<Output = ()>) {
    let graceful = GracefulShutdown::new();
    let mut builder = Builder::new(TokioExecutor::new()).http1_only();
    builder.http1().timer(TokioTimer::new()).header_read_timeout(header_timeout);
    tokio::pin!(stop);
    loop {
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(a) => a,
                Err(e) => {
                    // Out of file descriptors and the like: wait for some to be freed.
                    tracing::warn!(error = %e, "cannot accept a connection");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            _ = &mut stop => break,
        };
        let service = app.clone().map_request(move |mut req: Request<Incoming>| {
            req.extensions_mut().insert(ConnectInfo(peer));
            req
        });
        let conn = builder.serve_connection(TokioIo::new(stream), TowerToHyperService::new(service)).into_owned();
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            if let Err(e) = conn.await {
                tracing::debug!(error = %e, "connection ended with an error");
            }
        });
    }
    drop(listener);
    graceful.shutdown().await;
}

/// Runs one worker on `db` until `signal` completes; the task in flight is given back.
pub async fn run_worker(
    db: Database,
    denoiser: Arc<Denoiser>,
    config: ServiceConfig,
    signal: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServiceError> {
    let (stop, stopped) = watch::channel(false);
    let worker = Worker::new(db, denoiser, config)?;
    tracing::info!(worker = worker.id(), "render node ready");
    tokio::spawn(async move {
        signal.await;
        let _ = stop.send(true);
    });
    worker.run(stopped).await;
    Ok(())
}

/// Deletes finished jobs older than `keep`, at start and then every minute.
async fn retention(store: JobStore, keep: Duration, mut stopped: watch::Receiver<bool>) {
    loop {
        match store.purge_before(now_ms() - keep.as_millis() as i64).await {
            Ok(0) => {}
            Ok(n) => tracing::info!(jobs = n, "deleted jobs past their keeping time"),
            Err(e) => tracing::warn!(error = %e, "retention sweep failed"),
        }
        tokio::select! {
            _ = tokio::time::sleep(RETENTION_SWEEP) => {}
            _ = stopped.wait_for(|s| *s) => return,
        }
    }
}

/// Completes on Ctrl-C or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
    tracing::info!("shutting down: no new uploads; running tasks go back to the queue");
}
