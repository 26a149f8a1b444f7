//! Samples per pixel: where inside each pixel the camera rays pass.
//!
//! Every renderer takes the same sub-pixel positions, so that the CPU renderers and the WGSL
//! pipelines sample a pixel at the same points and their images stay comparable at any
//! count: one sample is the pixel's centre (the images of a one-sample render are those of
//! the renderers before this knob existed); N > 1 samples are the first N points of a 2D
//! Owen-scrambled Sobol sequence (`sobol_burley`, a fixed seed), the same in every pixel.
//! They are stratified: for N a power of two each of N equal sub-pixel boxes (of any
//! aspect that tiles the pixel in powers of two) holds exactly one.

use crate::error::{Error, Result};
use crate::limits::MAX_IMAGE_SIDE;
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
}
