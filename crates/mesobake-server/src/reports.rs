//! The measured reports of the web page's figures, compiled in: the codec table
//! (`docs/codecs.json`, `mesobake report codecs` on the sample scenes) and the conformance
//! matrix (`docs/conformance.json`, `mesobake report conformance` on every shipped scene);
//! docs/BENCHMARKS.md names the machine and commit. The server does not measure them: a
//! sweep takes minutes.

use axum::http::header;
use axum::response::IntoResponse;

/// The codecs report as committed.
pub const CODEC_REPORT: &str = include_str!("../../../docs/codecs.json");

/// Every GDM codec and size on the sample scenes, as measured.
#[utoipa::path(get, path = "/api/v1/reports/codecs", responses((status = 200, description = "The codecs report (`mesobake report codecs`) on the sample scenes")))]
pub async fn codecs() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/json")], CODEC_REPORT)
}

/// The conformance report as committed.
pub const CONFORMANCE_REPORT: &str = include_str!("../../../docs/conformance.json");

/// Every shipped scene, technique and preset against the supersampled truth, as measured.
#[utoipa::path(get, path = "/api/v1/reports/conformance", responses((status = 200, description = "The conformance report (`mesobake report conformance`) on every shipped scene")))]
pub async fn conformance() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "application/json")],
        CONFORMANCE_REPORT,
    )
}
