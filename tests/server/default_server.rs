//! The README's main job as a user runs it: the real `mesobake serve` binary on its default
//! configuration, started from an empty directory (relative `data` paths), bakes an upload
//! end to end, logs every request and job change, exports metrics, and on SIGTERM hands its
//! running job back and exits within the grace period. Also the key commands and the
//! redaction of database passwords.

use crate::binary_server::BinaryServer;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_bake::package::Package;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use serde_json::{Value, json};
use std::process::Command;
use std::time::{Duration, Instant};

fn scene(mesostructure: Value, res: [u32; 3], dirs: [u32; 2]) -> Value {
    json!({
        "base_mesh": { "builtin": { "plane": { "size": 2.0, "segments": 4 } } },
        "mesostructure": mesostructure,
        "resolution": res,
        "directions": dirs,
        "shell": { "thickness": 0.1, "tiles_per_uv": [2, 2] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 48, "height": 48 },
        "lights": [{ "directional": { "direction": [0.3, 0.5, 1.0], "irradiance": [1, 1, 1] } }],
        "effects": ["silhouettes", "shadows"]
    })
}

/// Submits the job `spec`, which must be queued (202), and returns its id.
async fn submit(s: &BinaryServer, spec: &Value) -> String {
    let r = reqwest::Client::new()
        .post(s.url("/api/v1/jobs"))
        .json(spec)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned()
}

