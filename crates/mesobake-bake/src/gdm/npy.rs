//! Export of a GDM as a NumPy `.npy` file: shape (X, Y, Z, Nθ, Nφ), distances in voxel
//! units, escapes as +inf, inside solid as 0. See [`mesobake_package::grid`] for where samples and
//! directions sit.

use super::Gdm;
use mesobake_core::Result;
use mesobake_core::npy::header;
use std::io::Write;
use std::path::Path;

/// Writes `gdm` to `path`. Escapes are written as +inf unless the GDM is in the boundary
/// convention, whose boundary distances are then written as they are.
pub fn write_gdm(gdm: &Gdm, path: &Path) -> Result<()> {
    mesobake_core::fs::write_atomic_with(path, |w| write_gdm_to(gdm, w))
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
