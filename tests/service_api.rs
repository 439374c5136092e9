//! The service's HTTP API against a real server on 127.0.0.1, each test on SQLite and on
//! PostgreSQL: results equal the command line's bytes, a split render equals the one-machine
//! render, every refusal is a 4xx with one JSON sentence and stores nothing, and queued work
//! survives restarts and shutdowns.

mod common;
mod service_support;

use std::time::Duration;

use common::bomb::png_bomb;
use rtd::service::{execute, Database, JobKey, JobQueue, JobStore, TaskInputs, TaskOutput, TaskProgress};
use service_support::*;
use sqlx::Row;

/// Runs `$name(Db)` as two tests: `$name::sqlite` and `$name::postgres`.
macro_rules! on_both_databases {
    ($($name:ident),* $(,)?) => {$(
        mod $name {
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn sqlite() {
                super::$name(super::Db::Sqlite).await
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn postgres() {
                super::$name(super::Db::Postgres).await
            }
        }
    )*};
}

on_both_databases!(
    denoise_result_equals_the_cli,
    split_render_equals_the_one_machine_render,
    refusals_are_4xx_json_and_store_nothing,
    sql_in_a_name_is_stored_as_text,
    a_full_queue_answers_503,
    queued_jobs_survive_a_restart,
    shutdown_gives_running_work_back,
    finished_jobs_expire_with_their_inputs,
    an_unreadable_task_fails_its_job_once,
);

async fn table_count(url: &str, table: &str) -> i64 {
    let db = Database::connect(url).await.unwrap();
    sqlx::query(&format!("SELECT COUNT(*) FROM {table}")).fetch_one(&db.pool).await.unwrap().try_get(0).unwrap()
}

async fn denoise_result_equals_the_cli(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 1, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 40, 1);
    let files = [
        ("color", "noisy.exr", std::fs::read(&color).unwrap()),
        ("guide", "guide.exr", std::fs::read(&guide).unwrap()),
    ];
    let (status, body, headers) =
        post_job(&s.base, form(&files, &[("name", "Ada"), ("email", "ada@example.com")])).await;
    assert_eq!(status, 201, "{body}");
    assert_eq!(body["state"], "queued");
    let key = body["key"].as_str().unwrap().to_string();
    assert_eq!(key.len(), 64, "a key carries 256 random bits");
    assert_eq!(headers["location"], format!("/jobs/{key}"));
    let st = wait_done(&s.base, &key, Duration::from_secs(60)).await;
    assert_eq!((st["width"].as_i64(), st["height"].as_i64(), st["progress"].as_f64()), (Some(40), Some(40), Some(1.0)));
    // The job page says what the result was made from.
    assert!(st["timings"]["inputs"].as_str().is_some_and(|i| i.starts_with("color, guide")), "{st}");
    // rtd render writes the first hit's albedo and normal beside the colour; not uploaded as
    // their inputs, they are not read, and the page says so.
    assert_eq!(st["timings"]["unread_layers"], "albedo, normal", "{st}");
    let (cli_exr, cli_png) = cli_denoise(&color, &guide);
    assert_eq!(
        get_bytes(&s.base, &format!("/api/jobs/{key}/result.exr")).await,
        (200, cli_exr),
        "EXR differs from rtd denoise"
    );
    assert_eq!(
        get_bytes(&s.base, &format!("/api/jobs/{key}/result.png")).await,
        (200, cli_png),
        "PNG differs from rtd denoise"
    );
    let (code, input) = get_bytes(&s.base, &format!("/api/jobs/{key}/input.png")).await;
    assert_eq!((code, &input[1..4]), (200, &b"PNG"[..]));
    // The rating form: stored, replaced, shown with the job.
    let rate = |v: serde_json::Value| client().post(format!("{}/api/jobs/{key}/rating", s.base)).json(&v).send();
    assert_eq!(rate(serde_json::json!({"rating": 2})).await.unwrap().status(), 200);
    assert_eq!(rate(serde_json::json!({"rating": 5, "comment": "clean"})).await.unwrap().status(), 200);
    let st: serde_json::Value =
        client().get(format!("{}/api/jobs/{key}", s.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(st["rating"], serde_json::json!({"rating": 5, "comment": "clean"}));
    assert_eq!(table_count(&tdb.url, "ratings").await, 1);
    s.server.shutdown().await.unwrap();
}

async fn split_render_equals_the_one_machine_render(db: Db) {
    let tdb = TestDb::new(db).await;
    // No in-process workers: node A is driven by hand below, node B is a worker.
    let s = TestServer::start(&tdb.url, 0, test_config()).await;
    let scene = std::fs::read(repo_scene("small-lights.gltf")).unwrap();
    let files = [("scene", "small-lights.gltf", scene)];
    let (status, body, _) = post_job(&s.base, form(&files, &[("spp", "8"), ("width", "48")])).await;
    assert_eq!(status, 201, "{body}");
    let key = JobKey::parse(body["key"].as_str().unwrap()).unwrap();
    // Node A renders the first range (samples 0..3) and stores its film.
    let dbc = Database::connect(&tdb.url).await.unwrap();
    let queue = JobQueue::new(dbc.clone());
    let claim = queue.claim("node-a", 60_000).await.unwrap().unwrap();
    assert_eq!((claim.first_sample, claim.samples), (0, 3));
    let inputs = TaskInputs {
        files: queue.inputs(&key).await.unwrap(),
        params: queue.params(&key).await.unwrap(),
        films: vec![],
    };
    let out = execute(&claim, &inputs, &denoiser(), Some(1), &TaskProgress::default()).unwrap();
    assert!(matches!(out, TaskOutput::Film(_)));
    assert!(queue.complete(&claim, out.clone()).await.unwrap());
    assert!(!queue.complete(&claim, out).await.unwrap(), "a task completes once");
    // Node B, a worker, does the other ranges and the finishing task.
    let b = rtd::service::Worker::new(dbc, denoiser(), test_config()).unwrap();
    let b_id = b.id().to_string();
    let (stop, stopped) = tokio::sync::watch::channel(false);
    let worker = tokio::spawn(b.run(stopped));
    wait_done(&s.base, key.as_str(), Duration::from_secs(60)).await;
    stop.send(true).unwrap();
    worker.await.unwrap();
    let by = queue.completed_by(&key).await.unwrap();
    let kinds: Vec<&str> = by.iter().map(|(k, _, _)| k.as_str()).collect();
    assert_eq!(kinds, ["render_range", "render_range", "render_range", "render_finish"]);
    assert_eq!(by[0].1.as_deref(), Some("node-a"));
    assert!(by[1..].iter().all(|(_, w, attempts)| w.as_deref() == Some(b_id.as_str()) && *attempts == 1), "{by:?}");
    // The same render on one machine, as `rtd render --spp 8 --width 48 --denoise` makes it.
    let dir = tempfile::tempdir().unwrap();
    for ext in ["exr", "png"] {
        let path = dir.path().join(format!("one.{ext}"));
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_rtd"))
            .args(["render", "-q", "--spp", "8", "--width", "48", "--denoise", "-o"])
            .arg(&path)
            .arg(repo_scene("small-lights.gltf"))
            .status()
            .unwrap();
        assert!(status.success());
        let (code, bytes) = get_bytes(&s.base, &format!("/api/jobs/{key}/result.{ext}")).await;
        assert_eq!(code, 200);
        assert!(bytes == std::fs::read(&path).unwrap(), "the split render's {ext} differs from the one-machine render");
    }
    s.server.shutdown().await.unwrap();
}

/// Asserts a refusal: status `code`, a JSON body of one sentence containing `words`.
fn refused(what: &str, (status, body): (u16, serde_json::Value), code: u16, words: &str) {
    assert_eq!(status, code, "{what}: {body}");
    let e = body["error"].as_str().unwrap_or_else(|| panic!("{what}: no JSON error in {body}"));
    assert!(e.ends_with('.') && e.matches(". ").count() == 0, "{what}: not one sentence: {e}");
    assert!(e.contains(words), "{what}: {e:?} lacks {words:?}");
}

async fn refusals_are_4xx_json_and_store_nothing(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 0, test_config().max_upload(1 << 20)).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 24, 2);
    let (small, _) = noisy_and_guide(dir.path(), 16, 3);
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    let post = |files: Vec<(&'static str, &'static str, Vec<u8>)>, text: Vec<(&'static str, &'static str)>| {
        let base = s.base.clone();
        async move {
            let (st, body, _) = post_job(&base, form(&files, &text)).await;
            (st, body)
        }
    };
    let traversal = br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"../../../etc/passwd"}]}"#.to_vec();
    let absolute = br#"{"asset":{"version":"2.0"},"images":[{"uri":"/etc/shadow"}]}"#.to_vec();
    let draco = br#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"]}"#.to_vec();
    let cases = vec![
        (
            "bomb",
            post(vec![("color", "a.png", png_bomb(100_000, 100_000)), ("guide", "g.exr", read(&guide))], vec![]).await,
            400,
            "100000x100000",
        ),
        (
            "64 Mpx",
            post(vec![("color", "a.png", png_bomb(16000, 16000)), ("guide", "g.exr", read(&guide))], vec![]).await,
            400,
            "exceeds",
        ),
        (
            "sizes",
            post(vec![("color", "c.exr", read(&small)), ("guide", "g.exr", read(&guide))], vec![]).await,
            400,
            "24x24",
        ),
        (
            "not an image",
            post(vec![("color", "c.exr", b"hello".to_vec()), ("guide", "g.exr", read(&guide))], vec![]).await,
            400,
            "judged by its bytes",
        ),
        (
            "normal without albedo",
            post(vec![("color", "c.exr", read(&color)), ("normal", "n.exr", read(&guide))], vec![]).await,
            400,
            "needs an albedo",
        ),
        (
            "unknown field",
            post(vec![("color", "c.exr", read(&color)), ("evil", "e", vec![1])], vec![]).await,
            400,
            "Unknown field",
        ),
        ("empty", post(vec![], vec![("name", "x")]).await, 400, "scene"),
        ("traversal", post(vec![("scene", "s.gltf", traversal)], vec![]).await, 400, "climbs out"),
        ("absolute", post(vec![("scene", "s.gltf", absolute)], vec![]).await, 400, "absolute"),
        ("extension", post(vec![("scene", "s.gltf", draco.clone())], vec![]).await, 400, "KHR_draco_mesh_compression"),
        (
            "spp",
            post(vec![("scene", "s.gltf", read(&repo_scene("cornell-box.gltf")))], vec![("spp", "0")]).await,
            400,
            "spp",
        ),
        (
            "absurd spp",
            post(vec![("scene", "s.gltf", read(&repo_scene("cornell-box.gltf")))], vec![("spp", "99999999999")]).await,
            400,
            "whole number",
        ),
        (
            "resolution",
            post(vec![("scene", "s.gltf", read(&repo_scene("cornell-box.gltf")))], vec![("width", "100000")]).await,
            400,
            "100000",
        ),
    ];
    for (what, got, code, words) in cases {
        refused(what, got, code, words);
    }
    // Over the size limit: 413. The server answers while the client is still sending, so the
    // client may see a broken pipe instead of the answer; it asks again until it gets one.
    let mut answer = None;
    for _ in 0..20 {
        let big = form(&[("color", "c.exr", vec![0x76; 2 << 20])], &[]);
        if let Ok(r) = client().post(format!("{}/api/jobs", s.base)).multipart(big).send().await {
            let code = r.status().as_u16();
            answer = Some((code, r.json::<serde_json::Value>().await.unwrap()));
            break;
        }
    }
    refused("too large", answer.expect("no answer to an oversized upload"), 413, "larger than 1 MiB");
    // Keys: unknown, malformed and traversal-shaped keys all get the same 404.
    let unknown = JobKey::generate().unwrap();
    for path in [
        format!("/api/jobs/{unknown}"),
        "/api/jobs/1234".into(),
        "/api/jobs/..%2F..%2Fetc".into(),
        format!("/api/jobs/{unknown}/result.png"),
    ] {
        let r = client().get(format!("{}{path}", s.base)).send().await.unwrap();
        let code = r.status().as_u16();
        refused(&path, (code, r.json().await.unwrap()), 404, "No such");
    }
    // Ratings are checked before anything is stored.
    let (st, body, _) =
        post_job(&s.base, form(&[("color", "c.exr", read(&color)), ("guide", "g.exr", read(&guide))], &[])).await;
    assert_eq!(st, 201, "{body}");
    let key = body["key"].as_str().unwrap();
    let rate = |k: String, b: &'static str| {
        let url = format!("{}/api/jobs/{k}/rating", s.base);
        async move {
            let r = client().post(url).header("content-type", "application/json").body(b).send().await.unwrap();
            (r.status().as_u16(), r.json::<serde_json::Value>().await.unwrap())
        }
    };
    refused("rating 9", rate(key.into(), r#"{"rating": 9}"#).await, 400, "1 to 5");
    refused("rating text", rate(key.into(), "five stars").await, 400, "JSON");
    refused("rating unknown key", rate(unknown.to_string(), r#"{"rating": 3}"#).await, 404, "No such job");
    // Not done yet (no workers): the result is a 404 too.
    let r = client().get(format!("{}/api/jobs/{key}/result.exr", s.base)).send().await.unwrap();
    assert_eq!(r.status(), 404);
    // Only the one good upload is stored.
    assert_eq!(table_count(&tdb.url, "jobs").await, 1);
    assert_eq!(table_count(&tdb.url, "ratings").await, 0);
    assert_eq!(table_count(&tdb.url, "inputs").await, 2);
    s.server.shutdown().await.unwrap();
}

async fn sql_in_a_name_is_stored_as_text(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 0, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 16, 4);
    let evil = "'); DROP TABLE jobs;--";
    let files =
        [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
    let (st, body, _) = post_job(&s.base, form(&files, &[("name", evil), ("email", "\" OR 1=1 --")])).await;
    assert_eq!(st, 201, "{body}");
    let dbc = Database::connect(&tdb.url).await.unwrap();
    let row = sqlx::query("SELECT name, email FROM jobs").fetch_one(&dbc.pool).await.unwrap();
    assert_eq!(row.try_get::<String, _>(0).unwrap(), evil);
    assert_eq!(row.try_get::<String, _>(1).unwrap(), "\" OR 1=1 --");
    s.server.shutdown().await.unwrap();
}

async fn a_full_queue_answers_503(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 0, test_config().max_queued(2)).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 16, 5);
    let files =
        [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
    for _ in 0..2 {
        assert_eq!(post_job(&s.base, form(&files, &[])).await.0, 201);
    }
    let (st, body, headers) = post_job(&s.base, form(&files, &[])).await;
    refused("full queue", (st, body), 503, "queue is full");
    assert_eq!(headers["retry-after"], "30");
    assert_eq!(table_count(&tdb.url, "jobs").await, 2);
    assert_eq!(table_count(&tdb.url, "inputs").await, 4);
    s.server.shutdown().await.unwrap();
}

async fn queued_jobs_survive_a_restart(db: Db) {
    let tdb = TestDb::new(db).await;
    let dir = tempfile::tempdir().unwrap();
    let first = TestServer::start(&tdb.url, 0, test_config()).await;
    let mut keys = Vec::new();
    for seed in 0..2 {
        let (color, guide) = noisy_and_guide(dir.path(), 16, 10 + seed);
        let files =
            [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
        let (st, body, _) = post_job(&first.base, form(&files, &[])).await;
        assert_eq!(st, 201);
        keys.push((body["key"].as_str().unwrap().to_string(), color, guide));
    }
    first.server.shutdown().await.unwrap();
    let second = TestServer::start(&tdb.url, 1, test_config()).await;
    for (key, color, guide) in keys {
        wait_done(&second.base, &key, Duration::from_secs(60)).await;
        let (code, exr) = get_bytes(&second.base, &format!("/api/jobs/{key}/result.exr")).await;
        assert_eq!((code, exr), (200, cli_denoise(&color, &guide).0));
    }
    second.server.shutdown().await.unwrap();
}

async fn shutdown_gives_running_work_back(db: Db) {
    let tdb = TestDb::new(db).await;
    let config = test_config().render_chunk_spp(100_000);
    let s = TestServer::start(&tdb.url, 1, config.clone()).await;
    let files = [("scene", "c.gltf", std::fs::read(repo_scene("cornell-box.gltf")).unwrap())];
    let (st, body, _) = post_job(&s.base, form(&files, &[("spp", "100000"), ("width", "64")])).await;
    assert_eq!(st, 201, "{body}");
    let key = body["key"].as_str().unwrap().to_string();
    // Wait until the render is under way, then stop the server as SIGTERM would.
    let t = std::time::Instant::now();
    loop {
        let st: serde_json::Value =
            client().get(format!("{}/api/jobs/{key}", s.base)).send().await.unwrap().json().await.unwrap();
        if st["state"] == "running" && st["progress"].as_f64().unwrap() > 0.0 {
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "render never started: {st}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    s.server.shutdown().await.unwrap();
    let dbc = Database::connect(&tdb.url).await.unwrap();
    let row = sqlx::query("SELECT state, attempts, worker FROM tasks WHERE kind = 'render_range'")
        .fetch_one(&dbc.pool)
        .await
        .unwrap();
    assert_eq!(row.try_get::<String, _>(0).unwrap(), "queued", "the running range was not given back");
    assert_eq!(row.try_get::<i64, _>(1).unwrap(), 0, "a given-back task must not count as an attempt");
    assert_eq!(row.try_get::<Option<String>, _>(2).unwrap(), None);
}

async fn finished_jobs_expire_with_their_inputs(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 1, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 16, 6);
    let files =
        [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
    let (_, body, _) = post_job(&s.base, form(&files, &[])).await;
    let key = body["key"].as_str().unwrap().to_string();
    wait_done(&s.base, &key, Duration::from_secs(60)).await;
    let store = JobStore::new(Database::connect(&tdb.url).await.unwrap());
    // Nothing is younger than a cutoff an hour ago; everything is older than one in the future.
    assert_eq!(store.purge_before(rtd::service::now_ms() - 3_600_000).await.unwrap(), 0);
    assert_eq!(store.purge_before(rtd::service::now_ms() + 1000).await.unwrap(), 1);
    assert_eq!(get_bytes(&s.base, &format!("/api/jobs/{key}/result.png")).await.0, 404);
    for table in ["jobs", "inputs", "tasks"] {
        assert_eq!(table_count(&tdb.url, table).await, 0, "{table} kept rows of an expired job");
    }
    s.server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn health_metrics_and_rate_limit() {
    let tdb = TestDb::new(Db::Sqlite).await;
    let s = TestServer::start(&tdb.url, 0, test_config().uploads_per_minute(3)).await;
    assert_eq!(get_bytes(&s.base, "/healthz").await, (200, b"ok\n".to_vec()));
    for _ in 0..3 {
        assert_eq!(post_job(&s.base, form(&[], &[])).await.0, 400);
    }
    let (st, body, headers) = post_job(&s.base, form(&[], &[])).await;
    refused("rate limit", (st, body), 429, "Too many requests");
    assert!(headers.contains_key("retry-after"));
    let (code, text) = get_bytes(&s.base, "/metrics").await;
    let text = String::from_utf8(text).unwrap();
    assert_eq!(code, 200);
    for m in ["rtd_queue_depth 0", "rtd_jobs_done 0", "rtd_jobs_failed 0", "rtd_job_seconds 0", "rtd_workers_seen 0"] {
        assert!(text.contains(m), "{m} missing from {text}");
    }
    let (code, page) = get_bytes(&s.base, "/").await;
    assert!(code == 200 && String::from_utf8(page).unwrap().contains("upload-form"));
    s.server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_large_render_becomes_a_bounded_number_of_ranges() {
    let tdb = TestDb::new(Db::Sqlite).await;
    let s = TestServer::start(&tdb.url, 0, test_config()).await;
    let files = [("scene", "c.gltf", std::fs::read(repo_scene("cornell-box.gltf")).unwrap())];
    let (st, body, _) = post_job(&s.base, form(&files, &[("spp", "1000"), ("width", "8")])).await;
    assert_eq!(st, 201, "{body}");
    let db = Database::connect(&tdb.url).await.unwrap();
    let rows = sqlx::query("SELECT first_sample, samples FROM tasks WHERE kind = 'render_range' ORDER BY first_sample")
        .fetch_all(&db.pool)
        .await
        .unwrap();
    let ranges: Vec<(i64, i64)> = rows.iter().map(|r| (r.try_get(0).unwrap(), r.try_get(1).unwrap())).collect();
    assert!(ranges.len() <= rtd::service::MAX_RANGES_PER_JOB as usize, "{} ranges", ranges.len());
    // The ranges tile 0..1000 without gap or overlap.
    let mut next = 0;
    for (first, n) in &ranges {
        assert_eq!(*first, next);
        next += n;
    }
    assert_eq!(next, 1000);
    s.server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_upload_times_out() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let tdb = TestDb::new(Db::Sqlite).await;
    let s = TestServer::start(&tdb.url, 0, test_config().upload_timeout(Duration::from_secs(1))).await;
    let mut tcp = tokio::net::TcpStream::connect(s.server.addr).await.unwrap();
    let head = "POST /api/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: multipart/form-data; boundary=B\r\nContent-Length: 100000\r\n\r\n--B\r\n";
    tcp.write_all(head.as_bytes()).await.unwrap();
    let mut answer = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(20), tcp.read_to_end(&mut answer)).await;
    let text = String::from_utf8_lossy(&answer);
    assert!(read.is_ok(), "the server waited on the slow upload");
    assert!(text.starts_with("HTTP/1.1 408"), "{text}");
    assert!(text.contains(r#"{"error":"The upload took longer than 1 s."}"#), "{text}");
    assert_eq!(table_count(&tdb.url, "jobs").await, 0);
    s.server.shutdown().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn trickled_headers_time_out() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let tdb = TestDb::new(Db::Sqlite).await;
    let s = TestServer::start(&tdb.url, 0, test_config().upload_timeout(Duration::from_secs(1))).await;
    let mut tcp = tokio::net::TcpStream::connect(s.server.addr).await.unwrap();
    // Slowloris: the request line and one header, then nothing.
    tcp.write_all(b"POST /api/jobs HTTP/1.1\r\nHost: x\r\n").await.unwrap();
    let mut answer = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(20), tcp.read_to_end(&mut answer)).await;
    assert!(read.is_ok(), "the server kept a connection whose headers never ended");
    assert!(!String::from_utf8_lossy(&answer).contains("201"));
    assert_eq!(table_count(&tdb.url, "jobs").await, 0);
    // The server still answers everyone else.
    let ok = client().get(format!("{}/healthz", s.base)).send().await.unwrap();
    assert_eq!(ok.status(), 200);
    s.server.shutdown().await.unwrap();
}

/// A task row no worker can read (here a kind this version does not know) fails with its job
/// at the first claim, instead of coming back every lease.
async fn an_unreadable_task_fails_its_job_once(db: Db) {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 0, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 16, 1);
    let files =
        [("color", "c.exr", std::fs::read(&color).unwrap()), ("guide", "g.exr", std::fs::read(&guide).unwrap())];
    let (status, body, _) = post_job(&s.base, form(&files, &[])).await;
    assert_eq!(status, 201, "{body}");
    let key = body["key"].as_str().unwrap().to_string();
    let dbc = Database::connect(&tdb.url).await.unwrap();
    sqlx::query("UPDATE tasks SET kind = 'from_the_future' WHERE job_key = $1")
        .bind(&key)
        .execute(&dbc.pool)
        .await
        .unwrap();
    let queue = JobQueue::new(dbc.clone());
    let e = queue.claim("node-a", 1).await.unwrap_err().to_string();
    assert!(e.contains("from_the_future"), "{e}");
    tokio::time::sleep(Duration::from_millis(20)).await;
    assert!(queue.claim("node-a", 1).await.unwrap().is_none(), "the lease ran out, yet nothing is claimable");
    let st: serde_json::Value =
        client().get(format!("{}/api/jobs/{key}", s.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(st["state"], "failed", "{st}");
    assert_eq!(st["error"], "The job's record is damaged and cannot be worked on", "{st}");
    s.server.shutdown().await.unwrap();
}
