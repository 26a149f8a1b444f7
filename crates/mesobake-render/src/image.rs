//! Rendered images: linear RGB with a hit/miss mask; PNG (sRGB, alpha = mask) and OpenEXR
//! (linear float, A = mask) files; `compare`.

use mesobake_core::color::linear_to_srgb;
use mesobake_core::error::{Error, Result};
use mesobake_core::fs::write_atomic;
use mesobake_core::limits::MAX_IMAGE_SIDE;
use serde::Serialize;
use std::path::Path;

/// A rendered image: linear RGB per pixel, row 0 at the top, and whether a pixel's ray hit
/// mesostructure (misses are black).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, row-major.
    pub rgb: Vec<[f32; 3]>,
    /// Hit (true) or miss, row-major.
    pub mask: Vec<bool>,
}

impl Image {
    /// A black image with no hits.
    pub fn new(width: u32, height: u32) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            rgb: vec![[0.0; 3]; n],
            mask: vec![false; n],
        }
    }

    /// Number of pixels whose ray hit.
    pub fn hits(&self) -> usize {
        self.mask.iter().filter(|m| **m).count()
    }

    /// PNG bytes: 8-bit sRGB RGBA, alpha 255 on hits and 0 on misses.
    pub fn to_png(&self) -> Result<Vec<u8>> {
        let mut data = Vec::with_capacity(self.rgb.len() * 4);
        for (c, m) in self.rgb.iter().zip(&self.mask) {
            data.extend(c.map(|v| (linear_to_srgb(v) * 255.0).round() as u8));
            data.push(if *m { 255 } else { 0 });
        }
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        let png_error = |e: png::EncodingError| Error::InvalidParameter(format!("PNG: {e}"));
        let mut writer = encoder.write_header().map_err(png_error)?;
        writer.write_image_data(&data).map_err(png_error)?;
        writer.finish().map_err(png_error)?;
        Ok(out)
    }

    /// Writes `.png` or `.exr` (by extension), atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        match extension(path).as_str() {
            "png" => write_atomic(path, &self.to_png()?),
            "exr" => {
                use exr::prelude::{Image as ExrImage, SpecificChannels, Vec2, WritableImage};
                let w = self.width as usize;
                let channels = SpecificChannels::rgba(|p: Vec2<usize>| {
                    let i = p.y() * w + p.x();
                    let c = self.rgb[i];
                    (c[0], c[1], c[2], if self.mask[i] { 1.0f32 } else { 0.0 })
                });
                let image = ExrImage::from_channels((w, self.height as usize), channels);
                let mut bytes = std::io::Cursor::new(Vec::new());
                image
                    .write()
                    .to_buffered(&mut bytes)
                    .map_err(|e| Error::InvalidParameter(format!("EXR encoding failed: {e}")))?;
                write_atomic(path, bytes.get_ref())
            }
            other => Err(Error::InvalidParameter(format!(
                "{}: unknown image extension {other:?} (use .png or .exr)",
                path.display()
            ))),
        }
    }

    /// Reads a `.png` (8-bit RGB or RGBA; no alpha means every pixel is a hit) or an `.exr`
    /// (first RGBA layer; A ≥ ½ is a hit), at most [`MAX_IMAGE_SIDE`] on a side.
    pub fn read(path: &Path) -> Result<Image> {
        match extension(path).as_str() {
            "png" => read_png(path),
            "exr" => read_exr(path),
            other => Err(Error::InvalidParameter(format!(
                "{}: unknown image extension {other:?} (use .png or .exr)",
                path.display()
            ))),
        }
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

fn check_size(path: &Path, width: usize, height: usize) -> Result<()> {
    if width == 0
        || height == 0
        || width > MAX_IMAGE_SIDE as usize
        || height > MAX_IMAGE_SIDE as usize
    {
        return Err(Error::InvalidParameter(format!(
            "{}: a {width}×{height} image; sides must be in 1..={MAX_IMAGE_SIDE}",
            path.display()
        )));
    }
    Ok(())
}

fn read_png(path: &Path) -> Result<Image> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let bad = |e: png::DecodingError| {
        Error::InvalidParameter(format!("{}: not a readable PNG: {e}", path.display()))
    };
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let info = decoder.read_header_info().map_err(bad)?;
    check_size(path, info.width as usize, info.height as usize)?;
    let mut reader = decoder.read_info().map_err(bad)?;
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap_or(0)];
    let frame = reader.next_frame(&mut buf).map_err(bad)?;
    let channels = match frame.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => {
            return Err(Error::InvalidParameter(format!(
                "{}: {other:?} PNGs are not supported (RGB or RGBA)",
                path.display()
            )));
        }
    };
    let (w, h) = (frame.width, frame.height);
    let mut image = Image::new(w, h);
    for (i, px) in buf[..frame.buffer_size()]
        .chunks_exact(channels)
        .enumerate()
    {
        image.rgb[i] =
            [0, 1, 2].map(|c| mesobake_core::color::srgb_to_linear(px[c] as f32 / 255.0));
        image.mask[i] = channels == 3 || px[3] >= 128;
    }
    Ok(image)
}

