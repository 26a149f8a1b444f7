//! Bake jobs: what a client posts ([`JobSpec`]), the planner that derives the stages from
//! the scene's effects, and the durable queue in the database.
//!
//! The queue is the `jobs` table itself. A worker claims a job with one conditional
//! `UPDATE … RETURNING` (portable between SQLite and PostgreSQL: the condition is checked
//! again on the row it updates, so two workers never both win) and owns it until its lease
//! expires; heartbeats extend the lease. A worker that dies stops heartbeating, its lease
//! expires and another worker claims the job again. Finishing is conditional on still owning
//! the lease, so a job has exactly one successful result. Transient failures are retried
//! with exponential backoff; input errors fail at once.

use super::api_error::ApiError;
use super::assets::resolve_assets;
use super::blobs::BlobStore;
use super::db::{Db, db_error, now_ms};
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_scene::Scene;
use mesobake_scene::package::{ScenePackageParams, package_key, plan_package};
use mesobake_scene::plan::Plan;
use mesobake_scene::technique::Technique;
use serde::{Deserialize, Serialize};
use sqlx::any::AnyRow;
use sqlx::{AssertSqlSafe, Row};
use std::path::Path;

/// How many times a job is tried before it fails for good.
pub const MAX_ATTEMPTS: i32 = 3;

/// What a client asks to bake.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobSpec {
    /// The scene (docs/scene-format.md). Files it names (a volume, a mesh tile, a base mesh)
    /// are the digests of uploaded assets.
    #[schema(value_type = Object)]
    pub scene: Scene,
    /// What answers the renderers' GDM queries: `occupancy` (the default) or `paper-svd`.
    #[serde(default)]
    #[schema(value_type = String)]
    pub codec: GdmCodec,
    /// SVD components of the package (`paper-svd` only; default 8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rank: Option<usize>,
    /// Number format of the package's factors (`paper-svd` only; default f16).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub quantization: Option<Quantization>,
}

impl JobSpec {
    /// The package parameters.
    pub fn package_params(&self) -> ScenePackageParams {
        ScenePackageParams {
            codec: self.codec,
            rank: RankChoice::Rank(self.rank.unwrap_or(8)),
            quantization: self.quantization.unwrap_or_default(),
        }
    }

    /// The job's plan: the technique chosen for the scene on its base mesh (uploaded assets
    /// in `blobs`) and the scene's stages ([`mesobake_scene::plan::plan`]), then `store`.
    /// Package parameters that do not apply to the technique are an error.
    pub fn plan(&self, blobs: &BlobStore, limits: &Limits) -> Result<Plan> {
        let mut scene = self.scene.clone();
        resolve_assets(&mut scene, blobs)?;
        let mut plan = plan_package(&scene, Path::new("/"), self.package_params(), limits)?;
        plan.stages.push("store".into());
        Ok(plan)
    }

    /// What the result depends on ([`package_key`]), hashed: jobs with equal keys share
    /// one package.
    pub fn dedup_key(&self, technique: Technique) -> String {
        let key = package_key(&self.scene, technique, self.package_params());
        blake3::hash(key.to_string().as_bytes())
            .to_hex()
            .to_string()
    }
}

/// A job as the API shows it.
#[derive(Clone, Debug, PartialEq, Serialize, utoipa::ToSchema)]
pub struct JobView {
    /// The job's id.
    pub id: String,
    /// `queued`, `running`, `succeeded`, `failed` or `cancelled`.
    pub state: String,
    /// The stage running now (or the last one).
    pub stage: Option<String>,
    /// Fraction done, 0 to 1.
    pub progress: f64,
    /// Attempts so far.
    pub attempts: i32,
    /// Attempts allowed before the job fails.
    pub max_attempts: i32,
    /// What runs and what was skipped.
    pub plan: Plan,
    /// Seconds per finished stage.
    #[schema(value_type = Object)]
    pub timings: serde_json::Value,
    /// Why it failed.
    pub error: Option<String>,
    /// The package, once succeeded.
    pub package_digest: Option<String>,
    /// Whether a cancellation was asked for.
    pub cancel_requested: bool,
    /// Submission time, Unix milliseconds.
    pub created_ms: i64,
    /// Last change, Unix milliseconds.
    pub updated_ms: i64,
}

impl JobView {
    /// Whether the job will not change any more.
    pub fn is_final(&self) -> bool {
        matches!(self.state.as_str(), "succeeded" | "failed" | "cancelled")
    }
}

