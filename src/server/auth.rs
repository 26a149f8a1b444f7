//! API keys with scopes. A key is `mbk_<id>_<secret>` (128 random bits of secret); the
//! database keeps only its BLAKE3 hash (a high-entropy key needs no slow hash). With
//! `require_keys` in the configuration, every API request carries `Authorization: Bearer
//! KEY` with the scope its route needs: `upload` for uploads, `bake` for jobs and previews,
//! `read` for everything else under `/api/v1` (package downloads too, unless
//! `public_packages`). No key: 401; a key without the scope: 403.

use super::AppState;
use super::api_error::ApiError;
use super::db::{Db, db_error, now_ms};
use crate::error::{Error, Result};
use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;
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

/// The scope a request needs, or `None` for public routes.
pub fn required_scope(method: &Method, path: &str, public_packages: bool) -> Option<Scope> {
    let api = path.strip_prefix("/api/v1/")?;
    if api == "openapi.json" || api == "scenes/sample" {
        return None;
    }
    if api.starts_with("packages/") && public_packages && method == Method::GET {
        return None;
    }
    Some(match (method, api) {
        (&Method::POST, "assets") => Scope::Upload,
        (&Method::POST, _) => Scope::Bake,
        _ => Scope::Read,
    })
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
    let Some(scope) = required_scope(
        request.method(),
        request.uri().path(),
        state.auth.public_packages,
    ) else {
        return Ok(next.run(request).await);
    };
    let key = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .map(str::trim);
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routes_need_the_scopes_of_what_they_do() {
        let s = |m: Method, p: &str| required_scope(&m, p, true);
        assert_eq!(s(Method::POST, "/api/v1/assets"), Some(Scope::Upload));
        assert_eq!(s(Method::POST, "/api/v1/jobs"), Some(Scope::Bake));
        assert_eq!(s(Method::POST, "/api/v1/jobs/ab/cancel"), Some(Scope::Bake));
        assert_eq!(s(Method::POST, "/api/v1/preview"), Some(Scope::Bake));
        assert_eq!(s(Method::GET, "/api/v1/jobs"), Some(Scope::Read));
        assert_eq!(s(Method::GET, "/api/v1/assets/x"), Some(Scope::Read));
        assert_eq!(s(Method::GET, "/api/v1/packages/x"), None);
        assert_eq!(
            required_scope(&Method::GET, "/api/v1/packages/x", false),
            Some(Scope::Read)
        );
        assert_eq!(s(Method::GET, "/api/v1/openapi.json"), None);
        assert_eq!(s(Method::GET, "/healthz"), None);
        assert_eq!(s(Method::GET, "/"), None);
        assert!(Scope::parse_list("upload, bake,read").unwrap().len() == 3);
        assert!(Scope::parse_list("admin").is_err());
    }
}
