//! `rtd datagen --database`: a dataset rendered a scene per task by render nodes, with the
//! coordinator killed with `kill -9` after queuing and rerun, ends up the same files and the
//! same manifest (but for wall-clock seconds) as the one-machine run, with every scene rendered
//! exactly once. On SQLite and on PostgreSQL.

mod common;
mod service_support;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::dataset_files;
use rtd::service::{Database, JobKey, JobQueue, QUEUE_FILE};
use service_support::*;
use sqlx::Row;

/// A small dataset: 6 scenes (the last held out) of 2 views at 24², 8-spp references.
const OPTIONS: [&str; 9] = ["--scenes", "6", "--views", "2", "--size", "24", "--reference-spp", "8", "-q"];

fn datagen(dir: &Path, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_rtd"));
    c.arg("datagen").arg("-o").arg(dir).args(OPTIONS).args(extra);
    c
}

fn spawn_worker(url: &str) -> Child {
    Command::new(env!("CARGO_BIN_EXE_rtd"))
        // A lease long enough that a loaded 2-core machine never lets one run out mid-scene.
        .args(["worker", "--database", url, "--lease", "20s", "--threads", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

async fn tasks(db: &Database) -> Vec<(String, i64, Option<String>)> {
    let rows =
        sqlx::query("SELECT state, attempts, completed_by FROM tasks ORDER BY id").fetch_all(&db.pool).await.unwrap();
    rows.iter().map(|r| (r.try_get(0).unwrap(), r.try_get(1).unwrap(), r.try_get(2).unwrap())).collect()
}

async fn wait_for(what: &str, limit: Duration, mut done: impl AsyncFnMut() -> bool) {
    let t = Instant::now();
    while !done().await {
        assert!(t.elapsed() < limit, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

async fn distributed_datagen_equals_one_machine(db: Db) {
    let root = tempfile::tempdir().unwrap();
    let (single, multi) = (root.path().join("single"), root.path().join("multi"));
    assert!(datagen(&single, &[]).status().unwrap().success());
    let tdb = TestDb::new(db).await;

    // The coordinator queues the scenes and is killed before any node has started.
    let mut first = datagen(&multi, &["--database", &tdb.url]).stderr(Stdio::null()).spawn().unwrap();
    let queued = multi.join(QUEUE_FILE);
    wait_for("the job to be queued", Duration::from_secs(60), async || queued.exists()).await;
    let dbc = Database::connect(&tdb.url).await.unwrap();
    wait_for("the tasks", Duration::from_secs(30), async || tasks(&dbc).await.len() == 6).await;
    // A second coordinator on the same directory is refused while the first gathers.
    let second = datagen(&multi, &["--database", &tdb.url]).output().unwrap();
    let said = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success() && said.contains("another rtd datagen is gathering"), "{said}");
    first.kill().unwrap(); // SIGKILL
    first.wait().unwrap();

    // One node renders while nobody gathers; the rerun finds the same job and adds its own worker.
    let mut node = spawn_worker(&tdb.url);
    let some_done = async || tasks(&dbc).await.iter().any(|(state, ..)| state == "done");
    wait_for("a scene to be rendered", Duration::from_secs(120), some_done).await;
    let rerun = datagen(&multi, &["--database", &tdb.url, "--workers", "1"]).output().unwrap();
    assert!(rerun.status.success(), "{}", String::from_utf8_lossy(&rerun.stderr));
    node.kill().unwrap();
    node.wait().unwrap();

    assert!(!queued.exists(), "the finished job's record is removed");
    assert!(!multi.join("datagen.lock").exists(), "the finished dataset's lock file is removed");
    let jobs: Vec<(String, String)> = sqlx::query("SELECT key, state FROM jobs")
        .fetch_all(&dbc.pool)
        .await
        .unwrap()
        .iter()
        .map(|r| (r.try_get(0).unwrap(), r.try_get(1).unwrap()))
        .collect();
    assert_eq!(jobs.len(), 1, "the rerun queued nothing new: {jobs:?}");
    assert_eq!(jobs[0].1, "done");
    let by = JobQueue::new(dbc.clone()).completed_by(&JobKey::parse(&jobs[0].0).unwrap()).await.unwrap();
    assert_eq!(by.len(), 6);
    assert!(
        by.iter().all(|(kind, who, attempts)| kind == "dataset_scene" && who.is_some() && *attempts == 1),
        "{by:?}"
    );
    let left: i64 = sqlx::query("SELECT COUNT(*) FROM tasks WHERE output IS NOT NULL")
        .fetch_one(&dbc.pool)
        .await
        .unwrap()
        .try_get(0)
        .unwrap();
    assert_eq!(left, 0, "every shard's bytes are dropped once gathered");

    let (a, b) = (dataset_files(&single), dataset_files(&multi));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    assert!(a.keys().filter(|k| k.starts_with("views/")).count() >= 4, "{:?}", a.keys());
    for (name, bytes) in &a {
        assert!(bytes == &b[name], "{name} differs between the one-machine and the distributed dataset");
    }

    // Rerunning a finished dataset queues nothing and changes nothing.
    let again = datagen(&multi, &["--database", &tdb.url]).output().unwrap();
    assert!(again.status.success(), "{}", String::from_utf8_lossy(&again.stderr));
    assert_eq!(dataset_files(&multi), b);
    let n: i64 = sqlx::query("SELECT COUNT(*) FROM jobs").fetch_one(&dbc.pool).await.unwrap().try_get(0).unwrap();
    assert_eq!(n, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn distributed_datagen_equals_one_machine_on_sqlite() {
    distributed_datagen_equals_one_machine(Db::Sqlite).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn distributed_datagen_equals_one_machine_on_postgres() {
    distributed_datagen_equals_one_machine(Db::Postgres).await
}
