//! The database behind the queue: embedded SQLite on one machine, PostgreSQL across many,
//! reached through sqlx's `Any` driver so that one set of queries serves both. The schema is
//! created and upgraded by sqlx migrations (`migrations/sqlite`, `migrations/postgres`).

use std::path::Path;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use sqlx::any::{AnyConnectOptions, AnyPoolOptions};
use sqlx::migrate::Migrator;
use sqlx::{AnyPool, ConnectOptions, Executor};

use crate::ServiceError;

/// The SQLite schema's migrations.
static SQLITE_MIGRATIONS: Migrator = sqlx::migrate!("migrations/sqlite");
/// The PostgreSQL schema's migrations.
static POSTGRES_MIGRATIONS: Migrator = sqlx::migrate!("migrations/postgres");

/// Which database engine a URL names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// Embedded SQLite (`sqlite://path`).
    Sqlite,
    /// PostgreSQL (`postgres://…` or `postgresql://…`).
    Postgres,
}

impl Backend {
    /// The engine `url` names, or an error for any other scheme.
    pub fn of(url: &str) -> Result<Self, ServiceError> {
        if url.starts_with("sqlite:") {
            Ok(Backend::Sqlite)
        } else if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            Ok(Backend::Postgres)
        } else {
            Err(ServiceError::Config(format!("database URL {:?} is neither sqlite://… nor postgres://…", redact(url))))
        }
    }
}

/// A connection pool with the schema in place.
#[derive(Clone, Debug)]
pub struct Database {
    /// The pool.
    pub pool: AnyPool,
    /// The engine behind it.
    pub backend: Backend,
}

/// The URL of the SQLite database kept in `data_dir` (created if missing).
pub fn sqlite_url(data_dir: &Path) -> String {
    format!("sqlite://{}?mode=rwc", data_dir.join("rtd.sqlite").display())
}

/// `url` with any password replaced by `***`, for messages and logs.
pub fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(s), Some(at)) if at > s => {
            let creds = &url[s + 3..at];
            match creds.find(':') {
                Some(c) => format!("{}{}:***{}", &url[..s + 3], &creds[..c], &url[at..]),
                None => url.to_string(),
            }
        }
        _ => url.to_string(),
    }
}

impl Database {
    /// Connects to `url` and runs the migrations. SQLite gets write-ahead logging, full
    /// synchronous commits (a committed job survives a power cut) and a 10 s busy timeout, so
    /// concurrent writers wait for each other instead of failing.
    pub async fn connect(url: &str) -> Result<Self, ServiceError> {
        sqlx::any::install_default_drivers();
        let backend = Backend::of(url)?;
        let options: AnyConnectOptions = url
            .parse::<AnyConnectOptions>()
            .map_err(|e| ServiceError::Config(format!("database URL {:?}: {e}", redact(url))))?
            .log_statements(tracing::log::LevelFilter::Trace);
        let pool = AnyPoolOptions::new()
            .max_connections(if backend == Backend::Sqlite { 4 } else { 8 })
            .acquire_timeout(Duration::from_secs(10))
            .after_connect(move |conn, _| {
                Box::pin(async move {
                    if backend == Backend::Sqlite {
                        conn.execute("PRAGMA journal_mode = WAL").await?;
                        conn.execute("PRAGMA synchronous = FULL").await?;
                        conn.execute("PRAGMA busy_timeout = 10000").await?;
                        conn.execute("PRAGMA foreign_keys = ON").await?;
                    }
                    Ok(())
                })
            })
            .connect_with(options)
            .await
            .map_err(|e| ServiceError::Connect { url: redact(url), source: e })?;
        let migrator = match backend {
            Backend::Sqlite => &SQLITE_MIGRATIONS,
            Backend::Postgres => &POSTGRES_MIGRATIONS,
        };
        migrator.run(&pool).await.map_err(|e| ServiceError::Migrate { url: redact(url), source: e })?;
        Ok(Database { pool, backend })
    }

    /// True if the database answers.
    pub async fn ping(&self) -> bool {
        sqlx::query("SELECT 1").execute(&self.pool).await.is_ok()
    }
}

/// Milliseconds since the Unix epoch: every time the database stores. Leases compare times
/// from different machines, so nodes need synchronised clocks (NTP), as any lease does.
pub fn now_ms() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_millis() as i64).unwrap_or(0)
}

/// Locks job `job`'s row for the rest of `tx`: completions and failures of one job's tasks then
/// run one at a time (and SQLite takes its write lock here, before any read). Returns the rows
/// locked: 0 if there is no such job.
pub(crate) async fn lock_job(tx: &mut sqlx::AnyConnection, job: &str) -> Result<u64, ServiceError> {
    Ok(sqlx::query("UPDATE jobs SET key = key WHERE key = $1").bind(job).execute(tx).await?.rows_affected())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_name_their_backend_and_hide_passwords() {
        assert_eq!(Backend::of("sqlite://x.db").unwrap(), Backend::Sqlite);
        assert_eq!(Backend::of("postgres://u@h/db").unwrap(), Backend::Postgres);
        assert!(Backend::of("mysql://h/db").is_err());
        assert_eq!(redact("postgres://rtd:secret@h:5432/db"), "postgres://rtd:***@h:5432/db");
        assert_eq!(redact("postgres://h/db"), "postgres://h/db");
    }
}
