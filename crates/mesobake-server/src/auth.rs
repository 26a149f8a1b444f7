//! API keys with scopes. A key is `mbk_<id>_<secret>`: the id is 16 hex digits (not secret:
//! `mesobake keys list` shows it), the secret a UUID v4 in 32 hex digits (122 random bits); the database keeps only the key's BLAKE3 hash (a high-entropy key needs no slow
//! hash). With `require_keys` in the configuration, every API request carries
//! `Authorization: Bearer KEY` (the scheme in any case) with the scope its route needs:
//! `upload` for uploads, `bake` for jobs and previews, `read` for everything else under
//! `/api/v1` and for `/metrics` (package downloads and metrics are public with
//! `public_packages` and `public_metrics`). HEAD needs what GET needs. No key: 401; a key
//! without the scope: 403.

use super::AppState;
use super::api_error::ApiError;
use super::db::{Db, db_error, now_ms};
use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;
use mesobake_core::error::{Error, Result};
use sqlx::Row;

/// What a key may do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// Upload assets.
    Upload,
    /// Submit and cancel jobs, request previews.
    Bake,
    /// Read assets, jobs and packages.
    Read,
}

impl Scope {
    /// The scope's name.
    pub fn name(self) -> &'static str {
        match self {
            Scope::Upload => "upload",
            Scope::Bake => "bake",
            Scope::Read => "read",
        }
    }

    /// Parses a comma-separated list of scope names.
    pub fn parse_list(text: &str) -> Result<Vec<Scope>> {
        text.split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|s| match s {
                "upload" => Ok(Scope::Upload),
                "bake" => Ok(Scope::Bake),
                "read" => Ok(Scope::Read),
                _ => Err(Error::InvalidParameter(format!(
                    "scope {s:?}: expected upload, bake or read"
                ))),
            })
            .collect()
    }
}

/// The scope a request needs under `policy`, or `None` for public routes.
pub fn required_scope(method: &Method, path: &str, policy: &AuthPolicy) -> Option<Scope> {
    let reads = method == Method::GET || method == Method::HEAD;
    if path == "/metrics" {
        return (!policy.public_metrics).then_some(Scope::Read);
    }
    let api = path.strip_prefix("/api/v1/")?;
    if api == "openapi.json" || api == "scenes/sample" {
        return None;
    }
    if api.starts_with("packages/") && policy.public_packages && reads {
        return None;
    }
    Some(match (method, api) {
        (&Method::POST, "assets") => Scope::Upload,
        (&Method::POST, _) => Scope::Bake,
        _ => Scope::Read,
    })
}

/// The key of an `Authorization` header value: `Bearer KEY`, the scheme in any case.
pub fn bearer_key(value: &str) -> Option<&str> {
    let (scheme, key) = value.trim().split_once(' ')?;
    scheme.eq_ignore_ascii_case("bearer").then(|| key.trim())
}

/// An issued key as `mesobake keys list` shows it (never the key itself).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct KeyInfo {
    /// The key's id (the part after `mbk_`).
    pub id: String,
    /// Its scopes, comma-separated.
    pub scopes: String,
    /// Its label.
    pub label: String,
    /// When it was issued, Unix milliseconds.
    pub created_ms: i64,
    /// Whether it was revoked.
    pub revoked: bool,
}

fn hash(key: &str) -> String {
    blake3::hash(key.as_bytes()).to_hex().to_string()
}

impl Db {
    /// Issues a key with `scopes`; returns the key (shown once; only its hash is stored).
    pub async fn create_api_key(&self, scopes: &[Scope], label: &str) -> Result<String> {
        if scopes.is_empty() {
            return Err(Error::InvalidParameter(
                "a key needs at least one scope".into(),
            ));
        }
        let id = uuid::Uuid::new_v4().simple().to_string()[..16].to_owned();
        let key = format!("mbk_{id}_{}", uuid::Uuid::new_v4().simple());
        let names: Vec<&str> = scopes.iter().map(|s| s.name()).collect();
        sqlx::query(
            "INSERT INTO api_keys (id, key_hash, scopes, label, created_ms, revoked) \
             VALUES ($1, $2, $3, $4, $5, 0)",
        )
        .bind(&id)
        .bind(hash(&key))
        .bind(names.join(","))
        .bind(label)
        .bind(now_ms())
        .execute(&self.pool)
        .await
        .map_err(db_error)?;
        Ok(key)
    }

    /// Every issued key, oldest first.
    pub async fn api_keys(&self) -> Result<Vec<KeyInfo>> {
        let rows = sqlx::query(
            "SELECT id, scopes, label, created_ms, revoked FROM api_keys ORDER BY created_ms, id",
        )
        .fetch_all(&self.pool)
        .await
        .map_err(db_error)?;
        rows.iter()
            .map(|r| {
                Ok(KeyInfo {
                    id: r.try_get("id").map_err(db_error)?,
                    scopes: r.try_get("scopes").map_err(db_error)?,
                    label: r.try_get("label").map_err(db_error)?,
                    created_ms: r.try_get("created_ms").map_err(db_error)?,
                    revoked: r.try_get::<i32, _>("revoked").map_err(db_error)? != 0,
                })
            })
            .collect()
    }

