//! `mesobake bench server`: the server's throughput and latencies, each against a baseline
//! in the same run where one exists. Package downloads are compared with nginx serving the
//! same file (both measured with wrk on loopback; both programs must be installed).

use crate::config::ServerConfig;
use crate::jobs::JobSpec;
use crate::{AppState, open_state, serve_on, spawn_workers};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_bake::mesostructure::volume_format;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use serde_json::{Value, json};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

fn err(what: &str, e: impl std::fmt::Display) -> Error {
    Error::InvalidParameter(format!("{what}: {e}"))
}

/// Runs `wrk` against `url` for `seconds` and returns the transfer rate in bytes/s.
fn wrk(url: &str, seconds: u32) -> Result<f64> {
    let out = Command::new("wrk")
        .args(["-t1", "-c8", &format!("-d{seconds}s"), url])
        .output()
        .map_err(|e| err("running wrk (install it: apt-get install wrk)", e))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("Transfer/sec:"))
        .ok_or_else(|| err("wrk printed no transfer rate", &text))?
        .trim();
    let (number, unit) = line.split_at(
        line.find(|c: char| c.is_ascii_alphabetic())
            .unwrap_or(line.len()),
    );
    let scale = match unit {
        "GB" => 1024.0 * 1024.0 * 1024.0,
        "MB" => 1024.0 * 1024.0,
        "KB" => 1024.0,
        _ => 1.0,
    };
    Ok(number.parse::<f64>().map_err(|e| err("wrk's rate", e))? * scale)
}

/// Serves `dir` with nginx on `port` (sendfile, one worker per core) until dropped.
struct Nginx(std::process::Child);

impl Nginx {
    fn start(dir: &std::path::Path, port: u16) -> Result<Nginx> {
        let conf = dir.join("nginx.conf");
        std::fs::write(
            &conf,
            format!(
                "worker_processes auto; daemon off; pid {0}/nginx.pid; error_log {0}/error.log;\n\
                 events {{ worker_connections 1024; }}\n\
                 http {{ access_log off; sendfile on; \
                 server {{ listen 127.0.0.1:{port}; root {0}/www; }} }}\n",
                dir.display()
            ),
        )
        .map_err(|e| Error::io(&conf, e))?;
        let child = Command::new("nginx")
            .args(["-c", &conf.to_string_lossy(), "-p", &dir.to_string_lossy()])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .map_err(|e| err("running nginx (install it: apt-get install nginx-light)", e))?;
        std::thread::sleep(Duration::from_millis(500));
        Ok(Nginx(child))
    }
}

impl Drop for Nginx {
    fn drop(&mut self) {
        // SIGTERM, so that the master stops its workers too.
        let _ = Command::new("kill").arg(self.0.id().to_string()).status();
        let _ = self.0.wait();
    }
}

/// The results, as Markdown.
pub fn run(database_url: Option<&str>, limits: &Limits) -> Result<String> {
    let runtime = tokio::runtime::Runtime::new().map_err(|e| err("runtime", e))?;
    runtime.block_on(run_async(database_url, limits))
}