fn read_exr(path: &Path) -> Result<Image> {
    let bad = |e: exr::error::Error| {
        Error::InvalidParameter(format!(
            "{}: not a readable OpenEXR image: {e}",
            path.display()
        ))
    };
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(bad)?;
    let size = meta
        .headers
        .first()
        .map(|h| h.layer_size)
        .ok_or_else(|| Error::InvalidParameter(format!("{}: no layer", path.display())))?;
    check_size(path, size.width(), size.height())?;
    let read = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| Image::new(size.width() as u32, size.height() as u32),
        |image: &mut Image, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            let i = pos.y() * image.width as usize + pos.x();
            image.rgb[i] = [r, g, b];
            image.mask[i] = a >= 0.5;
        },
    )
    .map_err(bad)?;
    Ok(read.layer_data.channel_data.pixels)
}

/// A picture of where two images of equal size differ: red where only `a` hit, blue where
/// only `b` hit, elsewhere the absolute sRGB difference ×4 in grey.
pub fn difference(a: &Image, b: &Image) -> Result<Image> {
    compare(a, b)?;
    let mut out = Image::new(a.width, a.height);
    for i in 0..a.rgb.len() {
        out.mask[i] = true;
        out.rgb[i] = match (a.mask[i], b.mask[i]) {
            (true, false) => [1.0, 0.0, 0.0],
            (false, true) => [0.0, 0.0, 1.0],
            _ => {
                let d = (0..3)
                    .map(|c| (linear_to_srgb(a.rgb[i][c]) - linear_to_srgb(b.rgb[i][c])).abs())
                    .fold(0.0f32, f32::max);
                [mesobake_core::color::srgb_to_linear((4.0 * d).min(1.0)); 3]
            }
        };
    }
    Ok(out)
}

/// How two images differ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Comparison {
    /// Peak signal-to-noise ratio in dB over all pixels and channels of the sRGB-encoded
    /// values in [0, 1] (what a viewer sees); +∞ for identical images.
    pub psnr_db: f64,
    /// Mean absolute difference of the sRGB-encoded values.
    pub mean_abs_error: f64,
    /// Fraction of pixels whose hit/miss mask differs.
    pub mask_disagreement: f64,
    /// Mean ꟻLIP error (NVIDIA's perceptual difference, 0 identical to 1 most different) of
    /// the 8-bit sRGB images, the first as reference, at 67 pixels per degree (`nv-flip`).
    pub flip_mean: f64,
    /// Pixels compared.
    pub pixels: usize,
}

/// Compares two images of equal size.
pub fn compare(a: &Image, b: &Image) -> Result<Comparison> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::InvalidParameter(format!(
            "cannot compare a {}×{} image with a {}×{} one",
            a.width, a.height, b.width, b.height
        )));
    }
    let (mut sq, mut abs) = (0.0f64, 0.0f64);
    for (p, q) in a.rgb.iter().zip(&b.rgb) {
        for c in 0..3 {
            let d = (linear_to_srgb(p[c]) - linear_to_srgb(q[c])) as f64;
            sq += d * d;
            abs += d.abs();
        }
    }
    let n = a.rgb.len();
    let mse = sq / (3 * n) as f64;
    let differing = a.mask.iter().zip(&b.mask).filter(|(p, q)| p != q).count();
    let srgb8 = |image: &Image| -> nv_flip::FlipImageRgb8 {
        let bytes: Vec<u8> = image
            .rgb
            .iter()
            .flat_map(|c| c.map(|v| (linear_to_srgb(v) * 255.0).round() as u8))
            .collect();
        nv_flip::FlipImageRgb8::with_data(image.width, image.height, &bytes)
    };
    let error = nv_flip::flip(srgb8(a), srgb8(b), nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let flip_mean = nv_flip::FlipPool::from_image(&error).mean() as f64;
    Ok(Comparison {
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            -10.0 * mse.log10()
        },
        mean_abs_error: abs / (3 * n) as f64,
        mask_disagreement: differing as f64 / n as f64,
        flip_mean,
        pixels: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64×64 image: a grey ramp with a bright square, plus `noise` (±, in linear units) on
    /// a fixed checkerboard of pixels.
    fn image(noise: f32) -> Image {
        let mut image = Image::new(64, 64);
        for (i, px) in image.rgb.iter_mut().enumerate() {
            let (x, y) = (i % 64, i / 64);
            let base = if (20..40).contains(&x) && (20..40).contains(&y) {
                0.8
            } else {
                x as f32 / 128.0
            };
            let sign = if (x + y) % 2 == 0 { 1.0 } else { -1.0 };
            *px = [(base + sign * noise).clamp(0.0, 1.0); 3];
        }
        image
    }

    #[test]
    fn flip_is_zero_for_identical_images_and_grows_with_the_difference() {
        let reference = image(0.0);
        assert_eq!(compare(&reference, &reference).unwrap().flip_mean, 0.0);
        let small = compare(&reference, &image(0.01)).unwrap().flip_mean;
        let large = compare(&reference, &image(0.2)).unwrap().flip_mean;
        // FLIP's range is [0, 1]; a faint checkerboard is a small error, a strong one large.
        assert!(
            0.0 < small && small < large && large <= 1.0,
            "{small} {large}"
        );
        let black = Image::new(64, 64);
        let opposite = compare(&reference, &black).unwrap();
        assert!(opposite.flip_mean > large, "{opposite:?}");
    }
}