    /// Revokes the key `id`; an error naming it when no such key was issued.
    pub async fn revoke_api_key(&self, id: &str) -> Result<()> {
        let done = sqlx::query("UPDATE api_keys SET revoked = 1 WHERE id = $1")
            .bind(id)
            .execute(&self.pool)
            .await
            .map_err(db_error)?;
        if done.rows_affected() == 0 {
            return Err(Error::InvalidParameter(format!(
                "no API key has the id {id:?} (mesobake keys list shows them)"
            )));
        }
        Ok(())
    }

    /// The scopes of a valid, unrevoked key (`None` for an unknown key).
    pub async fn key_scopes(&self, key: &str) -> Result<Option<Vec<Scope>>> {
        let row = sqlx::query("SELECT scopes FROM api_keys WHERE key_hash = $1 AND revoked = 0")
            .bind(hash(key))
            .fetch_optional(&self.pool)
            .await
            .map_err(db_error)?;
        row.map(|r| {
            let scopes: String = r.try_get("scopes").map_err(db_error)?;
            Scope::parse_list(&scopes)
        })
        .transpose()
    }
}

/// The middleware: checks the request's key against the scope its route needs.
pub async fn check(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if !state.auth.require_keys {
        return Ok(next.run(request).await);
    }
    let Some(scope) = required_scope(request.method(), request.uri().path(), &state.auth) else {
        return Ok(next.run(request).await);
    };
    let key = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(bearer_key);
    let Some(key) = key else {
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "an API key is required: Authorization: Bearer KEY (mesobake keys create)",
        ));
    };
    match state.db.key_scopes(key).await? {
        None => Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unknown or revoked API key",
        )),
        Some(scopes) if !scopes.contains(&scope) => Err(ApiError::new(
            StatusCode::FORBIDDEN,
            format!("this API key lacks the {} scope", scope.name()),
        )),
        Some(_) => Ok(next.run(request).await),
    }
}

/// How requests are authenticated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AuthPolicy {
    /// Whether API requests need a key.
    pub require_keys: bool,
    /// Whether package downloads are public even when keys are required.
    pub public_packages: bool,
    /// Whether `/metrics` is public even when keys are required.
    pub public_metrics: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routes_need_the_scopes_of_what_they_do() {
        let policy = AuthPolicy {
            require_keys: true,
            public_packages: true,
            public_metrics: false,
        };
        let s = |m: Method, p: &str| required_scope(&m, p, &policy);
        assert_eq!(s(Method::POST, "/api/v1/assets"), Some(Scope::Upload));
        assert_eq!(s(Method::POST, "/api/v1/jobs"), Some(Scope::Bake));
        assert_eq!(s(Method::POST, "/api/v1/jobs/ab/cancel"), Some(Scope::Bake));
        assert_eq!(s(Method::POST, "/api/v1/preview"), Some(Scope::Bake));
        assert_eq!(s(Method::GET, "/api/v1/jobs"), Some(Scope::Read));
        assert_eq!(s(Method::HEAD, "/api/v1/jobs"), Some(Scope::Read));
        assert_eq!(s(Method::GET, "/api/v1/assets/x"), Some(Scope::Read));
        assert_eq!(s(Method::GET, "/api/v1/packages/x"), None);
        assert_eq!(s(Method::HEAD, "/api/v1/packages/x"), None);
        assert_eq!(s(Method::GET, "/metrics"), Some(Scope::Read));
        let private = AuthPolicy {
            public_packages: false,
            public_metrics: true,
            ..policy
        };
        assert_eq!(
            required_scope(&Method::HEAD, "/api/v1/packages/x", &private),
            Some(Scope::Read)
        );
        assert_eq!(required_scope(&Method::GET, "/metrics", &private), None);
        assert_eq!(s(Method::GET, "/api/v1/openapi.json"), None);
        assert_eq!(s(Method::GET, "/healthz"), None);
        assert_eq!(s(Method::GET, "/"), None);
        assert!(Scope::parse_list("upload, bake,read").unwrap().len() == 3);
        assert!(Scope::parse_list("admin").is_err());
    }

    #[test]
    fn the_bearer_scheme_is_case_insensitive() {
        for value in ["Bearer k", "bearer k", "BEARER  k ", " bEaReR k"] {
            assert_eq!(bearer_key(value), Some("k"), "{value}");
        }
        for value in ["Basic k", "Bearerk", "k"] {
            assert_eq!(bearer_key(value), None, "{value}");
        }
    }
}
