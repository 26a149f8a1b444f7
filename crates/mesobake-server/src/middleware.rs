//! Middleware every request passes: one log line per request, and error bodies as JSON
//! `{"error": …}` whoever produced them (handlers, extractors' rejections, body limits,
//! unknown routes).

use super::api_error::ApiError;
use super::health::Metrics;
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{HeaderValue, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::sync::Arc;
use std::time::Instant;

/// Logs method, path, status and milliseconds of every request, and counts it.
pub async fn log_requests(
    State(metrics): State<Arc<Metrics>>,
    request: Request,
    next: Next,
) -> Response {
    let start = Instant::now();
    let method = request.method().clone();
    let path = request.uri().path().to_owned();
    let response = next.run(request).await;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let status = response.status();
    metrics.count_request(status.as_u16());
    tracing::info!("{method} {path} {} {ms:.1} ms", status.as_u16());
    response
}

/// Largest error body rewritten as JSON (framework rejections are one line of text).
const MAX_ERROR_TEXT: usize = 64 << 10;

/// Rewrites error responses whose body is not JSON as `{"error": text}`, keeping their
/// status and headers.
pub async fn json_errors(request: Request, next: Next) -> Response {
    let response = next.run(request).await;
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let (mut parts, body) = response.into_parts();
    let text = match axum::body::to_bytes(body, MAX_ERROR_TEXT).await {
        Ok(bytes) if !bytes.is_empty() => String::from_utf8_lossy(&bytes).trim().to_owned(),
        _ => status
            .canonical_reason()
            .unwrap_or("error")
            .to_ascii_lowercase(),
    };
    let json = serde_json::json!({ "error": text }).to_string();
    parts.headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    parts.headers.remove(header::CONTENT_LENGTH);
    Response::from_parts(parts, Body::from(json))
}

/// The answer for unknown routes.
pub async fn not_found(request: Request) -> Response {
    ApiError::not_found(format!("route {}", request.uri().path())).into_response()
}
