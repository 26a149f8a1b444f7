//! The cache of rendered previews: PNG blobs under the hash of (package, scene), bounded by
//! bytes ([`ServerConfig::preview_cache_bytes`](super::config::ServerConfig)); the least
//! recently used entries are evicted first, their blobs removed unless something else
//! stores the same bytes.

use super::AppState;
use super::db::{db_error, now_ms};
use mesobake_core::error::Result;
use sqlx::Row;

/// The cached PNG of `key`, marked as used now; `None` when absent (or its blob is gone).
pub async fn lookup(state: &AppState, key: &str) -> Result<Option<Vec<u8>>> {
    let pool = &state.db.pool;
    let digest: Option<String> =
        sqlx::query("SELECT png_digest FROM previews WHERE cache_key = $1")
            .bind(key)
            .fetch_optional(pool)
            .await
            .map_err(db_error)?
            .map(|r| r.try_get("png_digest"))
            .transpose()
            .map_err(db_error)?;
    let Some(digest) = digest else {
        return Ok(None);
    };
    let blobs = state.blobs.clone();
    let png = tokio::task::spawn_blocking(move || blobs.get(&digest))
        .await
        .map_err(|e| mesobake_core::error::Error::Database(format!("preview cache: {e}")))??;
    let update = match png {
        Some(_) => sqlx::query("UPDATE previews SET used_ms = $2 WHERE cache_key = $1")
            .bind(key)
            .bind(now_ms()),
        None => sqlx::query("DELETE FROM previews WHERE cache_key = $1").bind(key),
    };
    update.execute(pool).await.map_err(db_error)?;
    Ok(png)
}

/// Stores `png` under `key`, then evicts least recently used entries until the cache fits
/// its byte budget.
pub async fn store(state: &AppState, key: &str, png: Vec<u8>) -> Result<()> {
    let bytes = png.len() as i64;
    super::storage_reserve::check(&state.config, png.len() as u64)?;
    let blobs = state.blobs.clone();
    let digest = tokio::task::spawn_blocking(move || blobs.put(&png))
        .await
        .map_err(|e| mesobake_core::error::Error::Database(format!("preview cache: {e}")))??;
    let now = now_ms();
    sqlx::query(
        "INSERT INTO previews (cache_key, png_digest, created_ms, bytes, used_ms) \
         VALUES ($1, $2, $3, $4, $3) ON CONFLICT (cache_key) DO NOTHING",
    )
    .bind(key)
    .bind(&digest)
    .bind(now)
    .bind(bytes)
    .execute(&state.db.pool)
    .await
    .map_err(db_error)?;
    evict(state).await
}

/// Removes the least recently used entries while the cache holds more than its budget.
async fn evict(state: &AppState) -> Result<()> {
    let pool = &state.db.pool;
    let budget = i64::try_from(state.config.preview_cache_bytes).unwrap_or(i64::MAX);
    loop {
        // PostgreSQL sums BIGINTs as NUMERIC, which the Any driver cannot decode.
        let total: i64 =
            sqlx::query_scalar("SELECT CAST(COALESCE(SUM(bytes), 0) AS BIGINT) FROM previews")
                .fetch_one(pool)
                .await
                .map_err(db_error)?;
        if total <= budget {
            return Ok(());
        }
        let Some(row) = sqlx::query(
            "SELECT cache_key, png_digest FROM previews ORDER BY used_ms, cache_key LIMIT 1",
        )
        .fetch_optional(pool)
        .await
        .map_err(db_error)?
        else {
            return Ok(());
        };
        let key: String = row.try_get("cache_key").map_err(db_error)?;
        let digest: String = row.try_get("png_digest").map_err(db_error)?;
        sqlx::query("DELETE FROM previews WHERE cache_key = $1")
            .bind(&key)
            .execute(pool)
            .await
            .map_err(db_error)?;
        let still_used: i64 = sqlx::query_scalar(
            "SELECT (SELECT COUNT(*) FROM previews WHERE png_digest = $1) \
             + (SELECT COUNT(*) FROM assets WHERE id = $1) \
             + (SELECT COUNT(*) FROM packages WHERE digest = $1)",
        )
        .bind(&digest)
        .fetch_one(pool)
        .await
        .map_err(db_error)?;
        if still_used == 0 {
            let blobs = state.blobs.clone();
            tokio::task::spawn_blocking(move || blobs.remove(&digest))
                .await
                .map_err(|e| {
                    mesobake_core::error::Error::Database(format!("preview cache: {e}"))
                })??;
        }
    }
}
