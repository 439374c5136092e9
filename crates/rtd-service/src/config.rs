//! The service's settings and limits: one owner for every number a request or a worker is
//! held to (image limits themselves belong to `rtd_image`, render limits to `rtd_render`).

use std::time::Duration;

/// Largest request body by default: 64 MiB.
pub const DEFAULT_MAX_UPLOAD: usize = 64 << 20;
/// Queued and running jobs allowed by default before uploads get 503.
pub const DEFAULT_MAX_QUEUED: u64 = 1000;
/// How long results are kept by default: 7 days.
pub const DEFAULT_KEEP: Duration = Duration::from_secs(7 * 24 * 3600);
/// Samples per pixel of a render job when the upload gives none.
pub const DEFAULT_SPP: u32 = 8;
/// Longest comment kept with a rating, in characters.
pub const MAX_COMMENT_CHARS: usize = 4000;
/// Longest `name`, `email` or `camera` field, in characters.
pub const MAX_TEXT_FIELD_CHARS: usize = 200;
/// Claims of one task before it is failed: a job that kills every worker that takes it is
/// given up on, not retried for ever.
pub const MAX_ATTEMPTS: i64 = 3;
/// Most sample-range tasks one render job becomes: a large spp gets larger ranges, so one
/// upload cannot flood the queue with tasks or the finishing task with films.
pub const MAX_RANGES_PER_JOB: u32 = 64;
/// Shortest lease accepted: renewal runs every quarter lease.
pub const MIN_LEASE: Duration = Duration::from_secs(1);
/// Longest lease, retention or timeout accepted (about ten years): the queue keeps times as
/// `i64` milliseconds, and a longer span would overflow them.
pub const MAX_SPAN: Duration = Duration::from_secs(3650 * 24 * 3600);

/// How `rtd serve` and `rtd worker` behave, builder style from [`ServiceConfig::default`].
#[derive(Clone, Debug)]
pub struct ServiceConfig {
    /// Largest request body in bytes.
    pub max_upload: usize,
    /// Queued plus running jobs at which uploads are refused with 503.
    pub max_queued: u64,
    /// How long finished jobs are kept.
    pub keep: Duration,
    /// Uploads and ratings one client address may send per minute.
    pub uploads_per_minute: u32,
    /// How long a request's headers may take to arrive, and then its body.
    pub upload_timeout: Duration,
    /// How long a worker's claim on a task lasts unless renewed.
    pub lease: Duration,
    /// How long an idle worker waits before asking the queue again.
    pub poll: Duration,
    /// Samples per pixel in one range task of a render job.
    pub render_chunk_spp: u32,
    /// Render threads per task (`None`: all cores).
    pub threads: Option<usize>,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        ServiceConfig {
            max_upload: DEFAULT_MAX_UPLOAD,
            max_queued: DEFAULT_MAX_QUEUED,
            keep: DEFAULT_KEEP,
            uploads_per_minute: 60,
            upload_timeout: Duration::from_secs(60),
            lease: Duration::from_secs(30),
            poll: Duration::from_millis(250),
            render_chunk_spp: 16,
            threads: None,
        }
    }
}

impl ServiceConfig {
    /// Sets the largest request body.
    pub fn max_upload(mut self, bytes: usize) -> Self {
        self.max_upload = bytes;
        self
    }
    /// Sets the queue length at which uploads get 503.
    pub fn max_queued(mut self, jobs: u64) -> Self {
        self.max_queued = jobs;
        self
    }
    /// Sets how long finished jobs are kept.
    pub fn keep(mut self, keep: Duration) -> Self {
        self.keep = keep.min(MAX_SPAN);
        self
    }
    /// Sets the uploads per minute per client address.
    pub fn uploads_per_minute(mut self, n: u32) -> Self {
        self.uploads_per_minute = n;
        self
    }
    /// Sets how long a request body may take.
    pub fn upload_timeout(mut self, t: Duration) -> Self {
        self.upload_timeout = t.min(MAX_SPAN);
        self
    }
    /// Sets the lease a worker holds on a task.
    pub fn lease(mut self, lease: Duration) -> Self {
        self.lease = lease.clamp(MIN_LEASE, MAX_SPAN);
        self
    }
    /// Sets the idle worker's polling interval.
    pub fn poll(mut self, poll: Duration) -> Self {
        self.poll = poll;
        self
    }
    /// Sets the samples per pixel of one render range task.
    pub fn render_chunk_spp(mut self, spp: u32) -> Self {
        self.render_chunk_spp = spp.max(1);
        self
    }
    /// Sets the render threads per task.
    pub fn threads(mut self, threads: Option<usize>) -> Self {
        self.threads = threads;
        self
    }
}
