//! The paper's matrix layouts of baked data, read as [`RowSource`]s without a copy.

use super::svd::{BlockOrder, RowSource};
use crate::gdm::{EscapeConvention, Gdm};
use mesobake_core::error::{Error, Result};

/// The GDM as a matrix with rows (x, y, φ) and columns (θ, z): row r = (b·Y + j)·X + i,
/// column c = a·Z + k, so that weight maps are 3D textures W(x, y, φ) (x fastest) and
/// eigenmaps 2D textures E(z, θ) (z fastest).
pub struct GdmRows<'a> {
    gdm: &'a Gdm,
}

impl<'a> GdmRows<'a> {
    /// Wraps `gdm`, which must hold finite values (escapes replaced by the boundary distance).
    pub fn new(gdm: &'a Gdm) -> Result<Self> {
        if gdm.escape_convention() != EscapeConvention::Boundary {
            return Err(Error::InvalidParameter(
                "compress the GDM with escapes replaced by the boundary distance".into(),
            ));
        }
        Ok(GdmRows { gdm })
    }
}

impl RowSource for GdmRows<'_> {
    fn rows(&self) -> usize {
        let (d, dirs) = (self.gdm.dims(), self.gdm.dirs());
        (d.x * d.y * dirs.n_phi) as usize
    }

    fn cols(&self) -> usize {
        (self.gdm.dirs().n_theta * self.gdm.dims().z) as usize
    }

    fn read_block(&self, start: usize, out: &mut [f32]) -> BlockOrder {
        let (d, dirs) = (self.gdm.dims(), self.gdm.dirs());
        let (layer, z) = ((d.x * d.y) as usize, d.z as usize);
        let (n, n_phi) = (self.cols(), dirs.n_phi as usize);
        let data = self.gdm.data();
        let count = out.len() / n;
        // Column by column: runs of rows sharing one φ are contiguous in every column's
        // source, while row-major order would touch a new cache line per value.
        let mut r = start;
        while r < start + count {
            let (b, texel) = (r / layer, r % layer);
            let run = (layer - texel).min(start + count - r);
            for a in 0..dirs.n_theta as usize {
                for k in 0..z {
                    let c = a * z + k;
                    let src = &data[((a * n_phi + b) * z + k) * layer + texel..][..run];
                    out[c * count + r - start..][..run].copy_from_slice(src);
                }
            }
            r += run;
        }
        BlockOrder::ColumnMajor
    }
}
