//! The baking server (`mesobake serve`): axum on tokio over the database ([`db`]) and the
//! blob store ([`blobs`]). Routes live under `/api/v1`; the OpenAPI document is generated
//! from the handlers (utoipa) and served at `/api/v1/openapi.json`.
//!
//! What a request may cost is bounded before any work starts: bodies by kind (413 from the
//! `Content-Length` before reading), scenes by [`request_limits`], uploads and GPU renders by
//! the number running at once, previews by a render deadline, the queue by its length. Slow
//! clients are bounded by [`connections`].
//!
//! Beside the server: its benchmark ([`bench`], `mesobake bench server`) and the CI client
//! that talks to it ([`client`]).

pub mod api_error;
pub mod assets;
pub mod auth;
pub mod bench;
pub mod blobs;
pub mod client;
pub mod config;
pub mod connections;
pub mod db;
pub mod health;
pub mod jobs;
pub mod jobs_api;
pub mod json_body;
pub mod middleware;
pub mod object_jobs;
pub mod packages;
pub mod preview_api;
pub mod preview_cache;
pub mod reports;
pub mod request_limits;
pub mod scenes;
pub mod storage_reserve;
pub mod worker;

use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::routing::{get, post};
use blobs::{BlobStore, LEFTOVER_AGE};
use config::{ServerConfig, millis};
use db::Db;
use health::Metrics;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::timeout::RequestBodyTimeoutLayer;
use utoipa::OpenApi;

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    /// The database.
    pub db: Db,
    /// The blob store.
    pub blobs: BlobStore,
    /// Limits on what input may allocate.
    pub limits: Limits,
    /// Counters for `/metrics`.
    pub metrics: Arc<Metrics>,
    /// The GPU for previews, opened on first use.
    pub gpu: Arc<preview_api::PreviewGpu>,
    /// Who may call what.
    pub auth: auth::AuthPolicy,
    /// The configuration the server runs with.
    pub config: Arc<ServerConfig>,
    /// Upload validation slots ([`ServerConfig::max_concurrent_uploads`]).
    pub uploads: Arc<tokio::sync::Semaphore>,
}

/// The OpenAPI document of the API.
#[derive(OpenApi)]
#[openapi(
    info(title = "mesobake", description = "Mesostructure baking server"),
    paths(
        assets::upload,
        assets::get,
        jobs_api::submit,
        jobs_api::list,
        jobs_api::get,
        jobs_api::cancel,
        jobs_api::events,
        object_jobs::submit,
        packages::get,
        packages::manifest,
        preview_api::render,
        scenes::list,
        scenes::get,
        reports::codecs,
        reports::conformance,
        health::healthz,
        health::readyz,
        health::metrics,
    )
)]
pub struct ApiDoc;

/// The web page (`static/index.html`, compiled in).
async fn index() -> axum::response::Html<&'static str> {
    axum::response::Html(include_str!("../../../static/index.html"))
}

async fn openapi() -> axum::Json<utoipa::openapi::OpenApi> {
    axum::Json(ApiDoc::openapi())
}

/// The application's routes over `state`, with the body limits and timeouts of its
/// configuration.
pub fn router(state: AppState) -> Router {
    let config = &state.config;
    let as_usize = |n: u64| usize::try_from(n).unwrap_or(usize::MAX);
    let uploads =
        Router::new()
            .route("/assets", post(assets::upload))
            .layer(RequestBodyLimitLayer::new(as_usize(
                config.max_upload_bytes,
            )));
    let api = Router::new()
        .route("/assets/{id}", get(assets::get))
        .route("/jobs", post(jobs_api::submit).get(jobs_api::list))
        .route("/jobs/{id}", get(jobs_api::get))
        .route("/jobs/{id}/cancel", post(jobs_api::cancel))
        .route("/jobs/{id}/events", get(jobs_api::events))
        .route("/object-jobs", post(object_jobs::submit))
        .route("/packages/{digest}", get(packages::get))
        .route("/packages/{digest}/manifest", get(packages::manifest))
        .route("/preview", post(preview_api::render))
        .route("/scenes", get(scenes::list))
        .route("/scenes/{name}", get(scenes::get))
        .route("/reports/codecs", get(reports::codecs))
        .route("/reports/conformance", get(reports::conformance))
        .route("/openapi.json", get(openapi))
        .layer(RequestBodyLimitLayer::new(as_usize(config.max_json_bytes)))
        .merge(uploads);
    Router::new()
        .route("/", get(index))
        .nest("/api/v1", api)
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
        .fallback(middleware::not_found)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::check,
        ))
        .layer(DefaultBodyLimit::disable())
        .layer(RequestBodyTimeoutLayer::new(millis(
            config.body_read_timeout_ms,
        )))
        .layer(axum::middleware::from_fn(middleware::json_errors))
        .layer(axum::middleware::from_fn_with_state(
            state.metrics.clone(),
            middleware::log_requests,
        ))
        .with_state(state)
}

