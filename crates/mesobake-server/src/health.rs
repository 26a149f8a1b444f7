//! `/healthz` (the process answers), `/readyz` (the database answers and the blob store
//! takes a fresh write) and `/metrics` (Prometheus text format).

use super::AppState;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// A Prometheus summary without quantiles: how many, and their sum in seconds.
#[derive(Debug, Default, Clone, Copy)]
struct Summary {
    count: u64,
    sum: f64,
}

/// Counters since the process started.
#[derive(Debug, Default)]
pub struct Metrics {
    /// Assets stored by uploads (new or deduplicated).
    pub uploads: AtomicU64,
    /// Package downloads answered with content.
    pub packages_served: AtomicU64,
    /// Previews answered from the cache.
    pub preview_cache_hits: AtomicU64,
    /// Previews rendered.
    pub preview_cache_misses: AtomicU64,
    /// Requests answered, by status code.
    requests: Mutex<BTreeMap<u16, u64>>,
    /// Seconds: `preview` (request latency), `queue_wait` (submission or retry to claim),
    /// and `stage:NAME` (a bake stage's duration).
    timings: Mutex<BTreeMap<String, Summary>>,
}

impl Metrics {
    /// Counts a request answered with `status`.
    pub fn count_request(&self, status: u16) {
        if let Ok(mut map) = self.requests.lock() {
            *map.entry(status).or_default() += 1;
        }
    }

    /// Adds one observation of `seconds` to the summary `name`.
    pub fn observe(&self, name: &str, seconds: f64) {
        if let Ok(mut map) = self.timings.lock() {
            let s = map.entry(name.to_owned()).or_default();
            s.count += 1;
            s.sum += seconds;
        }
    }
}

/// Liveness.
#[utoipa::path(get, path = "/healthz", responses((status = 200, description = "Alive")))]
pub async fn healthz() -> &'static str {
    "ok\n"
}

/// Readiness: the free-space reserve holds, the database answers, and a fresh probe file
/// can be written to the blob store, read back and removed.
#[utoipa::path(
    get,
    path = "/readyz",
    responses((status = 200, description = "Ready"), (status = 503, description = "Not ready"))
)]
pub async fn readyz(State(state): State<AppState>) -> (StatusCode, String) {
    if let Err(e) = super::storage_reserve::check(&state.config, 0) {
        return (StatusCode::SERVICE_UNAVAILABLE, format!("{e}\n"));
    }
    if let Err(e) = state.db.ping().await {
        return (StatusCode::SERVICE_UNAVAILABLE, format!("{e}\n"));
    }
    let blobs = state.blobs.clone();
    match tokio::task::spawn_blocking(move || blobs.probe()).await {
        Ok(Ok(())) => (StatusCode::OK, "ready\n".into()),
        Ok(Err(e)) => {
            tracing::warn!("readiness: {e}");
            (
                StatusCode::SERVICE_UNAVAILABLE,
                format!("blob store: {}\n", state.blobs.scrub(&e.to_string())),
            )
        }
        Err(e) => (StatusCode::SERVICE_UNAVAILABLE, format!("{e}\n")),
    }
}

/// Prometheus metrics: requests by status, uploads, downloads, jobs by state, queue wait,
/// stage durations, preview latency and cache hits.
#[utoipa::path(get, path = "/metrics", responses((status = 200, description = "Prometheus text format")))]
pub async fn metrics(State(state): State<AppState>) -> impl IntoResponse {
    let m = &state.metrics;
    let mut out = String::new();
    let mut counter = |name: &str, help: &str, value: u64| {
        let _ = write!(
            out,
            "# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}\n"
        );
    };
    counter(
        "mesobake_uploads_total",
        "Assets stored by uploads.",
        m.uploads.load(Ordering::Relaxed),
    );
    counter(
        "mesobake_packages_served_total",
        "Package downloads answered with content.",
        m.packages_served.load(Ordering::Relaxed),
    );
    counter(
        "mesobake_preview_cache_hits_total",
        "Previews answered from the cache.",
        m.preview_cache_hits.load(Ordering::Relaxed),
    );
    counter(
        "mesobake_preview_cache_misses_total",
        "Previews rendered.",
        m.preview_cache_misses.load(Ordering::Relaxed),
    );
    out += "# HELP mesobake_requests_total Requests answered, by status.\n\
            # TYPE mesobake_requests_total counter\n";
    if let Ok(map) = m.requests.lock() {
        for (status, n) in map.iter() {
            let _ = writeln!(out, "mesobake_requests_total{{status=\"{status}\"}} {n}");
        }
    }
    out += "# HELP mesobake_jobs Jobs in the database, by state.\n# TYPE mesobake_jobs gauge\n";
    match state.db.job_counts().await {
        Ok(counts) => {
            for (job_state, n) in counts {
                let _ = writeln!(out, "mesobake_jobs{{state=\"{job_state}\"}} {n}");
            }
        }
        Err(e) => tracing::warn!("metrics: {e}"),
    }
    let timings = m.timings.lock().map(|t| t.clone()).unwrap_or_default();
    for (name, help, prefix) in [
        (
            "mesobake_queue_wait_seconds",
            "Time from a job's submission (or retry) to its claim by a worker.",
            "queue_wait",
        ),
        (
            "mesobake_preview_seconds",
            "Preview request latency.",
            "preview",
        ),
    ] {
        let s = timings.get(prefix).copied().unwrap_or_default();
        let _ = write!(
            out,
            "# HELP {name} {help}\n# TYPE {name} summary\n{name}_sum {}\n{name}_count {}\n",
            s.sum, s.count
        );
    }
    out += "# HELP mesobake_stage_seconds Duration of bake stages.\n\
            # TYPE mesobake_stage_seconds summary\n";
    for (name, s) in &timings {
        if let Some(stage) = name.strip_prefix("stage:") {
            let _ = write!(
                out,
                "mesobake_stage_seconds_sum{{stage=\"{stage}\"}} {}\n\
                 mesobake_stage_seconds_count{{stage=\"{stage}\"}} {}\n",
                s.sum, s.count
            );
        }
    }
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], out)
}
