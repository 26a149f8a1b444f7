//! Samples per pixel: where inside each pixel the camera rays pass, and how their results
//! combine into one pixel.
//!
//! Every renderer takes the same sub-pixel positions, so that the CPU renderers and the WGSL
//! pipelines sample a pixel at the same points and their images stay comparable at any
//! count: one sample is the pixel's centre (the images of a one-sample render are those of
//! the renderers before this knob existed); N > 1 samples are the first N points of a 2D
//! Owen-scrambled Sobol sequence (`sobol_burley`, a fixed seed), the same in every pixel.
//! They are stratified: for N a power of two each of N equal sub-pixel boxes (of any
//! aspect that tiles the pixel in powers of two) holds exactly one.
//!
//! A pixel's colour is the mean, in linear light, of its samples' radiance with misses black
//! (a box filter); it is a hit when at least half its samples hit (coverage ≥ ½).

use super::image::Image;
use crate::error::{Error, Result};
use crate::scene::{Camera, MAX_IMAGE_SIDE};
use serde::{Deserialize, Serialize};
use std::str::FromStr;

/// The most samples one pixel may take.
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1024;

/// The most camera rays one image may take, all samples of all pixels (as many as an
/// image of [`MAX_IMAGE_SIDE`] pixels a side at one sample each).
pub const MAX_IMAGE_SAMPLES: u64 = MAX_IMAGE_SIDE as u64 * MAX_IMAGE_SIDE as u64;

/// The Sobol sequence's seed: any fixed value keeps renders deterministic.
const SEED: u32 = 0x6d65_736f;

/// How many camera rays a pixel averages: 1 to [`MAX_SAMPLES_PER_PIXEL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "u32", into = "u32")]
pub struct SamplesPerPixel(u32);

impl SamplesPerPixel {
    /// One ray through each pixel's centre.
    pub const ONE: SamplesPerPixel = SamplesPerPixel(1);

    /// `n` samples, refused with the limit named outside 1..=[`MAX_SAMPLES_PER_PIXEL`].
    pub fn new(n: u32) -> Result<SamplesPerPixel> {
        if (1..=MAX_SAMPLES_PER_PIXEL).contains(&n) {
            Ok(SamplesPerPixel(n))
        } else {
            Err(Error::InvalidParameter(format!(
                "samples per pixel must be in 1..={MAX_SAMPLES_PER_PIXEL}, got {n}"
            )))
        }
    }

    /// The count.
    pub fn get(self) -> u32 {
        self.0
    }

    /// Whether this is one sample per pixel.
    pub fn is_one(&self) -> bool {
        self.0 == 1
    }

    /// The sub-pixel positions, in [0, 1)² from the pixel's top-left corner (x right, y
    /// down): the centre for one sample, else the first N scrambled Sobol points.
    pub fn offsets(self) -> Vec<[f64; 2]> {
        if self.0 == 1 {
            return vec![[0.5, 0.5]];
        }
        (0..self.0)
            .map(|i| [0, 1].map(|dim| f64::from(sobol_burley::sample(i, dim, SEED))))
            .collect()
    }

    /// Refuses an image of `width` × `height` pixels at this count whose rays would exceed
    /// `max_samples` in all, naming the limit.
    pub fn check_image(self, width: u32, height: u32, max_samples: u64) -> Result<()> {
        let total = u64::from(width) * u64::from(height) * u64::from(self.0);
        if total > max_samples {
            return Err(Error::InvalidParameter(format!(
                "{width}×{height} pixels at {} samples per pixel take {total} camera rays; at \
                 most {max_samples} are allowed",
                self.0
            )));
        }
        Ok(())
    }
}

impl Default for SamplesPerPixel {
    fn default() -> Self {
        SamplesPerPixel::ONE
    }
}

impl TryFrom<u32> for SamplesPerPixel {
    type Error = Error;
    fn try_from(n: u32) -> Result<Self> {
        SamplesPerPixel::new(n)
    }
}

impl From<SamplesPerPixel> for u32 {
    fn from(spp: SamplesPerPixel) -> u32 {
        spp.0
    }
}

impl FromStr for SamplesPerPixel {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let n = s.trim().parse::<u32>().map_err(|_| {
            Error::InvalidParameter(format!(
                "samples per pixel {s:?}: expected a whole number in 1..={MAX_SAMPLES_PER_PIXEL}"
            ))
        })?;
        SamplesPerPixel::new(n)
    }
}

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
    fn one_sample_is_the_pixel_centre() {
        assert_eq!(SamplesPerPixel::ONE.offsets(), vec![[0.5, 0.5]]);
    }

    #[test]
    fn power_of_two_counts_are_stratified_in_every_elementary_box() {
        // A (0, 2)-net: for N = 2^k, every box of 2^a × 2^(k−a) equal parts holds one point.
        for k in 1..=6u32 {
            let n = 1u32 << k;
            let offsets = SamplesPerPixel::new(n).unwrap().offsets();
            assert_eq!(offsets.len(), n as usize);
            for a in 0..=k {
                let (nx, ny) = (1u32 << a, 1u32 << (k - a));
                let mut count = vec![0u32; n as usize];
                for [x, y] in &offsets {
                    assert!((0.0..1.0).contains(x) && (0.0..1.0).contains(y));
                    let (i, j) = ((x * f64::from(nx)) as u32, (y * f64::from(ny)) as u32);
                    count[(j * nx + i) as usize] += 1;
                }
                assert!(
                    count.iter().all(|&c| c == 1),
                    "n {n}, boxes {nx}×{ny}: {count:?}"
                );
            }
        }
    }

    #[test]
    fn counts_outside_the_range_or_not_whole_numbers_are_refused_by_name() {
        for text in ["0", "1025", "-1", "2.5", "", "many"] {
            let e = text.parse::<SamplesPerPixel>().unwrap_err().to_string();
            assert!(e.contains("1..=1024"), "{text:?}: {e}");
        }
        assert_eq!("16".parse::<SamplesPerPixel>().unwrap().get(), 16);
        let e = SamplesPerPixel::new(1024)
            .unwrap()
            .check_image(8192, 8192, MAX_IMAGE_SAMPLES)
            .unwrap_err()
            .to_string();
        assert!(e.contains("68719476736 camera rays"), "{e}");
    }

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
