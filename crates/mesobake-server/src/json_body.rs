//! JSON request bodies, parsed straight into their typed structs (never into a
//! `serde_json::Value` first, but for the scene of a `SceneSpec`, which is split into its
//! objects before each is typed), off the async threads when they are large. The body's size is
//! bounded by the router's limit layer (413 from `Content-Length` before anything is read).

use super::api_error::{ApiError, ApiResult};
use axum::body::{Body, Bytes};
use axum::extract::{FromRequest, Request};
use axum::http::{StatusCode, header};
use serde::de::DeserializeOwned;

/// Bodies up to this size are parsed on the async thread; larger ones on the blocking pool.
const INLINE_PARSE_BYTES: usize = 64 << 10;

/// A JSON body of type `T` (`Content-Type: application/json`).
pub struct JsonBody<T>(pub T);

/// Reads a whole request body, naming timeouts (408) and the size limit (413).
pub async fn read_body(body: Body) -> ApiResult<Bytes> {
    axum::body::to_bytes(body, usize::MAX)
        .await
        .map_err(|e| body_error(&e))
}

/// The answer for a body that could not be read: its size limit, its timeout, or the
/// connection.
pub fn body_error(e: &(dyn std::error::Error + 'static)) -> ApiError {
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(err) = source {
        if err.is::<http_body_util::LengthLimitError>() {
            return ApiError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                "the request body is over the configured limit",
            );
        }
        if err.is::<tower_http::timeout::TimeoutError>() {
            return ApiError::new(
                StatusCode::REQUEST_TIMEOUT,
                "the request body stopped arriving (body_read_timeout_ms)",
            );
        }
        source = err.source();
    }
    ApiError::new(
        StatusCode::BAD_REQUEST,
        format!("reading the request body: {e}"),
    )
}

impl<S: Send + Sync, T: DeserializeOwned + Send + 'static> FromRequest<S> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(request: Request, _: &S) -> ApiResult<Self> {
        let is_json = request
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|v| {
                let mime = v.split(';').next().unwrap_or("").trim();
                mime.eq_ignore_ascii_case("application/json")
            });
        if !is_json {
            return Err(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "expected a body with Content-Type: application/json",
            ));
        }
        let bytes = read_body(request.into_body()).await?;
        let small = bytes.len() <= INLINE_PARSE_BYTES;
        let parse = move || {
            // Not JSON at all: 400 (checked first, without building anything); JSON of the
            // wrong shape: 422, as axum's `Json` answers.
            serde_json::from_slice::<serde::de::IgnoredAny>(&bytes)
                .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, format!("not JSON: {e}")))?;
            serde_json::from_slice::<T>(&bytes).map_err(|e| {
                let mut message = format!("job: {e}");
                if message.contains("unknown field `objects`") {
                    message.push_str(
                        " (a scene of several objects is baked by POST /api/v1/object-jobs, a \
                         job per object)",
                    );
                }
                ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, message)
            })
        };
        let value = if small {
            parse()?
        } else {
            tokio::task::spawn_blocking(parse).await??
        };
        Ok(JsonBody(value))
    }
}
