//! Server configuration: `config/default.toml` (compiled in), then a `--config` file, then
//! environment variables `MESOBAKE_<KEY>`, each overriding the one before. Relative paths
//! are resolved once, when the configuration is loaded, against the working directory.

use figment::Figment;
use figment::providers::{Env, Format, Toml};
use mesobake_core::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

const DEFAULTS: &str = include_str!("../../../config/default.toml");

/// Everything `mesobake serve`, `mesobake worker` and `mesobake keys` read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServerConfig {
    /// Address and port to listen on.
    pub listen: String,
    /// `sqlite://PATH` (created if missing) or `postgres://…`.
    pub database_url: String,
    /// Root of the local blob store (the cache of the remote one when `blob_url` is set).
    pub data_dir: PathBuf,
    /// Empty for the local blob store, or `s3://BUCKET[/PREFIX]`.
    pub blob_url: String,
    /// S3 options (object_store's keys: `endpoint`, `region`, `access_key_id`,
    /// `secret_access_key`, `allow_http`, …), over the `AWS_*` environment variables.
    #[serde(default)]
    pub blob_options: BTreeMap<String, String>,
    /// Bake workers in the server process.
    pub workers: u32,
    /// Seed the built-in sample scene at start.
    pub seed_sample: bool,
    /// Whether API requests need an API key.
    pub require_keys: bool,
    /// Whether package downloads are public even when keys are required.
    pub public_packages: bool,
    /// Whether `/metrics` is public even when keys are required.
    pub public_metrics: bool,
    /// Largest upload body in bytes.
    pub max_upload_bytes: u64,
    /// Largest JSON request body in bytes.
    pub max_json_bytes: u64,
    /// Most lights a scene may have.
    pub max_lights: u32,
    /// Largest preview image side in pixels.
    pub max_image_side: u32,
    /// Most pixels of an input image, checked from its header.
    pub max_input_pixels: u64,
    /// Most path-traced samples per pixel a scene may ask for.
    pub max_path_samples: u32,
    /// Most triangles of a built-in base mesh.
    pub max_base_triangles: u64,
    /// Uploads validated at once.
    pub max_concurrent_uploads: u32,
    /// Least average rate of an upload's body in bytes per second, after its first
    /// `body_read_timeout_ms` (0: none).
    pub min_upload_bytes_per_s: u64,
    /// Longest time an upload's body may take.
    pub upload_timeout_ms: u64,
    /// How long a request waits for an upload slot or the GPU before 503.
    pub busy_wait_ms: u64,
    /// How long a preview render may take before it is abandoned (503).
    pub preview_timeout_ms: u64,
    /// What previews do where no GPU adapter exists: the CPU twin (`cpu`) or 503 (`none`).
    pub preview_fallback: mesobake_scene::preview::PreviewFallback,
    /// Jobs queued or running at once (429 beyond).
    pub max_queued_jobs: u64,
    /// Bytes of preview images kept (least recently used evicted beyond).
    pub preview_cache_bytes: u64,
    /// Bytes kept free on the data directory's file system: below them the server is not
    /// ready and refuses uploads and new jobs (507).
    pub min_free_bytes: u64,
    /// Time for a request's headers to arrive; also the idle keep-alive timeout.
    pub header_read_timeout_ms: u64,
    /// Time for each part of a request body to arrive.
    pub body_read_timeout_ms: u64,
    /// Time from SIGTERM to exit.
    pub shutdown_grace_ms: u64,
}

impl ServerConfig {
    /// The defaults, overridden by the TOML file `file` (if any), then by `MESOBAKE_*`
    /// environment variables, with relative paths made absolute against the working
    /// directory.
    pub fn load(file: Option<&Path>) -> Result<ServerConfig> {
        let mut figment = Figment::from(Toml::string(DEFAULTS));
        if let Some(path) = file {
            if !path.is_file() {
                return Err(Error::InvalidParameter(format!(
                    "config file {} does not exist",
                    path.display()
                )));
            }
            figment = figment.merge(Toml::file_exact(path));
        }
        let config: ServerConfig = figment
            .merge(Env::prefixed("MESOBAKE_").only(KEYS))
            .extract()
            .map_err(|e| Error::InvalidParameter(format!("configuration: {e}")))?;
        let cwd = std::env::current_dir().map_err(|e| Error::io(".", e))?;
        config.resolved_against(&cwd)
    }

