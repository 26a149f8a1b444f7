//! The database: one `sqlx::AnyPool` over SQLite (the default, a file) or PostgreSQL (when
//! several machines share the work), the numbered migrations in `migrations/` (portable SQL,
//! embedded in the binary), and the queries on assets and packages. Job queries live in
//! [`super::jobs`].

use mesobake_core::error::{Error, Result};
use serde::Serialize;
use sqlx::any::{AnyPoolOptions, install_default_drivers};
use sqlx::{AnyPool, Row};
use std::time::{SystemTime, UNIX_EPOCH};

/// The database handle.
#[derive(Clone, Debug)]
pub struct Db {
    /// The connection pool.
    pub pool: AnyPool,
}

/// Wraps a database error (a full disk as [`Error::StorageFull`]).
pub fn db_error(e: sqlx::Error) -> Error {
    // SQLITE_FULL, and PostgreSQL's disk_full.
    let code = e.as_database_error().and_then(|d| d.code());
    if matches!(code.as_deref(), Some("13" | "53100")) {
        return Error::StorageFull(format!("the database: {e}"));
    }
    Error::Database(e.to_string())
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

/// An uploaded asset.
#[derive(Clone, Debug, PartialEq, Serialize, utoipa::ToSchema)]
pub struct AssetRow {
    /// BLAKE3 of the bytes (the blob key).
    pub id: String,
    /// `volume`, `mesh_tile` or `base_mesh`.
    pub kind: String,
    /// The name it was uploaded under.
    pub name: String,
    /// Size in bytes.
    pub bytes: i64,
    /// What validation found (JSON).
    #[schema(value_type = Object)]
    pub summary: serde_json::Value,
    /// Upload time, Unix milliseconds.
    pub created_ms: i64,
}

/// A stored package.
#[derive(Clone, Debug, PartialEq, Serialize, utoipa::ToSchema)]
pub struct PackageRow {
    /// BLAKE3 of the package bytes (the blob key).
    pub digest: String,
    /// Size in bytes.
    pub bytes: i64,
    /// The package's manifest.
    #[schema(value_type = Object)]
    pub manifest: serde_json::Value,
    /// Creation time, Unix milliseconds.
    pub created_ms: i64,
}

fn json_column(row: &sqlx::any::AnyRow, name: &str) -> Result<serde_json::Value> {
    let text: String = row.try_get(name).map_err(db_error)?;
    serde_json::from_str(&text).map_err(|e| Error::Database(format!("column {name}: {e}")))
}

impl Db {
    /// Connects to `url` (`sqlite://PATH`, created if missing, or `postgres://…`) and runs
    /// the pending migrations.
    pub async fn connect(url: &str) -> Result<Db> {
        install_default_drivers();
        let url = if let Some(path) = url.strip_prefix("sqlite://") {
            let file = path.split('?').next().unwrap_or(path);
            if let Some(dir) = std::path::Path::new(file).parent()
                && !dir.as_os_str().is_empty()
            {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            if path.contains('?') {
                url.to_owned()
            } else {
                format!("{url}?mode=rwc")
            }
        } else if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            url.to_owned()
        } else {
            return Err(Error::InvalidParameter(format!(
                "database_url {url:?}: expected sqlite://PATH or postgres://…"
            )));
        };
        let pool = AnyPoolOptions::new()
            .max_connections(if url.starts_with("sqlite") { 4 } else { 16 })
            .connect(&url)
            .await
            .map_err(db_error)?;
        sqlx::migrate!("../../migrations")
            .run(&pool)
            .await
            .map_err(|e| Error::Database(format!("migrations: {e}")))?;
        Ok(Db { pool })
    }

    /// Whether the database answers.
    pub async fn ping(&self) -> Result<()> {
        sqlx::query("SELECT 1")
            .execute(&self.pool)
            .await
            .map(|_| ())
            .map_err(db_error)
    }

    /// Records an asset; an asset with the same id is kept as it was. Returns the stored row
    /// and whether it was new.
    pub async fn insert_asset(&self, asset: &AssetRow) -> Result<(AssetRow, bool)> {
        let inserted = sqlx::query(
            "INSERT INTO assets (id, kind, name, bytes, summary, created_ms) \
             VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT (id) DO NOTHING",
        )
        .bind(&asset.id)
        .bind(&asset.kind)
        .bind(&asset.name)
        .bind(asset.bytes)
        .bind(asset.summary.to_string())
        .bind(asset.created_ms)
        .execute(&self.pool)
        .await
        .map_err(db_error)?
        .rows_affected()
            == 1;
        let stored = self
            .asset(&asset.id)
            .await?
            .ok_or_else(|| Error::Database(format!("asset {} vanished", asset.id)))?;
        Ok((stored, inserted))
    }

    /// The asset `id`.
    pub async fn asset(&self, id: &str) -> Result<Option<AssetRow>> {
        let row = sqlx::query(
            "SELECT id, kind, name, bytes, summary, created_ms FROM assets WHERE id = $1",
        )
        .bind(id)
        .fetch_optional(&self.pool)
        .await
        .map_err(db_error)?;
        row.map(|r| {
            Ok(AssetRow {
                id: r.try_get("id").map_err(db_error)?,
                kind: r.try_get("kind").map_err(db_error)?,
                name: r.try_get("name").map_err(db_error)?,
                bytes: r.try_get("bytes").map_err(db_error)?,
                summary: json_column(&r, "summary")?,
                created_ms: r.try_get("created_ms").map_err(db_error)?,
            })
        })
        .transpose()
    }

    /// Records a package (kept as it was if already present).
    pub async fn insert_package(&self, package: &PackageRow) -> Result<()> {
        sqlx::query(
            "INSERT INTO packages (digest, bytes, manifest, created_ms) \
             VALUES ($1, $2, $3, $4) ON CONFLICT (digest) DO NOTHING",
        )
        .bind(&package.digest)
        .bind(package.bytes)
        .bind(package.manifest.to_string())
        .bind(package.created_ms)
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(())
    }

    /// The package `digest`.
    pub async fn package(&self, digest: &str) -> Result<Option<PackageRow>> {
        let row = sqlx::query(
            "SELECT digest, bytes, manifest, created_ms FROM packages WHERE digest = $1",
        )
        .bind(digest)
        .fetch_optional(&self.pool)
        .await
        .map_err(db_error)?;
        row.map(|r| {
            Ok(PackageRow {
                digest: r.try_get("digest").map_err(db_error)?,
                bytes: r.try_get("bytes").map_err(db_error)?,
                manifest: json_column(&r, "manifest")?,
                created_ms: r.try_get("created_ms").map_err(db_error)?,
            })
        })
        .transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_full_sqlite_database_is_storage_full() {
        // SQLite answers SQLITE_FULL once a database reaches its page limit, as on a full
        // disk.
        sqlx::any::install_default_drivers();
        let pool = sqlx::any::AnyPoolOptions::new()
            .max_connections(1)
            .connect("sqlite::memory:")
            .await
            .unwrap();
        sqlx::query("CREATE TABLE t (b BLOB)")
            .execute(&pool)
            .await
            .unwrap();
        sqlx::query("PRAGMA max_page_count = 8")
            .execute(&pool)
            .await
            .unwrap();
        let full = sqlx::query("INSERT INTO t VALUES (zeroblob(100000))")
            .execute(&pool)
            .await
            .unwrap_err();
        let e = db_error(full);
        assert!(matches!(e, Error::StorageFull(_)), "{e}");
        let other = sqlx::query("SELECT * FROM missing")
            .execute(&pool)
            .await
            .unwrap_err();
        assert!(matches!(db_error(other), Error::Database(_)));
    }
}