/// A job a worker has claimed.
#[derive(Clone, Debug)]
pub struct Claimed {
    /// The job's id.
    pub id: String,
    /// What to bake.
    pub spec: JobSpec,
    /// Its plan, as made at submission.
    pub plan: Plan,
    /// This attempt's number (1 for the first).
    pub attempt: i32,
    /// When the job became runnable (its submission or its retry's backoff), Unix ms.
    pub ready_ms: i64,
}

const VIEW_COLUMNS: &str = "id, state, stage, progress, attempts, max_attempts, plan, timings, \
    error, package_digest, cancel_requested, created_ms, updated_ms";

fn json(row: &AnyRow, name: &str) -> Result<serde_json::Value> {
    let text: String = row.try_get(name).map_err(db_error)?;
    serde_json::from_str(&text).map_err(|e| Error::Database(format!("column {name}: {e}")))
}

fn view(row: &AnyRow) -> Result<JobView> {
    let get = |e: sqlx::Error| db_error(e);
    Ok(JobView {
        id: row.try_get("id").map_err(get)?,
        state: row.try_get("state").map_err(get)?,
        stage: row.try_get("stage").map_err(get)?,
        progress: row.try_get("progress").map_err(get)?,
        attempts: row.try_get("attempts").map_err(get)?,
        max_attempts: row.try_get("max_attempts").map_err(get)?,
        plan: serde_json::from_value(json(row, "plan")?)
            .map_err(|e| Error::Database(format!("plan: {e}")))?,
        timings: json(row, "timings")?,
        error: row.try_get("error").map_err(get)?,
        package_digest: row.try_get("package_digest").map_err(get)?,
        cancel_requested: row.try_get::<i32, _>("cancel_requested").map_err(get)? != 0,
        created_ms: row.try_get("created_ms").map_err(get)?,
        updated_ms: row.try_get("updated_ms").map_err(get)?,
    })
}

/// A random job id: a UUID v4 as 32 lowercase hex digits.
fn new_id() -> String {
    uuid::Uuid::new_v4().simple().to_string()
}

impl Db {
    /// Submits `spec` with its `plan` ([`JobSpec::plan`]): a new queued job, or the existing
    /// job with the same inputs and parameters (re-queued if it failed or was cancelled).
    /// Returns the job and whether a bake was queued.
    pub async fn submit_job(&self, spec: &JobSpec, plan: &Plan) -> Result<(JobView, bool)> {
        let technique = plan.technique.technique;
        let key = spec.dedup_key(technique);
        let now = now_ms();
        let plan = serde_json::to_string(plan).expect("plans serialize");
        let spec_text = serde_json::to_string(spec).expect("specs serialize");
        let inserted = sqlx::query(
            "INSERT INTO jobs (id, dedup_key, spec, plan, state, stage, progress, attempts, \
             max_attempts, run_after_ms, cancel_requested, timings, created_ms, updated_ms) \
             VALUES ($1, $2, $3, $4, 'queued', NULL, 0, 0, $5, $6, 0, '{}', $6, $6) \
             ON CONFLICT (dedup_key) DO NOTHING",
        )
        .bind(new_id())
        .bind(&key)
        .bind(&spec_text)
        .bind(&plan)
        .bind(MAX_ATTEMPTS)
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?
        .rows_affected()
            == 1;
        let requeued = !inserted
            && sqlx::query(
                "UPDATE jobs SET state = 'queued', stage = NULL, progress = 0, attempts = 0, \
                 error = NULL, cancel_requested = 0, lease_owner = NULL, \
                 lease_expires_ms = NULL, run_after_ms = $2, updated_ms = $2 \
                 WHERE dedup_key = $1 AND state IN ('failed', 'cancelled')",
            )
            .bind(&key)
            .bind(now)
            .execute(&self.pool)
            .await
            .map_err(db_error)?
            .rows_affected()
                == 1;
        let job = self.job_for(spec, technique).await?.ok_or_else(|| {
            Error::Database(format!(
                "the job of dedup key {key} vanished after its insert"
            ))
        })?;
        Ok((job, inserted || requeued))
    }

    /// The job of `spec` (same inputs and parameters) for a package of `technique`, if one was
    /// ever submitted: a read, so that callers that only need a finished result (the
    /// preview) write nothing.
    pub async fn job_for(&self, spec: &JobSpec, technique: Technique) -> Result<Option<JobView>> {
        self.job_where("dedup_key", &spec.dedup_key(technique))
            .await
    }

    /// The job `id`.
    pub async fn job(&self, id: &str) -> Result<Option<JobView>> {
        self.job_where("id", id).await
    }

