//! `/api/v1/jobs`: submit a bake, follow it (JSON or server-sent events), cancel it.

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::jobs::{JobSpec, JobView, check_job_id};
use super::json_body::JsonBody;
use super::request_limits::check_scene_cost;
use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::sse::{Event, KeepAlive, Sse};
use futures_util::stream::{self, Stream};
use mesobake_bake::package::bake::check_codec_options;
use mesobake_core::error::Error;
use mesobake_scene::plan::Plan;
use mesobake_scene::{BaseMeshSource, MesostructureSource, Scene};
use std::convert::Infallible;
use std::time::Duration;

/// How often an event stream looks at its job.
const EVENT_POLL: Duration = Duration::from_millis(250);

/// Checks that every file `scene` names is an uploaded asset of the kind it is used as.
async fn check_assets(state: &AppState, scene: &Scene) -> ApiResult<()> {
    let mut wanted = Vec::new();
    match &scene.mesostructure {
        MesostructureSource::Volume(p) => wanted.push((p.as_path(), "volume")),
        MesostructureSource::Tile(p) => wanted.push((p, "mesh_tile")),
        MesostructureSource::HeightField(p) => wanted.push((p, "height_field")),
        MesostructureSource::Sample(_)
        | MesostructureSource::SampleTile(_)
        | MesostructureSource::Relief(_)
        | MesostructureSource::Medium(_) => {}
    }
    match &scene.base_mesh {
        BaseMeshSource::Obj(p) => wanted.push((p.as_path(), "base_mesh")),
        BaseMeshSource::Gltf(g) => wanted.push((g.file(), "base_mesh")),
        BaseMeshSource::Builtin(_) => {}
    }
    for (path, kind) in wanted {
        let id = path.to_string_lossy();
        let asset = if super::blobs::is_key(&id) {
            state.db.asset(&id).await?
        } else {
            None
        };
        match asset {
            Some(a) if a.kind == kind => {}
            Some(a) => {
                return Err(ApiError::new(
                    StatusCode::UNPROCESSABLE_ENTITY,
                    format!(
                        "asset {id} is a {}, but the scene uses it as a {kind}",
                        a.kind
                    ),
                ));
            }
            None => {
                return Err(ApiError::new(
                    StatusCode::UNPROCESSABLE_ENTITY,
                    format!(
                        "the scene names {id:?}, which is not the digest of an uploaded {kind}"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Checks a job specification and returns its plan: the scene is valid and within the
/// server's cost limits, the codec options as the CLI checks them
/// ([`check_codec_options`]), every asset it names uploaded as the right kind, and the
/// package parameters apply to the technique chosen ([`JobSpec::plan`]).
pub async fn check_spec(state: &AppState, spec: &JobSpec) -> ApiResult<Plan> {
    // Deserializing does not validate a scene; parsing its text does.
    let text = serde_json::to_string(&spec.scene).expect("scenes serialize");
    Scene::from_json(&text)?;
    check_codec_options(spec.codec, spec.rank, spec.quantization)
        .map_err(|e| ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, e.to_string()))?;
    check_scene_cost(&spec.scene, &state.config)?;
    check_assets(state, &spec.scene).await?;
    let (spec, blobs, limits) = (spec.clone(), state.blobs.clone(), state.limits);
    match tokio::task::spawn_blocking(move || spec.plan(&blobs, &limits)).await? {
        // The scene's bake, not the request's body, is over the memory limit.
        Err(e @ Error::MemoryLimit { .. }) => Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            e.to_string(),
        )),
        plan => Ok(plan?),
    }
}

/// Submits `spec` (checked) with its `plan` to the queue, refusing with 429 a new job beyond
/// [`ServerConfig::max_queued_jobs`](super::config::ServerConfig::max_queued_jobs).
pub async fn enqueue(state: &AppState, spec: &JobSpec, plan: &Plan) -> ApiResult<(JobView, bool)> {
    if adds_a_job(state, spec, plan).await? {
        check_queue_room(state, 1).await?;
    }
    let (job, queued) = state.db.submit_job(spec, plan).await?;
    if queued {
        tracing::info!("job {} queued", job.id);
    }
    Ok((job, queued))
}

/// Whether submitting `spec` would add a job: none was submitted, or only one that failed or
/// was cancelled.
pub async fn adds_a_job(state: &AppState, spec: &JobSpec, plan: &Plan) -> ApiResult<bool> {
    Ok(state
        .db
        .job_for(spec, plan.technique.technique)
        .await?
        .is_none_or(|j| matches!(j.state.as_str(), "failed" | "cancelled")))
}

/// Refuses (429, or 507 below the storage reserve) `new_jobs` more jobs where the queue
/// cannot take them all.
pub async fn check_queue_room(state: &AppState, new_jobs: u64) -> ApiResult<()> {
    if new_jobs == 0 {
        return Ok(());
    }
    super::storage_reserve::check(&state.config, 0)?;
    let active = state.db.active_job_count().await?;
    let limit = state.config.max_queued_jobs;
    if active + new_jobs > limit {
        let more = match new_jobs {
            1 => String::new(),
            n => format!(" and this needs {n} more"),
        };
        return Err(ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "{active} jobs are queued or running{more}, the server's limit is {limit} \
                 (max_queued_jobs); try again later"
            ),
        ));
    }
    Ok(())
}

/// Submits a bake. Identical inputs and parameters reuse the existing job and its result.
#[utoipa::path(
    post,
    path = "/api/v1/jobs",
    request_body = JobSpec,
    responses(
        (status = 202, description = "Queued", body = JobView),
        (status = 200, description = "The same inputs and parameters were submitted before", body = JobView),
        (status = 413, description = "Body over max_json_bytes"),
        (status = 422, description = "Invalid scene or parameters, a cost over the server's limits, or unknown assets"),
        (status = 429, description = "The queue is full (max_queued_jobs)"),
        (status = 507, description = "The server's storage is below its reserve (min_free_bytes) or full"),
    )
)]
pub async fn submit(
    State(state): State<AppState>,
    JsonBody(spec): JsonBody<JobSpec>,
) -> ApiResult<(StatusCode, Json<JobView>)> {
    let plan = check_spec(&state, &spec).await?;
    let (job, queued) = enqueue(&state, &spec, &plan).await?;
    let status = if queued {
        StatusCode::ACCEPTED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(job)))
}

