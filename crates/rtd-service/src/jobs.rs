//! Job records: creating a job with its inputs and tasks in one transaction, reading its
//! state and results, ratings, the counts `/metrics` shows, and retention.

use serde::{Deserialize, Serialize};
use sqlx::Row;

use crate::config::MAX_RANGES_PER_JOB;
use crate::database::{now_ms, Backend, Database};
use crate::{JobKey, ServiceError};

/// What a job does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JobKind {
    /// Denoise an uploaded noisy image with its guide.
    Denoise,
    /// Render an uploaded scene, split into sample ranges, then denoise it.
    Render,
    /// Render a training dataset's scenes (`rtd datagen --database`), one task per scene.
    Dataset,
}

impl JobKind {
    /// The name stored and shown.
    pub fn as_str(self) -> &'static str {
        match self {
            JobKind::Denoise => "denoise",
            JobKind::Render => "render",
            JobKind::Dataset => "dataset",
        }
    }
    /// The kind named `s`.
    pub fn parse(s: &str) -> Result<Self, ServiceError> {
        match s {
            "denoise" => Ok(JobKind::Denoise),
            "render" => Ok(JobKind::Render),
            "dataset" => Ok(JobKind::Dataset),
            other => Err(ServiceError::Corrupt(format!("job kind {other:?}"))),
        }
    }
}

/// A render job's settings (a denoise job has none), stored as JSON.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RenderParams {
    /// Samples per pixel.
    pub spp: u32,
    /// Image width, if given.
    pub width: Option<u32>,
    /// Image height, if given.
    pub height: Option<u32>,
    /// Camera name or index, if given.
    pub camera: Option<String>,
}

/// One uploaded file.
#[derive(Clone, Debug)]
pub struct Input {
    /// The form field it came in (`color`, `guide`, `albedo`, `normal`, `scene`).
    pub name: String,
    /// Its extension as judged from its bytes (`exr`, `png`, `jpg`, `glb`, `gltf`).
    pub format: String,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// A checked upload, ready to be queued.
#[derive(Clone, Debug)]
pub struct NewJob {
    /// What it does.
    pub kind: JobKind,
    /// Render settings (default for a denoise job).
    pub params: RenderParams,
    /// The user's name, if given.
    pub name: Option<String>,
    /// The user's e-mail, if given.
    pub email: Option<String>,
    /// The client address it came from.
    pub client: Option<String>,
    /// Image size, when known from the upload (0 until a render job has loaded its scene).
    pub size: (u32, u32),
    /// The files.
    pub inputs: Vec<Input>,
}

/// A job's rating by its user.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Rating {
    /// 1 to 5.
    pub rating: i64,
    /// Free text.
    pub comment: Option<String>,
}

/// What `GET /api/jobs/{key}` answers.
#[derive(Clone, Debug, Serialize)]
pub struct JobStatus {
    /// The key.
    pub key: String,
    /// `denoise` or `render`.
    pub kind: String,
    /// `queued`, `running`, `done` or `failed`.
    pub state: String,
    /// 0 to 1.
    pub progress: f64,
    /// Why it failed.
    pub error: Option<String>,
    /// Seconds per stage, once done.
    pub timings: Option<serde_json::Value>,
    /// Image width (0 until known).
    pub width: i64,
    /// Image height (0 until known).
    pub height: i64,
    /// When it was queued (ms since the epoch).
    pub created_ms: i64,
    /// When it finished.
    pub finished_ms: Option<i64>,
    /// The user's rating.
    pub rating: Option<Rating>,
}

/// Which stored image a request asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResultFile {
    /// The result as multilayer EXR.
    Exr,
    /// The result as tonemapped PNG.
    Png,
    /// The noisy input as tonemapped PNG.
    InputPng,
}

impl ResultFile {
    fn column(self) -> &'static str {
        match self {
            ResultFile::Exr => "result_exr",
            ResultFile::Png => "result_png",
            ResultFile::InputPng => "input_png",
        }
    }
}

