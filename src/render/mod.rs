//! The CPU renderers: the ground truth ([`truth`]) and the GDM per-pixel algorithm
//! ([`gdm_renderer`]), with what they share (lighting, images); the explicit geometry's ray
//! cast, the truth's independent check on mesh tiles ([`explicit`]); the path tracer, the
//! truth for environment light ([`path_tracer`]); the demo's flat preview ([`flat_preview`]).

pub mod accel;
pub mod cell_order;
pub mod explicit;
pub mod flat_preview;
pub mod gdm_lookup;
pub mod gdm_renderer;
pub mod image;
pub mod lighting;
pub mod medium_cells;
pub mod medium_shadow_map;
pub mod medium_truth;
pub mod path_tracer;
pub mod prism_map;
pub mod quality;
pub mod shell_walk;
pub mod truth;
pub mod vdm_renderer;

use crate::bake::gdm::BakeObserver;
use crate::scene::Camera;
use glam::DVec3;
use image::Image;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Pixels per side of the square tiles rendered in parallel: neighbouring rays read
/// neighbouring texels, so tiles keep them in cache (rows of 512 pixels did not).
const TILE: u32 = 16;

/// Renders an image by calling `radiance(origin, direction)` for every pixel's camera ray
/// (square tiles in parallel); `None` is a miss.
pub fn render_image(
    camera: &Camera,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Image {
    render_image_observed(camera, &(), radiance)
}

/// [`render_image`], reporting the tiles done to `observer` as they finish.
pub fn render_image_observed(
    camera: &Camera,
    observer: &dyn BakeObserver,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Image {
    let (w, h) = (camera.width, camera.height);
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let total = u64::from(tiles_x * tiles_y);
    let done = AtomicU64::new(0);
    let tiles: Vec<Vec<Option<DVec3>>> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (x0, y0) = (t % tiles_x * TILE, t / tiles_x * TILE);
            let pixels = (y0..(y0 + TILE).min(h))
                .flat_map(|y| (x0..(x0 + TILE).min(w)).map(move |x| (x, y)));
            let tile = pixels
                .map(|(x, y)| {
                    let (o, d) = camera.ray(x, y);
                    radiance(o, d)
                })
                .collect();
            observer.progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            tile
        })
        .collect();
    let mut image = Image::new(w, h);
    for (t, tile) in tiles.into_iter().enumerate() {
        let (x0, y0) = (t as u32 % tiles_x * TILE, t as u32 / tiles_x * TILE);
        let tile_w = (x0 + TILE).min(w) - x0;
        for (n, c) in tile.into_iter().enumerate() {
            let (x, y) = (x0 + n as u32 % tile_w, y0 + n as u32 / tile_w);
            if let Some(c) = c {
                let p = (y * w + x) as usize;
                image.rgb[p] = c.as_vec3().to_array();
                image.mask[p] = true;
            }
        }
    }
    image
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

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
        let camera = Camera {
            eye: [0.0, 0.0, 1.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y_degrees: 40.0,
            width: 40,
            height: 20,
        };
        let recorder = Recorder::default();
        let image = render_image_observed(&camera, &recorder, |_, d| Some(d.abs()));
        assert_eq!(image.hits(), 800);
        let mut reports = recorder.0.into_inner().unwrap();
        reports.sort();
        assert_eq!(reports, (1..=6).map(|k| (k, 6)).collect::<Vec<_>>());
        // The same image as without an observer.
        assert_eq!(render_image(&camera, |_, d| Some(d.abs())), image);
    }
}
