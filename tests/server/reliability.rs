//! The server under load and failure: concurrent uploads, worker processes killed with
//! SIGKILL mid-bake on PostgreSQL, a server process killed and restarted mid-job, and a blob
//! store that refuses writes.

use crate::server_harness::{TestServer, database_urls};
use futures_util::future::join_all;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_bake::mesostructure::volume_format;
use mesobake_bake::package::Package;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_server::jobs::JobSpec;
use mesobake_server::spawn_workers;
use serde_json::json;
use std::process::{Child, Command};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_concurrent_8mb_uploads_are_stored_once_and_intact() {
    let dir = tempfile::tempdir().unwrap();
    let url = database_urls(dir.path(), "concurrent").await.pop().unwrap();
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(&url, data.path(), 16 << 20).await;
    // 25 distinct 128³ volumes (8.4 MB each), each uploaded twice at the same time.
    let dims = Dims::new(128, 128, 128).unwrap();
    let bodies: Vec<Vec<u8>> = (0..25u32)
        .map(|n| {
            let v = Volume::from_fn(dims, &Limits::default(), |i, j, k| {
                (i * 7 + j * 3 + k + n) % 29 < 9
            })
            .unwrap();
            volume_format::encode(&v)
        })
        .collect();
    assert!(bodies[0].len() > 8_000_000);
    let client = reqwest::Client::new();
    let requests = bodies.iter().chain(&bodies).map(|b| {
        client
            .post(s.url("/api/v1/assets?kind=volume&name=v.mbvol"))
            .body(b.clone())
            .send()
    });
    let answers = join_all(requests).await;
    let mut created = std::collections::HashMap::new();
    for r in answers {
        let r = r.unwrap();
        let status = r.status().as_u16();
        assert!(status == 201 || status == 200, "{status}");
        let id = r.json::<serde_json::Value>().await.unwrap()["id"]
            .as_str()
            .unwrap()
            .to_owned();
        *created.entry(id).or_insert(0) += (status == 201) as u32;
    }
    assert_eq!(created.len(), 25);
    assert!(
        created.values().all(|&n| n == 1),
        "each volume created exactly once: {created:?}"
    );
    for body in &bodies {
        let key = mesobake_server::blobs::key_of(body);
        assert_eq!(s.state.blobs.get(&key).unwrap().as_deref(), Some(&body[..]));
    }
    let rows: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM assets")
        .fetch_one(&s.state.db.pool)
        .await
        .unwrap();
    assert_eq!(rows, 25);
    // No temporary files left beside the blobs.
    let mut files = 0;
    for sub in std::fs::read_dir(data.path().join("blobs")).unwrap() {
        for f in std::fs::read_dir(sub.unwrap().path()).unwrap() {
            let name = f.unwrap().file_name().into_string().unwrap();
            assert!(mesobake_server::blobs::is_key(&name), "stray file {name}");
            files += 1;
        }
    }
    assert_eq!(files, 25);
}

fn spec(sample: &str, rank: usize, dirs: [u32; 2]) -> JobSpec {
    serde_json::from_value(json!({
        "scene": {
            "base_mesh": { "builtin": { "plane": { "segments": 4 } } },
            "mesostructure": { "sample": sample },
            "resolution": [16, 16, 8],
            "directions": dirs,
            "shell": { "thickness": 0.1, "tiles_per_uv": [2, 2] },
            "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 8, "height": 8 }
        },
        "codec": "paper-svd",
        "rank": rank,
    }))
    .unwrap()
}

