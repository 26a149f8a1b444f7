//! The CPU renderers: the ground truth ([`truth`]) and the GDM per-pixel algorithm
//! ([`gdm_renderer`]), with what they share (lighting, images); the explicit geometry's ray
//! cast, the truth's independent check on mesh tiles ([`explicit`]); the path tracer, the
//! truth for environment light ([`path_tracer`]); the demo's flat preview ([`flat_preview`]).

pub mod accel;
pub mod explicit;
pub mod flat_preview;
pub mod gdm_lookup;
pub mod gdm_renderer;
pub mod image;
pub mod lighting;
pub mod path_tracer;
pub mod prism_map;
pub mod quality;
pub mod truth;

use crate::scene::Camera;
use glam::DVec3;
use image::Image;
use rayon::prelude::*;

/// Pixels per side of the square tiles rendered in parallel: neighbouring rays read
/// neighbouring texels, so tiles keep them in cache (rows of 512 pixels did not).
const TILE: u32 = 16;

/// Renders an image by calling `radiance(origin, direction)` for every pixel's camera ray
/// (square tiles in parallel); `None` is a miss.
pub fn render_image(
    camera: &Camera,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Image {
    let (w, h) = (camera.width, camera.height);
    let (tiles_x, tiles_y) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let tiles: Vec<Vec<Option<DVec3>>> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|t| {
            let (x0, y0) = (t % tiles_x * TILE, t / tiles_x * TILE);
            let pixels = (y0..(y0 + TILE).min(h))
                .flat_map(|y| (x0..(x0 + TILE).min(w)).map(move |x| (x, y)));
            pixels
                .map(|(x, y)| {
                    let (o, d) = camera.ray(x, y);
                    radiance(o, d)
                })
                .collect()
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
