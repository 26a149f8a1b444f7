//! `/healthz` (the process answers), `/readyz` (the database and the blob store work) and
//! `/metrics` (Prometheus text format).

use super::AppState;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counters since the process started.
#[derive(Debug, Default)]
pub struct Metrics {
    /// Assets stored by uploads (new or deduplicated).
    pub uploads: AtomicU64,
    /// Package downloads answered with content.
    pub packages_served: AtomicU64,
}

/// Liveness.
#[utoipa::path(get, path = "/healthz", responses((status = 200, description = "Alive")))]
pub async fn healthz() -> &'static str {
    "ok\n"
}

/// Readiness: the database answers and the blob store accepts writes.
#[utoipa::path(
    get,
    path = "/readyz",
    responses((status = 200, description = "Ready"), (status = 503, description = "Not ready"))
)]
pub async fn readyz(State(state): State<AppState>) -> (StatusCode, String) {
    if let Err(e) = state.db.ping().await {
        return (StatusCode::SERVICE_UNAVAILABLE, format!("{e}\n"));
    }
    let blobs = state.blobs.clone();
    match tokio::task::spawn_blocking(move || blobs.put(b"mesobake readiness probe")).await {
        Ok(Ok(_)) => (StatusCode::OK, "ready\n".into()),
        Ok(Err(e)) => (
            StatusCode::SERVICE_UNAVAILABLE,
            format!("blob store: {e}\n"),
        ),
        Err(e) => (StatusCode::SERVICE_UNAVAILABLE, format!("{e}\n")),
    }
}

/// Prometheus metrics.
#[utoipa::path(get, path = "/metrics", responses((status = 200, description = "Prometheus text format")))]
pub async fn metrics(State(state): State<AppState>) -> impl IntoResponse {
    let m = &state.metrics;
    let mut out = String::new();
    for (name, help, value) in [
        (
            "mesobake_uploads_total",
            "Assets stored by uploads.",
            m.uploads.load(Ordering::Relaxed),
        ),
        (
            "mesobake_packages_served_total",
            "Package downloads answered with content.",
            m.packages_served.load(Ordering::Relaxed),
        ),
    ] {
        out += &format!("# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}\n");
    }
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], out)
}
