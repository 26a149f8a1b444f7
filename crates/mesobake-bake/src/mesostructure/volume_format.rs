//! The `.mbvol` mesostructure volume file format, versions 1 and 2. All numbers little-endian.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `MBVOL\0\r\n` |
//! | 8 | 4 | version (u32): 1, or 2 when the opacity channel is present |
//! | 12 | 12 | X, Y, Z (u32 each), 1..=65536 |
//! | 24 | 4 | channels (u32 bit set): bit 0 density (required), bit 1 albedo, bit 2 opacity (version 2) |
//! | 28 | 4 | solid threshold (f32, finite): voxel solid iff density ≥ threshold |
//! | 32 | 4 | voxel size in metres (f32, finite, > 0) |
//! | 36 | 4 | CRC-32 (IEEE) of the payload |
//! | 40 | 8 | reserved, zero |
//! | 48 | 4·N | density, f32 per voxel, x fastest, then y, then z (N = X·Y·Z) |
//! | 48+4N | 3·N | albedo, sRGB u8 triples, same order (when bit 1 is set) |
//! | after albedo | 4·N | opacity per voxel length, f32 in [0, 1], same order (when bit 2 is set) |
//!
//! Opacity makes the volume a translucent medium ([`crate::mesostructure::medium`]): a voxel's
//! opacity is the fraction of light one voxel length of it absorbs. Version 2 adds only this
//! channel; files without it are written as version 1, so version-1 readers still read them.
//!
//! The file ends right after the payload. A reader checks every field, the exact file length
//! (truncated or oversized files are errors), the CRC, finite densities, and refuses sizes
//! over the memory limit before allocating.

use crate::mesostructure::volume::Volume;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, MAX_AXIS};
use std::path::Path;

/// The file's first eight bytes.
pub const MAGIC: &[u8; 8] = b"MBVOL\0\r\n";
/// The newest format version this code reads and writes.
pub const VERSION: u32 = 2;
/// Size of the fixed header.
pub const HEADER_BYTES: usize = 48;
const CHANNEL_DENSITY: u32 = 1;
const CHANNEL_ALBEDO: u32 = 2;
const CHANNEL_OPACITY: u32 = 4;

/// Voxel size written by this version (one millimetre); carried for scenes and packages.
pub const DEFAULT_VOXEL_SIZE_M: f32 = 1e-3;

/// Serializes `volume` to the `.mbvol` bytes.
pub fn encode(volume: &Volume) -> Vec<u8> {
    let dims = volume.dims();
    let mut payload = Vec::with_capacity(volume.density().len() * 7);
    for d in volume.density() {
        payload.extend_from_slice(&d.to_le_bytes());
    }
    let mut channels = CHANNEL_DENSITY;
    if let Some(albedo) = volume.albedo() {
        channels |= CHANNEL_ALBEDO;
        for rgb in albedo {
            payload.extend_from_slice(rgb);
        }
    }
    let mut version = 1;
    if let Some(opacity) = volume.opacity() {
        channels |= CHANNEL_OPACITY;
        version = 2;
        for a in opacity {
            payload.extend_from_slice(&a.to_le_bytes());
        }
    }
    let mut out = Vec::with_capacity(HEADER_BYTES + payload.len());
    out.extend_from_slice(MAGIC);
    for v in [version, dims.x, dims.y, dims.z, channels] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&volume.threshold().to_le_bytes());
    out.extend_from_slice(&DEFAULT_VOXEL_SIZE_M.to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&[0; 8]);
    out.extend_from_slice(&payload);
    out
}

fn u32_at(bytes: &[u8], offset: usize) -> u32 {
    u32::from_le_bytes(bytes[offset..offset + 4].try_into().expect("4 bytes"))
}

fn f32_at(bytes: &[u8], offset: usize) -> f32 {
    f32::from_le_bytes(bytes[offset..offset + 4].try_into().expect("4 bytes"))
}

fn bad(msg: String) -> Error {
    Error::VolumeFormat(msg)
}