    /// The configuration with its relative paths (`data_dir`, a `sqlite://` database file)
    /// joined to `dir`, and its values checked.
    pub fn resolved_against(mut self, dir: &Path) -> Result<ServerConfig> {
        if self.data_dir.is_relative() {
            self.data_dir = dir.join(&self.data_dir);
        }
        if let Some(rest) = self.database_url.strip_prefix("sqlite://") {
            let (file, query) = rest
                .split_once('?')
                .map_or((rest, None), |(f, q)| (f, Some(q)));
            if !file.is_empty() && Path::new(file).is_relative() && file != ":memory:" {
                let absolute = dir.join(file);
                self.database_url = match query {
                    Some(q) => format!("sqlite://{}?{q}", absolute.display()),
                    None => format!("sqlite://{}", absolute.display()),
                };
            }
        }
        for (name, value) in [
            ("max_upload_bytes", self.max_upload_bytes),
            ("max_json_bytes", self.max_json_bytes),
            (
                "max_concurrent_uploads",
                u64::from(self.max_concurrent_uploads),
            ),
            ("preview_timeout_ms", self.preview_timeout_ms),
            ("upload_timeout_ms", self.upload_timeout_ms),
            ("header_read_timeout_ms", self.header_read_timeout_ms),
            ("body_read_timeout_ms", self.body_read_timeout_ms),
        ] {
            if value == 0 {
                return Err(Error::InvalidParameter(format!(
                    "configuration: {name} must be positive"
                )));
            }
        }
        Ok(self)
    }

    /// The database URL with any password replaced by `***`, for logs and messages.
    pub fn database_url_redacted(&self) -> String {
        redact_url(&self.database_url)
    }
}

/// `url` with the password of its `user:password@` part replaced by `***`.
pub fn redact_url(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    let authority_end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(authority_end);
    match authority.rsplit_once('@') {
        Some((userinfo, host)) => match userinfo.split_once(':') {
            Some((user, _)) => format!("{scheme}://{user}:***@{host}{tail}"),
            None => url.to_owned(),
        },
        None => url.to_owned(),
    }
}

/// Milliseconds as a [`Duration`].
pub fn millis(ms: u64) -> Duration {
    Duration::from_millis(ms)
}

/// The configuration keys (environment variables are only read for these, so that other
/// `MESOBAKE_*` variables such as `MESOBAKE_MEMORY_LIMIT` keep their own meaning).
const KEYS: &[&str] = &[
    "listen",
    "database_url",
    "data_dir",
    "blob_url",
    "workers",
    "seed_sample",
    "require_keys",
    "public_packages",
    "public_metrics",
    "max_upload_bytes",
    "max_json_bytes",
    "max_lights",
    "max_image_side",
    "max_input_pixels",
    "max_path_samples",
    "max_base_triangles",
    "max_concurrent_uploads",
    "min_upload_bytes_per_s",
    "upload_timeout_ms",
    "busy_wait_ms",
    "preview_timeout_ms",
    "preview_fallback",
    "max_queued_jobs",
    "preview_cache_bytes",
    "min_free_bytes",
    "header_read_timeout_ms",
    "body_read_timeout_ms",
    "shutdown_grace_ms",
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_are_resolved_against_the_directory() {
        let config = ServerConfig::load(None).unwrap();
        let config = ServerConfig {
            data_dir: "data".into(),
            database_url: "sqlite://data/db.sqlite?mode=rwc".into(),
            ..config
        }
        .resolved_against(Path::new("/srv/mb"))
        .unwrap();
        assert_eq!(config.data_dir, Path::new("/srv/mb/data"));
        assert_eq!(
            config.database_url,
            "sqlite:///srv/mb/data/db.sqlite?mode=rwc"
        );
        let absolute = ServerConfig {
            database_url: "sqlite:///var/db.sqlite".into(),
            ..config
        }
        .resolved_against(Path::new("/elsewhere"))
        .unwrap();
        assert_eq!(absolute.database_url, "sqlite:///var/db.sqlite");
        assert_eq!(absolute.data_dir, Path::new("/srv/mb/data"));
    }

    #[test]
    fn passwords_are_redacted() {
        assert_eq!(
            redact_url("postgres://postgres:S3cretPW@db:5432/mesobake"),
            "postgres://postgres:***@db:5432/mesobake"
        );
        assert_eq!(
            redact_url("postgres://u:p@ss@db/x?sslmode=require"),
            "postgres://u:***@db/x?sslmode=require"
        );
        assert_eq!(redact_url("postgres://db/x"), "postgres://db/x");
        assert_eq!(redact_url("sqlite:///a/b.sqlite"), "sqlite:///a/b.sqlite");
    }
}
