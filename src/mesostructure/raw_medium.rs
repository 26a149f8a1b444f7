//! Translucent media from raw RGBA voxel files: X·Y·Z voxels, x fastest, then y, then z,
//! four channels per voxel — red, green, blue (sRGB-encoded, as `.mbvol` stores albedo) and
//! opacity per voxel length — either one byte each ([`RawFormat::Rgba8`]: value/255) or one
//! little-endian f32 each ([`RawFormat::Rgba32f`]: values in [0, 1]). The result is a
//! version-2 volume: the colour as albedo, the opacity channel, and the opaque voxels
//! (α = 1) as its solid, like the built-in media.

use crate::error::{Error, Result};
use crate::grid::Dims;
use crate::mesostructure::volume::Volume;
use crate::util::limits::Limits;

/// How a raw file stores each channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
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
    let n = dims.voxel_count() as usize;
    let (mut albedo, mut opacity) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (v, voxel) in bytes
        .chunks_exact(format.voxel_bytes() as usize)
        .enumerate()
    {
        let rgba: [f32; 4] = match format {
            RawFormat::Rgba8 => std::array::from_fn(|c| f32::from(voxel[c]) / 255.0),
            RawFormat::Rgba32f => std::array::from_fn(|c| {
                f32::from_le_bytes([
                    voxel[4 * c],
                    voxel[4 * c + 1],
                    voxel[4 * c + 2],
                    voxel[4 * c + 3],
                ])
            }),
        };
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
        albedo.push([0, 1, 2].map(|c| (rgba[c] * 255.0).round() as u8));
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
}
