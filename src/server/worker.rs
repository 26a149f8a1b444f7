//! The bake worker: claims jobs from the database queue ([`super::jobs`]), runs them on the
//! blocking pool (rayon inside), heartbeats while they run, stores the package and finishes
//! the job. Runs inside `mesobake serve` (`workers` in the configuration) and as
//! `mesobake worker` processes on other machines that share the database and blob store.

use super::AppState;
use super::blobs::BlobStore;
use super::db::{PackageRow, now_ms};
use super::jobs::{Claimed, JobSpec, MAX_ATTEMPTS};
use crate::error::{Error, Result};
use crate::gdm::BakeObserver;
use crate::limits::Limits;
use crate::package::Package;
use crate::scene::{BaseMeshSource, LoadedScene, MesostructureSource, Scene};
use crate::scene_package::bake_scene_package;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// How long a claim lasts without a heartbeat.
pub const LEASE_MS: i64 = 10_000;
/// How often a running job heartbeats (and looks for a cancellation).
const HEARTBEAT: Duration = Duration::from_millis(1_000);
/// How long an idle worker waits before looking for work again.
const POLL: Duration = Duration::from_millis(200);

/// Replaces every file a scene names (an asset digest) by the blob's path; an unknown
/// digest is an input error naming it.
pub fn resolve_assets(scene: &mut Scene, blobs: &BlobStore) -> Result<()> {
    let resolve = |p: &mut std::path::PathBuf| -> Result<()> {
        let digest = p.to_string_lossy().into_owned();
        if !super::blobs::is_key(&digest) {
            return Err(Error::Scene(format!(
                "{digest:?} is not the digest of an uploaded asset"
            )));
        }
        *p = blobs
            .file(&digest)?
            .ok_or_else(|| Error::Scene(format!("no uploaded asset has the digest {digest}")))?;
        Ok(())
    };
    match &mut scene.mesostructure {
        MesostructureSource::Volume(p)
        | MesostructureSource::Tile(p)
        | MesostructureSource::HeightField(p) => resolve(p)?,
        MesostructureSource::Sample(_) => {}
    }
    if let BaseMeshSource::Obj(p) = &mut scene.base_mesh {
        resolve(p)?;
    }
    Ok(())
}

/// Progress and cancellation shared between a running bake and its heartbeat.
#[derive(Default)]
struct Shared {
    /// Fraction done, as f64 bits.
    progress: AtomicU64,
    cancel: AtomicBool,
}

