//! Load: 50 uploads at once from a bounded client loop against a real server with two
//! workers. Every job completes, every result is its own input's `rtd denoise` result (so
//! nothing is mixed up) and nothing is lost. Throughput and latency are printed and written to
//! `target/service-load.json` (the README quotes them); they are measured here, not asserted.

mod service_support;

use std::sync::Arc;
use std::time::{Duration, Instant};

use futures::stream::{self, StreamExt};
use service_support::*;

const JOBS: usize = 50;
/// Uploads in flight at once: the client loop's bound.
const IN_FLIGHT: usize = 16;

async fn load(db: Db) -> serde_json::Value {
    let tdb = TestDb::new(db).await;
    let s = TestServer::start(&tdb.url, 2, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    // Distinct inputs: each seed gives other noise, hence another result.
    let inputs: Vec<_> = (0..JOBS as u64).map(|seed| noisy_and_guide(dir.path(), 32, 100 + seed)).collect();
    let expected: Vec<Vec<u8>> = inputs.iter().map(|(c, g)| cli_denoise(c, g).1).collect();
    assert!(expected.windows(2).any(|w| w[0] != w[1]), "the inputs must differ for the check to mean anything");
    let base = Arc::new(s.base.clone());
    let start = Instant::now();
    let latencies: Vec<(usize, Duration)> = stream::iter(inputs.iter().enumerate())
        .map(|(i, (color, guide))| {
            let (base, expected) = (base.clone(), &expected);
            async move {
                let t = Instant::now();
                let files = [
                    ("color", "c.exr", std::fs::read(color).unwrap()),
                    ("guide", "g.exr", std::fs::read(guide).unwrap()),
                ];
                let (status, body, _) = post_job(&base, form(&files, &[])).await;
                assert_eq!(status, 201, "upload {i}: {body}");
                let key = body["key"].as_str().unwrap().to_string();
                wait_done(&base, &key, Duration::from_secs(300)).await;
                let (code, png) = get_bytes(&base, &format!("/api/jobs/{key}/result.png")).await;
                assert_eq!(code, 200);
                assert!(png == expected[i], "job {i}'s result is not its own input's");
                (i, t.elapsed())
            }
        })
        .buffer_unordered(IN_FLIGHT)
        .collect()
        .await;
    let wall = start.elapsed().as_secs_f64();
    assert_eq!(latencies.len(), JOBS);
    let mut ms: Vec<f64> = latencies.iter().map(|(_, d)| d.as_secs_f64() * 1000.0).collect();
    ms.sort_by(f64::total_cmp);
    let pct = |p: f64| ms[((ms.len() - 1) as f64 * p).round() as usize];
    let counts =
        rtd::service::JobStore::new(rtd::service::Database::connect(&tdb.url).await.unwrap()).counts().await.unwrap();
    assert_eq!((counts.done, counts.failed, counts.queued, counts.running), (JOBS as i64, 0, 0, 0), "a job was lost");
    s.server.shutdown().await.unwrap();
    let report = serde_json::json!({
        "database": format!("{db:?}"), "jobs": JOBS, "in_flight": IN_FLIGHT, "workers": 2, "image": "32x32 EXR",
        "wall_s": wall, "jobs_per_s": JOBS as f64 / wall, "p50_ms": pct(0.5), "p99_ms": pct(0.99),
    });
    println!("service load: {report}");
    report
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_concurrent_uploads_all_complete_unmixed() {
    let reports = vec![load(Db::Sqlite).await, load(Db::Postgres).await];
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/service-load.json");
    rtd::image::write_json(&path, &reports).unwrap();
}
