//! The web page in a real headless browser (Debian's chromium and chromedriver, driven over
//! WebDriver with fantoccini): upload a sample volume, bake it and watch the job finish, see
//! the preview image change when a control moves, on the real binary's default
//! configuration. Skipped loudly when chromedriver is
//! missing, unless MESOBAKE_REQUIRE_BROWSER=1 (set by `.ci/run`, which installs it).

use crate::binary_server::BinaryServer;
use fantoccini::{ClientBuilder, Locator};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// chromedriver on a free port, killed on drop.
struct Driver(Child, u16);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_driver() -> Option<Driver> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .ok()?
        .local_addr()
        .ok()?
        .port();
    match Command::new("chromedriver")
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
    {
        Ok(child) => Some(Driver(child, port)),
        Err(e) if std::env::var("MESOBAKE_REQUIRE_BROWSER").as_deref() == Ok("1") => {
            panic!("chromedriver is required but did not start: {e}")
        }
        Err(e) => {
            eprintln!("SKIPPED: chromedriver did not start ({e}); install chromium-driver");
            None
        }
    }
}

/// Polls `check` until it gives a value, failing after `secs` seconds with `what`.
async fn eventually<T, F, Fut>(secs: u64, what: &str, mut check: F) -> T
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Option<T>>,
{
    let start = Instant::now();
    loop {
        if let Some(v) = check().await {
            return v;
        }
        assert!(
            start.elapsed() < Duration::from_secs(secs),
            "timed out waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// Polls `script` (JavaScript returning a boolean) until it returns true, failing after
/// `secs` seconds with `what`.
async fn until_true(c: &fantoccini::Client, secs: u64, what: &str, script: &str) {
    eventually(secs, what, || async {
        c.execute(script, vec![])
            .await
            .ok()?
            .as_bool()
            .filter(|done| *done)
    })
    .await;
}

/// Clicks the element with id `id`.
async fn click(c: &fantoccini::Client, id: &str) {
    c.find(Locator::Id(id))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_bake_and_preview_in_a_browser() {
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1 (the page's preview needs a GPU adapter)");
        return;
    }
    let Some(driver) = start_driver() else { return };
    // The README's main job: the real binary on its default configuration, started from an
    // empty directory.
    let dir = tempfile::tempdir().unwrap();
    let s = BinaryServer::start(dir.path(), &[]).await;
    // The volume to upload: the sample scene's mesostructure at its resolution.
    let volume = samples::volume(
        SampleKind::Weave,
        Dims::new(64, 64, 32).unwrap(),
        &Limits::default(),
    )
    .unwrap();
    let file = dir.path().join("weave.mbvol");
    mesobake_bake::mesostructure::volume_format::write(&volume, &file).unwrap();

    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        serde_json::json!({ "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1300,1000"] }),
    );
    let driver_url = format!("http://127.0.0.1:{}", driver.1);
    let c = eventually(20, "chromedriver", || {
        let caps = caps.clone();
        let url = driver_url.clone();
        async move {
            ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
                .capabilities(caps)
                .connect(&url)
                .await
                .ok()
        }
    })
    .await;
    c.goto(&s.url("/")).await.unwrap();
    eventually(20, "the sample scene in the editor", || async {
        let text = c
            .find(Locator::Id("scene-json"))
            .await
            .ok()?
            .prop("value")
            .await
            .ok()??;
        text.contains("torus").then_some(())
    })
    .await;

    // Upload.
    c.find(Locator::Id("upload-file"))
        .await
        .unwrap()
        .send_keys(file.to_str().unwrap())
        .await
        .unwrap();
    c.find(Locator::Id("upload-button"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let digest = mesobake_server::blobs::key_of(&std::fs::read(&file).unwrap());
    eventually(30, "the upload's digest", || async {
        let text = c
            .find(Locator::Id("upload-status"))
            .await
            .ok()?
            .text()
            .await
            .ok()?;
        text.contains(&digest).then_some(())
    })
    .await;
    let scene = c
        .find(Locator::Id("scene-json"))
        .await
        .unwrap()
        .prop("value")
        .await
        .unwrap()
        .unwrap();
    assert!(
        scene.contains(&digest),
        "the scene does not name the upload: {scene}"
    );

    // Bake, and watch the job finish in the list.
    c.find(Locator::Id("bake-button"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    eventually(120, "a succeeded job in the list", || async {
        let cells = c.find_all(Locator::Css("#jobs .job-state")).await.ok()?;
        for cell in cells {
            if cell.text().await.ok()? == "succeeded" {
                return Some(());
            }
        }
        None
    })
    .await;

    // The figures list every codec on the sample scenes, this package's (the default,
    // occupancy) highlighted, with a plot per scene.
    let current = eventually(60, "the codec table", || async {
        let rows = c
            .find_all(Locator::Css("#codec-table tr.current"))
            .await
            .ok()?;
        let mut texts = Vec::new();
        for row in rows {
            texts.push(row.text().await.ok()?);
        }
        (!texts.is_empty()).then_some(texts)
    })
    .await;
    assert!(
        current.iter().all(|t| t.contains("occupancy")),
        "{current:?}"
    );
    let plots = c.find_all(Locator::Css("svg.codec-plot")).await.unwrap();
    assert_eq!(plots.len(), 2);

    // A preview, then another after the orbit control moves.
    let hash = |c: fantoccini::Client| async move {
        let v = c
            .execute(
                "const img = document.getElementById('preview'); \
                 return [img.dataset.sceneHash || null, img.naturalWidth];",
                vec![],
            )
            .await
            .ok()?;
        let hash = v[0].as_str()?.to_owned();
        (v[1].as_u64()? > 0).then_some(hash)
    };
    c.find(Locator::Id("preview-button"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let first = eventually(120, "the first preview", || hash(c.clone())).await;
    c.execute(
        "const el = document.getElementById('orbit-azimuth'); el.value = 90; \
         el.dispatchEvent(new Event('input'));",
        vec![],
    )
    .await
    .unwrap();
    let second = eventually(120, "a new preview after orbiting", || async {
        hash(c.clone()).await.filter(|h| *h != first)
    })
    .await;
    assert_ne!(first, second);

    // A scene edit marks the shown preview stale until it is rendered again.
    let stale = |c: fantoccini::Client| async move {
        c.execute(
            "return [document.getElementById('preview').classList.contains('stale'), \
             !document.getElementById('preview-stale').hidden];",
            vec![],
        )
        .await
        .unwrap()
    };
    assert_eq!(stale(c.clone()).await, serde_json::json!([false, false]));
    c.execute(
        "const t = document.getElementById('scene-json'); const s = JSON.parse(t.value); \
         s.lights[0].point.intensity = [50, 50, 50]; t.value = JSON.stringify(s, null, 2); \
         t.dispatchEvent(new Event('input'));",
        vec![],
    )
    .await
    .unwrap();
    assert_eq!(stale(c.clone()).await, serde_json::json!([true, true]));

    // Background and exposure change the display only.
    let shown = c
        .execute(
            "const e = document.getElementById('preview-exposure'); e.value = 2; \
             e.dispatchEvent(new Event('input')); \
             const b = document.getElementById('preview-background'); b.value = '#fff'; \
             b.dispatchEvent(new Event('change')); const i = document.getElementById('preview'); \
             return [i.style.filter, getComputedStyle(i).backgroundColor, \
             document.getElementById('preview-exposure-out').textContent];",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        shown,
        serde_json::json!(["brightness(4)", "rgb(255, 255, 255)", "+2 EV"])
    );

    // The quality control writes the preset into the scene (the paper's is left out) and
    // marks the shown preview stale.
    let quality = c
        .execute(
            "const q = document.getElementById('quality'); q.value = 'high'; \
             q.dispatchEvent(new Event('change')); \
             const high = JSON.parse(document.getElementById('scene-json').value).quality; \
             q.value = 'paper'; q.dispatchEvent(new Event('change')); \
             const paper = JSON.parse(document.getElementById('scene-json').value).quality; \
             return [high, paper === undefined, \
             document.getElementById('preview').classList.contains('stale')];",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(quality, serde_json::json!(["high", true, true]));

    // A height-field relief on the (closed) torus, in a shell thin enough for the VDM's
    // curvature range: the technique stays auto, the job's plan picks VDM and the job list
    // says so, and the preview is drawn by the VDM pipeline.
    let chosen = c
        .execute(
            "const m = document.getElementById('sample'); m.value = 'relief:bumps'; \
             m.dispatchEvent(new Event('change')); \
             const t = document.getElementById('scene-json'); \
             const thin = JSON.parse(t.value); thin.shell.thickness = 0.04; \
             t.value = JSON.stringify(thin, null, 2); \
             const s = JSON.parse(document.getElementById('scene-json').value); \
             return [s.mesostructure, s.resolution[0] === s.resolution[1], \
             document.getElementById('technique').value];",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        chosen,
        serde_json::json!([{ "relief": "bumps" }, true, "auto"])
    );
    click(&c, "bake-button").await;
    until_true(
        &c,
        120,
        "a succeeded VDM job in the list",
        "return [...document.querySelectorAll('#jobs tbody tr')].some((tr) => \
         tr.querySelector('.job-technique').textContent === 'vdm' && \
         tr.querySelector('.job-state').textContent === 'succeeded');",
    )
    .await;
    click(&c, "preview-button").await;
    until_true(
        &c,
        120,
        "a preview by the VDM pipeline",
        "const img = document.getElementById('preview'); \
         return img.dataset.technique === 'vdm' && img.naturalWidth > 0 && \
         document.getElementById('preview-status').textContent.includes('VDM pipeline');",
    )
    .await;

    // The shipped fur scene from the sample-scene list (shrunk): the job's plan picks the
    // transparency technique, its figures show the medium package, and the preview is drawn
    // by the translucent-media pipeline.
    until_true(
        &c,
        30,
        "the sample-scene list",
        "return !!document.querySelector('#sample-scene option[value=\"torus-fur\"]');",
    )
    .await;
    c.execute(
        "const m = document.getElementById('sample-scene'); m.value = 'torus-fur'; \
         m.dispatchEvent(new Event('change'));",
        vec![],
    )
    .await
    .unwrap();
    until_true(
        &c,
        30,
        "the fur scene in the editor",
        "const t = document.getElementById('scene-json'); const s = JSON.parse(t.value); \
         if (!s.mesostructure || s.mesostructure.medium !== 'fur') return false; \
         s.resolution = [16, 16, 8]; s.camera.width = 64; s.camera.height = 64; \
         s.base_mesh.builtin.torus.segments = [24, 12]; \
         t.value = JSON.stringify(s, null, 2); \
         return document.getElementById('sample').value === 'medium:fur';",
    )
    .await;
    click(&c, "bake-button").await;
    until_true(
        &c,
        120,
        "a succeeded transparency job with its medium package",
        "const row = [...document.querySelectorAll('#jobs tbody tr')].find((tr) => \
         tr.querySelector('.job-technique').textContent === 'transparency' && \
         tr.querySelector('.job-state').textContent === 'succeeded'); \
         if (row) row.click(); \
         return !!row && document.getElementById('figures').textContent \
         .includes('transparency (semi-transparent 3D texture)');",
    )
    .await;
    click(&c, "preview-button").await;
    until_true(
        &c,
        120,
        "a preview by the translucent-media pipeline",
        "const img = document.getElementById('preview'); \
         return img.dataset.technique === 'transparency' && img.naturalWidth > 0;",
    )
    .await;

    // The scene of several objects from the list (shrunk): the preview waits for every
    // object's package and draws them together by the GDM pipeline; baking names a job per
    // object.
    c.execute(
        "const m = document.getElementById('sample-scene'); m.value = 'torus-over-weave'; \
         m.dispatchEvent(new Event('change'));",
        vec![],
    )
    .await
    .unwrap();
    until_true(
        &c,
        30,
        "the scene of several objects in the editor",
        "const t = document.getElementById('scene-json'); const s = JSON.parse(t.value); \
         if (!Array.isArray(s.objects)) return false; \
         s.resolution = [16, 16, 8]; s.camera.width = 64; s.camera.height = 64; \
         s.objects[1].base_mesh.builtin.torus.segments = [24, 12]; \
         t.value = JSON.stringify(s, null, 2); return true;",
    )
    .await;
    click(&c, "preview-button").await;
    until_true(
        &c,
        240,
        "a preview of both objects",
        "const img = document.getElementById('preview'); \
         return img.dataset.technique === 'gdm' && img.naturalWidth === 64 && \
         document.getElementById('preview-status').textContent.startsWith('Rendered');",
    )
    .await;
    click(&c, "bake-button").await;
    until_true(
        &c,
        30,
        "a job per object",
        "return /one per object: ground: .*, torus: /.test( \
         document.getElementById('bake-status').textContent);",
    )
    .await;

    // A job put back in the queue after a failed attempt says it is retrying, with the count,
    // and a long error wraps inside the table (the view as the server sends it).
    let retrying = c
        .execute(
            "upsert({id: 'retrying-job-0000', state: 'queued', stage: 'bake_gdm', progress: 0, \
             attempts: 1, max_attempts: 3, plan: {stages: [], skipped: []}, timings: {}, \
             error: 'x'.repeat(600), package_digest: null, cancel_requested: false, \
             created_ms: Date.now(), updated_ms: Date.now()}); \
             const tr = document.querySelector('tr[data-job-id=\"retrying-job-0000\"]'); \
             const table = document.getElementById('jobs'); \
             return [tr.querySelector('.job-state').textContent, \
             table.scrollWidth <= table.parentElement.clientWidth + 1];",
            vec![],
        )
        .await
        .unwrap();
    assert_eq!(
        retrying,
        serde_json::json!(["retrying (attempt 2 of 3)", true])
    );

    // On a narrow window nothing sticks out sideways.
    c.set_window_size(400, 900).await.unwrap();
    let fits = eventually(10, "the page to fit a 400-pixel window", || async {
        let v = c
            .execute(
                "return document.documentElement.scrollWidth <= window.innerWidth;",
                vec![],
            )
            .await
            .ok()?;
        v.as_bool().filter(|f| *f)
    })
    .await;
    assert!(fits);
    c.close().await.unwrap();
}
