//! `POST /api/v1/preview`: a scene rendered by the real-time pipeline (wgpu) from the package
//! baked for it (a scene of several objects from each object's), as PNG, cached by (scene,
//! packages).

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::assets::resolve_assets;
use super::config::millis;
use super::jobs_api::enqueue;
use super::json_body::JsonBody;
use super::object_jobs::{ObjectJob, SceneSpec, not_previewable};
use super::preview_cache;
use axum::Json;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use mesobake_bake::package::AnyPackage;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::observer::BakeObserver;
use mesobake_scene::preview::PreviewDevice;
use mesobake_scene::technique::Technique;
use mesobake_scene::{EnvironmentSource, LoadedScene, Scene};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;
use tokio::sync::Semaphore;

/// The header that says which technique's pipeline drew a preview: `gdm` or `vdm` (the
/// plan's choice for the scene).
pub const TECHNIQUE_HEADER: &str = "x-mesobake-technique";

/// The header that says which renderer drew a preview: `gpu`, or `cpu` (the CPU twin, where
/// no GPU adapter exists).
pub const RENDERER_HEADER: &str = "x-mesobake-renderer";

/// The GPU (or, where none exists, the CPU twin), opened on first use and shared by previews,
/// one render at a time.
pub struct PreviewGpu {
    device: Mutex<Option<PreviewDevice>>,
    /// `gpu` or `cpu`, once the device is open.
    renderer: OnceLock<&'static str>,
    /// The right to render: whoever holds it may lock `device` without waiting.
    slot: Arc<Semaphore>,
}

impl Default for PreviewGpu {
    fn default() -> Self {
        PreviewGpu {
            device: Mutex::new(None),
            renderer: OnceLock::new(),
            slot: Arc::new(Semaphore::new(1)),
        }
    }
}

/// Renders the PNG of `scenes` (one object's, or several objects' drawn together) from their
/// `packages`, opening the device on first use; returns it with the renderer's name. Stops
/// with [`Error::Cancelled`] once `cancel` is set: before rendering, between the GPU's
/// frames, within a tile of the CPU twin's.
fn render_png(
    gpu: &PreviewGpu,
    scenes: Vec<Scene>,
    packages: Vec<Vec<u8>>,
    state: &AppState,
    cancel: &AtomicBool,
) -> Result<(Vec<u8>, &'static str)> {
    let packages = packages
        .into_iter()
        .map(|p| AnyPackage::parse_within(p, &state.limits))
        .collect::<Result<Vec<_>>>()?;
    let mut loaded = Vec::with_capacity(scenes.len());
    for mut scene in scenes {
        resolve_assets(&mut scene, &state.blobs)?;
        loaded.push(LoadedScene::load(scene, Path::new("/"), &state.limits)?);
    }
    if cancel.cancelled() {
        return Err(Error::Cancelled);
    }
    let mut guard = gpu
        .device
        .lock()
        .map_err(|_| Error::Gpu("a previous preview panicked".into()))?;
    if guard.is_none() {
        let device = PreviewDevice::open(None, state.config.preview_fallback)?;
        if let PreviewDevice::Cpu { reason } = &device {
            tracing::warn!(
                "previews render with the CPU twin of the real-time pipeline: {reason} \
                 (preview_fallback = \"cpu\")"
            );
        }
        let _ = gpu.renderer.set(device.renderer());
        *guard = Some(device);
    }
    let device = guard.as_ref().expect("opened above");
    let (image, _) = match (&loaded[..], &packages[..]) {
        ([one], [package]) => device.render(one, package, 0, cancel)?,
        _ => device.render_objects(&loaded, &packages, 0, cancel)?,
    };
    Ok((image.to_png()?, device.renderer()))
}

/// Sets a flag when dropped: a preview's render is cancelled when its request ends, answered,
/// timed out or dropped because the client went away.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// Renders `scenes` from their `packages` on the GPU: waits at most `busy_wait_ms` for the
/// GPU and `preview_timeout_ms` for the render (503 beyond either). A render past its
/// deadline, or whose client went away, is cancelled and frees the GPU within a frame (a
/// tile of the CPU twin's).
async fn render_on_gpu(
    state: &AppState,
    scenes: Vec<Scene>,
    packages: Vec<Vec<u8>>,
) -> ApiResult<(Vec<u8>, &'static str)> {
    let config = &state.config;
    let permit = tokio::time::timeout(
        millis(config.busy_wait_ms),
        state.gpu.slot.clone().acquire_owned(),
    )
    .await
    .map_err(|_| ApiError::busy("the GPU is busy with other previews; try again shortly"))?
    .map_err(|_| ApiError::busy("the GPU is closed"))?;
    let cancel = Arc::new(AtomicBool::new(false));
    let _cancel_on_drop = CancelOnDrop(cancel.clone());
    let st = state.clone();
    let render = tokio::task::spawn_blocking(move || {
        let _permit = permit;
        render_png(&st.gpu, scenes, packages, &st, &cancel)
            .map_err(|e| ApiError::scrubbed(e, &st.blobs))
    });
    match tokio::time::timeout(millis(config.preview_timeout_ms), render).await {
        Ok(result) => Ok(result??),
        Err(_) => Err(ApiError::busy(format!(
            "the preview render ran past {} ms (preview_timeout_ms) and was abandoned",
            config.preview_timeout_ms
        ))),
    }
}

