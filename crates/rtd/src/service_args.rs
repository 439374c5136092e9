//! `rtd serve` and `rtd worker` options.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use clap::Args;

/// `rtd serve` options.
#[derive(Debug, Clone, Args)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// Folder for the embedded SQLite database (ignored with --database).
    #[arg(long, default_value = "rtd-data")]
    pub data: PathBuf,
    /// A PostgreSQL URL (postgres://user:pass@host/db) to share with `rtd worker` nodes.
    #[arg(long)]
    pub database: Option<String>,
    /// In-process workers (default 1 with SQLite, 0 with --database).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Largest upload, e.g. 64MiB.
    #[arg(long, default_value = "64MiB", value_parser = parse_size)]
    pub max_upload: usize,
    /// Queued and running jobs at which uploads are refused with 503.
    #[arg(long, default_value_t = rtd_service::DEFAULT_MAX_QUEUED)]
    pub max_queued: u64,
    /// How long results are kept, e.g. 7d or 12h.
    #[arg(long, default_value = "7d", value_parser = parse_duration)]
    pub keep: Duration,
    /// Uploads and ratings per minute from one client address.
    #[arg(long, default_value_t = 60)]
    pub rate_limit: u32,
    /// How long a request's headers may take to arrive, and then its body (an upload).
    #[arg(long, default_value = "60s", value_parser = parse_duration)]
    pub upload_timeout: Duration,
    /// Samples per pixel in one render range task (a render job splits into ranges).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    pub render_chunk_spp: u32,
    /// Options shared with `rtd worker`.
    #[command(flatten)]
    pub node: NodeArgs,
}

/// `rtd worker` options.
#[derive(Debug, Clone, Args)]
pub struct WorkerArgs {
    /// The database the server queues jobs in (postgres://…, or sqlite://path on one machine).
    #[arg(long)]
    pub database: String,
    /// Options shared with `rtd serve`.
    #[command(flatten)]
    pub node: NodeArgs,
}

/// How workers run, in `rtd serve` and `rtd worker` alike.
#[derive(Debug, Clone, Args)]
pub struct NodeArgs {
    /// How long a worker's claim on a task lasts unless renewed (a killed worker's task is
    /// taken over after this).
    #[arg(long, default_value = "30s", value_parser = parse_duration)]
    pub lease: Duration,
    /// Render threads per task (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// A denoiser model (.bpk) in place of the built-in one.
    #[arg(long)]
    pub model: Option<PathBuf>,
}

fn parse_duration(s: &str) -> Result<Duration, String> {
    match humantime::parse_duration(s) {
        Ok(d) if d > Duration::ZERO && d <= rtd_service::MAX_SPAN => Ok(d),
        _ => {
            let days = rtd_service::MAX_SPAN.as_secs() / 86_400;
            Err(format!("'{s}' is not a positive duration of at most {days}d, such as 30s, 12h or 7d"))
        }
    }
}

fn parse_size(s: &str) -> Result<usize, String> {
    match s.parse::<bytesize::ByteSize>() {
        Ok(b) if b.as_u64() >= 1024 && b.as_u64() <= 1 << 34 => Ok(b.as_u64() as usize),
        _ => Err(format!("'{s}' is not a size between 1KiB and 16GiB, such as 64MiB")),
    }
}
