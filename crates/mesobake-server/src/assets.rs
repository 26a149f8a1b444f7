//! `POST /api/v1/assets` and `GET /api/v1/assets/{id}`: uploads, validated by kind and
//! deduplicated by content.

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::blobs::{BlobStore, is_key};
use super::config::{ServerConfig, millis};
use super::db::{AssetRow, now_ms};
use super::json_body::body_error;
use super::storage_reserve;
use axum::Json;
use axum::body::Body;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use futures_util::StreamExt;
use mesobake_bake::mesostructure::height_field::HeightField;
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::openvdb::{self, VdbImport, VdbImported};
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_bake::mesostructure::volume_format;
use mesobake_bake::surface::base_mesh::{BaseMesh, GltfSelection};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_scene::{BaseMeshSource, MesostructureSource, Scene};
use serde::Deserialize;
use std::time::Duration;
use tokio::io::AsyncWriteExt;
use tokio::time::Instant;

/// What an upload is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AssetKind {
    /// A `.mbvol` voxel volume, or an OpenVDB file (a level set or a fog volume), stored
    /// imported as `.mbvol`.
    Volume,
    /// A closed OBJ mesostructure tile.
    MeshTile,
    /// An OBJ base mesh with UVs.
    BaseMesh,
    /// A grayscale PNG height field (8 or 16 bits).
    HeightField,
}

impl AssetKind {
    fn name(self) -> &'static str {
        match self {
            AssetKind::Volume => "volume",
            AssetKind::MeshTile => "mesh_tile",
            AssetKind::BaseMesh => "base_mesh",
            AssetKind::HeightField => "height_field",
        }
    }
}

/// Query parameters of an upload.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
pub struct UploadParams {
    /// What the body is.
    pub kind: AssetKind,
    /// A display name (no path separators), e.g. the original file name.
    pub name: String,
    /// An OpenVDB volume upload's grid to import (by default its first level set or fog
    /// volume).
    #[serde(default)]
    pub grid: Option<String>,
    /// An OpenVDB volume upload's index box `XxYxZ` from index (0, 0, 0) (by default the
    /// grid's active voxels' bounds).
    #[serde(default)]
    pub res: Option<String>,
    /// An OpenVDB fog volume's density scale: opacity per voxel 1 − exp(−scale·ρ·h) (1 by
    /// default).
    #[serde(default)]
    pub density_scale: Option<f64>,
}

impl UploadParams {
    /// The OpenVDB import options, when any is given.
    fn vdb_import(&self) -> Result<Option<VdbImport>> {
        if self.grid.is_none() && self.res.is_none() && self.density_scale.is_none() {
            return Ok(None);
        }
        if self.kind != AssetKind::Volume {
            return Err(Error::InvalidParameter(
                "grid, res and density_scale apply to OpenVDB uploads of kind volume".into(),
            ));
        }
        Ok(Some(VdbImport {
            grid: self.grid.clone(),
            res: self.res.as_deref().map(str::parse).transpose()?,
            density_scale: self.density_scale.unwrap_or(1.0),
        }))
    }
}

/// Checks a display name: 1–255 bytes, no path separators, no `..`, no control characters.
pub fn check_name(name: &str) -> Result<()> {
    let bad = name.is_empty()
        || name.len() > 255
        || name.contains(['/', '\\'])
        || name.contains("..")
        || name.chars().any(char::is_control);
    if bad {
        return Err(Error::InvalidParameter(format!(
            "name {name:?}: must be 1–255 bytes without path separators, \"..\" or control characters"
        )));
    }
    Ok(())
}

fn utf8(bytes: &[u8], what: &str) -> Result<String> {
    String::from_utf8(bytes.to_vec())
        .map_err(|e| Error::InvalidParameter(format!("{what} is not UTF-8 text: {e}")))
}

/// Whether `bytes` are glTF: a GLB's magic number, or JSON (an object, which no OBJ line
/// starts with); the glTF reader then names what is wrong with it.
fn is_gltf(bytes: &[u8]) -> bool {
    bytes.starts_with(b"glTF") || bytes.trim_ascii_start().starts_with(b"{")
}

