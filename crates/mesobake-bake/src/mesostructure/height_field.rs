//! Height-field mesostructure: a grayscale PNG (8 or 16 bits) whose pixel value, over its
//! maximum, is the height as a fraction of the volume's depth (0 = bottom, 1 = top), tileable
//! in x and y. It is baked as the volume it bounds: the voxel column under each height is
//! solid, and so is the bottom layer (the relief's floor), so every GDM path (and every
//! renderer) handles it like any other volume.

use crate::mesostructure::volume::Volume;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::path::Path;

/// The PNG signature, by which inputs are recognized as height fields.
pub const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];

/// Heights in [0, 1] on a W×H grid, x fastest; pixel (i, j) is the height at texture
/// position ((i + ½)/W, (j + ½)/H).
#[derive(Clone, Debug, PartialEq)]
pub struct HeightField {
    width: u32,
    height: u32,
    heights: Vec<f32>,
}

impl HeightField {
    /// Decodes a grayscale PNG of 8 or 16 bits, refusing colour images (which channel would be
    /// the height is not obvious) and images whose decoding would exceed `limits`.
    pub fn decode_png(bytes: &[u8], limits: &Limits) -> Result<HeightField> {
        let bad = |why: String| Error::InvalidParameter(format!("height field PNG: {why}"));
        let budget = png::Limits {
            bytes: usize::try_from(limits.memory_bytes).unwrap_or(usize::MAX),
        };
        let decoder = png::Decoder::new_with_limits(std::io::Cursor::new(bytes), budget);
        let mut reader = decoder.read_info().map_err(|e| bad(e.to_string()))?;
        let (width, height) = (reader.info().width, reader.info().height);
        limits.check_image("height field PNG", u64::from(width), u64::from(height))?;
        let (color, depth) = reader.output_color_type();
        if color != png::ColorType::Grayscale {
            return Err(bad(format!(
                "{color:?} images are not height fields; save it as 8- or 16-bit grayscale"
            )));
        }
        let max = match depth {
            png::BitDepth::Eight => 255.0,
            png::BitDepth::Sixteen => 65535.0,
            other => {
                return Err(bad(format!(
                    "{other:?}-bit samples; save it as 8- or 16-bit grayscale"
                )));
            }
        };
        limits.check(
            "height field samples",
            u64::from(width) * u64::from(height),
            4,
        )?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| bad(format!("a {width}×{height} image is too large")))?;
        let mut buf = vec![0u8; size];
        let frame = reader
            .next_frame(&mut buf)
            .map_err(|e| bad(e.to_string()))?;
        let buf = &buf[..frame.buffer_size()];
        let heights = match depth {
            png::BitDepth::Sixteen => buf
                .chunks_exact(2)
                .map(|b| f32::from(u16::from_be_bytes([b[0], b[1]])) / max)
                .collect(),
            _ => buf.iter().map(|&b| f32::from(b) / max).collect(),
        };
        Ok(HeightField {
            width,
            height,
            heights,
        })
    }

    /// A height field of `width` × `height` pixels (x fastest), every height finite in [0, 1].
    pub fn new(width: u32, height: u32, heights: Vec<f32>) -> Result<HeightField> {
        if width == 0 || height == 0 || heights.len() as u64 != u64::from(width) * u64::from(height)
        {
            return Err(Error::InvalidParameter(format!(
                "a {width}×{height} height field needs {} heights, got {}",
                u64::from(width) * u64::from(height),
                heights.len()
            )));
        }
        if let Some(n) = heights.iter().position(|h| !(0.0..=1.0).contains(h)) {
            return Err(Error::InvalidParameter(format!(
                "height field pixel {n}: height {} is not in [0, 1]",
                heights[n]
            )));
        }
        Ok(HeightField {
            width,
            height,
            heights,
        })
    }

    /// The field as a 16-bit grayscale PNG (height × 65535, rounded), which
    /// [`HeightField::decode_png`] reads back to within 1/131070.
    pub fn to_png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Sixteen);
        let data: Vec<u8> = self
            .heights
            .iter()
            .flat_map(|h| ((h * 65535.0).round() as u16).to_be_bytes())
            .collect();
        let mut writer = encoder.write_header().expect("a valid header");
        writer.write_image_data(&data).expect("the whole image");
        writer.finish().expect("in memory");
        out
    }

    /// Reads and decodes the PNG at `path`.
    pub fn read(path: &Path, limits: &Limits) -> Result<HeightField> {
        let bytes = mesobake_core::fs::read_bounded(path, "height field", limits.memory_bytes)?;
        Self::decode_png(&bytes, limits).map_err(|e| e.context(path.display()))
    }

    /// The width and height of the PNG at `path`, from its header alone.
    pub fn png_size(path: &Path) -> Result<(u32, u32)> {
        let bad = |why: String| {
            Error::InvalidParameter(format!("height field PNG {}: {why}", path.display()))
        };
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let decoder = png::Decoder::new(std::io::BufReader::new(file));
        let reader = decoder.read_info().map_err(|e| bad(e.to_string()))?;
        Ok((reader.info().width, reader.info().height))
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The heights, x fastest.
    pub fn heights(&self) -> &[f32] {
        &self.heights
    }

    /// The height at texture position (u, v), bilinear between pixel centres, wrapping in
    /// both directions.
    pub fn sample(&self, u: f64, v: f64) -> f64 {
        let (w, h) = (self.width as i64, self.height as i64);
        let (x, y) = (u * w as f64 - 0.5, v * h as f64 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |i: i64, j: i64| -> f64 {
            f64::from(self.heights[(j.rem_euclid(h) * w + i.rem_euclid(w)) as usize])
        };
        let (i, j) = (x0 as i64, y0 as i64);
        let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
        let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The volume under the surface on grid `dims`: voxel (i, j, k)'s density is the fraction
    /// of its height below the surface at its column's centre (threshold ½, so a voxel is
    /// solid iff its centre lies below the surface), and the bottom layer is solid: the
    /// relief's floor, where a height of 0 lies (and a VDM's rays end), is a surface rather
    /// than a hole through the shell.
    pub fn to_volume(&self, dims: Dims, limits: &Limits) -> Result<Volume> {
        limits.check("volume densities", dims.voxel_count(), 4)?;
        let columns: Vec<f64> = (0..dims.y)
            .flat_map(|j| (0..dims.x).map(move |i| (i, j)))
            .map(|(i, j)| {
                let u = (f64::from(i) + 0.5) / f64::from(dims.x);
                let v = (f64::from(j) + 0.5) / f64::from(dims.y);
                self.sample(u, v) * f64::from(dims.z)
            })
            .collect();
        let density = (0..dims.z)
            .flat_map(|k| {
                columns.iter().map(move |&top| {
                    if k == 0 {
                        1.0
                    } else {
                        (top - f64::from(k)).clamp(0.0, 1.0)
                    }
                })
            })
            .map(|d| d as f32)
            .collect();
        Volume::new(dims, density, 0.5, None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(
        width: u32,
        height: u32,
        depth: png::BitDepth,
        color: png::ColorType,
        data: &[u8],
    ) -> Vec<u8> {
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, width, height);
        encoder.set_color(color);
        encoder.set_depth(depth);
        encoder
            .write_header()
            .unwrap()
            .write_image_data(data)
            .unwrap();
        out
    }

    #[test]
    fn a_16_bit_ramp_bounds_the_volume_below_it() {
        // Heights j/3 for rows j = 0..3 (16 bits), constant along x.
        let data: Vec<u8> = (0..4u16)
            .flat_map(|j| (0..4).flat_map(move |_| (j * 21845).to_be_bytes()))
            .collect();
        let bytes = png(
            4,
            4,
            png::BitDepth::Sixteen,
            png::ColorType::Grayscale,
            &data,
        );
        let limits = Limits::default();
        let field = HeightField::decode_png(&bytes, &limits).unwrap();
        assert_eq!(field.size(), (4, 4));
        // At pixel centres the samples are the pixels; between rows, the mean.
        assert!((field.sample(0.375, 2.5 / 4.0) - 2.0 / 3.0).abs() < 1e-6);
        assert!((field.sample(0.1, 0.5) - 0.5).abs() < 1e-6);
        // Wrapping: above the last row comes the first again.
        assert!((field.sample(0.1, 1.0) - 0.5).abs() < 1e-6);
        let v = field
            .to_volume(Dims::new(4, 4, 6).unwrap(), &limits)
            .unwrap();
        for j in 0..4 {
            let top = 6.0 * j as f64 / 3.0;
            for k in 0..6 {
                let centre = k as f64 + 0.5;
                let expected = centre < top || k == 0;
                assert_eq!(v.is_solid(1, j, k), expected, "column {j}, voxel {k}");
            }
        }
    }

    #[test]
    fn colour_truncated_and_oversized_images_are_refused() {
        let limits = Limits::default();
        let rgb = png(2, 2, png::BitDepth::Eight, png::ColorType::Rgb, &[0; 12]);
        let e = HeightField::decode_png(&rgb, &limits)
            .unwrap_err()
            .to_string();
        assert!(e.contains("grayscale"), "{e}");
        let gray = png(
            2,
            2,
            png::BitDepth::Eight,
            png::ColorType::Grayscale,
            &[0, 64, 128, 255],
        );
        let e = HeightField::decode_png(&gray[..gray.len() - 20], &limits).unwrap_err();
        assert!(e.to_string().contains("height field PNG"), "{e}");
        let tiny = Limits {
            memory_bytes: 8,
            ..Limits::default()
        };
        assert!(HeightField::decode_png(&gray, &tiny).is_err());
        let ok = HeightField::decode_png(&gray, &limits).unwrap();
        assert_eq!(ok.heights, vec![0.0, 64.0 / 255.0, 128.0 / 255.0, 1.0]);
    }
}
