//! `rtd datagen --database`: a training dataset whose scenes render on any number of render
//! nodes. The machine that owns the dataset directory queues one task per scene that still
//! lacks views, then adds each finished scene's views to the directory as workers complete
//! them ([`Manifest::add_shard`]), and marks the job done when every scene is in. The dataset
//! ends up the files and manifest of a one-machine `rtd datagen` with the same options.
//!
//! Nothing is lost or done twice: the job's key is written to `DIR/queue.json` before the job
//! is queued, so a coordinator killed at any point finds its job again when rerun; a shard's
//! bytes stay in the database until its views are in the manifest, and a shard added twice
//! adds nothing the second time.

use std::path::PathBuf;
use std::time::Duration;

use rtd_image::Progress;
use rtd_train::dataset::{DatasetOptions, Manifest, SceneShard};
use serde::{Deserialize, Serialize};
use sqlx::Row;

use crate::database::now_ms;
use crate::{Database, JobKey, JobStore, ServiceError};

/// The file in a dataset directory naming the job that renders it.
pub const QUEUE_FILE: &str = "queue.json";

/// What `DIR/queue.json` holds.
#[derive(Debug, Serialize, Deserialize)]
struct QueueRecord {
    /// The dataset job's key.
    job: String,
}

/// How a [`DatasetJob::run`] ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DatasetRun {
    /// Every view is in the dataset; the job (if one was needed) is marked done.
    Complete {
        /// The job that rendered the missing scenes, if any were missing.
        job: Option<JobKey>,
        /// Views added by this run.
        added: u64,
    },
    /// Stopped by the user; rerunning picks up the same job.
    Interrupted {
        /// The job still rendering.
        job: JobKey,
        /// Views added by this run.
        added: u64,
    },
}

/// The coordinator of a dataset rendered through the queue: start from [`DatasetJob::new`],
/// then [`DatasetJob::run`].
#[derive(Clone, Debug)]
pub struct DatasetJob {
    db: Database,
    dir: PathBuf,
    poll: Duration,
}

impl DatasetJob {
    /// A coordinator for the dataset in `dir` over `db`, polling every second.
    pub fn new(db: Database, dir: impl Into<PathBuf>) -> Self {
        DatasetJob { db, dir: dir.into(), poll: Duration::from_secs(1) }
    }

    /// Sets how often the queue is asked for finished scenes.
    pub fn poll(mut self, every: Duration) -> Self {
        self.poll = every;
        self
    }

    /// Makes (or resumes) the dataset of `options` in the directory: queues the scenes it
    /// lacks (or finds the job queued before), adds finished scenes as they come and returns
    /// when all are in, when the job fails (its error) or when `progress` is cancelled.
    pub async fn run(&self, options: &DatasetOptions, progress: &dyn Progress) -> Result<DatasetRun, ServiceError> {
        let _owner = self.lock_dir()?;
        let mut manifest = Manifest::open(&self.dir, options)?;
        progress.start(manifest.views_in_total(), "datagen");
        progress.inc(manifest.views_done());
        let Some(key) = self.find_or_queue(&manifest).await? else {
            self.unlock_dir();
            return Ok(DatasetRun::Complete { job: None, added: 0 });
        };
        let mut added = 0;
        loop {
            added += self.collect(&key, &mut manifest, progress).await?;
            let (state, left, error) = self.job_state(&key).await?;
            if state == "failed" {
                // Scenes that finished before the failure are kept.
                let kept = added + self.collect(&key, &mut manifest, progress).await?;
                self.forget_job()?;
                let why = error.unwrap_or_else(|| "a scene could not be rendered".into());
                return Err(ServiceError::Job(format!(
                    "{}: dataset job {key} failed: {why}; {kept} views were kept, and rerunning queues the \
                     missing scenes again",
                    self.dir.display()
                )));
            }
            if left == 0 {
                self.finish_job(&key).await?;
                self.forget_job()?;
                self.unlock_dir();
                return Ok(DatasetRun::Complete { job: Some(key), added });
            }
            if progress.cancelled() {
                return Ok(DatasetRun::Interrupted { job: key, added });
            }
            tokio::time::sleep(self.poll).await;
        }
    }