/// Why OpenVDB options are refused for an upload that is not OpenVDB.
const NOT_OPENVDB: &str =
    "grid, res and density_scale apply to OpenVDB volume uploads; this is not an OpenVDB file";

/// What validating an upload found: a summary of what it holds, and the bytes to store
/// when they are not the upload's own (an OpenVDB volume is stored imported, as `.mbvol`).
pub struct Validated {
    /// What the asset holds.
    pub summary: serde_json::Value,
    /// The bytes to store instead of the upload's.
    pub converted: Option<Vec<u8>>,
}

/// Validates `bytes` as an asset of `kind` (a base mesh is OBJ or glTF, a volume `.mbvol` or
/// OpenVDB, told by their content); an OpenVDB volume is imported as `vdb` says (defaults
/// when `None`; only OpenVDB uploads take options).
pub fn validate(
    kind: AssetKind,
    bytes: &[u8],
    vdb: Option<VdbImport>,
    limits: &Limits,
) -> Result<Validated> {
    let is_vdb = kind == AssetKind::Volume && bytes.starts_with(&openvdb::archive::MAGIC);
    if vdb.is_some() && !is_vdb {
        return Err(Error::InvalidParameter(NOT_OPENVDB.into()));
    }
    let summary = match kind {
        AssetKind::Volume if is_vdb => {
            let (volume, imported) = openvdb::import(bytes, &vdb.unwrap_or_default(), limits)?;
            let summary = volume_summary(&volume, Some(&imported));
            let converted = Some(volume_format::encode(&volume));
            return Ok(Validated { summary, converted });
        }
        AssetKind::Volume => volume_summary(&volume_format::decode(bytes, limits)?, None),
        AssetKind::MeshTile => {
            let mesh = TriMesh::from_obj(&utf8(bytes, "an OBJ tile")?)?;
            let triangles = mesh.triangles.len();
            MeshTile::new(mesh, false)?;
            serde_json::json!({ "triangles": triangles })
        }
        AssetKind::BaseMesh => {
            let (mesh, report) = if is_gltf(bytes) {
                BaseMesh::from_gltf(bytes, None, GltfSelection::default(), limits)?
            } else {
                BaseMesh::from_obj(&utf8(bytes, "an OBJ base mesh")?)?
            };
            serde_json::json!({ "triangles": mesh.triangles.len(), "report": report })
        }
        AssetKind::HeightField => {
            let (width, height) = HeightField::decode_png(bytes, limits)?.size();
            serde_json::json!({ "size": [width, height] })
        }
    };
    Ok(Validated {
        summary,
        converted: None,
    })
}

/// A volume's summary: its grid, whether it has albedo and opacity, and what it was
/// imported from.
fn volume_summary(volume: &Volume, imported: Option<&VdbImported>) -> serde_json::Value {
    let d = volume.dims();
    let mut summary = serde_json::json!({
        "dims": [d.x, d.y, d.z],
        "albedo": volume.albedo().is_some(),
        "opacity": volume.opacity().is_some(),
    });
    if let Some(imported) = imported {
        summary["openvdb"] = serde_json::json!(imported);
    }
    summary
}

