//! The radiance-transfer sections of a package (see `docs/package-format.md`): the compressed
//! RTV ([`CompressedRtv`]) as a sample-index volume, a weight buffer and an eigenfunction
//! texture, and the macro-scale PRT as one buffer of 16×16 matrices.

use super::Package;
use super::manifest::GiInfo;
use crate::gi::compressed_rtv::CompressedRtv;
use crate::gi::prt::geometry_hash;
use crate::gi::sh::{COEFFS, ShMatrix};
use crate::surface::base_mesh::BaseMesh;
use mesobake_core::error::{Error, Result};
use mesobake_package::GiContent;
use mesobake_package::gi::RadianceTransfer;

pub use mesobake_package::gi::{PRT_TRANSFER, RTV_EIGEN, RTV_INDEX, RTV_WEIGHTS};

/// What a package holds for global illumination besides the GDM.
pub struct GiPayload<'a> {
    /// Its manifest entry.
    pub info: GiInfo,
    /// The compressed RTV.
    pub rtv: &'a CompressedRtv,
    /// The PRT matrix of every base-mesh vertex.
    pub prt: &'a [ShMatrix],
}

/// The GI sections of `gi` as the format crate's writer takes them.
pub(super) fn content(gi: &GiPayload) -> GiContent {
    RadianceTransfer {
        dims: gi.rtv.dims(),
        dirs: gi.rtv.dirs(),
        rank: gi.rtv.rank(),
        sample_of: gi.rtv.sample_map().to_vec(),
        weights: gi.rtv.weights().to_vec(),
        eigen: gi.rtv.eigen().to_vec(),
        prt: gi
            .prt
            .iter()
            .flatten()
            .flatten()
            .map(|&v| v as f32)
            .collect(),
    }
    .encode(gi.info.clone())
}

impl Package {
    /// The compressed RTV and the PRT matrices, for rendering on `base` (which must be the
    /// base mesh the PRT was baked for). An error when the package holds no GI sections.
    pub fn gi(&self, base: &BaseMesh) -> Result<(CompressedRtv, Vec<ShMatrix>)> {
        let info = self.manifest().gi.as_ref().ok_or_else(|| {
            Error::Package(
                "the package holds no radiance transfer: bake it from a scene that calls for \
                 environment_lighting (mesobake bake --scene)"
                    .into(),
            )
        })?;
        let hash = geometry_hash(base);
        if info.base_mesh != hash || info.vertices as usize != base.positions.len() {
            return Err(Error::Package(format!(
                "the package's PRT belongs to another base mesh ({} vertices, geometry {}), \
                 not this one ({} vertices, geometry {hash})",
                info.vertices,
                info.base_mesh,
                base.positions.len()
            )));
        }
        let transfer = self.radiance_transfer().expect("checked above")?;
        let rtv = CompressedRtv::from_parts(
            self.dims(),
            self.dirs(),
            transfer.rank,
            transfer.sample_of,
            transfer.weights,
            transfer.eigen,
        )?;
        let prt = transfer
            .prt
            .chunks_exact(COEFFS * COEFFS)
            .map(|m| std::array::from_fn(|i| std::array::from_fn(|j| f64::from(m[i * COEFFS + j]))))
            .collect();
        Ok((rtv, prt))
    }
}
