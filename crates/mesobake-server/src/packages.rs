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
    /// The whole body: no range, another unit, an invalid range (ignored, as RFC 9110
    /// §14.2 allows) or several ranges.
    Whole,
    /// The inclusive byte range.
    Part(u64, u64),
    /// A valid range the body does not have (416).
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
    let Some((a, b)) = spec.split_once('-') else {
        return ByteRange::Whole;
    };
    let (a, b) = (a.trim(), b.trim());
    let number = |t: &str| t.parse::<u64>().ok();
    match (a.is_empty(), b.is_empty()) {
        // bytes=-N: the last N bytes; N = 0 asks for nothing.
        (true, false) => match number(b) {
            Some(0) => ByteRange::Unsatisfiable,
            Some(_) if len == 0 => ByteRange::Unsatisfiable,
            Some(n) => ByteRange::Part(len.saturating_sub(n), len - 1),
            None => ByteRange::Whole,
        },
        // bytes=A- and bytes=A-B (B < A is invalid, not unsatisfiable).
        (false, _) => {
            let Some(start) = number(a) else {
                return ByteRange::Whole;
            };
            let end = if b.is_empty() {
                None
            } else {
                match number(b) {
                    Some(end) if end >= start => Some(end),
                    _ => return ByteRange::Whole,
                }
            };
            if start >= len {
                return ByteRange::Unsatisfiable;
            }
            ByteRange::Part(start, end.map_or(len - 1, |e| e.min(len - 1)))
        }
        (true, true) => ByteRange::Whole,
    }
}

/// Whether an `If-None-Match` value matches `etag`, by weak comparison (RFC 9110 §13.1.2:
/// `W/"x"` matches `"x"`).
pub fn none_match(value: &str, etag: &str) -> bool {
    let opaque = |t: &str| t.trim().trim_start_matches("W/").to_owned();
    value.trim() == "*" || value.split(',').any(|t| opaque(t) == opaque(etag))
}

/// Whether an `If-Range` value lets a range be served: only a strong ETag equal to
/// `etag` (dates and weak tags never do: the whole body is sent).
pub fn if_range_holds(value: &str, etag: &str) -> bool {
    value.trim() == etag
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
    let header_text = |name| {
        headers
            .get(name)
            .and_then(|v: &HeaderValue| v.to_str().ok())
    };
    let matches = header_text(header::IF_NONE_MATCH).is_some_and(|v| none_match(v, &etag));
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
    let range_allowed = header_text(header::IF_RANGE).is_none_or(|v| if_range_holds(v, &etag));
    let range = header_text(header::RANGE)
        .filter(|_| range_allowed)
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
    use super::{ByteRange, if_range_holds, none_match, parse_range};

    #[test]
    fn byte_ranges_follow_rfc_9110() {
        assert_eq!(parse_range("bytes=0-9", 100), ByteRange::Part(0, 9));
        assert_eq!(parse_range("bytes=90-", 100), ByteRange::Part(90, 99));
        assert_eq!(parse_range("bytes=-10", 100), ByteRange::Part(90, 99));
        assert_eq!(parse_range("bytes=-1000", 100), ByteRange::Part(0, 99));
        assert_eq!(parse_range("bytes=50-1000", 100), ByteRange::Part(50, 99));
        assert_eq!(parse_range("bytes=0-0,5-9", 100), ByteRange::Whole);
        assert_eq!(parse_range("items=0-9", 100), ByteRange::Whole);
        // Invalid ranges are ignored: the whole body.
        for invalid in ["bytes=9-0", "bytes=-", "bytes=a-b", "bytes=5", "bytes=1-x"] {
            assert_eq!(parse_range(invalid, 100), ByteRange::Whole, "{invalid}");
        }
        // Valid ranges the body does not have.
        for unsatisfiable in ["bytes=100-", "bytes=100-200", "bytes=-0"] {
            assert_eq!(
                parse_range(unsatisfiable, 100),
                ByteRange::Unsatisfiable,
                "{unsatisfiable}"
            );
        }
        assert_eq!(parse_range("bytes=0-", 0), ByteRange::Unsatisfiable);
    }

    #[test]
    fn validators_compare_as_rfc_9110_says() {
        let etag = "\"abc\"";
        for matching in ["\"abc\"", "W/\"abc\"", " \"x\", W/\"abc\"", "*"] {
            assert!(none_match(matching, etag), "{matching}");
        }
        assert!(!none_match("\"abd\"", etag));
        assert!(if_range_holds("\"abc\"", etag));
        for other in ["W/\"abc\"", "\"abd\"", "Wed, 21 Oct 2015 07:28:00 GMT"] {
            assert!(!if_range_holds(other, etag), "{other}");
        }
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