/// Removes a temporary upload file when the upload ends early.
struct TempFile(std::path::PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// A deadline beyond any upload (for configured times too long to add to an instant).
const FAR: Duration = Duration::from_secs(365 * 24 * 3600);

/// Which of [`UploadPace`]'s bounds a deadline comes from.
#[derive(Clone, Copy)]
enum Bound {
    /// `min_upload_bytes_per_s`.
    Rate,
    /// `upload_timeout_ms`.
    Whole,
}

/// How fast an upload's body must arrive: `received` bytes by `min_bytes_per_s` after a
/// grace period, and all of it within `whole`, both counted from the start of the body.
struct UploadPace {
    start: Instant,
    grace: Duration,
    min_bytes_per_s: u64,
    whole: Duration,
}

impl UploadPace {
    fn new(config: &ServerConfig) -> UploadPace {
        UploadPace {
            start: Instant::now(),
            grace: millis(config.body_read_timeout_ms),
            min_bytes_per_s: config.min_upload_bytes_per_s,
            whole: millis(config.upload_timeout_ms),
        }
    }

    /// When the bytes after the first `received` must have begun to arrive, and which
    /// bound says so.
    fn deadline(&self, received: u64) -> (Instant, Bound) {
        let after = |d: Duration| self.start.checked_add(d).unwrap_or(self.start + FAR);
        let whole = after(self.whole);
        let paced = (self.min_bytes_per_s > 0)
            .then(|| Duration::try_from_secs_f64(received as f64 / self.min_bytes_per_s as f64))
            .and_then(Result::ok)
            .map(|d| after(self.grace.saturating_add(d)))
            .filter(|&paced| paced < whole);
        match paced {
            Some(paced) => (paced, Bound::Rate),
            None => (whole, Bound::Whole),
        }
    }

    /// The 408 for a body that fell behind its deadline after `received` bytes.
    fn too_slow(&self, received: u64, bound: Bound) -> ApiError {
        let seconds = self.start.elapsed().as_secs_f64();
        let why = match bound {
            Bound::Whole => format!(
                "the upload took longer than {} ms (upload_timeout_ms)",
                self.whole.as_millis()
            ),
            Bound::Rate => format!(
                "the upload arrived slower than {} bytes/s after its first {} ms \
                 (min_upload_bytes_per_s)",
                self.min_bytes_per_s,
                self.grace.as_millis()
            ),
        };
        ApiError::new(
            StatusCode::REQUEST_TIMEOUT,
            format!("{why}: {received} bytes in {seconds:.1} s"),
        )
    }
}

/// Streams `body` into the temporary file `path` at `pace`, returning the BLAKE3 key and
/// length of its bytes.
async fn stream_to_file(
    body: Body,
    path: &std::path::Path,
    pace: &UploadPace,
) -> ApiResult<(String, u64)> {
    let io = |e: std::io::Error| ApiError::from(Error::io(path, e));
    let mut file = tokio::fs::File::create(path).await.map_err(io)?;
    let mut hasher = blake3::Hasher::new();
    let mut len = 0u64;
    let mut stream = body.into_data_stream();
    loop {
        let (deadline, bound) = pace.deadline(len);
        let chunk = match tokio::time::timeout_at(deadline, stream.next()).await {
            Err(_) => return Err(pace.too_slow(len, bound)),
            Ok(None) => break,
            Ok(Some(chunk)) => chunk.map_err(|e| body_error(&e))?,
        };
        hasher.update(&chunk);
        len += chunk.len() as u64;
        file.write_all(&chunk).await.map_err(io)?;
    }
    file.flush().await.map_err(io)?;
    Ok((hasher.finalize().to_hex().to_string(), len))
}

/// Uploads an asset. The body streams to a temporary file in the blob store (hashed on the
/// way) at the pace the configuration asks for (408 when it falls behind), is validated from
/// there and moved into place. At most `max_concurrent_uploads` are validated at once (a
/// slot is taken once the body is there): others wait up to `busy_wait_ms`, then get 503.
#[utoipa::path(
    post,
    path = "/api/v1/assets",
    params(UploadParams),
    request_body(content = Vec<u8>, content_type = "application/octet-stream"),
    responses(
        (status = 201, description = "Stored", body = AssetRow),
        (status = 200, description = "The same bytes were uploaded before", body = AssetRow),
        (status = 409, description = "The same bytes were uploaded before as another kind"),
        (status = 408, description = "Body slower than min_upload_bytes_per_s, or longer than upload_timeout_ms"),
        (status = 413, description = "Body over max_upload_bytes"),
        (status = 422, description = "Not a valid asset of that kind"),
        (status = 503, description = "Too many uploads at once; Retry-After says when to retry"),
        (status = 507, description = "The body would leave less than the reserve free (min_free_bytes), or the storage is full"),
    )
)]
pub async fn upload(
    State(state): State<AppState>,
    Query(params): Query<UploadParams>,
    headers: HeaderMap,
    body: Body,
) -> ApiResult<(StatusCode, Json<AssetRow>)> {
    check_name(&params.name)?;
    let vdb = params.vdb_import()?;
    let announced = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok()?.parse().ok())
        .unwrap_or(0);
    storage_reserve::check(&state.config, announced)?;
    let tmp = TempFile(state.blobs.temp_path()?);
    let (id, len) = stream_to_file(body, &tmp.0, &UploadPace::new(&state.config)).await?;
    if len == 0 {
        return Err(ApiError::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            "empty upload",
        ));
    }
    if vdb.is_some() {
        // Options for a body that is not OpenVDB are refused even if its bytes are stored.
        let mut head = [0u8; 8];
        let file = tokio::fs::File::open(&tmp.0).await;
        let read = match file {
            Ok(mut f) => tokio::io::AsyncReadExt::read_exact(&mut f, &mut head)
                .await
                .is_ok(),
            Err(_) => false,
        };
        if !(read && head == openvdb::archive::MAGIC) {
            return Err(Error::InvalidParameter(NOT_OPENVDB.into()).into());
        }
    }
    if let Some(existing) = state.db.asset(&id).await? {
        if existing.kind != params.kind.name() {
            return Err(ApiError::new(
                StatusCode::CONFLICT,
                format!(
                    "these bytes are already stored as the {} asset {id}; an asset has one kind",
                    existing.kind
                ),
            ));
        }
        return Ok((StatusCode::OK, Json(existing)));
    }
    let _permit = tokio::time::timeout(
        millis(state.config.busy_wait_ms),
        state.uploads.clone().acquire_owned(),
    )
    .await
    .map_err(|_| ApiError::busy("too many uploads at once; try again shortly"))?
    .map_err(|_| ApiError::busy("uploads are closed"))?;
    let (limits, blobs, kind) = (state.limits, state.blobs.clone(), params.kind);
    let (id, len, summary) =
        tokio::task::spawn_blocking(move || -> Result<(String, u64, serde_json::Value)> {
            let bytes = std::fs::read(&tmp.0).map_err(|e| Error::io(&tmp.0, e))?;
            let validated = validate(kind, &bytes, vdb, &limits)?;
            drop(bytes);
            match validated.converted {
                None => {
                    blobs.put_file(&tmp.0, &id)?;
                    Ok((id, len, validated.summary))
                }
                Some(converted) => {
                    let stored_len = converted.len() as u64;
                    Ok((blobs.put(&converted)?, stored_len, validated.summary))
                }
            }
        })
        .await??;
    let row = AssetRow {
        id,
        kind: kind.name().into(),
        name: params.name,
        bytes: len as i64,
        summary,
        created_ms: now_ms(),
    };
    let (stored, new) = state.db.insert_asset(&row).await?;
    state
        .metrics
        .uploads
        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let status = if new {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(stored)))
}

