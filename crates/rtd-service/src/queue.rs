//! The job queue: tasks claimed with a lease, renewed while worked on, completed exactly once.
//!
//! A claim is one `UPDATE … WHERE id = (SELECT … LIMIT 1)` statement. On PostgreSQL the
//! inner select takes `FOR UPDATE SKIP LOCKED`, so concurrent workers on many machines each
//! get a different task without waiting on each other; SQLite runs one writer at a time, so
//! the statement is atomic there as it stands. A task whose lease has run out (its worker died)
//! is claimable again. Every later write names the claim (worker and attempt), so a worker
//! that lost its lease cannot complete, fail or renew a task someone else now holds.

use sqlx::Row;

use crate::database::{lock_job, now_ms, Backend, Database};
use crate::jobs::Input;
use crate::{JobKey, ServiceError};

/// What a task does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TaskKind {
    /// Denoise a job's uploaded images.
    Denoise,
    /// Render one sample range of a job's scene.
    RenderRange,
    /// Merge a render's ranges, run the guide pass and the denoiser.
    RenderFinish,
    /// Render every view of one scene of a dataset (`rtd datagen --database`).
    DatasetScene,
}

impl TaskKind {
    /// The task kind named `s` in the database.
    fn parse(s: &str) -> Result<Self, ServiceError> {
        match s {
            "denoise" => Ok(TaskKind::Denoise),
            "render_range" => Ok(TaskKind::RenderRange),
            "render_finish" => Ok(TaskKind::RenderFinish),
            "dataset_scene" => Ok(TaskKind::DatasetScene),
            other => Err(ServiceError::Corrupt(format!("task kind {other:?}"))),
        }
    }
}

/// A task this worker holds the lease on.
#[derive(Clone, Debug)]
pub struct Claim {
    /// The task's id.
    pub id: i64,
    /// The job it belongs to.
    pub job: JobKey,
    /// What to do.
    pub kind: TaskKind,
    /// First sample index (render ranges).
    pub first_sample: u32,
    /// Samples (render ranges; the whole spp for the finishing task).
    pub samples: u32,
    /// The scene's index (dataset scenes).
    pub scene: u64,
    /// Which claim of this task this is (1 for the first).
    pub attempt: i64,
    /// The worker holding it.
    pub worker: String,
}

/// A finished task's product.
#[derive(Clone, Debug)]
pub enum TaskOutput {
    /// A render range's film, encoded.
    Film(Vec<u8>),
    /// A dataset scene's views ([`rtd_train::dataset::SceneShard`]), encoded; kept until the
    /// dataset's owner has added them to its directory.
    Shard(Vec<u8>),
    /// The job's result.
    Result {
        /// Multilayer EXR.
        exr: Vec<u8>,
        /// Tonemapped PNG.
        png: Vec<u8>,
        /// The noisy input, tonemapped.
        input_png: Vec<u8>,
        /// Seconds per stage, as JSON.
        timings: String,
        /// Image size.
        size: (u32, u32),
    },
}

/// The claim a `RETURNING id, job_key, kind, first_sample, samples, attempts, scene` row gives
/// `worker`.
fn read_claim(row: &sqlx::any::AnyRow, worker: &str) -> Result<Claim, ServiceError> {
    let key: String = row.try_get(1)?;
    Ok(Claim {
        id: row.try_get(0)?,
        job: JobKey::parse(&key).ok_or_else(|| ServiceError::Corrupt(format!("job key {key:?}")))?,
        kind: TaskKind::parse(&row.try_get::<String, _>(2)?)?,
        first_sample: u32::try_from(row.try_get::<i64, _>(3)?).map_err(|e| ServiceError::Corrupt(e.to_string()))?,
        samples: u32::try_from(row.try_get::<i64, _>(4)?).map_err(|e| ServiceError::Corrupt(e.to_string()))?,
        attempt: row.try_get(5)?,
        scene: u64::try_from(row.try_get::<Option<i64>, _>(6)?.unwrap_or(0))
            .map_err(|e| ServiceError::Corrupt(e.to_string()))?,
        worker: worker.to_string(),
    })
}

/// The queue over a [`Database`].
#[derive(Clone, Debug)]
pub struct JobQueue {
    db: Database,
}

impl JobQueue {
    /// The queue in `db`.
    pub fn new(db: Database) -> Self {
        JobQueue { db }
    }

