//! SVG figures with one panel per scene (plotters), shared by the reports.

use mesobake_core::error::{Error, Result};
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

/// A point of [`labelled_scatter`]: x, y, its label and its colour.
pub type LabelledPoint = (f64, f64, String, RGBColor);

/// An SVG of one panel titled `caption`: `points` over a logarithmic x axis (all x > 0), each
/// a dot with its label.
pub fn labelled_scatter(
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    points: &[LabelledPoint],
) -> Result<String> {
    scene_panels(&[caption], |panel, caption| {
        let fold = |f: &dyn Fn(&LabelledPoint) -> f64| {
            points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(f(p)), hi.max(f(p)))
                })
        };
        let (x_lo, x_hi) = fold(&|p| p.0);
        let (y_lo, y_hi) = fold(&|p| p.1);
        let mut chart = ChartBuilder::on(panel)
            .caption(caption, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d(
                ((x_lo * 0.5)..(x_hi * 2.0)).log_scale(),
                (y_lo - 1.5)..(y_hi + 1.5),
            )
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .draw()
            .map_err(plot_error)?;
        chart
            .draw_series(points.iter().map(|(x, y, label, colour)| {
                EmptyElement::at((*x, *y))
                    + Circle::new((0, 0), 4, colour.filled())
                    + Text::new(label.clone(), (6, -6), ("sans-serif", 12))
            }))
            .map_err(plot_error)?;
        Ok(())
    })
}