/// Opens the database and the blob store named by `config` (removing what a killed
/// process left in the store), with `limits` on what input may allocate.
pub async fn open_state(config: &ServerConfig, limits: Limits) -> Result<AppState> {
    let db = Db::connect(&config.database_url).await.map_err(|e| {
        Error::Database(format!(
            "{}: {}",
            config.database_url_redacted(),
            e.to_string().replace(&config.database_url, "")
        ))
    })?;
    let blobs = BlobStore::open(&config.data_dir, &config.blob_url, &config.blob_options)?;
    let removed = blobs.remove_leftovers()?;
    if removed > 0 {
        tracing::info!("removed {removed} temporary files left by a killed process");
    }
    Ok(AppState {
        db,
        blobs,
        limits: Limits {
            image_pixels: config.max_input_pixels,
            ..limits
        },
        metrics: Arc::new(Metrics::default()),
        gpu: Default::default(),
        auth: auth::AuthPolicy {
            require_keys: config.require_keys,
            public_packages: config.public_packages,
            public_metrics: config.public_metrics,
        },
        config: Arc::new(config.clone()),
        uploads: Arc::new(tokio::sync::Semaphore::new(
            config.max_concurrent_uploads as usize,
        )),
    })
}

/// Starts `count` workers in this process; they stop when `stop` is set, handing their
/// running jobs back to the queue.
pub fn spawn_workers(
    state: &AppState,
    count: u32,
    stop: &Arc<AtomicBool>,
) -> Vec<tokio::task::JoinHandle<()>> {
    (0..count)
        .map(|i| {
            tokio::spawn(worker::work(
                state.clone(),
                worker::worker_name(i),
                stop.clone(),
            ))
        })
        .collect()
}

/// How often a running server or worker looks for a killed process's temporary files.
const LEFTOVER_SWEEP: std::time::Duration = std::time::Duration::from_secs(600);

/// Removes a killed process's temporary files now and then, until the returned task is
/// aborted: at start [`open_state`] removes those old enough already; the first sweep here,
/// [`LEFTOVER_AGE`] later, those of a kill just before a quick restart; then every
/// [`LEFTOVER_SWEEP`].
fn spawn_leftover_sweeps(blobs: &BlobStore) -> tokio::task::JoinHandle<()> {
    let blobs = blobs.clone();
    tokio::spawn(async move {
        let first = tokio::time::Instant::now() + LEFTOVER_AGE;
        let mut every = tokio::time::interval_at(first, LEFTOVER_SWEEP);
        loop {
            every.tick().await;
            let store = blobs.clone();
            match tokio::task::spawn_blocking(move || store.remove_leftovers()).await {
                Ok(Ok(0)) => {}
                Ok(Ok(n)) => tracing::info!("removed {n} temporary files left by a killed process"),
                Ok(Err(e)) => tracing::warn!("sweeping temporary files: {e}"),
                Err(e) => tracing::warn!("sweeping temporary files: {e}"),
            }
        }
    })
}

/// Logs where the state lives, as absolute paths, with the database password redacted.
fn log_locations(config: &ServerConfig) {
    tracing::info!(
        "data directory {}, database {}",
        config.data_dir.display(),
        config.database_url_redacted()
    );
}

/// Serves until Ctrl-C or SIGTERM, with the configured number of workers; then stops
/// accepting, hands running jobs back to the queue and returns within the grace period.
pub async fn serve(config: ServerConfig, limits: Limits) -> Result<()> {
    log_locations(&config);
    let state = open_state(&config, limits).await?;
    let stop = Arc::new(AtomicBool::new(false));
    let workers = spawn_workers(&state, config.workers, &stop);
    let sweeps = spawn_leftover_sweeps(&state.blobs);
    if config.seed_sample {
        seed_sample(&state).await?;
    }
    let listener = tokio::net::TcpListener::bind(&config.listen)
        .await
        .map_err(|e| Error::InvalidParameter(format!("cannot listen on {}: {e}", config.listen)))?;
    let addr = listener
        .local_addr()
        .map_err(|e| Error::InvalidParameter(format!("listen address: {e}")))?;
    eprintln!("mesobake serving on http://{addr}/");
    let signal = {
        let stop = stop.clone();
        async move {
            shutdown_signal().await;
            stop.store(true, Ordering::Relaxed);
        }
    };
    let deadline = serve_on(listener, state, signal).await;
    sweeps.abort();
    stop_workers(&stop, workers, deadline).await;
    Ok(())
}

