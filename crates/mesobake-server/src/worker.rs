//! The bake worker: claims jobs from the database queue ([`super::jobs`]), runs them on the
//! blocking pool (rayon inside), heartbeats while they run, stores the package and finishes
//! the job. Runs inside `mesobake serve` (`workers` in the configuration) and as
//! `mesobake worker` processes on other machines that share the database and blob store.

use super::AppState;
use super::assets::resolve_assets;
use super::blobs::BlobStore;
use super::db::{PackageRow, now_ms};
use super::jobs::{Claimed, JobSpec, MAX_ATTEMPTS};
use super::storage_reserve;
use mesobake_bake::package::AnyPackage;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_core::observer::BakeObserver;
use mesobake_scene::LoadedScene;
use mesobake_scene::package::{bake_scene_package, plan_package};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How long a claim lasts without a heartbeat.
pub const LEASE_MS: i64 = 10_000;
/// How often a running job heartbeats and looks for a cancellation or a shutdown: well
/// within the second in which a cancellation is honoured.
const HEARTBEAT: Duration = Duration::from_millis(250);
/// How long an idle worker waits before looking for work again.
const POLL: Duration = Duration::from_millis(200);

/// Relative cost of each stage, for the job's overall progress.
fn stage_weight(stage: &str) -> f64 {
    match stage {
        "bake_gdm" | "bake_rtv" | "bake_vdm" => 10.0,
        "compress" | "compress_vdm" => 3.0,
        "bake_prt" | "compress_rtv" => 2.0,
        _ => 1.0,
    }
}

/// Progress and cancellation shared between a running bake and its heartbeat.
struct Shared {
    /// The job's stages, in order.
    stages: Vec<String>,
    /// The running stage and the fraction of it done.
    now: std::sync::Mutex<(usize, f64)>,
    cancel: AtomicBool,
}

impl Shared {
    fn new(stages: Vec<String>) -> Shared {
        Shared {
            stages,
            now: std::sync::Mutex::new((0, 0.0)),
            cancel: AtomicBool::new(false),
        }
    }

    /// The running stage's name and the job's fraction done.
    fn progress_now(&self) -> (String, f64) {
        let (index, fraction) = self.now.lock().map(|g| *g).unwrap_or((0, 0.0));
        let total: f64 = self.stages.iter().map(|s| stage_weight(s)).sum();
        let done: f64 = self.stages[..index].iter().map(|s| stage_weight(s)).sum();
        let stage = self.stages.get(index).cloned().unwrap_or_default();
        let weight = stage_weight(&stage);
        (stage, ((done + weight * fraction) / total).min(1.0))
    }
}

