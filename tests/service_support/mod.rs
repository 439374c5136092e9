//! What the service tests share: a real server on 127.0.0.1 with an ephemeral port, on a
//! throwaway SQLite file or a fresh PostgreSQL database, and inputs whose command-line
//! results are known.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rtd::denoise::Denoiser;
use rtd::service::{sqlite_url, start_server, Database, RunningServer, ServiceConfig};

/// The PostgreSQL server the tests use: `RTD_TEST_POSTGRES` (an admin URL such as
/// postgres://rtd:rtd@127.0.0.1:54329/postgres), which `.ci/run` sets after starting a cluster.
pub const POSTGRES_ENV: &str = "RTD_TEST_POSTGRES";

/// Which database a test runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Db {
    /// A new SQLite file.
    Sqlite,
    /// A new database on the test PostgreSQL server.
    Postgres,
}

/// A database URL for one test, with the folder (SQLite) kept alive beside it.
pub struct TestDb {
    /// The URL.
    pub url: String,
    _dir: Option<tempfile::TempDir>,
}

/// The admin URL of the test PostgreSQL server. Without it the PostgreSQL tests fail rather
/// than pass unseen: run them through `.ci/run`, which starts one.
pub fn postgres_admin_url() -> String {
    std::env::var(POSTGRES_ENV).unwrap_or_else(|_| {
        panic!("{POSTGRES_ENV} is not set: run the tests with .ci/run, which starts a throwaway PostgreSQL")
    })
}

impl TestDb {
    /// A fresh, empty database of kind `db`.
    pub async fn new(db: Db) -> TestDb {
        match db {
            Db::Sqlite => {
                let dir = tempfile::tempdir().unwrap();
                TestDb { url: sqlite_url(dir.path()), _dir: Some(dir) }
            }
            Db::Postgres => {
                let admin = postgres_admin_url();
                sqlx::any::install_default_drivers();
                let name = format!("rtd_test_{}", &rtd::service::JobKey::generate().unwrap().as_str()[..16]);
                let mut conn = <sqlx::AnyConnection as sqlx::Connection>::connect(&admin).await.unwrap();
                sqlx::Executor::execute(&mut conn, format!("CREATE DATABASE {name}").as_str()).await.unwrap();
                let base = admin.rsplit_once('/').unwrap().0;
                TestDb { url: format!("{base}/{name}"), _dir: None }
            }
        }
    }
}

/// The built-in denoiser, loaded once per test binary.
pub fn denoiser() -> Arc<Denoiser> {
    static MODEL: std::sync::OnceLock<Arc<Denoiser>> = std::sync::OnceLock::new();
    MODEL.get_or_init(|| Arc::new(Denoiser::builtin().unwrap())).clone()
}

/// Settings for tests: short leases, quick polling, small render ranges.
pub fn test_config() -> ServiceConfig {
    ServiceConfig::default()
        .lease(Duration::from_secs(3))
        .poll(Duration::from_millis(50))
        .render_chunk_spp(3)
        .threads(Some(1))
        .uploads_per_minute(10_000)
}

/// A server on 127.0.0.1 and its base URL.
pub struct TestServer {
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// The running server.
    pub server: RunningServer,
}

impl TestServer {
    /// Starts a server on `url` with `workers` in-process workers.
    pub async fn start(url: &str, workers: usize, config: ServiceConfig) -> TestServer {
        let db = Database::connect(url).await.unwrap();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let server = start_server(listener, db, workers, denoiser(), config, std::future::pending()).await.unwrap();
        TestServer { base: format!("http://{}", server.addr), server }
    }
}

/// An HTTP client that never uses a proxy.
pub fn client() -> reqwest::Client {
    reqwest::Client::builder().no_proxy().timeout(Duration::from_secs(120)).build().unwrap()
}

