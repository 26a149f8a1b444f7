//! `POST /api/v1/preview`: a scene rendered by the real-time pipeline (wgpu) from the package
//! baked for it, as PNG, cached by (scene, package). `GET /api/v1/scenes/sample`: the built-in
//! sample scene the web page starts from.

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::db::{db_error, now_ms};
use super::jobs::JobSpec;
use super::jobs_api::check_spec;
use super::worker::resolve_assets;
use crate::error::{Error, Result};
use crate::package::Package;
use crate::preview_scene::preview;
use crate::realtime::gpu::Gpu;
use crate::scene::{Effect, EnvironmentSource, LoadedScene, Scene};
use axum::Json;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use sqlx::Row;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The built-in sample scene (`scenes/torus-chain.json`).
pub const SAMPLE_SCENE: &str = include_str!("../../scenes/torus-chain.json");

/// Largest preview image side the server renders.
pub const MAX_PREVIEW_SIDE: u32 = 2048;

/// The GPU, opened on first use and shared by previews (one render at a time).
pub type SharedGpu = Arc<Mutex<Option<Gpu>>>;

/// The sample scene.
#[utoipa::path(get, path = "/api/v1/scenes/sample", responses((status = 200, description = "A scene (docs/scene-format.md)")))]
pub async fn sample_scene() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/json")], SAMPLE_SCENE)
}

fn render_png(
    gpu: &SharedGpu,
    scene: &Scene,
    package: Vec<u8>,
    state: &AppState,
) -> Result<Vec<u8>> {
    let package = Package::parse(package)?;
    let mut scene = scene.clone();
    resolve_assets(&mut scene, &state.blobs)?;
    let loaded = LoadedScene::load(scene, Path::new("/"), &state.limits)?;
    let mut guard = gpu
        .lock()
        .map_err(|_| Error::Gpu("a previous preview panicked".into()))?;
    if guard.is_none() {
        *guard = Some(Gpu::open(None)?);
    }
    let (image, _) = preview(guard.as_ref().expect("opened above"), &loaded, &package, 0)?;
    image.to_png()
}

/// Renders a scene with the real-time pipeline from the package baked for it. While that
/// package is not baked, answers 409 with the job baking it (submitted if needed).
#[utoipa::path(
    post,
    path = "/api/v1/preview",
    request_body = JobSpec,
    responses(
        (status = 200, description = "The image", content_type = "image/png"),
        (status = 409, description = "The scene's package is not baked yet: {error, job}"),
        (status = 422, description = "Invalid scene"),
        (status = 503, description = "No GPU adapter"),
    )
)]
pub async fn render(
    State(state): State<AppState>,
    Json(body): Json<serde_json::Value>,
) -> ApiResult<Response> {
    let spec = check_spec(&state, body).await?;
    let camera = spec.scene.camera;
    let lit_by_exr = matches!(spec.scene.environment, Some(EnvironmentSource::Exr(_)))
        && spec.scene.wants(Effect::EnvironmentLighting);
    if lit_by_exr {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "previews light environment-lit scenes with the built-in skies only: the server \
             takes no EXR environment uploads (bake jobs do not need the environment)"
                .to_owned(),
        ));
    }
    if camera.width > MAX_PREVIEW_SIDE || camera.height > MAX_PREVIEW_SIDE {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("previews are at most {MAX_PREVIEW_SIDE} pixels a side"),
        ));
    }
    let job = match state.db.job_for(&spec).await? {
        Some(job) if job.state == "succeeded" => job,
        _ => state.db.submit_job(&spec).await?.0,
    };
    let Some(digest) = job
        .package_digest
        .clone()
        .filter(|_| job.state == "succeeded")
    else {
        let body = serde_json::json!({
            "error": format!("the scene's package is not baked yet (job {} is {})", job.id, job.state),
            "job": job,
        });
        return Ok((StatusCode::CONFLICT, Json(body)).into_response());
    };
    let scene_text = serde_json::to_string(&spec.scene).expect("scenes serialize");
    let cache_key = blake3::hash(format!("preview-v1\n{digest}\n{scene_text}").as_bytes())
        .to_hex()
        .to_string();
    let cached: Option<String> =
        sqlx::query("SELECT png_digest FROM previews WHERE cache_key = $1")
            .bind(&cache_key)
            .fetch_optional(&state.db.pool)
            .await
            .map_err(db_error)?
            .map(|r| r.try_get("png_digest"))
            .transpose()
            .map_err(db_error)?;
    let blobs = state.blobs.clone();
    let png = match cached {
        Some(png_digest) => tokio::task::spawn_blocking(move || blobs.get(&png_digest)).await??,
        None => None,
    };
    let png = match png {
        Some(png) => png,
        None => {
            let package = {
                let blobs = state.blobs.clone();
                tokio::task::spawn_blocking(move || blobs.get(&digest)).await??
            }
            .ok_or_else(|| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    "the package's blob is missing",
                )
            })?;
            let (gpu, st, scene) = (state.gpu.clone(), state.clone(), spec.scene.clone());
            let png = tokio::task::spawn_blocking(move || render_png(&gpu, &scene, package, &st))
                .await??;
            let blobs = state.blobs.clone();
            let bytes = png.clone();
            let png_digest = tokio::task::spawn_blocking(move || blobs.put(&bytes)).await??;
            sqlx::query(
                "INSERT INTO previews (cache_key, png_digest, created_ms) VALUES ($1, $2, $3) \
                 ON CONFLICT (cache_key) DO NOTHING",
            )
            .bind(&cache_key)
            .bind(&png_digest)
            .bind(now_ms())
            .execute(&state.db.pool)
            .await
            .map_err(db_error)?;
            png
        }
    };
    Ok((
        [
            (header::CONTENT_TYPE, "image/png"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        png,
    )
        .into_response())
}