impl BakeObserver for Shared {
    fn progress(&self, done: u64, total: u64) {
        // The bake is most of a job; compression and storing are the rest.
        let fraction = 0.9 * done as f64 / total.max(1) as f64;
        self.progress.store(fraction.to_bits(), Ordering::Relaxed);
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// Runs one job to its package bytes and the seconds per stage.
fn bake(
    spec: &JobSpec,
    blobs: &BlobStore,
    limits: &Limits,
    observer: &Shared,
) -> Result<(Vec<u8>, serde_json::Value)> {
    let start = Instant::now();
    let mut scene = spec.scene.clone();
    resolve_assets(&mut scene, blobs)?;
    // A package holds transfer, not light: the environment is not loaded.
    scene.environment = None;
    let loaded = LoadedScene::load(scene, Path::new("/"), limits)?;
    let load = start.elapsed().as_secs_f64();
    let baked = bake_scene_package(
        &loaded,
        Path::new("/"),
        spec.package_params(),
        limits,
        observer,
    )?;
    let mut timings = serde_json::Map::new();
    timings.insert("load".into(), load.into());
    for (stage, seconds) in baked.seconds {
        timings.insert(stage, seconds.into());
    }
    Ok((baked.bytes, timings.into()))
}

/// Whether a failure may go away on retry (storage, database, GPU) rather than being the
/// input's fault.
fn is_transient(e: &Error) -> bool {
    matches!(e, Error::Io { .. } | Error::Database(_) | Error::Gpu(_))
}

/// Runs claimed job `job` as `worker`.
async fn run(state: &AppState, worker: &str, job: Claimed) -> Result<()> {
    let db = &state.db;
    if job.attempt > MAX_ATTEMPTS {
        let error = format!("gave up after {MAX_ATTEMPTS} attempts (workers lost their lease)");
        db.finish_job(
            &job.id,
            worker,
            "failed",
            None,
            Some(&error),
            &serde_json::json!({}),
        )
        .await?;
        return Ok(());
    }
    let shared = Arc::new(Shared::default());
    let (spec, blobs, limits) = (job.spec.clone(), state.blobs.clone(), state.limits);
    let task = {
        let shared = shared.clone();
        tokio::task::spawn_blocking(move || {
            let (bytes, mut timings) = bake(&spec, &blobs, &limits, &shared)?;
            let start = Instant::now();
            let package = Package::parse(bytes.clone())?;
            let digest = blobs.put(&bytes)?;
            timings["store"] = start.elapsed().as_secs_f64().into();
            let manifest = serde_json::to_value(package.manifest()).expect("manifests serialize");
            Ok::<_, Error>((digest, bytes.len(), manifest, timings))
        })
    };
    tokio::pin!(task);
    let mut lost = false;
    let result = loop {
        tokio::select! {
            result = &mut task => break result.map_err(|e| Error::InvalidParameter(format!("bake task: {e}")))?,
            _ = tokio::time::sleep(HEARTBEAT) => {
                let progress = f64::from_bits(shared.progress.load(Ordering::Relaxed));
                let stage = if progress < 0.9 { "bake_gdm" } else { "compress" };
                match db.heartbeat_job(&job.id, worker, LEASE_MS, stage, progress).await {
                    Ok(Some(cancel)) => if cancel { shared.cancel.store(true, Ordering::Relaxed) },
                    Ok(None) => { lost = true; shared.cancel.store(true, Ordering::Relaxed) }
                    Err(e) => tracing::warn!("heartbeat of job {}: {e}", job.id),
                }
            }
        }
    };
    if lost {
        tracing::warn!("worker {worker} lost its lease on job {}", job.id);
        return Ok(());
    }
    // A cancellation that arrived during the last, uninterruptible stages still wins.
    let result = match result {
        Ok(_) if shared.cancel.load(Ordering::Relaxed) => Err(Error::Cancelled),
        r => r,
    };
    match result {
        Ok((digest, bytes, manifest, timings)) => {
            db.insert_package(&PackageRow {
                digest: digest.clone(),
                bytes: bytes as i64,
                manifest,
                created_ms: now_ms(),
            })
            .await?;
            db.finish_job(&job.id, worker, "succeeded", Some(&digest), None, &timings)
                .await?;
        }
        Err(Error::Cancelled) => {
            db.finish_job(
                &job.id,
                worker,
                "cancelled",
                None,
                None,
                &serde_json::json!({}),
            )
            .await?;
        }
        Err(e) if is_transient(&e) && job.attempt < MAX_ATTEMPTS => {
            let backoff = 1_000i64 << job.attempt.min(6);
            db.retry_job(&job.id, worker, &e.to_string(), backoff)
                .await?;
        }
        Err(e) => {
            db.finish_job(
                &job.id,
                worker,
                "failed",
                None,
                Some(&e.to_string()),
                &serde_json::json!({}),
            )
            .await?;
        }
    }
    Ok(())
}

/// Claims and runs jobs as `worker` until `stop` is set.
pub async fn work(state: AppState, worker: String, stop: Arc<AtomicBool>) {
    while !stop.load(Ordering::Relaxed) {
        let claimed = match state.db.reap_cancelled_jobs().await {
            Ok(_) => state.db.claim_job(&worker, LEASE_MS).await,
            Err(e) => Err(e),
        };
        match claimed {
            Ok(Some(job)) => {
                let id = job.id.clone();
                if let Err(e) = run(&state, &worker, job).await {
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
