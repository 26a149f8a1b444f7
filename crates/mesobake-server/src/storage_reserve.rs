//! The free-space reserve: below `min_free_bytes` free on the file system of the data
//! directory, the server is not ready (`/readyz` 503), refuses uploads and new jobs with 507
//! Insufficient Storage, and its workers claim no job. Every check reads the free space
//! anew, so the server recovers by itself once space is freed.

use super::config::ServerConfig;
use mesobake_core::error::{Error, Result};
use std::path::Path;

/// Bytes free for unprivileged writers on the file system holding `dir`.
pub fn free_bytes(dir: &Path) -> Result<u64> {
    let stat = rustix::fs::statvfs(dir).map_err(|e| Error::io(dir, e.into()))?;
    Ok(stat.f_bavail.saturating_mul(stat.f_frsize))
}

/// Refuses ([`Error::StorageFull`]) work that would write `incoming` bytes where they would
/// leave less than the configured reserve free.
pub fn check(config: &ServerConfig, incoming: u64) -> Result<()> {
    let free = free_bytes(&config.data_dir)?;
    if free.saturating_sub(incoming) < config.min_free_bytes {
        let incoming = match incoming {
            0 => String::new(),
            n => format!(" for {n} more bytes"),
        };
        return Err(Error::StorageFull(format!(
            "{free} bytes are free on the server's storage, too few{incoming} to keep its \
             reserve of {} bytes (min_free_bytes); try again once space is freed",
            config.min_free_bytes
        )));
    }
    Ok(())
}
