//! Translucent media from RGBA voxel files: X·Y·Z voxels, x fastest, then y, then z, four
//! channels per voxel — red, green, blue and opacity per voxel length. A raw file holds
//! them sRGB-encoded (as `.mbvol` stores albedo), one byte each ([`RawFormat::Rgba8`]:
//! value/255) or one little-endian f32 each ([`RawFormat::Rgba32f`]: values in [0, 1]). An
//! OpenEXR file ([`medium_from_exr`]) holds them linear, in its first layer's R, G, B and A
//! channels, the Z slices stacked downwards (X wide, Y·Z tall). The result is a version-2
//! volume: the colour as albedo, the opacity channel, and the opaque voxels (α = 1) as its
//! solid, like the built-in media.

use crate::mesostructure::volume::Volume;
use mesobake_core::color::linear_to_srgb;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::path::Path;

/// How a raw file stores each channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawFormat {
    /// One byte per channel, value/255.
    Rgba8,
    /// One little-endian f32 per channel, in [0, 1].
    Rgba32f,
}

impl RawFormat {
    /// Bytes per voxel.
    pub fn voxel_bytes(self) -> u64 {
        match self {
            RawFormat::Rgba8 => 4,
            RawFormat::Rgba32f => 16,
        }
    }
}

/// Checks that a raw file of `len` bytes holds exactly `dims` voxels of `format`, and that
/// the volume fits `limits`, before anything is read or allocated.
pub fn check_size(len: u64, dims: Dims, format: RawFormat, limits: &Limits) -> Result<()> {
    let voxels = dims.voxel_count();
    let expected = voxels.saturating_mul(format.voxel_bytes());
    if len != expected {
        return Err(Error::VolumeFormat(format!(
            "a raw {format:?} file of a {dims} volume holds {voxels} voxels × {} bytes = \
             {expected} bytes; this one has {len}",
            format.voxel_bytes()
        )));
    }
    // Opacity and density (f32 each) and albedo (3 bytes) per voxel.
    limits.check("raw medium", voxels, 11)?;
    Ok(())
}

/// The medium of `bytes` (a whole raw file, checked by [`check_size`]).
pub fn medium_from_raw(
    bytes: &[u8],
    dims: Dims,
    format: RawFormat,
    limits: &Limits,
) -> Result<Volume> {
    check_size(bytes.len() as u64, dims, format, limits)?;
    let voxels = bytes
        .chunks_exact(format.voxel_bytes() as usize)
        .map(|voxel| match format {
            RawFormat::Rgba8 => std::array::from_fn(|c| f32::from(voxel[c]) / 255.0),
            RawFormat::Rgba32f => std::array::from_fn(|c| {
                f32::from_le_bytes([
                    voxel[4 * c],
                    voxel[4 * c + 1],
                    voxel[4 * c + 2],
                    voxel[4 * c + 3],
                ])
            }),
        });
    medium_from_rgba(dims, voxels, |c| c)
}

/// The medium of the OpenEXR file at `path`: its first layer, X wide and Y·Z tall (slice z
/// in rows z·Y to z·Y + Y − 1), linear R, G, B and A (the opacity) in [0, 1]. The layer's
/// size and channels are checked from its header, before its pixels are read.
pub fn medium_from_exr(path: &Path, dims: Dims, limits: &Limits) -> Result<Volume> {
    let bad = |why: String| Error::VolumeFormat(format!("{}: {why}", path.display()));
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| bad(e.to_string()))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| bad("no image layer".into()))?;
    let (width, height) = (header.layer_size.0 as u64, header.layer_size.1 as u64);
    let tall = u64::from(dims.y) * u64::from(dims.z);
    if width != u64::from(dims.x) || height != tall {
        return Err(bad(format!(
            "a {dims} medium is an image {} wide and Y·Z = {tall} tall (its Z slices stacked); \
             this one is {width}×{height}",
            dims.x
        )));
    }
    let names: Vec<String> = header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    if let Some(missing) = ["R", "G", "B", "A"]
        .iter()
        .find(|c| !names.iter().any(|n| n == *c))
    {
        return Err(bad(format!(
            "the first layer has channels {names:?}, no {missing} (a medium needs R, G, B and \
             the opacity in A)"
        )));
    }
    limits.check("EXR medium", width * height, 16 + 11)?;
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| vec![[0.0f32; 4]; size.0 * size.1],
        move |texels, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            texels[pos.1 * width as usize + pos.0] = [r, g, b, a];
        },
    )
    .map_err(|e| bad(e.to_string()))?;
    let texels = image.layer_data.channel_data.pixels;
    // Row y of slice z is image row z·Y + y: the texels are already x, then y, then z.
    medium_from_rgba(dims, texels.into_iter(), linear_to_srgb)
}