/// A child process of `mesobake`, killed (SIGKILL) when dropped.
struct Process(Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `mesobake COMMAND` (`worker` or `serve`) with one worker over `database_url` and
/// `data_dir`, configured by environment variables `extra` beyond those.
fn mesobake(
    command: &str,
    database_url: &str,
    data_dir: &std::path::Path,
    extra: &[(&str, &str)],
) -> Process {
    Process(
        Command::new(env!("CARGO_BIN_EXE_mesobake"))
            .arg(command)
            .env("MESOBAKE_DATABASE_URL", database_url)
            .env("MESOBAKE_DATA_DIR", data_dir)
            .env("MESOBAKE_WORKERS", "1")
            .envs(extra.iter().copied())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    )
}

fn worker(database_url: &str, data_dir: &std::path::Path) -> Process {
    mesobake("worker", database_url, data_dir, &[])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_jobs_survive_a_worker_killed_mid_bake() {
    let dir = tempfile::tempdir().unwrap();
    let urls = database_urls(dir.path(), "killed").await;
    let Some(url) = urls.iter().find(|u| u.starts_with("postgres")) else {
        eprintln!("SKIPPED: needs PostgreSQL");
        return;
    };
    let data = tempfile::tempdir().unwrap();
    let s = TestServer::start(url, data.path(), 1 << 20).await;
    let dirs = [[4, 8], [8, 16], [6, 12], [8, 8], [4, 16]];
    let mut ids = Vec::new();
    for sample in ["chain", "weave", "grid", "squama", "bark"] {
        for rank in 1..=8 {
            for d in dirs {
                let spec = spec(sample, rank, d);
                let plan = spec.plan(&s.state.blobs, &s.state.limits).unwrap();
                let (job, queued) = s.state.db.submit_job(&spec, &plan).await.unwrap();
                assert!(queued);
                ids.push(job.id);
            }
        }
    }
    assert_eq!(ids.len(), 200);
    let doomed = worker(url, data.path());
    let _survivor = worker(url, data.path());
    let pid = doomed.0.id();
    // Kill the first worker while it holds a running job, after some jobs are done. It is
    // stopped (SIGSTOP) before its jobs are counted, so that it cannot finish the job it
    // holds between the count and the kill; it resumes when it held none.
    let signal = |name: &str| {
        // The shell's builtin: no procps needed.
        let status = Command::new("sh")
            .args(["-c", &format!("kill {name} {pid}")])
            .status()
            .unwrap();
        assert!(status.success(), "kill {name} {pid}");
    };
    let start = Instant::now();
    loop {
        let done: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE state = 'succeeded'")
            .fetch_one(&s.state.db.pool)
            .await
            .unwrap();
        if done >= 20 {
            signal("-STOP");
            let holding: i64 = sqlx::query_scalar(
                "SELECT COUNT(*) FROM jobs WHERE state = 'running' AND lease_owner LIKE $1",
            )
            .bind(format!("%-{pid}-%"))
            .fetch_one(&s.state.db.pool)
            .await
            .unwrap();
            if holding > 0 {
                break;
            }
            signal("-CONT");
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "workers made no progress"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    drop(doomed); // SIGKILL
    let start = Instant::now();
    loop {
        let open: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE state IN ('queued', 'running')")
                .fetch_one(&s.state.db.pool)
                .await
                .unwrap();
        if open == 0 {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(240),
            "{open} jobs unfinished"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let jobs = s.state.db.jobs(1000).await.unwrap();
    assert_eq!(jobs.len(), 200);
    assert!(
        jobs.iter().all(|j| j.state == "succeeded"),
        "{:?}",
        jobs.iter().find(|j| j.state != "succeeded")
    );
    assert!(
        jobs.iter().any(|j| j.attempts == 2),
        "no job was taken over from the killed worker"
    );
    let mut digests: Vec<&str> = jobs
        .iter()
        .map(|j| j.package_digest.as_deref().unwrap())
        .collect();
    digests.sort();
    digests.dedup();
    let packages: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM packages")
        .fetch_one(&s.state.db.pool)
        .await
        .unwrap();
    assert_eq!(
        packages as usize,
        digests.len(),
        "a package row per distinct package"
    );
    for d in digests {
        let bytes = s
            .state
            .blobs
            .get(d)
            .unwrap()
            .expect("every package blob exists");
        Package::parse(bytes).unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_blob_store_that_refuses_writes_fails_the_job_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    for url in database_urls(dir.path(), "readonly").await {
        let data = tempfile::tempdir().unwrap();
        let s = TestServer::start(&url, data.path(), 1 << 20).await;
        // The blob directory becomes a plain file: every write fails (even for root).
        let blobs = data.path().join("blobs");
        std::fs::remove_dir_all(&blobs).unwrap();
        std::fs::write(&blobs, b"not a directory").unwrap();
        let spec = spec("grid", 2, [4, 8]);
        let plan = spec.plan(&s.state.blobs, &s.state.limits).unwrap();
        let (job, _) = s.state.db.submit_job(&spec, &plan).await.unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        spawn_workers(&s.state, 1, &stop);
        let start = Instant::now();
        let done = loop {
            let j = s.state.db.job(&job.id).await.unwrap().unwrap();
            if j.is_final() {
                break j;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "{j:?}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        };
        assert_eq!(done.state, "failed");
        assert_eq!(done.attempts, 3, "retried with backoff before failing");
        assert_eq!(
            done.max_attempts, 3,
            "the view says how many attempts it had"
        );
        // The error names the store, not the server's directories.
        let error = done.error.as_deref().unwrap();
        assert!(error.contains("blob store"), "{error}");
        assert!(!error.contains(&*data.path().to_string_lossy()), "{error}");
        assert!(done.package_digest.is_none());
        let packages: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM packages")
            .fetch_one(&s.state.db.pool)
            .await
            .unwrap();
        assert_eq!(packages, 0);
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_killed_mid_job_picks_the_job_up_again_after_restart() {
    let dir = tempfile::tempdir().unwrap();
    let url = format!("sqlite://{}", dir.path().join("db.sqlite").display());
    let data = dir.path().join("data");
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let listen = format!("127.0.0.1:{port}");
    let serve = || {
        mesobake(
            "serve",
            &url,
            &data,
            &[
                ("MESOBAKE_LISTEN", &listen),
                ("MESOBAKE_SEED_SAMPLE", "false"),
            ],
        )
    };
    let base = format!("http://{listen}/api/v1");
    let client = reqwest::Client::new();
    let up = || async {
        let start = Instant::now();
        while client
            .get(format!("{base}/../healthz"))
            .send()
            .await
            .is_err()
        {
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "the server did not start"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    let job = |id: String| {
        let client = client.clone();
        let url = format!("{base}/jobs/{id}");
        async move {
            let r = client.get(url).send().await.unwrap();
            r.json::<serde_json::Value>().await.unwrap()
        }
    };
    let first = serve();
    up().await;
    // A bake of some seconds: the chain at the default resolution and directions.
    let mut spec = serde_json::to_value(spec("chain", 4, [16, 32])).unwrap();
    spec["scene"]["resolution"] = json!([64, 64, 32]);
    let queued: serde_json::Value = client
        .post(format!("{base}/jobs"))
        .json(&spec)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = queued["id"].as_str().expect("a job id").to_owned();
    let start = Instant::now();
    loop {
        let j = job(id.clone()).await;
        assert!(j["state"] == "queued" || j["state"] == "running", "{j}");
        if j["state"] == "running" && j["progress"].as_f64().unwrap() > 0.0 {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "never ran: {j}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    drop(first); // SIGKILL, mid-bake
    let _second = serve();
    up().await;
    let start = Instant::now();
    let done = loop {
        let j = job(id.clone()).await;
        if j["state"] != "queued" && j["state"] != "running" {
            break j;
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "not picked up: {j}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(
        done["attempts"], 2,
        "taken over after the lease ran out: {done}"
    );
    let digest = done["package_digest"].as_str().unwrap();
    let bytes = client
        .get(format!("{base}/packages/{digest}"))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    Package::parse(bytes.to_vec()).unwrap();
}
