//! SVG figures with one panel per scene (plotters), shared by the reports.

use crate::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

/// A plotting failure as the library's error.
pub fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::InvalidParameter(format!("plotting failed: {e}"))
}

/// An SVG of 600×480 panels side by side, one per scene, each drawn by `panel`.
pub fn scene_panels(
    scenes: &[&str],
    mut panel: impl FnMut(&DrawingArea<SVGBackend<'_>, Shift>, &str) -> Result<()>,
) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (600 * scenes.len().max(1) as u32, 480))
            .into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        for (area, scene) in root
            .split_evenly((1, scenes.len().max(1)))
            .iter()
            .zip(scenes)
        {
            panel(area, scene)?;
        }
        root.present().map_err(plot_error)?;
    }
    Ok(svg)
}
