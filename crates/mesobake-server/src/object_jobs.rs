//! Scenes of several objects on the server (`objects`, docs/scene-format.md): a
//! [`SceneSpec`] is a [`JobSpec`] whose scene may hold several objects. Each object is baked
//! by a job of its own, the object as a scene of one (one package per object, each the
//! package `mesobake bake --scene` writes for it); `POST /api/v1/object-jobs` submits them
//! all, and `POST /api/v1/preview` draws them together once every one is baked.

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::jobs::{JobSpec, JobView};
use super::jobs_api::{adds_a_job, check_queue_room, check_spec, enqueue};
use super::json_body::JsonBody;
use axum::Json;
use axum::extract::State;
use axum::http::StatusCode;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_scene::objects;
use mesobake_scene::plan::Plan;
use serde::{Deserialize, Serialize};

/// What a client posts to bake or preview a scene of one object or of several.
#[derive(Clone, Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SceneSpec {
    /// The scene (docs/scene-format.md): one object, or several under `objects`. Files it
    /// names are the digests of uploaded assets.
    #[schema(value_type = Object)]
    pub scene: serde_json::Value,
    /// As [`JobSpec::codec`], for every object.
    #[serde(default)]
    #[schema(value_type = String)]
    pub codec: GdmCodec,
    /// As [`JobSpec::rank`], for every object.
    #[serde(default)]
    pub rank: Option<usize>,
    /// As [`JobSpec::quantization`], for every object.
    #[serde(default)]
    #[schema(value_type = Option<String>)]
    pub quantization: Option<Quantization>,
}

/// One object of a scene, its job specification and its checked plan.
pub struct ObjectSpec {
    /// The object's name (docs/scene-format.md: its `name`, its material's, or `object N`).
    pub name: String,
    /// Its bake: the object as a scene of its own, with the request's package parameters.
    pub spec: JobSpec,
    /// Its plan ([`check_spec`]).
    pub plan: Plan,
}

impl SceneSpec {
    /// Every object's job specification, each checked as `POST /api/v1/jobs` checks one (an
    /// error names the object where there are several), with room in the queue for every
    /// job they add (429 naming the count otherwise): all or none is queued.
    pub async fn objects(&self, state: &AppState) -> ApiResult<Vec<ObjectSpec>> {
        let text = serde_json::to_string(&self.scene).expect("JSON values serialize");
        let objects = objects::from_json(&text)?;
        let several = objects.len() > 1;
        let mut checked = Vec::with_capacity(objects.len());
        for object in objects {
            let spec = JobSpec {
                scene: object.scene,
                codec: self.codec,
                rank: self.rank,
                quantization: self.quantization,
            };
            let plan = check_spec(state, &spec).await.map_err(|mut e| {
                if several {
                    e.message = format!("object {:?}: {}", object.name, e.message);
                }
                e
            })?;
            checked.push(ObjectSpec {
                name: object.name,
                spec,
                plan,
            });
        }
        // Objects may share a mesostructure, and so a job.
        let mut new_jobs = std::collections::BTreeSet::new();
        for o in &checked {
            if adds_a_job(state, &o.spec, &o.plan).await? {
                new_jobs.insert(o.spec.dedup_key(o.plan.technique.technique));
            }
        }
        check_queue_room(state, new_jobs.len() as u64).await?;
        Ok(checked)
    }
}

/// One object's job.
#[derive(Clone, Debug, Serialize, utoipa::ToSchema)]
pub struct ObjectJob {
    /// The object's name.
    pub name: String,
    /// The job baking its package.
    pub job: JobView,
}

/// Submits a bake per object of a scene (of one object or several; every object is checked
/// before any is queued). Objects whose inputs and parameters were submitted before reuse
/// their jobs.
#[utoipa::path(
    post,
    path = "/api/v1/object-jobs",
    request_body = SceneSpec,
    responses(
        (status = 202, description = "At least one object's job was queued", body = Vec<ObjectJob>),
        (status = 200, description = "Every object's job had been submitted before", body = Vec<ObjectJob>),
        (status = 413, description = "Body over max_json_bytes"),
        (status = 422, description = "Invalid scene (naming the object) or parameters, a cost over the server's limits, or unknown assets"),
        (status = 429, description = "The queue has no room for every job the objects add (max_queued_jobs); none is queued"),
        (status = 507, description = "The server's storage is below its reserve (min_free_bytes) or full"),
    )
)]
pub async fn submit(
    State(state): State<AppState>,
    JsonBody(spec): JsonBody<SceneSpec>,
) -> ApiResult<(StatusCode, Json<Vec<ObjectJob>>)> {
    let mut queued_any = false;
    let mut jobs = Vec::new();
    for object in spec.objects(&state).await? {
        let (job, queued) = enqueue(&state, &object.spec, &object.plan).await?;
        queued_any |= queued;
        jobs.push(ObjectJob {
            name: object.name,
            job,
        });
    }
    let status = if queued_any {
        StatusCode::ACCEPTED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(jobs)))
}

/// `ApiError` for an object the preview of several cannot draw.
pub fn not_previewable(name: &str, technique: &str) -> ApiError {
    ApiError::new(
        StatusCode::UNPROCESSABLE_ENTITY,
        format!(
            "object {name:?}: its technique is {technique}; the preview of several objects \
             draws GDM and VDM objects"
        ),
    )
}