/// The newest jobs.
#[utoipa::path(get, path = "/api/v1/jobs", responses((status = 200, body = Vec<JobView>)))]
pub async fn list(State(state): State<AppState>) -> ApiResult<Json<Vec<JobView>>> {
    Ok(Json(state.db.jobs(100).await?))
}

async fn find(state: &AppState, id: &str) -> ApiResult<JobView> {
    check_job_id(id)?;
    state
        .db
        .job(id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("job {id}")))
}

/// A job's state, stages, progress, timings and errors.
#[utoipa::path(
    get,
    path = "/api/v1/jobs/{id}",
    params(("id" = String, Path, description = "Job id")),
    responses((status = 200, body = JobView), (status = 404, description = "No such job"))
)]
pub async fn get(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> ApiResult<Json<JobView>> {
    Ok(Json(find(&state, &id).await?))
}

/// Asks a job to stop; honoured mid-bake.
#[utoipa::path(
    post,
    path = "/api/v1/jobs/{id}/cancel",
    params(("id" = String, Path, description = "Job id")),
    responses((status = 200, body = JobView), (status = 404, description = "No such job"))
)]
pub async fn cancel(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> ApiResult<Json<JobView>> {
    check_job_id(&id)?;
    let job = state
        .db
        .cancel_job(&id)
        .await?
        .ok_or_else(|| ApiError::not_found(format!("job {id}")))?;
    tracing::info!("job {id}: cancellation asked for ({})", job.state);
    Ok(Json(job))
}

/// Server-sent events: a `job` event with the job's view whenever it changes, until it is
/// final.
#[utoipa::path(
    get,
    path = "/api/v1/jobs/{id}/events",
    params(("id" = String, Path, description = "Job id")),
    responses((status = 200, description = "text/event-stream of `job` events"), (status = 404, description = "No such job"))
)]
pub async fn events(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> ApiResult<Sse<impl Stream<Item = Result<Event, Infallible>>>> {
    let first = find(&state, &id).await?;
    let stream = stream::unfold(
        (Some(first), None::<JobView>, state, id),
        |(next, last, state, id)| async move {
            let mut current = next;
            loop {
                let job = match current.take() {
                    Some(job) => job,
                    None => {
                        if last.as_ref().is_some_and(JobView::is_final) {
                            return None;
                        }
                        tokio::time::sleep(EVENT_POLL).await;
                        match state.db.job(&id).await {
                            Ok(Some(job)) => job,
                            _ => return None,
                        }
                    }
                };
                if last.as_ref() != Some(&job) {
                    let event = Event::default()
                        .event("job")
                        .json_data(&job)
                        .expect("views serialize");
                    return Some((Ok(event), (None, Some(job), state, id)));
                }
            }
        },
    );
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}