/// Counts for `/metrics`.
#[derive(Clone, Debug, Default)]
pub struct QueueCounts {
    /// Jobs waiting for a worker.
    pub queued: i64,
    /// Jobs being worked on.
    pub running: i64,
    /// Jobs done (still kept).
    pub done: i64,
    /// Jobs failed (still kept).
    pub failed: i64,
    /// Total seconds from upload to result of the done jobs.
    pub done_seconds: f64,
    /// Workers that reported in the last minute.
    pub workers_seen: i64,
}

/// The columns of a new job's row that do not come from its upload.
struct JobRow<'a> {
    key: &'a JobKey,
    kind: JobKind,
    params: &'a str,
    size: (u32, u32),
}

/// Inserts a queued job's row: `row`, and the user's fields from `job`.
async fn insert_job(tx: &mut sqlx::AnyConnection, row: &JobRow<'_>, job: &NewJob) -> Result<(), ServiceError> {
    sqlx::query(
        "INSERT INTO jobs (key, kind, state, params, name, email, client, width, height, created_ms) \
         VALUES ($1, $2, 'queued', $3, $4, $5, $6, $7, $8, $9)",
    )
    .bind(row.key.as_str())
    .bind(row.kind.as_str())
    .bind(row.params)
    .bind(job.name.clone())
    .bind(job.email.clone())
    .bind(job.client.clone())
    .bind(row.size.0 as i64)
    .bind(row.size.1 as i64)
    .bind(now_ms())
    .execute(tx)
    .await?;
    Ok(())
}

/// A task to insert with its job.
struct NewTask {
    kind: &'static str,
    first_sample: u32,
    samples: u32,
    scene: Option<u64>,
    /// `queued`, or `waiting` for a finishing task.
    state: &'static str,
}

impl NewTask {
    fn new(kind: &'static str, first_sample: u32, samples: u32, state: &'static str) -> Self {
        NewTask { kind, first_sample, samples, scene: None, state }
    }
}

/// Inserts job `key`'s tasks.
async fn insert_tasks(tx: &mut sqlx::AnyConnection, key: &JobKey, tasks: &[NewTask]) -> Result<(), ServiceError> {
    for t in tasks {
        sqlx::query(
            "INSERT INTO tasks (job_key, kind, first_sample, samples, scene, state) VALUES ($1, $2, $3, $4, $5, $6)",
        )
        .bind(key.as_str())
        .bind(t.kind)
        .bind(t.first_sample as i64)
        .bind(t.samples as i64)
        .bind(t.scene.map(|s| s as i64))
        .bind(t.state)
        .execute(&mut *tx)
        .await?;
    }
    Ok(())
}

/// The jobs table and its neighbours.
#[derive(Clone, Debug)]
pub struct JobStore {
    db: Database,
}

impl JobStore {
    /// The store in `db`.
    pub fn new(db: Database) -> Self {
        JobStore { db }
    }

    /// The database.
    pub fn database(&self) -> &Database {
        &self.db
    }

    /// Stores `job` with its inputs and tasks and returns its new key. A render job becomes one
    /// range task per `chunk_spp` samples and a finishing task that waits for them. Refused
    /// with [`ServiceError::QueueFull`] when `max_queued` jobs are queued or running.
    pub async fn create(&self, job: &NewJob, chunk_spp: u32, max_queued: u64) -> Result<JobKey, ServiceError> {
        let key = JobKey::generate().map_err(ServiceError::Random)?;
        let params = serde_json::to_string(&job.params).map_err(|e| ServiceError::Corrupt(e.to_string()))?;
        let mut tx = self.db.pool.begin().await?;
        if self.db.backend == Backend::Postgres {
            // Uploads count the queue one at a time, so concurrent ones cannot all pass the limit.
            sqlx::query("SELECT pg_advisory_xact_lock(7044)").execute(&mut *tx).await?;
        }
        // The insert comes first so that SQLite takes its write lock before the count is read.
        let row = JobRow { key: &key, kind: job.kind, params: &params, size: job.size };
        insert_job(&mut tx, &row, job).await?;
        let active: i64 = sqlx::query("SELECT COUNT(*) FROM jobs WHERE state IN ('queued', 'running')")
            .fetch_one(&mut *tx)
            .await?
            .try_get(0)?;
        if active as u64 > max_queued {
            tx.rollback().await?;
            return Err(ServiceError::QueueFull);
        }
        for input in &job.inputs {
            sqlx::query("INSERT INTO inputs (job_key, name, format, data) VALUES ($1, $2, $3, $4)")
                .bind(key.as_str())
                .bind(input.name.clone())
                .bind(input.format.clone())
                .bind(input.data.clone())
                .execute(&mut *tx)
                .await?;
        }
        let mut tasks: Vec<NewTask> = Vec::new();
        match job.kind {
            JobKind::Denoise => tasks.push(NewTask::new("denoise", 0, 0, "queued")),
            JobKind::Render => {
                let spp = job.params.spp;
                let chunk = chunk_spp.max(spp.div_ceil(MAX_RANGES_PER_JOB)).max(1);
                tasks.extend(
                    (0..spp.div_ceil(chunk))
                        .map(|i| NewTask::new("render_range", i * chunk, chunk.min(spp - i * chunk), "queued")),
                );
                tasks.push(NewTask::new("render_finish", 0, spp, "waiting"));
            }
            JobKind::Dataset => return Err(ServiceError::Corrupt("a dataset job is queued by its owner".into())),
        }
        insert_tasks(&mut tx, &key, &tasks).await?;
        tx.commit().await?;
        Ok(key)
    }