    /// An exclusive lock on the directory for this run: two coordinators gathering into one
    /// dataset would each save their own manifest over the other's.
    fn lock_dir(&self) -> Result<std::fs::File, ServiceError> {
        // Durably: the manifest written into it names this folder's views.
        rtd_image::create_dir_durably(&self.dir)
            .map_err(|e| ServiceError::io(format!("{}: cannot create", self.dir.display()), e))?;
        let path = self.lock_file();
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| ServiceError::io(format!("{}: cannot open", path.display()), e))?;
        match file.try_lock() {
            Ok(()) => Ok(file),
            Err(std::fs::TryLockError::WouldBlock) => Err(ServiceError::Config(format!(
                "{}: another rtd datagen is gathering into this dataset",
                self.dir.display()
            ))),
            Err(std::fs::TryLockError::Error(e)) => {
                Err(ServiceError::io(format!("{}: cannot lock", path.display()), e))
            }
        }
    }

    fn lock_file(&self) -> PathBuf {
        self.dir.join("datagen.lock")
    }

    /// Removes the lock file of a finished dataset, which is then the one-machine run's files.
    /// (The lock itself goes with the open file when [`DatasetJob::run`] returns.)
    fn unlock_dir(&self) {
        let _ = std::fs::remove_file(self.lock_file());
    }

    fn queue_file(&self) -> PathBuf {
        self.dir.join(QUEUE_FILE)
    }

    /// The job rendering this dataset: the one `queue.json` names, else a new one for the
    /// scenes the manifest lacks (`None` if it lacks none). The key is written before the job
    /// is queued, so a coordinator killed in between queues the same job when rerun.
    async fn find_or_queue(&self, manifest: &Manifest) -> Result<Option<JobKey>, ServiceError> {
        let options_json =
            serde_json::to_string(&manifest.options).map_err(|e| ServiceError::Corrupt(e.to_string()))?;
        if let Some(key) = self.recorded_job()? {
            match self.job_options(&key).await? {
                Some(stored) if stored == manifest.options => return Ok(Some(key)),
                Some(_) => {
                    return Err(ServiceError::Config(format!(
                        "{}: job {key} renders this dataset with other options; rerun with those to finish it, \
                         or delete the file to drop it",
                        self.queue_file().display()
                    )))
                }
                // Queued from this file but never committed: queue it now under the same key.
                None => {}
            }
        }
        let scenes = manifest.scenes_to_render();
        if scenes.is_empty() {
            self.forget_job()?;
            return Ok(None);
        }
        let key = match self.recorded_job()? {
            Some(k) => k,
            None => JobKey::generate().map_err(ServiceError::Random)?,
        };
        let record = QueueRecord { job: key.to_string() };
        rtd_image::write_json(&self.queue_file(), &record).map_err(rtd_train::TrainError::from)?;
        JobStore::new(self.db.clone()).create_dataset(&key, &options_json, &scenes).await?;
        Ok(Some(key))
    }

    /// The key `queue.json` names, if the file exists.
    fn recorded_job(&self) -> Result<Option<JobKey>, ServiceError> {
        let path = self.queue_file();
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(ServiceError::io(format!("{}: cannot read", path.display()), e)),
        };
        let corrupt =
            || ServiceError::Config(format!("{}: not a queue record; delete it to queue anew", path.display()));
        let record: QueueRecord = serde_json::from_str(&text).map_err(|_| corrupt())?;
        JobKey::parse(&record.job).map(Some).ok_or_else(corrupt)
    }

    /// Removes `queue.json`: the job is finished or failed.
    fn forget_job(&self) -> Result<(), ServiceError> {
        match std::fs::remove_file(self.queue_file()) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                Err(ServiceError::io(format!("{}: cannot remove", self.queue_file().display()), e))
            }
            _ => Ok(()),
        }
    }

    /// The options dataset job `key` was queued with, or `None` if there is no such job.
    async fn job_options(&self, key: &JobKey) -> Result<Option<DatasetOptions>, ServiceError> {
        let row = sqlx::query("SELECT params FROM jobs WHERE key = $1 AND kind = 'dataset'")
            .bind(key.as_str())
            .fetch_optional(&self.db.pool)
            .await?;
        row.map(|r| {
            let text: String = r.try_get(0)?;
            serde_json::from_str(&text).map_err(|e| ServiceError::Corrupt(format!("dataset options: {e}")))
        })
        .transpose()
    }

    /// Adds every finished, not yet collected scene of job `key` to the dataset, one at a
    /// time, and drops each shard's bytes from the database once its views are saved.
    /// Returns the views added. Needs tokio's multi-threaded runtime (the files are written
    /// in place, with `block_in_place`).
    async fn collect(
        &self,
        key: &JobKey,
        manifest: &mut Manifest,
        progress: &dyn Progress,
    ) -> Result<u64, ServiceError> {
        let mut added = 0;
        loop {
            let row = sqlx::query(
                "SELECT id, output FROM tasks WHERE job_key = $1 AND kind = 'dataset_scene' AND state = 'done' \
                 AND output IS NOT NULL ORDER BY id LIMIT 1",
            )
            .bind(key.as_str())
            .fetch_optional(&self.db.pool)
            .await?;
            let Some(row) = row else { return Ok(added) };
            let (id, bytes): (i64, Vec<u8>) = (row.try_get(0)?, row.try_get(1)?);
            let shard: SceneShard =
                postcard::from_bytes(&bytes).map_err(|e| ServiceError::Corrupt(format!("task {id}'s scene: {e}")))?;
            let n = tokio::task::block_in_place(|| manifest.add_shard(&self.dir, &shard, progress))?;
            progress.inc(n);
            added += n;
            sqlx::query("UPDATE tasks SET output = NULL WHERE id = $1").bind(id).execute(&self.db.pool).await?;
        }
    }

    /// Job `key`'s state, how many of its tasks are not done or not yet collected, and its error.
    async fn job_state(&self, key: &JobKey) -> Result<(String, i64, Option<String>), ServiceError> {
        let row = sqlx::query("SELECT state, error FROM jobs WHERE key = $1")
            .bind(key.as_str())
            .fetch_optional(&self.db.pool)
            .await?
            .ok_or_else(|| ServiceError::Job(format!("dataset job {key} is no longer in the database")))?;
        let left: i64 =
            sqlx::query("SELECT COUNT(*) FROM tasks WHERE job_key = $1 AND (state <> 'done' OR output IS NOT NULL)")
                .bind(key.as_str())
                .fetch_one(&self.db.pool)
                .await?
                .try_get(0)?;
        Ok((row.try_get(0)?, left, row.try_get(1)?))
    }

    /// Marks job `key` done: every scene is in the dataset.
    async fn finish_job(&self, key: &JobKey) -> Result<(), ServiceError> {
        sqlx::query("UPDATE jobs SET state = 'done', finished_ms = $1 WHERE key = $2 AND state <> 'done'")
            .bind(now_ms())
            .bind(key.as_str())
            .execute(&self.db.pool)
            .await?;
        Ok(())
    }
}
