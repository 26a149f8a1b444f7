//! The baking server (`mesobake serve`): axum on tokio over the database ([`db`]) and the
//! blob store ([`blobs`]). Routes live under `/api/v1`; the OpenAPI document is generated
//! from the handlers (utoipa) and served at `/api/v1/openapi.json`.

pub mod api_error;
pub mod assets;
pub mod auth;
pub mod blobs;
pub mod config;
pub mod db;
pub mod health;
pub mod jobs;
pub mod jobs_api;
pub mod packages;
pub mod preview_api;
pub mod worker;

use crate::error::{Error, Result};
use crate::limits::Limits;
use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::routing::{get, post};
use blobs::BlobStore;
use config::ServerConfig;
use db::Db;
use health::Metrics;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
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
    pub gpu: preview_api::SharedGpu,
    /// Who may call what.
    pub auth: auth::AuthPolicy,
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
        packages::get,
        packages::manifest,
        preview_api::render,
        preview_api::sample_scene,
        health::healthz,
        health::readyz,
        health::metrics,
    )
)]
pub struct ApiDoc;

/// The web page (`static/index.html`, compiled in).
async fn index() -> axum::response::Html<&'static str> {
    axum::response::Html(include_str!("../../static/index.html"))
}

async fn openapi() -> axum::Json<utoipa::openapi::OpenApi> {
    axum::Json(ApiDoc::openapi())
}

/// The application's routes over `state`, accepting bodies up to `max_body` bytes.
pub fn router(state: AppState, max_body: u64) -> Router {
    let api = Router::new()
        .route("/assets", post(assets::upload))
        .route("/assets/{id}", get(assets::get))
        .route("/jobs", post(jobs_api::submit).get(jobs_api::list))
        .route("/jobs/{id}", get(jobs_api::get))
        .route("/jobs/{id}/cancel", post(jobs_api::cancel))
        .route("/jobs/{id}/events", get(jobs_api::events))
        .route("/packages/{digest}", get(packages::get))
        .route("/packages/{digest}/manifest", get(packages::manifest))
        .route("/preview", post(preview_api::render))
        .route("/scenes/sample", get(preview_api::sample_scene))
        .route("/openapi.json", get(openapi));
    Router::new()
        .route("/", get(index))
        .nest("/api/v1", api)
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            auth::check,
        ))
        .layer(DefaultBodyLimit::max(
            usize::try_from(max_body).unwrap_or(usize::MAX),
        ))
        .layer(tower_http::trace::TraceLayer::new_for_http())
        .with_state(state)
}

/// Opens the database and the blob store named by `config`.
pub async fn open_state(config: &ServerConfig, limits: Limits) -> Result<AppState> {
    Ok(AppState {
        db: Db::connect(&config.database_url).await?,
        blobs: BlobStore::open(&config.data_dir, &config.blob_url, &config.blob_options)?,
        limits,
        metrics: Arc::new(Metrics::default()),
        gpu: Default::default(),
        auth: auth::AuthPolicy {
            require_keys: config.require_keys,
            public_packages: config.public_packages,
        },
    })
}

/// Starts `count` workers in this process; they stop when `stop` is set.
pub fn spawn_workers(state: &AppState, count: u32, stop: &Arc<AtomicBool>) {
    for i in 0..count {
        tokio::spawn(worker::work(
            state.clone(),
            worker::worker_name(i),
            stop.clone(),
        ));
    }
}

/// Serves until Ctrl-C or SIGTERM, with the configured number of workers.
pub async fn serve(config: ServerConfig, limits: Limits) -> Result<()> {
    let state = open_state(&config, limits).await?;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&state, config.workers, &stop);
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
    axum::serve(listener, router(state, config.max_upload_bytes))
        .with_graceful_shutdown(shutdown_signal())
        .await
        .map_err(|e| Error::InvalidParameter(format!("server: {e}")))?;
    stop.store(true, Ordering::Relaxed);
    Ok(())
}

/// Queues the bake of the built-in sample scene (a no-op when it was baked before), so that
/// the web page has a preview at once.
pub async fn seed_sample(state: &AppState) -> Result<()> {
    let scene = crate::scene::Scene::from_json(preview_api::SAMPLE_SCENE)?;
    let spec: jobs::JobSpec = serde_json::from_value(serde_json::json!({ "scene": scene }))
        .map_err(|e| Error::Scene(e.to_string()))?;
    let (job, queued) = state.db.submit_job(&spec).await?;
    eprintln!(
        "sample scene: job {} {}",
        job.id,
        if queued { "queued" } else { job.state.as_str() }
    );
    Ok(())
}

/// Runs `config.workers` (at least one) workers without the HTTP server, until Ctrl-C or
/// SIGTERM (`mesobake worker`).
pub async fn work(config: ServerConfig, limits: Limits) -> Result<()> {
    let state = open_state(&config, limits).await?;
    let stop = Arc::new(AtomicBool::new(false));
    spawn_workers(&state, config.workers.max(1), &stop);
    eprintln!(
        "mesobake worker: {} worker(s) on {}",
        config.workers.max(1),
        config.database_url
    );
    shutdown_signal().await;
    stop.store(true, Ordering::Relaxed);
    Ok(())
}

async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .expect("installing a SIGTERM handler");
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    let _ = ctrl_c.await;
}
