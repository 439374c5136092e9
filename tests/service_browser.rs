//! The pages in a real browser: headless Chromium, driven through ChromeDriver over WebDriver,
//! uploads a noisy image and its guide on `/`, waits on the job page for the result, moves the
//! before/after slider, zooms and rates the job. Checks the DOM and the stored rating, and
//! saves a screenshot to `target/browser/job-page.png`.

mod service_support;

use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{ClientBuilder, Locator};
use service_support::*;

/// ChromeDriver on a free loopback port, killed when dropped.
struct Driver(Child, u16);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_chromedriver() -> Driver {
    let exe = std::env::var("RTD_TEST_CHROMEDRIVER").unwrap_or_else(|_| "/usr/bin/chromedriver".into());
    assert!(
        std::path::Path::new(&exe).exists(),
        "{exe} is missing: run the tests with .ci/run, which installs chromium-driver"
    );
    let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let child =
        Command::new(exe).arg(format!("--port={port}")).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    Driver(child, port)
}

async fn connect(port: u16) -> fantoccini::Client {
    let chromium = std::env::var("RTD_TEST_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    let profile = tempfile::tempdir().unwrap().keep();
    let caps = serde_json::json!({
        "browserName": "chrome",
        "goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-quic",
                     "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync",
                     "--window-size=1280,1000", format!("--user-data-dir={}", profile.display())]
        }
    });
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    let t = Instant::now();
    loop {
        match ClientBuilder::new(connector.clone())
            .capabilities(caps.as_object().unwrap().clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
        {
            Ok(c) => return c,
            Err(e) if t.elapsed() < Duration::from_secs(20) => {
                let _ = e;
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            Err(e) => panic!("cannot start Chromium through ChromeDriver: {e}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_watch_compare_and_rate_in_chromium() {
    let tdb = TestDb::new(Db::Sqlite).await;
    let s = TestServer::start(&tdb.url, 1, test_config()).await;
    let dir = tempfile::tempdir().unwrap();
    let (color, guide) = noisy_and_guide(dir.path(), 96, 7);
    let driver = start_chromedriver();
    let c = connect(driver.1).await;
    let wait = Duration::from_secs(60);

    c.goto(&s.base).await.unwrap();
    c.find(Locator::Id("what-is-a-guide")).await.expect("the page explains what a guide is");
    c.find(Locator::Id("color")).await.unwrap().send_keys(color.to_str().unwrap()).await.unwrap();
    c.find(Locator::Id("guide")).await.unwrap().send_keys(guide.to_str().unwrap()).await.unwrap();
    c.find(Locator::Id("name")).await.unwrap().send_keys("Browser test").await.unwrap();
    c.find(Locator::Id("submit")).await.unwrap().click().await.unwrap();

    // The job page: state and progress go live, then both images load.
    // Polled by hand: a query that meets the navigation from / to the job page is answered
    // "aborted by navigation", which is not a failure, so it is asked again.
    let t = Instant::now();
    while c.find(Locator::Css("#compare[data-ready='true']")).await.is_err() {
        assert!(t.elapsed() < wait, "the result never showed");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let url = c.current_url().await.unwrap();
    let key = url.path().strip_prefix("/jobs/").expect("the upload did not lead to the job page").to_string();
    assert_eq!(c.find(Locator::Id("state")).await.unwrap().text().await.unwrap(), "done");
    let progress = c.execute("return document.getElementById('progress').value;", vec![]).await.unwrap();
    assert_eq!(progress, serde_json::json!(1));
    let natural = c
        .execute("const a = document.getElementById('after'); return [a.naturalWidth, a.naturalHeight];", vec![])
        .await
        .unwrap();
    assert_eq!(natural, serde_json::json!([96, 96]), "the result image is not the job's");

    // The slider, moved with the keyboard as a user would, moves the split.
    let slider = c.find(Locator::Id("slider")).await.unwrap();
    assert_eq!(c.find(Locator::Id("compare")).await.unwrap().attr("data-split").await.unwrap().as_deref(), Some("50"));
    slider.send_keys(&"\u{E012}".repeat(20)).await.unwrap(); // ArrowLeft x 20
    let split = c.find(Locator::Id("compare")).await.unwrap().attr("data-split").await.unwrap().unwrap();
    assert_eq!(split, "30", "the split did not follow the slider");
    c.execute("const z = document.getElementById('zoom'); z.value = 3; z.dispatchEvent(new Event('input'));", vec![])
        .await
        .unwrap();
    let zoomed = c.execute("return document.getElementById('stage').style.transform;", vec![]).await.unwrap();
    assert!(zoomed.as_str().unwrap_or("").contains('3'), "zoom did not scale the images: {zoomed}");

    let dir_out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/browser");
    std::fs::create_dir_all(&dir_out).unwrap();
    std::fs::write(dir_out.join("job-page.png"), c.screenshot().await.unwrap()).unwrap();

    // The rating form.
    c.find(Locator::Id("rating-4")).await.unwrap().click().await.unwrap();
    c.find(Locator::Id("comment")).await.unwrap().send_keys("sharp edges").await.unwrap();
    c.find(Locator::Id("rate")).await.unwrap().click().await.unwrap();
    let thanks = c.wait().at_most(wait).for_element(Locator::Id("rated")).await.unwrap();
    assert_eq!(thanks.text().await.unwrap(), "Thanks — rated 4/5.");
    let st: serde_json::Value =
        client().get(format!("{}/api/jobs/{key}", s.base)).send().await.unwrap().json().await.unwrap();
    assert_eq!(st["rating"], serde_json::json!({"rating": 4, "comment": "sharp edges"}));
    c.close().await.unwrap();
    s.server.shutdown().await.unwrap();
}