/// A multipart form of files `(field, file name, bytes)` and text fields.
pub fn form(files: &[(&str, &str, Vec<u8>)], text: &[(&str, &str)]) -> reqwest::multipart::Form {
    let mut f = reqwest::multipart::Form::new();
    for (field, name, bytes) in files {
        f = f.part(field.to_string(), reqwest::multipart::Part::bytes(bytes.clone()).file_name(name.to_string()));
    }
    for (k, v) in text {
        f = f.text(k.to_string(), v.to_string());
    }
    f
}

/// Posts `form` to `/api/jobs`; returns the status and the JSON body.
pub async fn post_job(
    base: &str,
    form: reqwest::multipart::Form,
) -> (u16, serde_json::Value, reqwest::header::HeaderMap) {
    let r = client().post(format!("{base}/api/jobs")).multipart(form).send().await.unwrap();
    let status = r.status().as_u16();
    let headers = r.headers().clone();
    (status, r.json().await.unwrap(), headers)
}

/// Waits until job `key` is done (panics if it fails or takes over `limit`); returns its status.
pub async fn wait_done(base: &str, key: &str, limit: Duration) -> serde_json::Value {
    let t = Instant::now();
    loop {
        let s: serde_json::Value =
            client().get(format!("{base}/api/jobs/{key}")).send().await.unwrap().json().await.unwrap();
        match s["state"].as_str().unwrap() {
            "done" => return s,
            "failed" => panic!("job {key} failed: {s}"),
            _ if t.elapsed() > limit => panic!("job {key} not done after {limit:?}: {s}"),
            _ => tokio::time::sleep(Duration::from_millis(50)).await,
        }
    }
}

/// The bytes of `GET {base}{path}`, with its status.
pub async fn get_bytes(base: &str, path: &str) -> (u16, Vec<u8>) {
    let r = client().get(format!("{base}{path}")).send().await.unwrap();
    (r.status().as_u16(), r.bytes().await.unwrap().to_vec())
}

/// A noisy render and its guide as EXR files in `dir`, made with the library as `rtd render`
/// and `rtd guide` make them; `seed` varies the noise. Returns (color, guide).
pub fn noisy_and_guide(dir: &Path, size: u32, seed: u64) -> (PathBuf, PathBuf) {
    use rtd::guide::{GuidePass, GuideSettings};
    use rtd::pipeline::{Budget, CameraChoice, Pipeline, SceneView};
    use rtd::render::RenderSettings;
    let view = SceneView::load(&repo_scene("cornell-box.gltf"), &CameraChoice::Default, None).unwrap();
    let run = Pipeline::new(&view, RenderSettings::new(size, size).seed(seed).threads(Some(1)))
        .run(Budget::Samples(2), &rtd::image::Quiet)
        .unwrap();
    let color = dir.join(format!("noisy-{seed}.exr"));
    run.write(&color, 0.0, rtd::image::Tonemap::Clamp).unwrap();
    let pass =
        GuidePass::render(&view.scene.scene, &view.scene.bvh, &view.camera, &GuideSettings::new(size, size)).unwrap();
    let guide = dir.join(format!("guide-{seed}.exr"));
    let mut layers = rtd::image::Layers::new(size, size);
    pass.add_to(&mut layers);
    rtd::image::write_exr(&guide, &layers).unwrap();
    (color, guide)
}

/// A bundled scene's path.
pub fn repo_scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)
}

/// What `rtd denoise --color C --guide G -o out.{exr,png}` writes, as bytes (exr, png).
pub fn cli_denoise(color: &Path, guide: &Path) -> (Vec<u8>, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    let sources = rtd::pipeline::DenoiseSources::new(color).guide(Some(guide.to_path_buf()));
    let (exr, png) = (dir.path().join("out.exr"), dir.path().join("out.png"));
    sources.run(&denoiser(), &exr, 0.0).unwrap();
    sources.run(&denoiser(), &png, 0.0).unwrap();
    (std::fs::read(exr).unwrap(), std::fs::read(png).unwrap())
}