    /// Claims the oldest claimable task for `worker` until `lease_ms` from now, or `None`.
    pub async fn claim(&self, worker: &str, lease_ms: i64) -> Result<Option<Claim>, ServiceError> {
        let lock = match self.db.backend {
            Backend::Postgres => " FOR UPDATE SKIP LOCKED",
            Backend::Sqlite => "",
        };
        let now = now_ms();
        let sql = format!(
            "UPDATE tasks SET state = 'running', worker = $1, lease_until_ms = $2, attempts = attempts + 1, progress = 0 \
             WHERE id = (SELECT id FROM tasks WHERE state = 'queued' OR (state = 'running' AND lease_until_ms < $3) \
             ORDER BY id LIMIT 1{lock}) \
             RETURNING id, job_key, kind, first_sample, samples, attempts, scene"
        );
        // One transaction: the task and its job change together, or neither does.
        let mut tx = self.db.pool.begin().await?;
        let row = sqlx::query(&sql).bind(worker).bind(now + lease_ms).bind(now).fetch_optional(&mut *tx).await?;
        let Some(row) = row else { return Ok(None) };
        let (id, key): (i64, String) = (row.try_get(0)?, row.try_get(1)?);
        let claim = read_claim(&row, worker);
        match &claim {
            Ok(_) => {
                sqlx::query("UPDATE jobs SET state = 'running', started_ms = $1 WHERE key = $2 AND state = 'queued'")
                    .bind(now)
                    .bind(key)
                    .execute(&mut *tx)
                    .await?;
            }
            Err(e) => {
                // A row no worker can read fails with its job, instead of being claimed again
                // every lease.
                let why = "The job's record is damaged and cannot be worked on";
                tracing::error!(task = id, error = %e, "failing an unreadable task");
                // The whole job stops, as `fail` stops it: no other task of it runs.
                sqlx::query(
                    "UPDATE tasks SET state = 'failed', lease_until_ms = NULL \
                     WHERE id = $1 OR (job_key = $2 AND state IN ('queued', 'waiting'))",
                )
                .bind(id)
                .bind(key.clone())
                .execute(&mut *tx)
                .await?;
                sqlx::query("UPDATE jobs SET state = 'failed', error = $1, finished_ms = $2 WHERE key = $3")
                    .bind(why)
                    .bind(now)
                    .bind(key)
                    .execute(&mut *tx)
                    .await?;
            }
        }
        tx.commit().await?;
        claim.map(Some)
    }

