//! Errors as HTTP responses: a status and `{"error": "..."}` naming the problem.

use axum::Json;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use mesobake_core::error::Error;

/// An error answer.
#[derive(Debug)]
pub struct ApiError {
    /// The HTTP status.
    pub status: StatusCode,
    /// What went wrong.
    pub message: String,
}

impl ApiError {
    /// An error with `status`.
    pub fn new(status: StatusCode, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            message: message.into(),
        }
    }

    /// 503 with `Retry-After: 1`: the server is busy with other requests.
    pub fn busy(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::SERVICE_UNAVAILABLE, message)
    }

    /// `e` as an answer, with the blob store's paths in its message cut down to keys.
    pub fn scrubbed(e: Error, blobs: &super::blobs::BlobStore) -> ApiError {
        let mut answer = ApiError::from(e);
        answer.message = blobs.scrub(&answer.message);
        answer
    }

    /// 404 for `what`.
    pub fn not_found(what: impl std::fmt::Display) -> ApiError {
        ApiError::new(StatusCode::NOT_FOUND, format!("{what} not found"))
    }
}

impl From<Error> for ApiError {
    fn from(e: Error) -> ApiError {
        let status = match &e {
            Error::InvalidParameter(_)
            | Error::VolumeFormat(_)
            | Error::MeshTile(_)
            | Error::BaseMesh(_)
            | Error::Scene(_)
            | Error::Package(_) => StatusCode::UNPROCESSABLE_ENTITY,
            Error::MemoryLimit { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            Error::Cancelled => StatusCode::CONFLICT,
            Error::Gpu(_) | Error::LoopBudget { .. } | Error::Database(_) => {
                StatusCode::SERVICE_UNAVAILABLE
            }
            Error::StorageFull(_) => StatusCode::INSUFFICIENT_STORAGE,
            Error::Io { source, .. } if is_storage_full(source) => {
                tracing::error!("{e}");
                return ApiError::new(
                    StatusCode::INSUFFICIENT_STORAGE,
                    format!("storage full: {source}; try again once space is freed"),
                );
            }
            Error::Io { source, .. } => {
                // The path is the server's business: logged, not answered.
                tracing::error!("{e}");
                return ApiError::new(
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("storage error: {source}"),
                );
            }
        };
        ApiError::new(status, e.to_string())
    }
}

/// Whether `e` says the disk (or the writer's quota) is full.
pub fn is_storage_full(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
    )
}

impl From<tokio::task::JoinError> for ApiError {
    fn from(e: tokio::task::JoinError) -> ApiError {
        ApiError::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("worker task: {e}"),
        )
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response = (
            self.status,
            Json(serde_json::json!({ "error": self.message })),
        )
            .into_response();
        // Busy and over-quota answers say when to come back.
        if matches!(
            self.status,
            StatusCode::SERVICE_UNAVAILABLE | StatusCode::TOO_MANY_REQUESTS
        ) {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
        }
        response
    }
}

/// Result of a handler.
pub type ApiResult<T> = std::result::Result<T, ApiError>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_device_is_507_without_the_path() {
        // /dev/full: every write fails with ENOSPC, as on a full disk.
        let path = std::path::Path::new("/dev/full");
        let write = std::fs::write(path, b"x").unwrap_err();
        let answer = ApiError::from(Error::io(path, write));
        assert_eq!(answer.status, StatusCode::INSUFFICIENT_STORAGE);
        assert!(
            answer.message.starts_with("storage full"),
            "{}",
            answer.message
        );
        assert!(!answer.message.contains("/dev"), "{}", answer.message);
        let other = std::fs::read("/nonexistent/x").unwrap_err();
        let answer = ApiError::from(Error::io("/nonexistent/x", other));
        assert_eq!(answer.status, StatusCode::INTERNAL_SERVER_ERROR);
    }
}
