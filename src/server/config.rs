//! Server configuration: `config/default.toml` (compiled in), then a `--config` file, then
//! environment variables `MESOBAKE_<KEY>`, each overriding the one before.

use crate::error::{Error, Result};
use figment::Figment;
use figment::providers::{Env, Format, Toml};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const DEFAULTS: &str = include_str!("../../config/default.toml");

/// Everything `mesobake serve` and `mesobake worker` read.
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
    /// Largest accepted request body in bytes.
    pub max_upload_bytes: u64,
    /// Bake workers in the server process.
    pub workers: u32,
    /// Seed the built-in sample scene at start.
    pub seed_sample: bool,
    /// Whether API requests need an API key.
    pub require_keys: bool,
    /// Whether package downloads are public even when keys are required.
    pub public_packages: bool,
}

impl ServerConfig {
    /// The defaults, overridden by the TOML file `file` (if any), then by `MESOBAKE_*`
    /// environment variables.
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
        figment
            .merge(Env::prefixed("MESOBAKE_").only(&KEYS))
            .extract()
            .map_err(|e| Error::InvalidParameter(format!("configuration: {e}")))
    }
}

/// The configuration keys (environment variables are only read for these, so that other
/// `MESOBAKE_*` variables such as `MESOBAKE_MEMORY_LIMIT` keep their own meaning).
const KEYS: [&str; 9] = [
    "listen",
    "database_url",
    "data_dir",
    "blob_url",
    "max_upload_bytes",
    "workers",
    "seed_sample",
    "require_keys",
    "public_packages",
];
