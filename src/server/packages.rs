//! `GET /api/v1/packages/{digest}`: package bytes for game builds. The digest is the ETag
//! (`If-None-Match` → 304); single byte ranges are served (206, or 416 when unsatisfiable);
//! content never changes under a digest, so responses are cacheable forever.

use super::AppState;
use super::api_error::{ApiError, ApiResult};
use super::blobs::is_key;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::Response;
use std::sync::atomic::Ordering;

/// What a `Range` header asks of a body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ByteRange {
    /// The whole body (no range, another unit, or several ranges: allowed by RFC 9110).
    Whole,
    /// The inclusive byte range.
    Part(u64, u64),
    /// Nothing the body has (416).
    Unsatisfiable,
}

/// Parses a `Range` header for a body of `len` bytes.
pub fn parse_range(value: &str, len: u64) -> ByteRange {
    let Some(spec) = value.trim().strip_prefix("bytes=") else {
        return ByteRange::Whole;
    };
    if spec.contains(',') {
        return ByteRange::Whole;
    }
    match single_range(spec, len) {
        Some((start, end)) => ByteRange::Part(start, end),
        None => ByteRange::Unsatisfiable,
    }
}

fn single_range(spec: &str, len: u64) -> Option<(u64, u64)> {
    let (a, b) = spec.split_once('-')?;
    let (a, b) = (a.trim(), b.trim());
    match (a.is_empty(), b.is_empty()) {
        (true, false) => {
            let n: u64 = b.parse().ok()?;
            (n > 0 && len > 0).then(|| (len.saturating_sub(n), len - 1))
        }
        (false, _) => {
            let start: u64 = a.parse().ok()?;
            let end = if b.is_empty() {
                len.checked_sub(1)?
            } else {
                b.parse::<u64>().ok()?.min(len.saturating_sub(1))
            };
            (start < len && end >= start).then_some((start, end))
        }
        (true, true) => None,
    }
}

/// Downloads a package.
#[utoipa::path(
    get,
    path = "/api/v1/packages/{digest}",
    params(("digest" = String, Path, description = "BLAKE3 of the package bytes")),
    responses(
        (status = 200, description = "The package", content_type = "application/octet-stream"),
        (status = 206, description = "The requested byte range"),
        (status = 304, description = "Not modified (If-None-Match matched)"),
        (status = 404, description = "No such package"),
        (status = 416, description = "Range not satisfiable"),
    )
)]
pub async fn get(
    State(state): State<AppState>,
    Path(digest): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Response> {
    if !is_key(&digest) || state.db.package(&digest).await?.is_none() {
        return Err(ApiError::not_found(format!("package {digest:?}")));
    }
    let etag = format!("\"{digest}\"");
    let common = |b: axum::http::response::Builder| {
        b.header(header::ETAG, &etag)
            .header(header::CACHE_CONTROL, "public, max-age=31536000, immutable")
            .header(header::ACCEPT_RANGES, "bytes")
    };
    let matches = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|t| t.trim() == etag || t.trim() == "*"));
    if matches {
        return Ok(common(Response::builder().status(StatusCode::NOT_MODIFIED))
            .body(Body::empty())
            .expect("valid response"));
    }
    let blobs = state.blobs.clone();
    let key = digest.clone();
    let bytes = tokio::task::spawn_blocking(move || blobs.get(&key))
        .await??
        .ok_or_else(|| {
            ApiError::new(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("package {digest} is recorded but its blob is missing"),
            )
        })?;
    let len = bytes.len() as u64;
    let range = headers
        .get(header::RANGE)
        .and_then(|v| v.to_str().ok())
        .map_or(ByteRange::Whole, |v| parse_range(v, len));
    state
        .metrics
        .packages_served
        .fetch_add(1, Ordering::Relaxed);
    let builder =
        common(Response::builder()).header(header::CONTENT_TYPE, "application/octet-stream");
    let response = match range {
        ByteRange::Unsatisfiable => builder
            .status(StatusCode::RANGE_NOT_SATISFIABLE)
            .header(header::CONTENT_RANGE, format!("bytes */{len}"))
            .body(Body::empty()),
        ByteRange::Whole => builder
            .header(header::CONTENT_LENGTH, HeaderValue::from(len))
            .body(Body::from(bytes)),
        ByteRange::Part(start, end) => builder
            .status(StatusCode::PARTIAL_CONTENT)
            .header(header::CONTENT_RANGE, format!("bytes {start}-{end}/{len}"))
            .header(header::CONTENT_LENGTH, HeaderValue::from(end - start + 1))
            .body(Body::from(bytes[start as usize..=end as usize].to_vec())),
    };
    Ok(response.expect("valid response"))
}

#[cfg(test)]
mod tests {
    use super::{ByteRange, parse_range};

    #[test]
    fn byte_ranges_follow_rfc_9110() {
        assert_eq!(parse_range("bytes=0-9", 100), ByteRange::Part(0, 9));
        assert_eq!(parse_range("bytes=90-", 100), ByteRange::Part(90, 99));
        assert_eq!(parse_range("bytes=-10", 100), ByteRange::Part(90, 99));
        assert_eq!(parse_range("bytes=-1000", 100), ByteRange::Part(0, 99));
        assert_eq!(parse_range("bytes=50-1000", 100), ByteRange::Part(50, 99));
        assert_eq!(parse_range("bytes=0-0,5-9", 100), ByteRange::Whole);
        assert_eq!(parse_range("items=0-9", 100), ByteRange::Whole);
        for bad in [
            "bytes=100-",
            "bytes=9-0",
            "bytes=-0",
            "bytes=-",
            "bytes=a-b",
            "bytes=5",
        ] {
            assert_eq!(parse_range(bad, 100), ByteRange::Unsatisfiable, "{bad}");
        }
        assert_eq!(parse_range("bytes=0-", 0), ByteRange::Unsatisfiable);
    }
}

/// A package's manifest (its JSON, as the package holds it).
#[utoipa::path(
    get,
    path = "/api/v1/packages/{digest}/manifest",
    params(("digest" = String, Path, description = "BLAKE3 of the package bytes")),
    responses((status = 200, description = "The manifest"), (status = 404, description = "No such package"))
)]
pub async fn manifest(
    State(state): State<AppState>,
    Path(digest): Path<String>,
) -> ApiResult<axum::Json<serde_json::Value>> {
    let row = if is_key(&digest) {
        state.db.package(&digest).await?
    } else {
        None
    };
    let row = row.ok_or_else(|| ApiError::not_found(format!("package {digest:?}")))?;
    Ok(axum::Json(row.manifest))
}