async fn wait_for_job(s: &BinaryServer, id: &str, until: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let job: Value = reqwest::get(s.url(&format!("/api/v1/jobs/{id}")))
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        if until(&job) {
            return job;
        }
        assert!(
            start.elapsed() < Duration::from_secs(180),
            "{job}\n{}",
            s.log_text()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_default_server_bakes_an_upload_end_to_end_from_an_empty_directory() {
    let cwd = tempfile::tempdir().unwrap();
    // What a SIGKILLed upload leaves: a temporary blob of a process that is gone.
    let shard = cwd.path().join("data/blobs/ab");
    std::fs::create_dir_all(&shard).unwrap();
    let leftover = shard.join(format!(".ab12.tmp{}-0", 1u32 << 30));
    std::fs::write(&leftover, b"half an upload").unwrap();
    std::fs::File::options()
        .write(true)
        .open(&leftover)
        .unwrap()
        .set_modified(std::time::SystemTime::now() - Duration::from_secs(600))
        .unwrap();

    let mut s = BinaryServer::start(cwd.path(), &[]).await;
    assert!(!leftover.exists(), "the leftover was not removed at start");
    let client = reqwest::Client::new();
    let volume = volume_format::encode(
        &samples::volume(
            SampleKind::Chain,
            Dims::new(16, 16, 8).unwrap(),
            &Limits::default(),
        )
        .unwrap(),
    );
    let r = client
        .post(s.url("/api/v1/assets?kind=volume&name=chain.mbvol"))
        .body(volume)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let digest = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let spec = json!({ "scene": scene(json!({ "volume": digest }), [16, 16, 8], [4, 8]) });
    let id = submit(&s, &spec).await;
    let done = wait_for_job(&s, &id, |j| {
        j["state"] != "queued" && j["state"] != "running"
    })
    .await;
    assert_eq!(done["state"], "succeeded", "{done}\n{}", s.log_text());
    let package = client
        .get(s.url(&format!(
            "/api/v1/packages/{}",
            done["package_digest"].as_str().unwrap()
        )))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let package = Package::parse(package.to_vec()).unwrap();
    assert_eq!(package.manifest().bake.res, [16, 16, 8]);
    assert_eq!(
        package.manifest().codec,
        GdmCodec::Occupancy,
        "the default codec"
    );
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() != Ok("1") {
        let r = client
            .post(s.url("/api/v1/preview"))
            .json(&spec)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
        assert_eq!(r.headers()["x-mesobake-renderer"], "gpu");
        let png = r.bytes().await.unwrap();
        assert_eq!(&png[..4], b"\x89PNG");
    }

    // Everything lives under the working directory, and the log says where, absolutely.
    assert!(cwd.path().join("data/mesobake.sqlite").is_file());
    let blob = cwd
        .path()
        .join(format!("data/blobs/{}/{digest}", &digest[..2]));
    assert!(blob.is_file(), "{}", blob.display());
    let metrics = reqwest::get(s.url("/metrics"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        metrics.contains("mesobake_jobs{state=\"succeeded\"}"),
        "{metrics}"
    );
    assert!(
        metrics.contains("mesobake_stage_seconds_count{stage=\"occupancy\"}"),
        "{metrics}"
    );
    assert!(
        metrics.contains("mesobake_queue_wait_seconds_count"),
        "{metrics}"
    );
    let log = s.log_text();
    let data_dir = cwd.path().join("data");
    assert!(
        log.contains(&format!("data directory {}", data_dir.display())),
        "{log}"
    );
    assert!(log.contains("POST /api/v1/assets 201"), "{log}");
    assert!(log.contains(&format!("job {id} succeeded")), "{log}");

    let (status, took) = s
        .terminate(Duration::from_secs(20))
        .expect("the server did not exit after SIGTERM");
    assert!(status.success(), "{status}: {}", s.log_text());
    eprintln!("exited {took:?} after SIGTERM");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_hands_the_running_job_back_and_exits_within_the_grace_period() {
    let cwd = tempfile::tempdir().unwrap();
    let mut s = BinaryServer::start(
        cwd.path(),
        &[
            ("MESOBAKE_SEED_SAMPLE", "false"),
            ("MESOBAKE_SHUTDOWN_GRACE_MS", "2000"),
        ],
    )
    .await;
    // A bake of several seconds: 128×128×32 voxels × 16×32 directions.
    let spec = json!({
        "scene": scene(json!({ "sample": "chain" }), [128, 128, 32], [16, 32]),
        "codec": "paper-svd"
    });
    let id = submit(&s, &spec).await;
    wait_for_job(&s, &id, |j| j["stage"] == "bake_gdm").await;
    // An open event stream must not hold the shutdown up either.
    let events = reqwest::get(s.url(&format!("/api/v1/jobs/{id}/events")))
        .await
        .unwrap();
    assert_eq!(events.status(), 200);
    let (status, took) = s
        .terminate(Duration::from_secs(6))
        .expect("the server did not exit within the grace period");
    assert!(status.success(), "{status}: {}", s.log_text());
    assert!(took < Duration::from_secs(4), "took {took:?}");
    drop(events);
    let log = s.log_text();
    assert!(
        log.contains(&format!("job {id} handed back to the queue")),
        "{log}"
    );
    // The job is queued again, its attempt not counted, for the next server or worker.
    let db = mesobake_server::db::Db::connect(&format!(
        "sqlite://{}",
        cwd.path().join("data/mesobake.sqlite").display()
    ))
    .await
    .unwrap();
    let job = db.job(&id).await.unwrap().unwrap();
    assert_eq!(job.state, "queued");
    assert_eq!(job.attempts, 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_a_gpu_adapter_previews_render_on_the_cpu_twin_and_say_so() {
    // WGPU_BACKEND names a backend this build lacks: no adapter at all.
    for (fallback, status) in [("cpu", 200), ("none", 503)] {
        let cwd = tempfile::tempdir().unwrap();
        let s = BinaryServer::start(
            cwd.path(),
            &[
                ("MESOBAKE_SEED_SAMPLE", "false"),
                ("WGPU_BACKEND", "gl"),
                ("MESOBAKE_PREVIEW_FALLBACK", fallback),
            ],
        )
        .await;
        let spec = json!({ "scene": scene(json!({ "sample": "weave" }), [16, 16, 8], [4, 8]) });
        let id = submit(&s, &spec).await;
        let done = wait_for_job(&s, &id, |j| j["state"] == "succeeded").await;
        assert_eq!(done["state"], "succeeded");
        let ask = || async {
            reqwest::Client::new()
                .post(s.url("/api/v1/preview"))
                .json(&spec)
                .send()
                .await
                .unwrap()
        };
        let r = ask().await;
        assert_eq!(r.status(), status, "{fallback}");
        if status == 200 {
            assert_eq!(r.headers()["x-mesobake-renderer"], "cpu");
            let png = r.bytes().await.unwrap();
            assert_eq!(&png[..4], b"\x89PNG");
            // The second answer comes from the cache, and still says who drew it.
            let again = ask().await;
            assert_eq!(again.headers()["x-mesobake-renderer"], "cpu");
            assert_eq!(again.bytes().await.unwrap(), png);
            assert!(s.log_text().contains("previews render with the CPU twin"));
        } else {
            let text = r.text().await.unwrap();
            assert!(text.contains("no GPU adapter available"), "{text}");
        }
    }
}

/// `mesobake ARGS` in `cwd` with `env`, the configuration's own variables removed.
fn mesobake_in(cwd: &std::path::Path, args: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_mesobake"));
    for (key, _) in std::env::vars() {
        if key.starts_with("MESOBAKE_") {
            command.env_remove(key);
        }
    }
    command
        .args(args)
        .current_dir(cwd)
        .envs(env.iter().copied())
        .output()
        .unwrap()
}

#[test]
fn keys_are_listed_and_revoked_and_say_where_they_live() {
    let cwd = tempfile::tempdir().unwrap();
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    let out = mesobake_in(
        cwd.path(),
        &["keys", "create", "--scopes", "read", "--label", "ci"],
        &[],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let key = text(&out.stdout).trim().to_owned();
    let database = format!(
        "sqlite://{}",
        cwd.path().join("data/mesobake.sqlite").display()
    );
    assert!(
        text(&out.stderr).contains(&database),
        "{}",
        text(&out.stderr)
    );
    let id = key
        .strip_prefix("mbk_")
        .unwrap()
        .split('_')
        .next()
        .unwrap()
        .to_owned();
    let list = |revoked: bool| {
        let out = mesobake_in(cwd.path(), &["keys", "list"], &[]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let rows: Vec<Value> = text(&out.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0]["id"], id.as_str());
        assert_eq!(rows[0]["label"], "ci");
        assert_eq!(rows[0]["revoked"], revoked);
        assert!(
            !text(&out.stdout).contains(&key),
            "keys are never shown again"
        );
    };
    list(false);
    let out = mesobake_in(cwd.path(), &["keys", "revoke", &id], &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    list(true);
    let out = mesobake_in(cwd.path(), &["keys", "revoke", "0123456789abcdef"], &[]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("no API key has the id"),
        "{}",
        text(&out.stderr)
    );
}

#[tokio::test]
async fn database_passwords_are_redacted_in_what_the_worker_prints() {
    let dir = tempfile::tempdir().unwrap();
    let urls = crate::server_harness::database_urls(dir.path(), "redact").await;
    let Some(postgres) = urls.iter().find(|u| u.starts_with("postgres://")) else {
        return; // skipped loudly by database_urls
    };
    // Trust authentication ignores the password, so the worker connects with it.
    let url = postgres.replacen("postgres://postgres@", "postgres://postgres:S3cretPW@", 1);
    let log = dir.path().join("worker.log");
    let mut command = Command::new(env!("CARGO_BIN_EXE_mesobake"));
    for (key, _) in std::env::vars() {
        if key.starts_with("MESOBAKE_") {
            command.env_remove(key);
        }
    }
    let mut child = command
        .arg("worker")
        .current_dir(dir.path())
        .env("MESOBAKE_DATABASE_URL", &url)
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !std::fs::read_to_string(&log)
        .unwrap()
        .contains("worker(s) on")
    {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "{}",
            std::fs::read_to_string(&log).unwrap()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    let status = child.wait().unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(
        text.contains("postgres://postgres:***@127.0.0.1:5432/"),
        "{text}"
    );
    assert!(!text.contains("S3cretPW"), "{text}");
}
