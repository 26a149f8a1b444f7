//! The measured codec table for the web page's figures: `docs/codecs.json`, written by
//! `mesobake report codecs` on the sample scenes (docs/BENCHMARKS.md names the machine and
//! commit) and compiled in. The server does not measure it: a sweep takes minutes.

use axum::http::header;
use axum::response::IntoResponse;

/// The codecs report as committed.
pub const CODEC_REPORT: &str = include_str!("../../docs/codecs.json");

/// Every GDM codec and size on the sample scenes, as measured.
#[utoipa::path(get, path = "/api/v1/reports/codecs", responses((status = 200, description = "The codecs report (`mesobake report codecs`) on the sample scenes")))]
pub async fn codecs() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "application/json")], CODEC_REPORT)
}