    /// Queues dataset job `key` (made by its owner, who keeps the key beside the dataset): one
    /// task for each of `scenes`, rendered with `options_json`. A job of that key already
    /// stored is left as it is, so queuing twice queues once. Returns true when it was new.
    pub async fn create_dataset(&self, key: &JobKey, options_json: &str, scenes: &[u64]) -> Result<bool, ServiceError> {
        let mut tx = self.db.pool.begin().await?;
        if crate::database::lock_job(&mut tx, key.as_str()).await? == 1 {
            return Ok(false);
        }
        let row = JobRow { key, kind: JobKind::Dataset, params: options_json, size: (0, 0) };
        let none = NewJob {
            kind: JobKind::Dataset,
            params: RenderParams::default(),
            name: Some("rtd datagen".into()),
            email: None,
            client: None,
            size: (0, 0),
            inputs: vec![],
        };
        insert_job(&mut tx, &row, &none).await?;
        let tasks: Vec<NewTask> = scenes
            .iter()
            .map(|&s| NewTask { scene: Some(s), ..NewTask::new("dataset_scene", 0, 0, "queued") })
            .collect();
        insert_tasks(&mut tx, key, &tasks).await?;
        tx.commit().await?;
        Ok(true)
    }

    /// The job's state, or `None` for an unknown key.
    pub async fn status(&self, key: &JobKey) -> Result<Option<JobStatus>, ServiceError> {
        let row = sqlx::query(
            "SELECT kind, state, error, timings, width, height, created_ms, finished_ms FROM jobs WHERE key = $1",
        )
        .bind(key.as_str())
        .fetch_optional(&self.db.pool)
        .await?;
        let Some(row) = row else { return Ok(None) };
        let state: String = row.try_get(1)?;
        // Progress: the mean over the job's tasks, a finished task counting as 1.
        let progress: Option<f64> = sqlx::query(
            "SELECT CAST(AVG(CASE WHEN state = 'done' THEN 1.0 ELSE progress END) AS DOUBLE PRECISION) \
             FROM tasks WHERE job_key = $1",
        )
        .bind(key.as_str())
        .fetch_one(&self.db.pool)
        .await?
        .try_get(0)?;
        let timings: Option<String> = row.try_get(3)?;
        let rating = sqlx::query("SELECT rating, comment FROM ratings WHERE job_key = $1")
            .bind(key.as_str())
            .fetch_optional(&self.db.pool)
            .await?
            .map(|r| Ok::<_, sqlx::Error>(Rating { rating: r.try_get(0)?, comment: r.try_get(1)? }))
            .transpose()?;
        Ok(Some(JobStatus {
            key: key.to_string(),
            kind: row.try_get(0)?,
            progress: if state == "done" { 1.0 } else { progress.unwrap_or(0.0).clamp(0.0, 1.0) },
            state,
            error: row.try_get(2)?,
            timings: timings.and_then(|t| serde_json::from_str(&t).ok()),
            width: row.try_get(4)?,
            height: row.try_get(5)?,
            created_ms: row.try_get(6)?,
            finished_ms: row.try_get(7)?,
            rating,
        }))
    }