/// An asset's record.
#[utoipa::path(
    get,
    path = "/api/v1/assets/{id}",
    params(("id" = String, Path, description = "The asset's BLAKE3 digest")),
    responses((status = 200, body = AssetRow), (status = 404, description = "No such asset"))
)]
pub async fn get(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> ApiResult<Json<AssetRow>> {
    if !is_key(&id) {
        return Err(ApiError::not_found(format!("asset {id:?}")));
    }
    Ok(Json(state.db.asset(&id).await?.ok_or_else(|| {
        ApiError::not_found(format!("asset {id}"))
    })?))
}

/// Replaces every file a scene names (an asset digest) by the blob's path; an unknown
/// digest is an input error naming it.
pub fn resolve_assets(scene: &mut Scene, blobs: &BlobStore) -> Result<()> {
    let resolve = |p: &mut std::path::PathBuf| -> Result<()> {
        let digest = p.to_string_lossy().into_owned();
        if !is_key(&digest) {
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
        MesostructureSource::Sample(_)
        | MesostructureSource::SampleTile(_)
        | MesostructureSource::Relief(_)
        | MesostructureSource::Medium(_) => {}
    }
    match &mut scene.base_mesh {
        BaseMeshSource::Obj(p) => resolve(p)?,
        BaseMeshSource::Gltf(g) => resolve(g.file_mut())?,
        BaseMeshSource::Builtin(_) => {}
    }
    Ok(())
}