    /// The job whose unique `column` (a name fixed in this file) holds `value`.
    async fn job_where(&self, column: &'static str, value: &str) -> Result<Option<JobView>> {
        sqlx::query(AssertSqlSafe(format!(
            "SELECT {VIEW_COLUMNS} FROM jobs WHERE {column} = $1"
        )))
        .bind(value)
        .fetch_optional(&self.pool)
        .await
        .map_err(db_error)?
        .map(|row| view(&row))
        .transpose()
    }

    /// The newest `limit` jobs.
    pub async fn jobs(&self, limit: i64) -> Result<Vec<JobView>> {
        sqlx::query(AssertSqlSafe(format!(
            "SELECT {VIEW_COLUMNS} FROM jobs ORDER BY created_ms DESC, id LIMIT $1"
        )))
        .bind(limit)
        .fetch_all(&self.pool)
        .await
        .map_err(db_error)?
        .iter()
        .map(view)
        .collect()
    }

    /// Claims the oldest runnable job for `worker` with a lease of `lease_ms`: a queued job
    /// whose backoff has passed, or a running job whose lease expired.
    pub async fn claim_job(&self, worker: &str, lease_ms: i64) -> Result<Option<Claimed>> {
        let now = now_ms();
        let runnable = "((state = 'queued' AND run_after_ms <= $3) \
                        OR (state = 'running' AND lease_expires_ms < $3)) AND cancel_requested = 0";
        let row = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET state = 'running', lease_owner = $1, lease_expires_ms = $2, \
             attempts = attempts + 1, updated_ms = $3 \
             WHERE id = (SELECT id FROM jobs WHERE {runnable} ORDER BY created_ms, id LIMIT 1) \
             AND {runnable} RETURNING id, spec, plan, attempts, run_after_ms"
        )))
        .bind(worker)
        .bind(now + lease_ms)
        .bind(now)
        .fetch_optional(&self.pool)
        .await
        .map_err(db_error)?;
        let Some(row) = row else { return Ok(None) };
        let spec: String = row.try_get("spec").map_err(db_error)?;
        Ok(Some(Claimed {
            id: row.try_get("id").map_err(db_error)?,
            spec: serde_json::from_str(&spec)
                .map_err(|e| Error::Database(format!("job spec: {e}")))?,
            plan: serde_json::from_value(json(&row, "plan")?)
                .map_err(|e| Error::Database(format!("job plan: {e}")))?,
            attempt: row.try_get("attempts").map_err(db_error)?,
            ready_ms: row.try_get("run_after_ms").map_err(db_error)?,
        }))
    }

    /// Extends `worker`'s lease on job `id` and records its progress. `None` when the lease
    /// was lost; otherwise whether a cancellation was asked for.
    pub async fn heartbeat_job(
        &self,
        id: &str,
        worker: &str,
        lease_ms: i64,
        stage: &str,
        progress: f64,
    ) -> Result<Option<bool>> {
        let now = now_ms();
        let row = sqlx::query(
            "UPDATE jobs SET lease_expires_ms = $3, stage = $4, progress = $5, updated_ms = $6 \
             WHERE id = $1 AND lease_owner = $2 AND state = 'running' \
             RETURNING cancel_requested",
        )
        .bind(id)
        .bind(worker)
        .bind(now + lease_ms)
        .bind(stage)
        .bind(progress)
        .bind(now)
        .fetch_optional(&self.pool)
        .await
        .map_err(db_error)?;
        row.map(|r| r.try_get::<i32, _>("cancel_requested").map(|c| c != 0))
            .transpose()
            .map_err(db_error)
    }

    /// Ends `worker`'s run of job `id` in `state` (with the package or the error), if it
    /// still owns the lease; returns whether it did.
    pub async fn finish_job(
        &self,
        id: &str,
        worker: &str,
        state: &str,
        package_digest: Option<&str>,
        error: Option<&str>,
        timings: &serde_json::Value,
    ) -> Result<bool> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET state = $3, package_digest = $4, error = $5, timings = $6, \
             progress = CASE WHEN $3 = 'succeeded' THEN 1 ELSE progress END, \
             stage = CASE WHEN $3 = 'succeeded' THEN 'store' ELSE stage END, \
             lease_owner = NULL, lease_expires_ms = NULL, updated_ms = $7 \
             WHERE id = $1 AND lease_owner = $2 AND state = 'running'",
        )
        .bind(id)
        .bind(worker)
        .bind(state)
        .bind(package_digest)
        .bind(error)
        .bind(timings.to_string())
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(done.rows_affected() == 1)
    }

    /// Fails `worker`'s job `id`, just claimed past its last attempt (workers kept losing
    /// its lease), without running it: the claim's count is taken back, so that the job
    /// shows the attempts that ran, never more than its `max_attempts`.
    pub async fn give_up_job(&self, id: &str, worker: &str, error: &str) -> Result<bool> {
        let done = sqlx::query(
            "UPDATE jobs SET state = 'failed', error = $3, attempts = attempts - 1, \
             lease_owner = NULL, lease_expires_ms = NULL, updated_ms = $4 \
             WHERE id = $1 AND lease_owner = $2 AND state = 'running'",
        )
        .bind(id)
        .bind(worker)
        .bind(error)
        .bind(now_ms())
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(done.rows_affected() == 1)
    }

    /// Puts `worker`'s job `id` back in the queue after a transient failure, to run again
    /// after `backoff_ms`; returns whether it still owned the lease.
    pub async fn retry_job(
        &self,
        id: &str,
        worker: &str,
        error: &str,
        backoff_ms: i64,
    ) -> Result<bool> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET state = 'queued', error = $3, lease_owner = NULL, \
             lease_expires_ms = NULL, run_after_ms = $4, updated_ms = $5 \
             WHERE id = $1 AND lease_owner = $2 AND state = 'running'",
        )
        .bind(id)
        .bind(worker)
        .bind(error)
        .bind(now + backoff_ms)
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(done.rows_affected() == 1)
    }

    /// Asks for job `id` to stop: a queued job is cancelled at once, a running one when its
    /// worker next looks (or when its lease expires, if the worker died). `None` when there
    /// is no such job.
    pub async fn cancel_job(&self, id: &str) -> Result<Option<JobView>> {
        let now = now_ms();
        sqlx::query(
            "UPDATE jobs SET cancel_requested = 1, updated_ms = $2, \
             state = CASE WHEN state = 'queued' THEN 'cancelled' ELSE state END \
             WHERE id = $1 AND state IN ('queued', 'running')",
        )
        .bind(id)
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        self.job(id).await
    }

    /// Hands `worker`'s running job `id` back to the queue at once (the worker is shutting
    /// down): the attempt does not count. Returns whether it still owned the lease.
    pub async fn release_job(&self, id: &str, worker: &str) -> Result<bool> {
        let now = now_ms();
        let done = sqlx::query(
            "UPDATE jobs SET state = 'queued', attempts = attempts - 1, lease_owner = NULL, \
             lease_expires_ms = NULL, run_after_ms = $3, updated_ms = $3 \
             WHERE id = $1 AND lease_owner = $2 AND state = 'running'",
        )
        .bind(id)
        .bind(worker)
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(done.rows_affected() == 1)
    }

    /// How many jobs are queued or running.
    pub async fn active_job_count(&self) -> Result<u64> {
        let n: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE state IN ('queued', 'running')")
                .fetch_one(&self.pool)
                .await
                .map_err(db_error)?;
        Ok(n.max(0) as u64)
    }

    /// How many jobs are in each state.
    pub async fn job_counts(&self) -> Result<Vec<(String, i64)>> {
        let rows =
            sqlx::query("SELECT state, COUNT(*) AS n FROM jobs GROUP BY state ORDER BY state")
                .fetch_all(&self.pool)
                .await
                .map_err(db_error)?;
        rows.iter()
            .map(|r| {
                Ok((
                    r.try_get("state").map_err(db_error)?,
                    r.try_get("n").map_err(db_error)?,
                ))
            })
            .collect()
    }

    /// Cancels running jobs whose cancellation was asked for and whose worker's lease
    /// expired (the worker died before it could see the request).
    pub async fn reap_cancelled_jobs(&self) -> Result<u64> {
        let now = now_ms();
        Ok(sqlx::query(
            "UPDATE jobs SET state = 'cancelled', lease_owner = NULL, lease_expires_ms = NULL, \
             updated_ms = $1 WHERE state = 'running' AND cancel_requested = 1 \
             AND lease_expires_ms < $1",
        )
        .bind(now)
        .execute(&self.pool)
        .await
        .map_err(db_error)?
        .rows_affected())
    }
}

/// A job id from a path: 32 lowercase hex digits.
pub fn check_job_id(id: &str) -> std::result::Result<(), ApiError> {
    if id.len() == 32 && id.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')) {
        Ok(())
    } else {
        Err(ApiError::not_found(format!("job {id:?}")))
    }
}