/// The medium of `voxels` (x fastest, then y, then z): colour channels mapped to sRGB by
/// `to_srgb`, then each channel checked to lie in [0, 1] (named by voxel if not).
fn medium_from_rgba(
    dims: Dims,
    voxels: impl Iterator<Item = [f32; 4]>,
    to_srgb: impl Fn(f32) -> f32,
) -> Result<Volume> {
    let n = dims.voxel_count() as usize;
    let (mut albedo, mut opacity) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (v, rgba) in voxels.enumerate() {
        if let Some(c) = rgba.iter().position(|x| !(0.0..=1.0).contains(x)) {
            let (i, j, k) = (
                v % dims.x as usize,
                (v / dims.x as usize) % dims.y as usize,
                v / (dims.x as usize * dims.y as usize),
            );
            return Err(Error::VolumeFormat(format!(
                "voxel ({i}, {j}, {k}) has {} {}, not a number in [0, 1]",
                ["red", "green", "blue", "opacity"][c],
                rgba[c]
            )));
        }
        albedo.push([0, 1, 2].map(|c| (to_srgb(rgba[c]) * 255.0).round() as u8));
        opacity.push(rgba[3]);
    }
    Volume::new(dims, opacity.clone(), 1.0, Some(albedo))?.with_opacity(opacity)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dims() -> Dims {
        Dims::new(4, 4, 2).unwrap()
    }

    /// Both formats give the same volume: albedo bytes, opacity, and α = 1 solid.
    #[test]
    fn both_formats_read_the_same_medium() {
        let n = 32;
        let rgba = |v: usize| {
            [
                v as u8 * 7,
                200 - v as u8,
                3,
                if v == 5 { 255 } else { v as u8 * 2 },
            ]
        };
        let bytes8: Vec<u8> = (0..n).flat_map(rgba).collect();
        let bytes32: Vec<u8> = (0..n)
            .flat_map(|v| rgba(v).map(|c| f32::from(c) / 255.0))
            .flat_map(f32::to_le_bytes)
            .collect();
        let limits = Limits::default();
        let a = medium_from_raw(&bytes8, dims(), RawFormat::Rgba8, &limits).unwrap();
        let b = medium_from_raw(&bytes32, dims(), RawFormat::Rgba32f, &limits).unwrap();
        for v in [&a, &b] {
            let opacity = v.opacity().unwrap();
            assert_eq!(opacity[3], 6.0 / 255.0);
            assert_eq!(opacity[5], 1.0);
            assert_eq!(v.occupancy().solid_count(), 1);
        }
        assert_eq!(a.opacity(), b.opacity());
        assert_eq!(a.albedo(), b.albedo());
        assert_eq!(a.albedo().unwrap()[9], [63, 191, 3]);
    }

    /// A file of the wrong size, a NaN or a value over 1, or a volume over the memory limit:
    /// a clear error naming the problem.
    #[test]
    fn bad_raw_files_are_refused_by_name() {
        let limits = Limits::default();
        let e = medium_from_raw(&[0; 127], dims(), RawFormat::Rgba8, &limits).unwrap_err();
        assert!(e.to_string().contains("128 bytes; this one has 127"), "{e}");
        let mut bytes: Vec<u8> = vec![0.5f32; 128]
            .into_iter()
            .flat_map(f32::to_le_bytes)
            .collect();
        bytes[4 * 6..4 * 7].copy_from_slice(&f32::NAN.to_le_bytes());
        let e = medium_from_raw(&bytes, dims(), RawFormat::Rgba32f, &limits).unwrap_err();
        assert!(
            e.to_string().contains("voxel (1, 0, 0) has blue NaN"),
            "{e}"
        );
        bytes[4 * 6..4 * 7].copy_from_slice(&1.5f32.to_le_bytes());
        let e = medium_from_raw(&bytes, dims(), RawFormat::Rgba32f, &limits).unwrap_err();
        assert!(e.to_string().contains("blue 1.5"), "{e}");
        let huge = Dims::new(4096, 4096, 4096).unwrap();
        let len = huge.voxel_count() * 4;
        let e = check_size(len, huge, RawFormat::Rgba8, &limits).unwrap_err();
        assert!(matches!(e, Error::MemoryLimit { .. }), "{e}");
    }

    /// An OpenEXR image of the Z slices stacked downwards, linear colour: the same medium as
    /// the raw file of its sRGB codes; the wrong size, a missing A channel or a value over 1
    /// are refused by name, before anything is written.
    #[test]
    fn an_exr_image_of_stacked_slices_reads_as_the_raw_file() {
        use mesobake_core::color::srgb_to_linear;
        let dir = tempfile::tempdir().unwrap();
        let d = dims();
        let code = |v: usize, c: usize| [v as u8 * 7, 200 - v as u8, 3, v as u8 * 2][c];
        let voxel = |x: usize, y: usize| x + (y % 4) * 4 + (y / 4) * 16;
        let write = |name: &str, alpha: &(dyn Fn(usize) -> f32 + Sync), height: usize| {
            let path = dir.path().join(name);
            exr::prelude::write_rgba_file(&path, 4, height, |x, y| {
                let v = voxel(x, y);
                let lin = |c| srgb_to_linear(f32::from(code(v, c)) / 255.0);
                (lin(0), lin(1), lin(2), alpha(v))
            })
            .unwrap();
            path
        };
        let opacity = |v: usize| f32::from(code(v, 3)) / 255.0;
        let limits = Limits::default();
        let exr = medium_from_exr(&write("m.exr", &opacity, 8), d, &limits).unwrap();
        let raw: Vec<u8> = (0..32)
            .flat_map(|v| [0, 1, 2, 3].map(|c| code(v, c)))
            .collect();
        let raw = medium_from_raw(&raw, d, RawFormat::Rgba8, &limits).unwrap();
        assert_eq!(exr.opacity(), raw.opacity());
        assert_eq!(exr.albedo(), raw.albedo());

        let e = medium_from_exr(&write("short.exr", &opacity, 6), d, &limits).unwrap_err();
        assert!(e.to_string().contains("this one is 4×6"), "{e}");
        let rgb = dir.path().join("rgb.exr");
        exr::prelude::write_rgb_file(&rgb, 4, 8, |_, _| (0.5f32, 0.5, 0.5)).unwrap();
        let e = medium_from_exr(&rgb, d, &limits).unwrap_err();
        assert!(e.to_string().contains("no A"), "{e}");
        let over = |v: usize| if v == 21 { 1.5 } else { 0.0 };
        let e = medium_from_exr(&write("over.exr", &over, 8), d, &limits).unwrap_err();
        assert!(
            e.to_string().contains("voxel (1, 1, 1) has opacity 1.5"),
            "{e}"
        );
    }
}
