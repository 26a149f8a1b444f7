//! The CPU renderers: the ground truth ([`truth`]) and the GDM per-pixel algorithm
//! ([`gdm_renderer`]), with what they share (material volume, lighting, images).

pub mod accel;
pub mod gdm_lookup;
pub mod gdm_renderer;
pub mod image;
pub mod lighting;
pub mod material;
pub mod path_tracer;
pub mod truth;

use crate::scene::Camera;
use glam::DVec3;
use image::Image;
use rayon::prelude::*;

/// Renders an image by calling `radiance(origin, direction)` for every pixel's camera ray
/// (rows in parallel); `None` is a miss.
pub fn render_image(
    camera: &Camera,
    radiance: impl Fn(DVec3, DVec3) -> Option<DVec3> + Sync,
) -> Image {
    let mut image = Image::new(camera.width, camera.height);
    let w = camera.width as usize;
    image
        .rgb
        .par_chunks_mut(w)
        .zip(image.mask.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (rgb, mask))| {
            for x in 0..w {
                let (o, d) = camera.ray(x as u32, y as u32);
                if let Some(c) = radiance(o, d) {
                    rgb[x] = c.as_vec3().to_array();
                    mask[x] = true;
                }
            }
        });
    image
}
