//! mesobake's CPU renderers, each the reference or the specification of one algorithm: the
//! ground truths ([`truth`] for opaque mesostructure, [`medium_truth`] for translucent media,
//! [`path_tracer`] for environment light, [`explicit`] the third, plainer check on mesh
//! tiles), and the CPU specifications of the real-time algorithms that the WGSL shaders
//! implement ([`gdm_renderer`], [`vdm_renderer`], [`medium_cells`]), with what they share
//! (lighting, images, sampling). A renderer reads a [`shot::Shot`] (camera, lights,
//! material, effects), never a scene file; it knows nothing of GPUs, HTTP or SQL.

pub mod accel;
pub mod cell_order;
pub mod environment_sampler;
pub mod explicit;
pub mod flat_preview;
pub mod gdm_lookup;
pub mod gdm_renderer;
pub mod gi_shading;
pub mod image;
pub mod lighting;
pub mod medium_cells;
pub mod medium_settings;
pub mod medium_shadow_map;
pub mod medium_truth;
pub mod objects;
pub mod path_tracer;
pub mod prepared_prism;
pub mod prism_map;
pub mod sampling;
pub mod shell_walk;
pub mod shot;
pub mod truth;
pub mod vdm_refine;
pub mod vdm_renderer;

use glam::DVec3;
use image::Image;
use mesobake_core::camera::Camera;
use mesobake_core::error::{Error, Result};
use mesobake_core::observer::BakeObserver;
use rayon::prelude::*;
use sampling::Accumulator;
use std::sync::atomic::{AtomicU64, Ordering};

/// Pixels per side of the square tiles rendered in parallel: neighbouring rays read
/// neighbouring texels, so tiles keep them in cache (rows of 512 pixels did not).
const TILE: u32 = 16;

/// Renders an image by calling `radiance(origin, direction)` for each of every pixel's
/// camera rays, the camera's samples per pixel ([`sampling`]; square tiles in parallel);
/// `None` is a miss.
pub fn render_image(
    camera: &Camera,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Image {
    render_tiles(camera, &(), radiance).unwrap_or_else(|| Image::new(camera.width, camera.height))
}

/// [`render_image`], reporting the tiles done to `observer` as they finish and stopping
/// with [`Error::Cancelled`] when it asks to.
pub fn render_image_observed(
    camera: &Camera,
    observer: &dyn BakeObserver,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Result<Image> {
    render_tiles(camera, observer, radiance).ok_or(Error::Cancelled)
}

/// A tile's pixels: each one's radiance summed over its samples that hit (`None` when none
/// did) and how many hit.
type TileSums = Vec<(Option<DVec3>, u32)>;

/// The tiles of [`render_image_observed`], or `None` when `observer` cancelled. A pixel's
/// samples are cast one after the other (neighbouring rays, in cache together).
fn render_tiles(
    camera: &Camera,
    observer: &dyn BakeObserver,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Option<Image> {
    let (w, h) = (camera.width, camera.height);
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let total = u64::from(tiles_x * tiles_y);
    let done = AtomicU64::new(0);
    let plane = camera.image_plane();
    let offsets = camera.samples_per_pixel.offsets();
    let one = camera.samples_per_pixel.is_one();
    let tiles: Option<Vec<TileSums>> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            if observer.cancelled() {
                return None;
            }
            let (x0, y0) = (t % tiles_x * TILE, t / tiles_x * TILE);
            let pixels = (y0..(y0 + TILE).min(h))
                .flat_map(|y| (x0..(x0 + TILE).min(w)).map(move |x| (x, y)));
            let tile = pixels
                .map(|(x, y)| {
                    if one {
                        let (o, d) = camera.ray(x, y);
                        let c = radiance(o, d);
                        return (c, u32::from(c.is_some()));
                    }
                    let mut sum = DVec3::ZERO;
                    let mut hits = 0;
                    for &offset in &offsets {
                        if let Some(c) = radiance(plane.eye, plane.direction_at(x, y, offset)) {
                            sum += c;
                            hits += 1;
                        }
                    }
                    ((hits > 0).then_some(sum), hits)
                })
                .collect();
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Some(tile)
        })
        .collect();
    let mut sum = Accumulator::new(w, h);
    for (t, tile) in tiles?.into_iter().enumerate() {
        let (x0, y0) = (t as u32 % tiles_x * TILE, t as u32 / tiles_x * TILE);
        let tile_w = (x0 + TILE).min(w) - x0;
        for (n, (c, hits)) in tile.into_iter().enumerate() {
            let (x, y) = (x0 + n as u32 % tile_w, y0 + n as u32 / tile_w);
            sum.add_pixel((y * w + x) as usize, c.map(|c| c.to_array()), hits);
        }
    }
    Some(sum.finish(Some(offsets.len() as u32)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// A camera 1 unit above the origin looking down, `spp` samples per pixel.
    fn camera(width: u32, height: u32, spp: u32) -> Camera {
        Camera {
            eye: [0.0, 0.0, 1.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y_degrees: 40.0,
            width,
            height,
            samples_per_pixel: mesobake_core::samples_per_pixel::SamplesPerPixel::new(spp).unwrap(),
            subpixel: [0.5, 0.5],
        }
    }

    /// Records every progress report.
    #[derive(Default)]
    struct Recorder(Mutex<Vec<(u64, u64)>>);

    impl BakeObserver for Recorder {
        fn progress(&self, done: u64, total: u64) {
            self.0.lock().unwrap().push((done, total));
        }
    }

    #[test]
    fn observed_renders_report_each_tile_once_and_end_at_the_total() {
        // 40×20 pixels: 3×2 tiles of 16 (the last ones partial).
        let camera = camera(40, 20, 1);
        let recorder = Recorder::default();
        let image = render_image_observed(&camera, &recorder, |_, d| Some(d.abs())).unwrap();
        assert_eq!(image.hits(), 800);
        let mut reports = recorder.0.into_inner().unwrap();
        reports.sort();
        assert_eq!(reports, (1..=6).map(|k| (k, 6)).collect::<Vec<_>>());
        // The same image as without an observer.
        assert_eq!(render_image(&camera, |_, d| Some(d.abs())), image);
    }

    #[test]
    fn a_supersampled_pixel_covers_an_edge_by_its_area() {
        // 16 samples form a (0, 2)-net: one in each of 16 columns and in each of 16 rows of
        // the pixel, so an edge along either axis covers a pixel by its area within 1/16.
        let camera = camera(8, 8, 16);
        let plane = camera.image_plane();
        for axis in 0..2 {
            let edge = 3.3;
            let image = render_image(&camera, |o, d| {
                (plane.project(o + d).unwrap()[axis] < edge).then_some(DVec3::ONE)
            });
            for (p, (rgb, &hit)) in image.rgb.iter().zip(&image.mask).enumerate() {
                let at = [p % 8, p / 8][axis] as f64;
                let area = (edge - at).clamp(0.0, 1.0);
                assert!(
                    (f64::from(rgb[0]) - area).abs() <= 1.0 / 16.0 + 1e-6,
                    "{p}: {rgb:?}"
                );
                assert_eq!(hit, area >= 0.5, "{p}");
            }
        }
    }
}
