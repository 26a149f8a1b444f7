//! The baking server (`mesobake serve`): axum on tokio over the database ([`db`]) and the
//! blob store ([`blobs`]). Routes live under `/api/v1`; the OpenAPI document is generated
//! from the handlers (utoipa) and served at `/api/v1/openapi.json`.

pub mod api_error;
pub mod assets;
pub mod blobs;
pub mod config;
pub mod db;
pub mod health;
pub mod packages;

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
}

/// The OpenAPI document of the API.
#[derive(OpenApi)]
#[openapi(
    info(title = "mesobake", description = "Mesostructure baking server"),
    paths(
        assets::upload,
        assets::get,
        packages::get,
        health::healthz,
        health::readyz,
        health::metrics,
    )
)]
pub struct ApiDoc;

async fn openapi() -> axum::Json<utoipa::openapi::OpenApi> {
    axum::Json(ApiDoc::openapi())
}

/// The application's routes over `state`, accepting bodies up to `max_body` bytes.
pub fn router(state: AppState, max_body: u64) -> Router {
    let api = Router::new()
        .route("/assets", post(assets::upload))
        .route("/assets/{id}", get(assets::get))
        .route("/packages/{digest}", get(packages::get))
        .route("/openapi.json", get(openapi));
    Router::new()
        .nest("/api/v1", api)
        .route("/healthz", get(health::healthz))
        .route("/readyz", get(health::readyz))
        .route("/metrics", get(health::metrics))
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
        blobs: BlobStore::open(&config.data_dir)?,
        limits,
        metrics: Arc::new(Metrics::default()),
    })
}

/// Serves until Ctrl-C or SIGTERM.
pub async fn serve(config: ServerConfig, limits: Limits) -> Result<()> {
    let state = open_state(&config, limits).await?;
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
        .map_err(|e| Error::InvalidParameter(format!("server: {e}")))
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
