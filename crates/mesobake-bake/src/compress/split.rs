//! The split GDM: one representation per question the renderer asks (the packages issue's
//! third candidate). The primary query only asks whether the fragment's texture-space segment
//! hits solid, and that segment is never longer than the longest segment a prism of the
//! scene can hold (`mesobake_render::prepared_prism::longest_segment`): its distances are capped there
//! (escapes and farther hits alike become the cap) and compressed by SVD in the paper's layout
//! or in tiles ([`compress_tiled`]). The shadow query only asks hit-or-escape: one bit per
//! sample of an exact GDM baked at a reduced direction resolution, interpolated by the raw
//! lookup's vote. Evaluated in `mesobake report codecs`; not a package codec.

use super::tiled::{TiledSvd, compress_tiled};
use crate::compress::quantize::Quantization;
use crate::gdm::{EscapeConvention, Gdm};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;

/// Reconstructed capped distances this close to the cap (voxels) or closer read as "no hit
/// within the cap": the compression blurs the cap both ways, and a segment reaches the cap
/// only at a prism's longest diagonal.
pub const CAP_MARGIN: f32 = 0.5;

/// A GDM split into capped primary distances and shadow escape bits.
pub struct SplitGdm {
    /// The cap, voxels.
    pub cap: f32,
    /// The capped distances' SVD; its reconstruction holds +∞ where no hit lies within
    /// `cap − CAP_MARGIN`.
    pub primary: TiledSvd,
    /// The shadow query's samples (infinite convention): 0 where the exact GDM hits, +∞ where
    /// it escapes. A package would store one bit each.
    pub visibility: Gdm,
}

impl SplitGdm {
    /// Bytes a package would take: the primary's factors and one bit per visibility sample.
    pub fn bytes(&self) -> u64 {
        self.primary.bytes() + (self.visibility.data().len() as u64).div_ceil(8)
    }
}

/// Splits `gdm` (boundary convention, the scene's direction grid): its distances capped at
/// `cap` and compressed in tiles of `tile` texels (the grid's width: one global basis, the
/// paper's layout) at rank `rank`, `quantization`; and the escape bits of `shadow` (the exact
/// GDM of the same voxels at the visibility's direction grid, either convention).
pub fn compress_split(
    gdm: &Gdm,
    cap: f32,
    (tile, rank, quantization): (u32, usize, Quantization),
    shadow: &Gdm,
    limits: &Limits,
) -> Result<SplitGdm> {
    if !(cap > CAP_MARGIN && cap.is_finite()) {
        return Err(Error::InvalidParameter(format!(
            "the distance cap {cap} is not a positive length"
        )));
    }
    if shadow.dims() != gdm.dims() {
        return Err(Error::InvalidParameter(format!(
            "the visibility grid {} is not the GDM's {}",
            shadow.dims(),
            gdm.dims()
        )));
    }
    let capped = Gdm::from_values(
        gdm.dims(),
        gdm.dirs(),
        EscapeConvention::Boundary,
        gdm.data().iter().map(|&d| d.min(cap)).collect(),
    )?;
    let mut primary = compress_tiled(&capped, tile, rank, quantization, limits)?;
    let recon = &primary.reconstruction;
    let values = (recon.data().iter())
        .map(|&d| {
            if d >= cap - CAP_MARGIN {
                f32::INFINITY
            } else {
                d
            }
        })
        .collect();
    primary.reconstruction = Gdm::from_values(
        recon.dims(),
        recon.dirs(),
        EscapeConvention::Infinite,
        values,
    )?;
    let visibility = Gdm::from_values(
        shadow.dims(),
        shadow.dirs(),
        EscapeConvention::Infinite,
        (0..shadow.data().len())
            .map(|n| {
                let (a, b, k, j, i) = unflatten(shadow, n);
                if shadow.is_escape(i, j, k, a, b) {
                    f32::INFINITY
                } else {
                    0.0
                }
            })
            .collect(),
    )?;
    Ok(SplitGdm {
        cap,
        primary,
        visibility,
    })
}

/// The (θ bin, φ bin, layer, row, column) of flat sample `n` of `gdm`.
fn unflatten(gdm: &Gdm, n: usize) -> (u32, u32, u32, u32, u32) {
    let (dims, n_phi) = (gdm.dims(), gdm.dirs().n_phi as usize);
    let (d, v) = (n / gdm.direction_stride(), n % gdm.direction_stride());
    let (x, y) = (dims.x as usize, dims.y as usize);
    (
        (d / n_phi) as u32,
        (d % n_phi) as u32,
        (v / (x * y)) as u32,
        (v / x % y) as u32,
        (v % x) as u32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gdm::volume_caster::VolumeCaster;
    use crate::mesostructure::samples::{SampleKind, volume};
    use mesobake_package::grid::{Dims, DirectionGrid};

    fn chain_gdm(dirs: DirectionGrid) -> Gdm {
        let limits = Limits::default();
        let v = volume(SampleKind::Chain, Dims::new(16, 16, 8).unwrap(), &limits).unwrap();
        crate::gdm::exact::bake(&VolumeCaster::new(&v), dirs, &limits, &()).unwrap()
    }

    #[test]
    fn full_rank_split_answers_like_the_exact_gdm_below_the_cap() {
        let limits = Limits::default();
        let dirs = DirectionGrid::new(4, 8).unwrap();
        let exact = chain_gdm(dirs);
        let mut boundary = exact.clone();
        boundary.set_escape_convention(EscapeConvention::Boundary);
        let coarse = chain_gdm(DirectionGrid::new(2, 4).unwrap());
        let cap = 6.0;
        // Rank 32 is full rank for tiles of 8 (see `tiled`): exact up to f32 round-off.
        let split =
            compress_split(&boundary, cap, (8, 32, Quantization::F32), &coarse, &limits).unwrap();
        let (mut below, mut beyond) = (0, 0);
        for (&e, &r) in exact.data().iter().zip(split.primary.reconstruction.data()) {
            if e < cap - CAP_MARGIN - 1e-3 {
                below += 1;
                assert!((e - r).abs() < 1e-3, "{e} reconstructed as {r}");
            } else if e > cap - CAP_MARGIN + 1e-3 {
                beyond += 1;
                assert_eq!(r, f32::INFINITY, "{e} reconstructed as {r}");
            }
        }
        assert!(
            below > 1000 && beyond > 1000,
            "{below} below, {beyond} beyond"
        );
        // One bit per coarse sample, set exactly where the coarse GDM escapes.
        assert_eq!(split.visibility.dirs(), coarse.dirs());
        for (&c, &v) in coarse.data().iter().zip(split.visibility.data()) {
            assert_eq!(c.is_infinite(), v.is_infinite());
        }
        let bits = coarse.data().len() as u64 / 8;
        assert_eq!(split.bytes(), split.primary.bytes() + bits);
        assert!(
            compress_split(&boundary, 0.1, (8, 4, Quantization::F16), &coarse, &limits).is_err()
        );
    }
}
