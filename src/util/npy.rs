//! Export of a GDM (and of any float32 array, such as a VDM) as a NumPy `.npy` file (format version 1.0): little-endian float32,
//! C order, shape (X, Y, Z, Nθ, Nφ), distances in voxel units, escapes as +inf, inside solid
//! as 0. See [`crate::grid`] for where samples and directions sit.

use crate::bake::gdm::Gdm;
use crate::error::Result;
use std::io::Write;
use std::path::Path;

/// Writes `gdm` to `path`. Escapes are written as +inf unless the GDM is in the boundary
/// convention, whose boundary distances are then written as they are.
pub fn write_gdm(gdm: &Gdm, path: &Path) -> Result<()> {
    crate::util::fs::write_atomic_with(path, |w| write_gdm_to(gdm, w))
}

/// Writes `values`, a C-order float32 array of `shape`, to `path`.
pub fn write_array(path: &Path, shape: &[u64], values: &[f32]) -> Result<()> {
    debug_assert_eq!(shape.iter().product::<u64>(), values.len() as u64);
    crate::util::fs::write_atomic_with(path, |w| {
        w.write_all(&header(shape))?;
        for chunk in values.chunks(1 << 16) {
            let bytes: Vec<u8> = chunk.iter().flat_map(|v| v.to_le_bytes()).collect();
            w.write_all(&bytes)?;
        }
        Ok(())
    })
}

/// The `.npy` header for a little-endian float32 C-order array of `shape`.
fn header(shape: &[u64]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}), }}",
        dims.join(", ") + if shape.len() == 1 { "," } else { "" }
    );
    // magic (6) + version (2) + length (2) + dict + padding + '\n' is a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let padding = unpadded.next_multiple_of(64) - unpadded;
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend_from_slice(&((dict.len() + padding + 1) as u16).to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.extend(std::iter::repeat_n(b' ', padding));
    h.push(b'\n');
    h
}

/// Writes the `.npy` bytes of `gdm` to `out`. The direction-major layout is transposed a
/// block of x-slices at a time, with a block buffer of at most an eighth of the GDM.
pub fn write_gdm_to(gdm: &Gdm, out: &mut impl Write) -> std::io::Result<()> {
    let dims = gdm.dims();
    let dirs = gdm.dirs();
    out.write_all(&header(&[
        dims.x as u64,
        dims.y as u64,
        dims.z as u64,
        dirs.n_theta as u64,
        dirs.n_phi as u64,
    ]))?;
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let n_dirs = dirs.count();
    let stride = gdm.direction_stride();
    let block = (nx / 8).clamp(1, 16);
    let slice = ny * nz * n_dirs;
    let mut buf = vec![0f32; block * slice];
    let mut bytes = Vec::with_capacity(slice * 4);
    let data = gdm.data();
    for x0 in (0..nx).step_by(block) {
        let width = block.min(nx - x0);
        for d in 0..n_dirs {
            for z in 0..nz {
                for y in 0..ny {
                    let src = &data[d * stride + (z * ny + y) * nx + x0..][..width];
                    for (xb, &v) in src.iter().enumerate() {
                        buf[xb * slice + (y * nz + z) * n_dirs + d] = v;
                    }
                }
            }
        }
        for xb in 0..width {
            bytes.clear();
            for v in &buf[xb * slice..][..slice] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
            out.write_all(&bytes)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_padded_to_64_bytes() {
        let h = header(&[64, 64, 32, 16, 32]);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(*h.last().unwrap(), b'\n');
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert!(text.contains("'shape': (64, 64, 32, 16, 32)"));
    }
}