/// Renders a scene with the real-time pipeline from the package baked for it; a scene of
/// several objects from each object's package, drawn together (GDM and VDM objects). While a
/// package is not baked, answers 409 with the job baking it (submitted if needed) and, for
/// several objects, every object's job.
#[utoipa::path(
    post,
    path = "/api/v1/preview",
    request_body = SceneSpec,
    responses(
        (status = 200, description = "The image", content_type = "image/png"),
        (status = 409, description = "A package of the scene is not baked yet: {error, job, jobs} (job: the first not baked; jobs: every object's)"),
        (status = 413, description = "Body over max_json_bytes"),
        (status = 422, description = "Invalid scene, a cost over the server's limits, or an object among several that is not GDM"),
        (status = 429, description = "A package of the scene is not baked and the queue is full"),
        (status = 507, description = "A package of the scene is not baked and the server's storage is below its reserve"),
        (status = 503, description = "No GPU adapter (with preview_fallback = \"none\"), the GPU busy, or the render past preview_timeout_ms (then cancelled)"),
    )
)]
pub async fn render(
    State(state): State<AppState>,
    JsonBody(spec): JsonBody<SceneSpec>,
) -> ApiResult<Response> {
    let start = Instant::now();
    let objects = spec.objects(&state).await?;
    let several = objects.len() > 1;
    let mut jobs = Vec::with_capacity(objects.len());
    for object in &objects {
        let scene = &object.spec.scene;
        let lit_by_exr = matches!(scene.environment, Some(EnvironmentSource::Exr(_)))
            && scene.wants(Effect::EnvironmentLighting);
        if lit_by_exr {
            return Err(ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                "previews light environment-lit scenes with the built-in skies only: the \
                 server takes no EXR environment uploads (bake jobs do not need the environment)"
                    .to_owned(),
            ));
        }
        let technique = object.plan.technique.technique;
        if several && !matches!(technique, Technique::Gdm | Technique::Vdm) {
            return Err(not_previewable(&object.name, technique.name()));
        }
        let job = match state.db.job_for(&object.spec, technique).await? {
            Some(job) if job.state == "succeeded" => job,
            _ => enqueue(&state, &object.spec, &object.plan).await?.0,
        };
        jobs.push(ObjectJob {
            name: object.name.clone(),
            job,
        });
    }
    let digest = |j: &ObjectJob| {
        (j.job.state == "succeeded")
            .then(|| j.job.package_digest.clone())
            .flatten()
    };
    if let Some(waiting) = jobs.iter().find(|j| digest(j).is_none()) {
        let job = &waiting.job;
        let error = if several {
            format!(
                "the package of object {:?} is not baked yet (job {} is {})",
                waiting.name, job.id, job.state
            )
        } else {
            format!(
                "the scene's package is not baked yet (job {} is {})",
                job.id, job.state
            )
        };
        let body = serde_json::json!({ "error": error, "job": job, "jobs": jobs });
        return Ok((StatusCode::CONFLICT, Json(body)).into_response());
    }
    let digests: Vec<String> = jobs.iter().filter_map(digest).collect();
    // One object's technique, or GDM for several (checked above).
    let technique = objects[0].plan.technique.technique;
    let scene_texts: Vec<String> = objects
        .iter()
        .map(|o| serde_json::to_string(&o.spec.scene).expect("scenes serialize"))
        .collect();
    let cache_key = |renderer: &str| {
        let text = format!(
            "preview-v2\n{renderer}\n{}\n{}",
            digests.join(","),
            scene_texts.join("\n")
        );
        blake3::hash(text.as_bytes()).to_hex().to_string()
    };
    // Before the device is first opened the renderer is unknown, and so is the cache key.
    let cached = match state.gpu.renderer.get() {
        Some(&renderer) => preview_cache::lookup(&state, &cache_key(renderer))
            .await?
            .map(|png| (png, renderer)),
        None => None,
    };
    let (png, renderer) = match cached {
        Some(hit) => {
            state
                .metrics
                .preview_cache_hits
                .fetch_add(1, Ordering::Relaxed);
            hit
        }
        None => {
            state
                .metrics
                .preview_cache_misses
                .fetch_add(1, Ordering::Relaxed);
            let packages = {
                let (blobs, digests) = (state.blobs.clone(), digests.clone());
                tokio::task::spawn_blocking(move || {
                    digests
                        .iter()
                        .map(|d| blobs.get(d))
                        .collect::<Result<Option<Vec<_>>>>()
                })
                .await??
            }
            .ok_or_else(|| {
                ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    "a package's blob is missing",
                )
            })?;
            let scenes = objects.into_iter().map(|o| o.spec.scene).collect();
            let (png, renderer) = render_on_gpu(&state, scenes, packages).await?;
            // An image the cache cannot keep (a full disk, say) is still answered.
            if let Err(e) = preview_cache::store(&state, &cache_key(renderer), png.clone()).await {
                tracing::warn!("preview not cached: {e}");
            }
            (png, renderer)
        }
    };
    state
        .metrics
        .observe("preview", start.elapsed().as_secs_f64());
    Ok((
        [
            (header::CONTENT_TYPE, "image/png"),
            (header::CACHE_CONTROL, "no-cache"),
            (header::HeaderName::from_static(RENDERER_HEADER), renderer),
            (
                header::HeaderName::from_static(TECHNIQUE_HEADER),
                technique.name(),
            ),
        ],
        png,
    )
        .into_response())
}