impl BakeObserver for Shared {
    fn progress(&self, done: u64, total: u64) {
        if let Ok(mut now) = self.now.lock() {
            now.1 = done as f64 / total.max(1) as f64;
        }
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    fn stage(&self, name: &str) {
        if let (Ok(mut now), Some(index)) =
            (self.now.lock(), self.stages.iter().position(|s| s == name))
        {
            *now = (index, 0.0);
        }
    }
}

/// Seconds per stage, in the order run.
type StageSeconds = Vec<(String, f64)>;

/// Runs one job to its package bytes and the seconds per stage.
fn bake(
    spec: &JobSpec,
    blobs: &BlobStore,
    limits: &Limits,
    observer: &Shared,
) -> Result<(Vec<u8>, StageSeconds)> {
    let start = Instant::now();
    observer.stage("load");
    let mut scene = spec.scene.clone();
    resolve_assets(&mut scene, blobs)?;
    // A package holds transfer, not light: the environment is not loaded.
    scene.environment = None;
    // Planned again under this worker's limits: refused before loading when the bake's
    // memory is over them.
    plan_package(&scene, Path::new("/"), spec.package_params(), limits)?;
    let loaded = LoadedScene::load(scene, Path::new("/"), limits)?;
    if observer.cancelled() {
        return Err(Error::Cancelled);
    }
    let mut seconds = vec![("load".to_owned(), start.elapsed().as_secs_f64())];
    let baked = bake_scene_package(
        &loaded,
        Path::new("/"),
        spec.package_params(),
        limits,
        observer,
    )?;
    seconds.extend(baked.seconds);
    Ok((baked.bytes, seconds))
}

/// Whether a failure may go away on retry (storage, database, GPU) rather than being the
/// input's fault.
fn is_transient(e: &Error) -> bool {
    matches!(
        e,
        Error::Io { .. } | Error::Database(_) | Error::Gpu(_) | Error::StorageFull(_)
    )
}

/// What a bake task hands back: the package's digest, size, manifest and stage seconds.
type Baked = (String, usize, serde_json::Value, StageSeconds);

/// How a run of a job ended, before its outcome is written.
enum Ended {
    /// The bake task returned.
    Returned(Result<Baked>),
    /// A cancellation was asked for.
    Cancelled,
    /// The worker is stopping: the job goes back to the queue.
    Stopping,
    /// Another worker holds the lease now.
    LostLease,
}

/// Runs claimed job `job` as `worker`, until it ends or `stop` is set.
async fn run(state: &AppState, worker: &str, job: Claimed, stop: &AtomicBool) -> Result<()> {
    let db = &state.db;
    if job.attempt > MAX_ATTEMPTS {
        let error = format!("gave up after {MAX_ATTEMPTS} attempts (workers lost their lease)");
        tracing::warn!("job {} failed: {error}", job.id);
        db.give_up_job(&job.id, worker, &error).await?;
        return Ok(());
    }
    if job.attempt == 1 {
        let waited = (now_ms() - job.ready_ms).max(0) as f64 / 1e3;
        state.metrics.observe("queue_wait", waited);
    }
    tracing::info!(
        "job {} running (attempt {}) on {worker}",
        job.id,
        job.attempt
    );
    let shared = Arc::new(Shared::new(job.plan.stages.clone()));
    let (spec, blobs, limits) = (job.spec.clone(), state.blobs.clone(), state.limits);
    let task = {
        let shared = shared.clone();
        tokio::task::spawn_blocking(move || {
            let (bytes, mut seconds) = bake(&spec, &blobs, &limits, &shared)?;
            shared.stage("store");
            let start = Instant::now();
            let package = AnyPackage::parse_within(bytes.clone(), &limits)?;
            let digest = blobs.put(&bytes)?;
            seconds.push(("store".into(), start.elapsed().as_secs_f64()));
            let manifest = package.manifest_json();
            Ok::<_, Error>((digest, bytes.len(), manifest, seconds))
        })
    };
    tokio::pin!(task);
    let ended = loop {
        tokio::select! {
            result = &mut task => break Ended::Returned(
                result.map_err(|e| Error::InvalidParameter(format!("bake task: {e}"))).and_then(|r| r)
            ),
            () = tokio::time::sleep(HEARTBEAT) => {
                if stop.load(Ordering::Relaxed) {
                    break Ended::Stopping;
                }
                let (stage, progress) = shared.progress_now();
                match db.heartbeat_job(&job.id, worker, LEASE_MS, &stage, progress).await {
                    Ok(Some(true)) => break Ended::Cancelled,
                    Ok(Some(false)) => {}
                    Ok(None) => break Ended::LostLease,
                    Err(e) => tracing::warn!("heartbeat of job {}: {e}", job.id),
                }
            }
        }
    };
    let still_running = !matches!(ended, Ended::Returned(_));
    if still_running {
        // The bake stops at its next check; its result, if any, is dropped.
        shared.cancel.store(true, Ordering::Relaxed);
    }
    let empty = serde_json::json!({});
    let scrub = |e: &Error| state.blobs.scrub(&e.to_string());
    match ended {
        Ended::Stopping => {
            if db.release_job(&job.id, worker).await? {
                tracing::info!(
                    "job {} handed back to the queue: the worker is stopping",
                    job.id
                );
            }
            // A stopping worker does not wait for its bake to notice.
            return Ok(());
        }
        Ended::LostLease => tracing::warn!("worker {worker} lost its lease on job {}", job.id),
        Ended::Cancelled | Ended::Returned(Err(Error::Cancelled)) => {
            db.finish_job(&job.id, worker, "cancelled", None, None, &empty)
                .await?;
            tracing::info!("job {} cancelled", job.id);
        }
        Ended::Returned(Ok((digest, bytes, manifest, seconds))) => {
            db.insert_package(&PackageRow {
                digest: digest.clone(),
                bytes: bytes as i64,
                manifest,
                created_ms: now_ms(),
            })
            .await?;
            let mut timings = serde_json::Map::new();
            for (stage, s) in &seconds {
                state.metrics.observe(&format!("stage:{stage}"), *s);
                timings.insert(stage.clone(), (*s).into());
            }
            db.finish_job(
                &job.id,
                worker,
                "succeeded",
                Some(&digest),
                None,
                &timings.into(),
            )
            .await?;
            tracing::info!("job {} succeeded: package {digest}", job.id);
        }
        Ended::Returned(Err(e)) if is_transient(&e) && job.attempt < MAX_ATTEMPTS => {
            let backoff = 1_000i64 << job.attempt.min(6);
            tracing::warn!(
                "job {} attempt {} failed, retrying: {e}",
                job.id,
                job.attempt
            );
            db.retry_job(&job.id, worker, &scrub(&e), backoff).await?;
        }
        Ended::Returned(Err(e)) => {
            tracing::warn!("job {} failed: {e}", job.id);
            db.finish_job(&job.id, worker, "failed", None, Some(&scrub(&e)), &empty)
                .await?;
        }
    }
    if still_running {
        // Wait for the abandoned bake to stop before taking more work, so that a worker
        // never runs two bakes at once.
        let _ = task.await;
    }
    Ok(())
}

/// Claims and runs jobs as `worker` until `stop` is set; claims none while the storage is
/// below its reserve ([`storage_reserve`]).
pub async fn work(state: AppState, worker: String, stop: Arc<AtomicBool>) {
    let mut short_of_space = false;
    while !stop.load(Ordering::Relaxed) {
        if let Err(e) = storage_reserve::check(&state.config, 0) {
            if !short_of_space {
                tracing::warn!("worker {worker} claims no job: {e}");
            }
            short_of_space = true;
            tokio::time::sleep(POLL * 5).await;
            continue;
        }
        short_of_space = false;
        let claimed = match state.db.reap_cancelled_jobs().await {
            Ok(_) => state.db.claim_job(&worker, LEASE_MS).await,
            Err(e) => Err(e),
        };
        match claimed {
            Ok(Some(job)) => {
                let id = job.id.clone();
                if let Err(e) = run(&state, &worker, job, &stop).await {
                    tracing::error!("worker {worker}, job {id}: {e}");
                }
            }
            Ok(None) => tokio::time::sleep(POLL).await,
            Err(e) => {
                tracing::error!("worker {worker}: {e}");
                tokio::time::sleep(POLL * 5).await;
            }
        }
    }
}

/// A worker name unique across machines and processes.
pub fn worker_name(index: u32) -> String {
    let host = std::env::var("HOSTNAME").unwrap_or_else(|_| "host".into());
    format!(
        "{host}-{}-{index}-{}",
        std::process::id(),
        &uuid::Uuid::new_v4().simple().to_string()[..8]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_moves_through_every_stage_by_weight() {
        let stages = ["load", "bake_gdm", "compress", "encode", "store"];
        let shared = Shared::new(stages.iter().map(|s| s.to_string()).collect());
        // Weights 1 + 10 + 3 + 1 + 1 = 16.
        let at = |stage: &str, done: u64, total: u64| {
            shared.stage(stage);
            shared.progress(done, total);
            shared.progress_now()
        };
        assert_eq!(at("load", 0, 1), ("load".to_owned(), 0.0));
        assert_eq!(
            at("bake_gdm", 256, 512),
            ("bake_gdm".to_owned(), 6.0 / 16.0)
        );
        assert_eq!(at("compress", 0, 1), ("compress".to_owned(), 11.0 / 16.0));
        assert_eq!(at("store", 1, 1), ("store".to_owned(), 1.0));
        // A stage the plan does not name leaves the running stage as it was.
        assert_eq!(at("bake_rtv", 1, 1), ("store".to_owned(), 1.0));
    }
}
