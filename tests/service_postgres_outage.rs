//! PostgreSQL stops for a few seconds under a running server and a render node: both wait it
//! out and reconnect, and work queued after it is back completes. (Its own test binary: it
//! stops the server every PostgreSQL test shares.)

mod service_support;

use std::process::{Command, Stdio};
use std::time::Duration;

use service_support::*;

/// Runs `pg_ctl ACTION` on the test cluster (`RTD_TEST_PG_CTL`, set by `.ci/run`).
fn pg_ctl(action: &str) {
    let ctl = std::env::var("RTD_TEST_PG_CTL").expect("RTD_TEST_PG_CTL is not set: run the tests with .ci/run");
    let extra = if action == "stop" { " -m fast" } else { "" };
    let ok = Command::new("sh").arg("-c").arg(format!("{ctl} {action}{extra}")).stdout(Stdio::null()).status().unwrap();
    assert!(ok.success(), "pg_ctl {action} failed");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn server_and_workers_reconnect_after_postgres_restarts() {
    let tdb = TestDb::new(Db::Postgres).await;
    let s = TestServer::start(&tdb.url, 0, test_config()).await;
    let mut node = Command::new(env!("CARGO_BIN_EXE_rtd"))
        .args(["worker", "--database", &tdb.url, "--lease", "2s", "--threads", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let upload = |seed: u64| {
        let (color, guide) = noisy_and_guide(dir.path(), 16, 60 + seed);
        let files =
            [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
        (form(&files, &[]), color, guide)
    };
    let (f, ..) = upload(0);
    let (st, body, _) = post_job(&s.base, f).await;
    assert_eq!(st, 201, "{body}");
    wait_done(&s.base, body["key"].as_str().unwrap(), Duration::from_secs(60)).await;

    pg_ctl("stop");
    let (code, _) = get_bytes(&s.base, "/healthz").await;
    assert_eq!(code, 503, "health must say the database is gone");
    let (f, ..) = upload(1);
    let (st, body, _) = post_job(&s.base, f).await;
    assert_eq!(st, 500, "{body}");
    assert_eq!(body["error"], "The server could not complete the request.");
    tokio::time::sleep(Duration::from_secs(3)).await;
    assert!(node.try_wait().unwrap().is_none(), "the render node exited while the database was down");
    pg_ctl("start");

    let (f, color, guide) = upload(2);
    let (st, body, _) = post_job(&s.base, f).await;
    assert_eq!(st, 201, "{body}");
    let key = body["key"].as_str().unwrap().to_string();
    wait_done(&s.base, &key, Duration::from_secs(60)).await;
    assert_eq!(get_bytes(&s.base, &format!("/api/jobs/{key}/result.png")).await, (200, cli_denoise(&color, &guide).1));
    assert_eq!(get_bytes(&s.base, "/healthz").await.0, 200);
    node.kill().unwrap();
    node.wait().unwrap();
    s.server.shutdown().await.unwrap();
}