/// Serves the API over `state` on `listener` with the configuration's connection
/// timeouts until `shutdown` resolves, then drains connections for at most the grace
/// period; returns the end of that period.
pub async fn serve_on(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()>,
) -> tokio::time::Instant {
    let config = state.config.clone();
    connections::serve(
        listener,
        router(state),
        millis(config.header_read_timeout_ms),
        shutdown,
        millis(config.shutdown_grace_ms),
    )
    .await
}

/// Sets `stop` and waits for the workers until `deadline` (each hands its running job back
/// to the queue when it sees the flag).
async fn stop_workers(
    stop: &AtomicBool,
    workers: Vec<tokio::task::JoinHandle<()>>,
    deadline: tokio::time::Instant,
) {
    stop.store(true, Ordering::Relaxed);
    for worker in workers {
        if tokio::time::timeout_at(deadline, worker).await.is_err() {
            tracing::warn!("a worker did not stop within the grace period");
        }
    }
    tracing::info!("stopped");
}

/// Queues the bake of the built-in sample scene (a no-op when it was baked before), so that
/// the web page has a preview at once.
pub async fn seed_sample(state: &AppState) -> Result<()> {
    let scene = mesobake_scene::Scene::from_json(scenes::SAMPLE_SCENE)?;
    let spec: jobs::JobSpec = serde_json::from_value(serde_json::json!({ "scene": scene }))
        .map_err(|e| Error::Scene(e.to_string()))?;
    let plan = spec.plan(&state.blobs, &state.limits)?;
    let (job, queued) = state.db.submit_job(&spec, &plan).await?;
    eprintln!(
        "sample scene: job {} {}",
        job.id,
        if queued { "queued" } else { job.state.as_str() }
    );
    Ok(())
}

/// Runs `config.workers` (at least one) workers without the HTTP server, until Ctrl-C or
/// SIGTERM (`mesobake worker`); then hands running jobs back within the grace period.
pub async fn work(config: ServerConfig, limits: Limits) -> Result<()> {
    log_locations(&config);
    let state = open_state(&config, limits).await?;
    let stop = Arc::new(AtomicBool::new(false));
    let workers = spawn_workers(&state, config.workers.max(1), &stop);
    let sweeps = spawn_leftover_sweeps(&state.blobs);
    eprintln!(
        "mesobake worker: {} worker(s) on {}",
        config.workers.max(1),
        config.database_url_redacted()
    );
    shutdown_signal().await;
    sweeps.abort();
    let deadline = tokio::time::Instant::now() + millis(config.shutdown_grace_ms);
    stop_workers(&stop, workers, deadline).await;
    Ok(())
}

/// Resolves on Ctrl-C or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = ctrl_c => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = ctrl_c.await;
            }
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
    tracing::info!("shutting down: no new connections or jobs");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test(start_paused = true)]
    async fn a_quick_restart_sweeps_the_killed_uploads_files_a_minute_later() {
        // A process killed mid-upload just before this one started: its temporary file is
        // too young at start to be taken for a leftover, and used to stay for good.
        let dir = tempfile::tempdir().unwrap();
        let blobs = BlobStore::open(dir.path(), "", &Default::default()).unwrap();
        // No process has a pid this large (Linux caps them at 2^22).
        let name = format!(".upload.tmp{}-0123456789ab-0", 1u32 << 30);
        let left = blobs.temp_path().unwrap().with_file_name(name);
        std::fs::write(&left, b"half an upload").unwrap();
        assert_eq!(blobs.remove_leftovers().unwrap(), 0, "too young at start");
        let sweeps = spawn_leftover_sweeps(&blobs);
        tokio::task::yield_now().await;
        // A minute passes: the file ages with it.
        let aged = std::time::SystemTime::now() - LEFTOVER_AGE;
        let file = std::fs::File::options().write(true).open(&left).unwrap();
        file.set_modified(aged).unwrap();
        tokio::time::advance(LEFTOVER_AGE).await;
        for _ in 0..500 {
            if !left.exists() {
                break;
            }
            tokio::task::yield_now().await;
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(
            !left.exists(),
            "a killed upload's file outlived the first sweep"
        );
        sweeps.abort();
    }
}
