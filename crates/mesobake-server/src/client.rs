//! The CI client of the baking server (`mesobake bake --server`, `mesobake fetch`): uploads
//! an input, submits its bake, follows the job and downloads the package, verifying that
//! its bytes hash to the digest the server names and that it parses as a package.

use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::package::AnyPackage;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};
use serde_json::{Value, json};
use std::io::Read;
use std::path::Path;
use std::time::Duration;

/// A connection to a server.
pub struct Client {
    base: String,
    key: Option<String>,
    http: reqwest::blocking::Client,
}

fn http_error(e: reqwest::Error) -> Error {
    Error::InvalidParameter(format!("server request failed: {e}"))
}

/// The body of an answer, or an error with the server's message for a non-2xx status.
fn answer(r: reqwest::blocking::Response) -> Result<reqwest::blocking::Response> {
    if r.status().is_success() {
        return Ok(r);
    }
    let status = r.status();
    let text = r.text().unwrap_or_default();
    let message = serde_json::from_str::<Value>(&text)
        .ok()
        .and_then(|v| v["error"].as_str().map(str::to_owned))
        .unwrap_or(text);
    Err(Error::InvalidParameter(format!(
        "server answered {status}: {message}"
    )))
}

impl Client {
    /// A client of the server at `base` (e.g. `http://127.0.0.1:8080`) using API key `key`.
    pub fn new(base: &str, key: Option<String>) -> Result<Client> {
        let http = reqwest::blocking::Client::builder()
            .timeout(Duration::from_secs(600))
            .build()
            .map_err(http_error)?;
        Ok(Client {
            base: base.trim_end_matches('/').to_owned(),
            key,
            http,
        })
    }

    fn request(&self, method: reqwest::Method, path: &str) -> reqwest::blocking::RequestBuilder {
        let r = self
            .http
            .request(method, format!("{}/api/v1{path}", self.base));
        match &self.key {
            Some(k) => r.bearer_auth(k),
            None => r,
        }
    }

    /// Uploads the file at `path` (`.obj`: a mesh tile; otherwise a volume), read within the
    /// memory limit; returns the asset's record.
    pub fn upload(&self, path: &Path, limits: &Limits) -> Result<Value> {
        let bytes = mesobake_core::fs::read_bounded(path, "upload", limits.memory_bytes)?;
        let is_obj = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        let name = path
            .file_name()
            .map_or("input".into(), |n| n.to_string_lossy().into_owned());
        let r = self
            .request(reqwest::Method::POST, "/assets")
            .query(&[
                ("kind", if is_obj { "mesh_tile" } else { "volume" }),
                ("name", name.as_str()),
            ])
            .body(bytes)
            .send()
            .map_err(http_error)?;
        answer(r)?.json().map_err(http_error)
    }

    /// Submits the bake of uploaded asset `asset` (kind `volume` or `mesh_tile`) on the
    /// grids `res` × `dirs`; returns the job.
    pub fn submit(
        &self,
        asset: &Value,
        res: Dims,
        dirs: DirectionGrid,
        codec: GdmCodec,
        rank: usize,
        quantization: Quantization,
    ) -> Result<Value> {
        let id = asset["id"].as_str().unwrap_or_default();
        let source = if asset["kind"] == "mesh_tile" {
            json!({ "tile": id })
        } else {
            json!({ "volume": id })
        };
        // A package holds only the mesostructure's GDM; the rest of the scene is a minimal
        // stand-in (it does not change the job's identity).
        let scene = json!({
            "base_mesh": { "builtin": { "plane": {} } },
            "mesostructure": source,
            "resolution": [res.x, res.y, res.z],
            "directions": [dirs.n_theta, dirs.n_phi],
            "shell": { "thickness": 0.1, "tiles_per_uv": [1, 1] },
            "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 64, "height": 64 }
        });
        let body =
            json!({ "scene": scene, "codec": codec, "rank": rank, "quantization": quantization });
        let r = self
            .request(reqwest::Method::POST, "/jobs")
            .json(&body)
            .send()
            .map_err(http_error)?;
        answer(r)?.json().map_err(http_error)
    }

    /// Follows job `id` until it is final, calling `progress` with each state; returns the
    /// final job, or an error when it failed or was cancelled.
    pub fn wait(&self, id: &str, mut progress: impl FnMut(&Value)) -> Result<Value> {
        loop {
            let r = self
                .request(reqwest::Method::GET, &format!("/jobs/{id}"))
                .send()
                .map_err(http_error)?;
            let job: Value = answer(r)?.json().map_err(http_error)?;
            progress(&job);
            match job["state"].as_str() {
                Some("succeeded") => return Ok(job),
                Some("failed") | Some("cancelled") => {
                    return Err(Error::InvalidParameter(format!(
                        "job {id} {}: {}",
                        job["state"].as_str().unwrap_or_default(),
                        job["error"].as_str().unwrap_or("no error given")
                    )));
                }
                _ => std::thread::sleep(Duration::from_millis(250)),
            }
        }
    }

    /// Downloads package `digest`, checks that its bytes hash to the digest and parse as a
    /// package of any kind, and returns them; the body and the parse are held to the memory
    /// limit (a larger `Content-Length` is refused before the body is read).
    pub fn fetch(&self, digest: &str, limits: &Limits) -> Result<Vec<u8>> {
        let r = self
            .request(reqwest::Method::GET, &format!("/packages/{digest}"))
            .send()
            .map_err(http_error)?;
        let r = answer(r)?;
        let limit = limits.memory_bytes;
        let too_large = |needed| Error::MemoryLimit {
            what: format!("downloading package {digest}"),
            needed,
            limit,
        };
        if let Some(length) = r.content_length().filter(|&n| n > limit) {
            return Err(too_large(length));
        }
        let mut bytes = Vec::new();
        r.take(limit.saturating_add(1))
            .read_to_end(&mut bytes)
            .map_err(|e| Error::InvalidParameter(format!("downloading package {digest}: {e}")))?;
        if bytes.len() as u64 > limit {
            return Err(too_large(bytes.len() as u64));
        }
        let actual = blake3::hash(&bytes).to_hex().to_string();
        if actual != digest {
            return Err(Error::Package(format!(
                "downloaded {} bytes hash to {actual}, not to the requested digest {digest}",
                bytes.len()
            )));
        }
        AnyPackage::parse_within(bytes.clone(), limits)?;
        Ok(bytes)
    }
}