    /// Extends the lease by `lease_ms` and records `progress`; false if the lease was lost
    /// (the task timed out and another worker took it, or the job is gone).
    pub async fn renew(&self, claim: &Claim, lease_ms: i64, progress: f64) -> Result<bool, ServiceError> {
        let done = sqlx::query(
            "UPDATE tasks SET lease_until_ms = $1, progress = $2 \
             WHERE id = $3 AND worker = $4 AND attempts = $5 AND state = 'running'",
        )
        .bind(now_ms() + lease_ms)
        .bind(progress.clamp(0.0, 1.0))
        .bind(claim.id)
        .bind(claim.worker.clone())
        .bind(claim.attempt)
        .execute(&self.db.pool)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    /// The job's uploaded files.
    pub async fn inputs(&self, job: &JobKey) -> Result<Vec<Input>, ServiceError> {
        let rows = sqlx::query("SELECT name, format, data FROM inputs WHERE job_key = $1 ORDER BY name")
            .bind(job.as_str())
            .fetch_all(&self.db.pool)
            .await?;
        rows.iter().map(|r| Ok(Input { name: r.try_get(0)?, format: r.try_get(1)?, data: r.try_get(2)? })).collect()
    }

    /// The job's render parameters as stored (JSON).
    pub async fn params(&self, job: &JobKey) -> Result<String, ServiceError> {
        Ok(sqlx::query("SELECT params FROM jobs WHERE key = $1")
            .bind(job.as_str())
            .fetch_one(&self.db.pool)
            .await?
            .try_get(0)?)
    }

    /// The films of the job's finished render ranges, in sample order.
    pub async fn range_films(&self, job: &JobKey) -> Result<Vec<Vec<u8>>, ServiceError> {
        let rows = sqlx::query(
            "SELECT output FROM tasks WHERE job_key = $1 AND kind = 'render_range' AND state = 'done' ORDER BY first_sample",
        )
        .bind(job.as_str())
        .fetch_all(&self.db.pool)
        .await?;
        rows.iter().map(|r| Ok(r.try_get::<Vec<u8>, _>(0)?)).collect()
    }

    /// Completes the claimed task with `output`, in one transaction: a render range's film is
    /// kept, and the last range makes the finishing task claimable; a job's result marks the job
    /// done. False (and nothing written) if the claim was lost, so a task completes exactly once.
    pub async fn complete(&self, claim: &Claim, output: TaskOutput) -> Result<bool, ServiceError> {
        let now = now_ms();
        let mut tx = self.db.pool.begin().await?;
        // Locked first, so the last range is seen as last by exactly one completion.
        lock_job(&mut tx, claim.job.as_str()).await?;
        let kept = match &output {
            TaskOutput::Film(bytes) | TaskOutput::Shard(bytes) => Some(bytes.clone()),
            TaskOutput::Result { .. } => None,
        };
        let mine = sqlx::query(
            "UPDATE tasks SET state = 'done', progress = 1, output = $1, completed_by = $2, lease_until_ms = NULL \
             WHERE id = $3 AND worker = $2 AND attempts = $4 AND state = 'running'",
        )
        .bind(kept)
        .bind(claim.worker.clone())
        .bind(claim.id)
        .bind(claim.attempt)
        .execute(&mut *tx)
        .await?;
        if mine.rows_affected() != 1 {
            tx.rollback().await?;
            return Ok(false);
        }
        match output {
            // The dataset's owner collects shards and marks the job done ([`crate::DatasetJob`]).
            TaskOutput::Shard(_) => {}
            TaskOutput::Film(_) => {
                let left: i64 = sqlx::query(
                    "SELECT COUNT(*) FROM tasks WHERE job_key = $1 AND kind = 'render_range' AND state <> 'done'",
                )
                .bind(claim.job.as_str())
                .fetch_one(&mut *tx)
                .await?
                .try_get(0)?;
                if left == 0 {
                    sqlx::query("UPDATE tasks SET state = 'queued' WHERE job_key = $1 AND kind = 'render_finish' AND state = 'waiting'")
                        .bind(claim.job.as_str())
                        .execute(&mut *tx)
                        .await?;
                }
            }
            TaskOutput::Result { exr, png, input_png, timings, size } => {
                sqlx::query(
                    "UPDATE jobs SET state = 'done', finished_ms = $1, result_exr = $2, result_png = $3, input_png = $4, \
                     timings = $5, width = $6, height = $7 WHERE key = $8 AND state <> 'failed'",
                )
                .bind(now)
                .bind(exr)
                .bind(png)
                .bind(input_png)
                .bind(timings)
                .bind(size.0 as i64)
                .bind(size.1 as i64)
                .bind(claim.job.as_str())
                .execute(&mut *tx)
                .await?;
                // The ranges' films are not needed once the result exists.
                sqlx::query("UPDATE tasks SET output = NULL WHERE job_key = $1")
                    .bind(claim.job.as_str())
                    .execute(&mut *tx)
                    .await?;
            }
        }
        sqlx::query("UPDATE workers SET tasks_done = tasks_done + 1, last_seen_ms = $1 WHERE id = $2")
            .bind(now)
            .bind(claim.worker.clone())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// Fails the claimed task and its job with `error` (one sentence for the user); the job's
    /// other tasks are dropped. False if the claim was lost.
    pub async fn fail(&self, claim: &Claim, error: &str) -> Result<bool, ServiceError> {
        let mut tx = self.db.pool.begin().await?;
        lock_job(&mut tx, claim.job.as_str()).await?;
        let mine = sqlx::query(
            "UPDATE tasks SET state = 'failed', lease_until_ms = NULL WHERE id = $1 AND worker = $2 AND attempts = $3 AND state = 'running'",
        )
        .bind(claim.id)
        .bind(claim.worker.clone())
        .bind(claim.attempt)
        .execute(&mut *tx)
        .await?;
        if mine.rows_affected() != 1 {
            tx.rollback().await?;
            return Ok(false);
        }
        // The job's other tasks stop too: queued ones are dropped, running ones lose their lease.
        sqlx::query(
            "UPDATE tasks SET state = 'failed' WHERE job_key = $1 AND state IN ('queued', 'waiting', 'running')",
        )
        .bind(claim.job.as_str())
        .execute(&mut *tx)
        .await?;
        sqlx::query(
            "UPDATE jobs SET state = 'failed', error = $1, finished_ms = $2 WHERE key = $3 AND state <> 'failed'",
        )
        .bind(error)
        .bind(now_ms())
        .bind(claim.job.as_str())
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// Gives the claimed task back to the queue unfinished (a worker shutting down), without
    /// counting the attempt.
    pub async fn release(&self, claim: &Claim) -> Result<(), ServiceError> {
        sqlx::query(
            "UPDATE tasks SET state = 'queued', worker = NULL, lease_until_ms = NULL, attempts = attempts - 1, progress = 0 \
             WHERE id = $1 AND worker = $2 AND attempts = $3 AND state = 'running'",
        )
        .bind(claim.id)
        .bind(claim.worker.clone())
        .bind(claim.attempt)
        .execute(&self.db.pool)
        .await?;
        Ok(())
    }

    /// Records that `worker` on `host` is alive.
    pub async fn heartbeat(&self, worker: &str, host: &str) -> Result<(), ServiceError> {
        let now = now_ms();
        sqlx::query(
            "INSERT INTO workers (id, host, started_ms, last_seen_ms) VALUES ($1, $2, $3, $3) \
             ON CONFLICT (id) DO UPDATE SET last_seen_ms = excluded.last_seen_ms",
        )
        .bind(worker)
        .bind(host)
        .bind(now)
        .execute(&self.db.pool)
        .await?;
        Ok(())
    }

    /// Which worker completed each of the job's tasks, in task order (for tests and audits).
    pub async fn completed_by(&self, job: &JobKey) -> Result<Vec<(String, Option<String>, i64)>, ServiceError> {
        let rows = sqlx::query("SELECT kind, completed_by, attempts FROM tasks WHERE job_key = $1 ORDER BY id")
            .bind(job.as_str())
            .fetch_all(&self.db.pool)
            .await?;
        rows.iter().map(|r| Ok((r.try_get(0)?, r.try_get(1)?, r.try_get(2)?))).collect()
    }
}