async fn run_async(database_url: Option<&str>, limits: &Limits) -> Result<String> {
    let dir = std::env::temp_dir().join(format!("mesobake-bench-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("www")).map_err(|e| Error::io(&dir, e))?;
    let mut config = ServerConfig::load(None)?;
    config.data_dir = dir.join("data");
    config.database_url = database_url.map_or_else(
        || format!("sqlite://{}/db.sqlite", dir.display()),
        str::to_owned,
    );
    config.max_upload_bytes = 64 << 20;
    let state = open_state(&config, *limits).await?;
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .map_err(|e| err("listen", e))?;
    let addr = listener.local_addr().map_err(|e| err("listen", e))?;
    tokio::spawn(serve_on(listener, state.clone(), std::future::pending()));
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&state, 1, &stop);
    let base = format!("http://{addr}/api/v1");
    let http = reqwest::Client::new();
    let mut out = format!(
        "Database: {}\n\n| measurement | value | baseline | ratio |\n|---|---:|---:|---:|\n",
        config.database_url
    );

    // End to end: upload the chain sample (64×64×32), bake (16×32, rank 8), download.
    let start = Instant::now();
    let chain = volume_format::encode(&samples::volume(
        SampleKind::Chain,
        Dims::new(64, 64, 32)?,
        limits,
    )?);
    let asset: Value = http
        .post(format!("{base}/assets?kind=volume&name=chain.mbvol"))
        .body(chain)
        .send()
        .await
        .map_err(|e| err("upload", e))?
        .json()
        .await
        .map_err(|e| err("upload", e))?;
    let mut scene: Value =
        serde_json::from_str(crate::scenes::SAMPLE_SCENE).map_err(|e| err("scene", e))?;
    scene["mesostructure"] = json!({ "volume": asset["id"] });
    let job: Value = http
        .post(format!("{base}/jobs"))
        .json(&json!({ "scene": scene }))
        .send()
        .await
        .map_err(|e| err("submit", e))?
        .json()
        .await
        .map_err(|e| err("submit", e))?;
    let id = job["id"].as_str().unwrap_or_default().to_owned();
    let digest = loop {
        let j: Value = http
            .get(format!("{base}/jobs/{id}"))
            .send()
            .await
            .map_err(|e| err("job", e))?
            .json()
            .await
            .map_err(|e| err("job", e))?;
        match j["state"].as_str() {
            Some("succeeded") => break j["package_digest"].as_str().unwrap_or_default().to_owned(),
            Some("failed") | Some("cancelled") => return Err(err("the bake", j)),
            _ => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    };
    let package = http
        .get(format!("{base}/packages/{digest}"))
        .send()
        .await
        .map_err(|e| err("download", e))?
        .bytes()
        .await
        .map_err(|e| err("download", e))?;
    let e2e = start.elapsed().as_secs_f64();
    let timings: &Value = &state
        .db
        .job(&id)
        .await?
        .map(|j| j.timings)
        .unwrap_or_default();
    let bake_s: f64 = ["load", "bake_gdm", "compress", "store"]
        .iter()
        .filter_map(|k| timings[k].as_f64())
        .sum();
    out += &format!(
        "| upload → package, `chain` 64×64×32, 16×32, rank 8 (s) | {e2e:.2} | {bake_s:.2} (the job's stages) | {:.2} |\n",
        e2e / bake_s
    );

    // Upload throughput: 16 distinct 8.4 MB volumes, 4 at a time.
    let dims = Dims::new(128, 128, 128)?;
    let bodies: Vec<Vec<u8>> = (0..16u32)
        .map(|n| {
            Volume::from_fn(dims, limits, |i, j, k| (i * 5 + j * 3 + k + n) % 31 < 11)
                .map(|v| volume_format::encode(&v))
        })
        .collect::<Result<_>>()?;
    let total: usize = bodies.iter().map(Vec::len).sum();
    let start = Instant::now();
    for chunk in bodies.chunks(4) {
        let sends = chunk.iter().map(|b| {
            http.post(format!("{base}/assets?kind=volume&name=v.mbvol"))
                .body(b.clone())
                .send()
        });
        for r in futures_util::future::join_all(sends).await {
            r.map_err(|e| err("upload", e))?
                .error_for_status()
                .map_err(|e| err("upload", e))?;
        }
    }
    let upload_rate = total as f64 / start.elapsed().as_secs_f64();
    // Baseline: what the store cannot avoid, writing the same bytes durably, one by one.
    let start = Instant::now();
    for (n, b) in bodies.iter().enumerate() {
        mesobake_core::fs::write_atomic(&dir.join(format!("copy{n}")), b)?;
    }
    let write_rate = total as f64 / start.elapsed().as_secs_f64();
    out += &format!(
        "| upload throughput, 16 × 8.4 MB volumes, 4 concurrent (MB/s) | {:.0} | {:.0} (write + fsync of the same bytes) | {:.2} |\n",
        upload_rate / 1e6,
        write_rate / 1e6,
        upload_rate / write_rate
    );

    // Claim latency: 200 queued jobs, claimed one by one.
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    tokio::time::sleep(Duration::from_millis(500)).await;
    claim_latency(&state, &mut out).await?;

    // Downloads against nginx serving the same file.
    std::fs::write(dir.join("www/pkg"), &package).map_err(|e| Error::io(&dir, e))?;
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map_err(|e| err("port", e))?
        .port();
    let nginx = Nginx::start(&dir, port)?;
    let (mut ours, mut theirs) = (0.0f64, 0.0f64);
    for _ in 0..2 {
        theirs = theirs.max(wrk(&format!("http://127.0.0.1:{port}/pkg"), 5)?);
        ours = ours.max(wrk(&format!("{base}/packages/{digest}"), 5)?);
    }
    drop(nginx);
    out += &format!(
        "| package download, {:.1} MB, wrk -c8 on loopback (GB/s, best of 2) | {:.2} | {:.2} (nginx, sendfile) | {:.2} |\n",
        package.len() as f64 / 1e6,
        ours / 1e9,
        theirs / 1e9,
        ours / theirs
    );
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out)
}

async fn claim_latency(state: &AppState, out: &mut String) -> Result<()> {
    for n in 0..200u32 {
        let spec: JobSpec = serde_json::from_value(json!({
            "scene": {
                "base_mesh": { "builtin": { "plane": {} } },
                "mesostructure": { "sample": "grid" },
                "resolution": [16, 16, 8 + 2 * (n % 100)],
                "directions": [4, 8 + 2 * (n / 100)],
                "shell": { "thickness": 0.1, "tiles_per_uv": [1, 1] },
                "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 8, "height": 8 }
            }
        }))
        .map_err(|e| err("spec", e))?;
        let plan = spec.plan(&state.blobs, &state.limits)?;
        state.db.submit_job(&spec, &plan).await?;
    }
    let mut times = Vec::new();
    while let Some((t, claimed)) = {
        let start = Instant::now();
        state
            .db
            .claim_job("bench", 60_000)
            .await?
            .map(|c| (start.elapsed().as_secs_f64(), c))
    } {
        times.push(t);
        state
            .db
            .finish_job(&claimed.id, "bench", "cancelled", None, None, &json!({}))
            .await?;
    }
    times.sort_by(f64::total_cmp);
    let start = Instant::now();
    for _ in 0..times.len() {
        state.db.ping().await?;
    }
    let ping = start.elapsed().as_secs_f64() / times.len().max(1) as f64;
    let median = times.get(times.len() / 2).copied().unwrap_or(0.0);
    *out += &format!(
        "| job claim latency, {} claims over a queue of 200, median (ms) | {:.2} | {:.2} (`SELECT 1`) | {:.1} |\n",
        times.len(),
        median * 1e3,
        ping * 1e3,
        median / ping
    );
    Ok(())
}