/// Whether `bytes` start with the `.mbvol` magic.
pub fn has_magic(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Validates the header of a file of `file_len` bytes; returns the dimensions, channels and
/// the payload size. Never allocates according to the header before checking the limit.
fn parse_header(header: &[u8], file_len: u64, limits: &Limits) -> Result<(Dims, u32, u64)> {
    if header.len() < HEADER_BYTES {
        return Err(bad(format!(
            "file is {file_len} bytes, shorter than the {HEADER_BYTES}-byte header"
        )));
    }
    if !has_magic(header) {
        return Err(bad("not a mesobake volume (bad magic number)".into()));
    }
    let version = u32_at(header, 8);
    if !(1..=VERSION).contains(&version) {
        return Err(bad(format!(
            "format version {version} is not supported (this build reads versions 1 to {VERSION})"
        )));
    }
    let (x, y, z) = (u32_at(header, 12), u32_at(header, 16), u32_at(header, 20));
    if [x, y, z].iter().any(|&n| n == 0 || n > MAX_AXIS) {
        return Err(bad(format!(
            "dimensions {x}x{y}x{z} are invalid: each must be in 1..={MAX_AXIS}"
        )));
    }
    let dims = Dims::new(x, y, z)?;
    let channels = u32_at(header, 24);
    let known = match version {
        1 => CHANNEL_DENSITY | CHANNEL_ALBEDO,
        _ => CHANNEL_DENSITY | CHANNEL_ALBEDO | CHANNEL_OPACITY,
    };
    if channels & CHANNEL_DENSITY == 0 || channels & !known != 0 {
        return Err(bad(format!(
            "channel set {channels:#x} is invalid for version {version}: density (bit 0) is \
             required, bits above {} are unknown",
            known.ilog2()
        )));
    }
    let threshold = f32_at(header, 28);
    if !threshold.is_finite() {
        return Err(bad(format!(
            "solid threshold is {threshold}, not a finite number"
        )));
    }
    let voxel_size = f32_at(header, 32);
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        return Err(bad(format!(
            "voxel size is {voxel_size}, not a positive finite number"
        )));
    }
    if header[40..48].iter().any(|&b| b != 0) {
        return Err(bad("reserved header bytes 40..48 are not zero".into()));
    }
    let per_voxel = 4
        + if channels & CHANNEL_ALBEDO != 0 { 3 } else { 0 }
        + if channels & CHANNEL_OPACITY != 0 {
            4
        } else {
            0
        };
    let payload = limits.check(&format!("a {dims} volume"), dims.voxel_count(), per_voxel)?;
    let expected = HEADER_BYTES as u64 + payload;
    if file_len < expected {
        return Err(bad(format!(
            "file is truncated: {file_len} bytes, but a {dims} volume needs {expected}"
        )));
    }
    if file_len > expected {
        return Err(bad(format!(
            "file has {} unexpected bytes after the {expected}-byte volume",
            file_len - expected
        )));
    }
    Ok((dims, channels, payload))
}

/// Parses and validates `.mbvol` bytes.
pub fn decode(bytes: &[u8], limits: &Limits) -> Result<Volume> {
    let (dims, channels, _) = parse_header(bytes, bytes.len() as u64, limits)?;
    let payload = &bytes[HEADER_BYTES..];
    let crc = u32_at(bytes, 36);
    if crc32fast::hash(payload) != crc {
        return Err(bad("payload checksum mismatch: the file is corrupt".into()));
    }
    let n = dims.voxel_count() as usize;
    let floats = |bytes: &[u8]| -> Vec<f32> {
        bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect()
    };
    let density = floats(&payload[..4 * n]);
    let mut rest = &payload[4 * n..];
    let albedo = (channels & CHANNEL_ALBEDO != 0).then(|| {
        let (albedo, after) = rest.split_at(3 * n);
        rest = after;
        albedo.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    });
    let volume = Volume::new(dims, density, f32_at(bytes, 28), albedo)?;
    match channels & CHANNEL_OPACITY {
        0 => Ok(volume),
        _ => volume.with_opacity(floats(rest)),
    }
}

/// Whether the `.mbvol` file at `path` holds an opacity channel (a translucent medium), from
/// its validated header alone.
pub fn has_opacity(path: &Path, limits: &Limits) -> Result<bool> {
    let (_, _, channels) = open_checked(path, limits)?;
    Ok(channels & CHANNEL_OPACITY != 0)
}

/// Reads a `.mbvol` file, checking its header and size against the limit before reading the
/// payload.
pub fn read(path: &Path, limits: &Limits) -> Result<Volume> {
    use std::io::Read;
    let (mut file, mut bytes, _) = open_checked(path, limits)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    bytes.reserve_exact((len as usize).saturating_sub(HEADER_BYTES));
    file.read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    decode(&bytes, limits)
}

/// Opens the `.mbvol` file at `path` and validates its header against the file's size and
/// `limits`; returns the file (positioned after the header), the header and its channels.
fn open_checked(path: &Path, limits: &Limits) -> Result<(std::fs::File, Vec<u8>, u32)> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut header = vec![0u8; HEADER_BYTES.min(len as usize)];
    file.read_exact(&mut header)
        .map_err(|e| Error::io(path, e))?;
    let (_, channels, _) = parse_header(&header, len, limits)?;
    Ok((file, header, channels))
}

/// Writes `volume` to `path` atomically (temporary file, then rename).
pub fn write(volume: &Volume, path: &Path) -> Result<()> {
    mesobake_core::fs::write_atomic(path, &encode(volume))
}
