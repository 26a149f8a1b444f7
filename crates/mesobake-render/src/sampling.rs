//! How the results of a pixel's camera rays (at the sub-pixel positions of
//! [`mesobake_core::samples_per_pixel`]) combine into one pixel.
//!
//! A pixel's colour is the mean, in linear light, of its samples' radiance with misses black
//! (a box filter); it is a hit when at least half its samples hit (coverage ≥ ½).

use super::image::Image;
use mesobake_core::camera::Camera;
use mesobake_core::error::{Error, Result};

/// Sums images rendered at the sub-pixel offsets of one pixel pattern into their box-
/// filtered mean (see the module's documentation).
pub struct Accumulator {
    width: u32,
    height: u32,
    sum: Vec<[f64; 3]>,
    hits: Vec<u32>,
    samples: u32,
}

impl Accumulator {
    /// An empty sum for `width` × `height` images.
    pub fn new(width: u32, height: u32) -> Accumulator {
        let n = width as usize * height as usize;
        Accumulator {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            hits: vec![0; n],
            samples: 0,
        }
    }

    /// Adds one sample's image (of the accumulator's size).
    pub fn add(&mut self, image: &Image) -> Result<()> {
        if (image.width, image.height) != (self.width, self.height) {
            return Err(Error::InvalidParameter(format!(
                "a {}×{} sample image added to a {}×{} sum",
                image.width, image.height, self.width, self.height
            )));
        }
        for (p, (rgb, &hit)) in image.rgb.iter().zip(&image.mask).enumerate() {
            if hit {
                self.add_pixel(p, Some(rgb.map(f64::from)), 1);
            }
        }
        self.samples += 1;
        Ok(())
    }

    /// Adds one pixel's samples: the sum of their radiance (`None` when none hit) and how
    /// many hit.
    pub fn add_pixel(&mut self, pixel: usize, radiance: Option<[f64; 3]>, hits: u32) {
        if let Some(c) = radiance {
            for (sum, v) in self.sum[pixel].iter_mut().zip(c) {
                *sum += v;
            }
        }
        self.hits[pixel] += hits;
    }

    /// The mean image over `samples` samples per pixel (what [`Accumulator::add`] counted
    /// when `samples` is `None`).
    pub fn finish(self, samples: Option<u32>) -> Image {
        let n = samples.unwrap_or(self.samples).max(1);
        let mut image = Image::new(self.width, self.height);
        for (p, (sum, &hits)) in self.sum.iter().zip(&self.hits).enumerate() {
            image.rgb[p] = sum.map(|v| (v / f64::from(n)) as f32);
            image.mask[p] = 2 * hits >= n;
        }
        image
    }
}

/// Renders `render(offset)` at each sub-pixel offset of `camera` and returns the mean
/// image: its samples per pixel's offsets, or with one sample its own sub-pixel position,
/// whose image is returned as it is.
pub fn supersample(
    camera: &Camera,
    mut render: impl FnMut([f64; 2]) -> Result<Image>,
) -> Result<Image> {
    let spp = camera.samples_per_pixel;
    if spp.is_one() {
        return render(camera.subpixel);
    }
    let offsets = spp.offsets();
    let mut sum: Option<Accumulator> = None;
    for offset in offsets {
        let image = render(offset)?;
        sum.get_or_insert_with(|| Accumulator::new(image.width, image.height))
            .add(&image)?;
    }
    Ok(sum.map_or_else(|| Image::new(0, 0), |s| s.finish(None)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_is_a_box_filter_with_misses_black_and_half_coverage_a_hit() {
        let camera: Camera = serde_json::from_str(
            r#"{"eye": [0, 0, 1], "target": [0, 0, 0], "fov_y_degrees": 40, "width": 1,
                "height": 1, "samples_per_pixel": 4}"#,
        )
        .unwrap();
        let mut k = 0;
        // One pixel: hit by samples 0 and 1 with 1.0 and 0.5, missed by the others.
        let image = supersample(&camera, |_| {
            let mut image = Image::new(1, 1);
            if k < 2 {
                image.rgb[0] = [1.0 / (k + 1) as f32; 3];
                image.mask[0] = true;
            }
            k += 1;
            Ok(image)
        })
        .unwrap();
        assert_eq!(k, 4);
        assert_eq!(image.rgb[0], [0.375; 3]);
        assert!(image.mask[0]);
    }
}
