//! A render node: claims tasks from the queue, works on them on a blocking thread while a
//! timer renews the lease and publishes progress, and stores the result. Workers know nothing
//! of each other; any number may run against one database.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use rtd_denoise::Denoiser;
use tokio::sync::watch;
use tracing::{info, warn};

use crate::config::MAX_ATTEMPTS;
use crate::execute::{execute, TaskInputs, TaskProgress};
use crate::queue::{Claim, JobQueue, TaskKind, TaskOutput};
use crate::{Database, JobKey, ServiceConfig, ServiceError};

/// How often a worker records that it is alive while idle.
const HEARTBEAT: Duration = Duration::from_secs(5);
/// How long storing a result is retried while the database is unreachable.
const STORE_RETRY: Duration = Duration::from_secs(60);
/// The longest one call to the database may take before it is abandoned (a connection left
/// half-open by a network fault can otherwise wait forever). Reading a finishing task's films
/// or storing a result moves the most data; this leaves them minutes.
const QUERY_TIMEOUT: Duration = Duration::from_secs(180);

/// `call`, or a timeout error after [`QUERY_TIMEOUT`].
async fn bounded<T>(call: impl Future<Output = Result<T, ServiceError>>) -> Result<T, ServiceError> {
    tokio::time::timeout(QUERY_TIMEOUT, call)
        .await
        .unwrap_or_else(|_| Err(ServiceError::io("the database did not answer", std::io::ErrorKind::TimedOut.into())))
}

/// One worker: a loop that takes one task at a time.
pub struct Worker {
    queue: JobQueue,
    id: String,
    host: String,
    denoiser: Arc<Denoiser>,
    config: ServiceConfig,
}

/// How a claimed task ended.
#[derive(Debug, PartialEq, Eq)]
enum Outcome {
    Completed,
    Failed,
    /// The lease was lost: another worker has the task now.
    Lost,
    /// Given back to the queue on shutdown.
    Released,
}

impl Worker {
    /// A worker on `db` with `denoiser`, named after this host and process with a random tag.
    pub fn new(db: Database, denoiser: Arc<Denoiser>, config: ServiceConfig) -> Result<Self, ServiceError> {
        let host = std::env::var("HOSTNAME")
            .ok()
            .or_else(|| std::fs::read_to_string("/etc/hostname").ok().map(|h| h.trim().to_string()))
            .filter(|h| !h.is_empty())
            .unwrap_or_else(|| "localhost".into());
        let tag = JobKey::generate().map_err(ServiceError::Random)?;
        let id = format!("{host}-{}-{}", std::process::id(), &tag.as_str()[..8]);
        Ok(Worker { queue: JobQueue::new(db), id, host, denoiser, config })
    }

    /// The worker's name, as stored with the tasks it completes.
    pub fn id(&self) -> &str {
        &self.id
    }

    /// Works until `shutdown` turns true: a task in flight is then stopped between passes and
    /// given back to the queue for another worker. Database outages are waited out.
    pub async fn run(self, mut shutdown: watch::Receiver<bool>) {
        info!(worker = %self.id, "worker started");
        let mut last_beat = None::<tokio::time::Instant>;
        while !*shutdown.borrow() {
            if last_beat.is_none_or(|t| t.elapsed() >= HEARTBEAT) {
                match bounded(self.queue.heartbeat(&self.id, &self.host)).await {
                    Ok(()) => last_beat = Some(tokio::time::Instant::now()),
                    Err(e) => warn!(worker = %self.id, error = %e, "heartbeat failed"),
                }
            }
            let claim = match bounded(self.queue.claim(&self.id, self.lease_ms())).await {
                Ok(c) => c,
                Err(e) => {
                    warn!(worker = %self.id, error = %e, "cannot reach the queue; retrying");
                    None
                }
            };
            match claim {
                Some(claim) => {
                    let outcome = self.work_on(&claim, &mut shutdown).await;
                    info!(worker = %self.id, task = claim.id, job = %claim.job, ?outcome, "task ended");
                }
                None => {
                    tokio::select! {
                        _ = tokio::time::sleep(self.config.poll) => {}
                        _ = shutdown.changed() => {}
                    }
                }
            }
        }
        info!(worker = %self.id, "worker stopped");
    }

    fn lease_ms(&self) -> i64 {
        self.config.lease.as_millis() as i64
    }

