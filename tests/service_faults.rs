//! Faults with real processes: a render node killed with `kill -9` mid-job loses its lease and
//! another node finishes the job exactly once; a server killed with queued jobs comes back and
//! they complete. On SQLite (nodes on one machine) and on PostgreSQL.

mod service_support;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rtd::service::{Database, JobKey, JobQueue};
use service_support::*;
use sqlx::Row;

/// `rtd worker` on `url` with a 2 s lease, one render thread.
fn spawn_worker(url: &str) -> Child {
    Command::new(env!("CARGO_BIN_EXE_rtd"))
        .args(["worker", "--database", url, "--lease", "2s", "--threads", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// The id of the worker process `pid` as the workers table holds it, with its completed tasks.
async fn worker_row(db: &Database, pid: u32) -> Option<(String, i64)> {
    let rows = sqlx::query("SELECT id, tasks_done FROM workers").fetch_all(&db.pool).await.unwrap();
    rows.iter()
        .map(|r| (r.try_get::<String, _>(0).unwrap(), r.try_get::<i64, _>(1).unwrap()))
        .find(|(id, _)| id.contains(&format!("-{pid}-")))
}

async fn killed_worker_job_finishes_once(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 0, test_config().render_chunk_spp(100_000)).await;
    let files = [("scene", "c.gltf", std::fs::read(repo_scene("cornell-box.gltf")).unwrap())];
    let (st, body, _) = post_job(&s.base, form(&files, &[("spp", "1500"), ("width", "64")])).await;
    assert_eq!(st, 201, "{body}");
    let key = body["key"].as_str().unwrap().to_string();
    let mut a = spawn_worker(&tdb.url);
    // Wait until node A has published progress on the render, then kill it without warning.
    let t = Instant::now();
    loop {
        let st: serde_json::Value =
            client().get(format!("{}/api/jobs/{key}", s.base)).send().await.unwrap().json().await.unwrap();
        if st["state"] == "running" && st["progress"].as_f64().unwrap() > 0.0 {
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "node A never got going: {st}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    a.kill().unwrap(); // SIGKILL
    a.wait().unwrap();
    let mut b = spawn_worker(&tdb.url);
    wait_done(&s.base, &key, Duration::from_secs(180)).await;
    b.kill().unwrap();
    b.wait().unwrap();
    let dbc = Database::connect(&tdb.url).await.unwrap();
    let (a_id, a_done) = worker_row(&dbc, a.id()).await.expect("node A never registered");
    let (b_id, b_done) = worker_row(&dbc, b.id()).await.expect("node B never registered");
    assert_eq!((a_done, b_done), (0, 2), "node B completes the range and the finish; node A nothing");
    let by = JobQueue::new(dbc).completed_by(&JobKey::parse(&key).unwrap()).await.unwrap();
    assert_eq!(by.len(), 2, "{by:?}");
    assert_eq!((by[0].1.as_deref(), by[0].2), (Some(b_id.as_str()), 2), "the range: claimed by A, then by B: {by:?}");
    assert_ne!(a_id, b_id);
    let (code, png) = get_bytes(&s.base, &format!("/api/jobs/{key}/result.png")).await;
    assert_eq!((code, &png[1..4]), (200, &b"PNG"[..]));
    s.server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killed_worker_job_finishes_once_on_sqlite() {
    killed_worker_job_finishes_once(Db::Sqlite).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn killed_worker_job_finishes_once_on_postgres() {
    killed_worker_job_finishes_once(Db::Postgres).await
}

/// `rtd serve` on an ephemeral port over the SQLite folder `data`; returns it with its URL.
fn spawn_server(data: &std::path::Path, workers: &str) -> (Child, String) {
    use std::io::BufRead;
    let mut child = Command::new(env!("CARGO_BIN_EXE_rtd"))
        .args(["serve", "--listen", "127.0.0.1:0", "--workers", workers, "--threads", "1", "--data"])
        .arg(data)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url =
        line.split_whitespace().find(|w| w.starts_with("http://")).expect(&line).trim_end_matches('/').to_string();
    (child, url)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_killed_server_comes_back_and_finishes_its_queue() {
    let data = tempfile::tempdir().unwrap();
    let (mut first, url) = spawn_server(data.path(), "0");
    let dir = tempfile::tempdir().unwrap();
    let mut jobs = Vec::new();
    for seed in 0..3 {
        let (color, guide) = noisy_and_guide(dir.path(), 16, 40 + seed);
        let files =
            [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
        let (st, body, _) = post_job(&url, form(&files, &[])).await;
        assert_eq!(st, 201, "{body}");
        jobs.push((body["key"].as_str().unwrap().to_string(), color, guide));
    }
    first.kill().unwrap();
    first.wait().unwrap();
    let (mut second, url) = spawn_server(data.path(), "1");
    for (key, color, guide) in &jobs {
        wait_done(&url, key, Duration::from_secs(60)).await;
        assert_eq!(get_bytes(&url, &format!("/api/jobs/{key}/result.png")).await, (200, cli_denoise(color, guide).1));
    }
    second.kill().unwrap();
    second.wait().unwrap();
}
