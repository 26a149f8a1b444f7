//! The radiance-transfer sections of a package (see `docs/package-format.md`): the compressed
//! RTV ([`CompressedRtv`]) as a sample-index volume, a weight buffer and an eigenfunction
//! texture, and the macro-scale PRT as one buffer of 16×16 matrices.

use super::Package;
use super::manifest::GiInfo;
use crate::gi::compressed_rtv::CompressedRtv;
use crate::gi::prt::geometry_hash;
use crate::gi::sh::{COEFFS, ShMatrix};
use crate::surface::base_mesh::BaseMesh;
use half::f16;
use mesobake_core::error::{Error, Result};
use mesobake_package::GiContent;

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
    let halves = |values: &[f32]| -> Vec<u8> {
        values
            .iter()
            .flat_map(|&v| f16::from_f32(v).to_le_bytes())
            .collect()
    };
    GiContent {
        info: gi.info.clone(),
        sections: [
            gi.rtv
                .sample_map()
                .iter()
                .flat_map(|s| s.to_le_bytes())
                .collect(),
            halves(gi.rtv.weights()),
            halves(gi.rtv.eigen()),
            gi.prt
                .iter()
                .flatten()
                .flatten()
                .flat_map(|&v| (v as f32).to_le_bytes())
                .collect(),
        ],
    }
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
        let section = |name| self.section(name).expect("validated by parse");
        let halves = |bytes: &[u8]| -> Vec<f32> {
            bytes
                .chunks_exact(2)
                .map(|h| f16::from_le_bytes([h[0], h[1]]).to_f32())
                .collect()
        };
        let sample_of = section(RTV_INDEX)
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let rtv = CompressedRtv::from_parts(
            self.dims(),
            self.dirs(),
            info.compression.rank,
            sample_of,
            halves(section(RTV_WEIGHTS)),
            halves(section(RTV_EIGEN)),
        )?;
        let values: Vec<f64> = section(PRT_TRANSFER)
            .chunks_exact(4)
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            .collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(Error::Package("a PRT value is not finite".into()));
        }
        let prt = values
            .chunks_exact(COEFFS * COEFFS)
            .map(|m| std::array::from_fn(|i| std::array::from_fn(|j| m[i * COEFFS + j])))
            .collect();
        Ok((rtv, prt))
    }
}