    /// Works on one claimed task to its end.
    async fn work_on(&self, claim: &Claim, shutdown: &mut watch::Receiver<bool>) -> Outcome {
        if claim.attempt > MAX_ATTEMPTS {
            let why =
                format!("The job was given up after {MAX_ATTEMPTS} attempts, each ended by a worker that stopped");
            return self.store_failure(claim, &why).await;
        }
        let inputs = match bounded(self.fetch(claim)).await {
            Ok(i) => i,
            Err(e) => {
                // The database went away between claim and fetch: give the task back if it
                // can be reached again, else the lease runs out.
                warn!(worker = %self.id, error = %e, "cannot read the task's inputs");
                return self.release(claim).await;
            }
        };
        // Fetching may have taken a while (a finishing task reads every range's film).
        let _ = bounded(self.queue.renew(claim, self.lease_ms(), 0.0)).await;
        let progress = Arc::new(TaskProgress::default());
        let work = {
            let (claim, progress, denoiser, threads) =
                (claim.clone(), progress.clone(), self.denoiser.clone(), self.config.threads);
            tokio::task::spawn_blocking(move || execute(&claim, &inputs, &denoiser, threads, &progress))
        };
        tokio::pin!(work);
        let mut renew = tokio::time::interval(self.config.lease / 4);
        renew.tick().await;
        let (mut lost, mut stopping) = (false, false);
        let result = loop {
            tokio::select! {
                r = &mut work => break r,
                // A renewal that hangs (a half-open connection) is abandoned at the next tick.
                _ = renew.tick() => match tokio::time::timeout(
                    self.config.lease / 4,
                    self.queue.renew(claim, self.lease_ms(), progress.fraction()),
                ).await {
                    Ok(Ok(true)) => {}
                    Ok(Ok(false)) => { lost = true; progress.stop(); }
                    Ok(Err(e)) => warn!(worker = %self.id, error = %e, "cannot renew the lease"),
                    Err(_) => warn!(worker = %self.id, "renewing the lease timed out"),
                },
                _ = shutdown.changed(), if !stopping => { stopping = true; progress.stop(); }
            }
        };
        if lost {
            return Outcome::Lost;
        }
        match result {
            Err(join) => {
                tracing::error!(worker = %self.id, error = %join, "the task's thread failed");
                self.store_failure(claim, "The render node failed on this job").await
            }
            Ok(Ok(output)) => {
                // Keep the claim alive while storing (the retries below can outlast a lease).
                let _ = bounded(self.queue.renew(claim, self.lease_ms(), 1.0)).await;
                self.store(claim, output).await
            }
            Ok(Err(_)) if stopping => self.release(claim).await,
            Ok(Err(e)) => self.store_failure(claim, &sentence(&e)).await,
        }
    }

    async fn fetch(&self, claim: &Claim) -> Result<TaskInputs, ServiceError> {
        let files = self.queue.inputs(&claim.job).await?;
        let params = self.queue.params(&claim.job).await?;
        let films = match claim.kind {
            TaskKind::RenderFinish => self.queue.range_films(&claim.job).await?,
            _ => Vec::new(),
        };
        Ok(TaskInputs { files, params, films })
    }

    /// Stores the output, retrying while the database is unreachable.
    async fn store(&self, claim: &Claim, output: TaskOutput) -> Outcome {
        let deadline = tokio::time::Instant::now() + STORE_RETRY;
        loop {
            match bounded(self.queue.complete(claim, output.clone())).await {
                Ok(true) => return Outcome::Completed,
                Ok(false) => return Outcome::Lost,
                Err(e) if tokio::time::Instant::now() < deadline => {
                    warn!(worker = %self.id, error = %e, "cannot store the result; retrying");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    let _ = bounded(self.queue.renew(claim, self.lease_ms(), 1.0)).await;
                }
                Err(e) => {
                    warn!(worker = %self.id, error = %e, "giving up storing the result; the lease will run out");
                    return Outcome::Lost;
                }
            }
        }
    }

    async fn store_failure(&self, claim: &Claim, why: &str) -> Outcome {
        match bounded(self.queue.fail(claim, why)).await {
            Ok(true) => Outcome::Failed,
            Ok(false) => Outcome::Lost,
            Err(e) => {
                warn!(worker = %self.id, error = %e, "cannot record the failure; the lease will run out");
                Outcome::Lost
            }
        }
    }

    async fn release(&self, claim: &Claim) -> Outcome {
        if let Err(e) = bounded(self.queue.release(claim)).await {
            warn!(worker = %self.id, error = %e, "cannot give the task back; its lease will run out");
        }
        Outcome::Released
    }
}

/// An error as one sentence for the job's user.
fn sentence(e: &ServiceError) -> String {
    let mut s = e.to_string().replace('\n', " ");
    if let Some(first) = s.get(..1) {
        s = first.to_uppercase() + &s[1..];
    }
    s
}