    /// A done job's stored image, or `None` if the key is unknown or the job is not done.
    pub async fn result(&self, key: &JobKey, file: ResultFile) -> Result<Option<Vec<u8>>, ServiceError> {
        let sql = format!("SELECT {} FROM jobs WHERE key = $1 AND state = 'done'", file.column());
        let row = sqlx::query(&sql).bind(key.as_str()).fetch_optional(&self.db.pool).await?;
        Ok(match row {
            Some(r) => r.try_get::<Option<Vec<u8>>, _>(0)?,
            None => None,
        })
    }

    /// Stores (or replaces) the rating of job `key`; false if there is no such job.
    pub async fn rate(&self, key: &JobKey, rating: i64, comment: Option<String>) -> Result<bool, ServiceError> {
        let mut tx = self.db.pool.begin().await?;
        if crate::database::lock_job(&mut tx, key.as_str()).await? == 0 {
            return Ok(false);
        }
        sqlx::query(
            "INSERT INTO ratings (job_key, rating, comment, created_ms) VALUES ($1, $2, $3, $4) \
             ON CONFLICT (job_key) DO UPDATE SET rating = excluded.rating, comment = excluded.comment, \
             created_ms = excluded.created_ms",
        )
        .bind(key.as_str())
        .bind(rating)
        .bind(comment)
        .bind(now_ms())
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// The counts `/metrics` reports.
    pub async fn counts(&self) -> Result<QueueCounts, ServiceError> {
        let mut c = QueueCounts::default();
        let rows = sqlx::query("SELECT state, COUNT(*) FROM jobs GROUP BY state").fetch_all(&self.db.pool).await?;
        for r in rows {
            let (state, n): (String, i64) = (r.try_get(0)?, r.try_get(1)?);
            match state.as_str() {
                "queued" => c.queued = n,
                "running" => c.running = n,
                "done" => c.done = n,
                "failed" => c.failed = n,
                _ => {}
            }
        }
        let ms: Option<i64> =
            sqlx::query("SELECT CAST(SUM(finished_ms - created_ms) AS BIGINT) FROM jobs WHERE state = 'done'")
                .fetch_one(&self.db.pool)
                .await?
                .try_get(0)?;
        c.done_seconds = ms.unwrap_or(0) as f64 / 1000.0;
        c.workers_seen = sqlx::query("SELECT COUNT(*) FROM workers WHERE last_seen_ms > $1")
            .bind(now_ms() - 60_000)
            .fetch_one(&self.db.pool)
            .await?
            .try_get(0)?;
        Ok(c)
    }

    /// Deletes finished jobs created before `cutoff_ms`, with their inputs, tasks and ratings;
    /// returns how many jobs went.
    pub async fn purge_before(&self, cutoff_ms: i64) -> Result<u64, ServiceError> {
        let old = "SELECT key FROM jobs WHERE created_ms < $1 AND state IN ('done', 'failed')";
        let mut tx = self.db.pool.begin().await?;
        if self.db.backend == Backend::Postgres {
            // One sweep at a time across servers, so that two never lock the same rows in turn.
            sqlx::query("SELECT pg_advisory_xact_lock(7045)").execute(&mut *tx).await?;
        }
        // The job rows are locked first, as every other writer of a job does (a rating locks
        // its job, then writes the ratings table), so the sweep cannot deadlock with them.
        sqlx::query("UPDATE jobs SET key = key WHERE created_ms < $1 AND state IN ('done', 'failed')")
            .bind(cutoff_ms)
            .execute(&mut *tx)
            .await?;
        for table in ["inputs", "tasks", "ratings"] {
            sqlx::query(&format!("DELETE FROM {table} WHERE job_key IN ({old})"))
                .bind(cutoff_ms)
                .execute(&mut *tx)
                .await?;
        }
        let gone = sqlx::query("DELETE FROM jobs WHERE created_ms < $1 AND state IN ('done', 'failed')")
            .bind(cutoff_ms)
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(gone.rows_affected())
    }
}
