//! The radiance-transfer sections of a package (see `docs/package-format.md`): the compressed
//! RTV ([`CompressedRtv`]) as a sample-index volume, a weight buffer and an eigenfunction
//! texture, and the macro-scale PRT as one buffer of 16×16 matrices.

use super::Package;
use super::manifest::{GiInfo, Section, TexelFormat, Texture, TextureDimension};
use crate::bake::gi::compressed_rtv::{CompressedRtv, MATRICES};
use crate::bake::gi::prt::geometry_hash;
use crate::bake::gi::sh::{COEFFS, ShMatrix};
use crate::error::{Error, Result};
use crate::grid::{Dims, DirectionGrid};
use crate::surface::base_mesh::BaseMesh;
use half::f16;

/// Section holding the sample index of every voxel (`u32::MAX`: not a sample).
pub const RTV_INDEX: &str = "rtv.index";
/// Section holding the weights of every sample, matrix and component.
pub const RTV_WEIGHTS: &str = "rtv.weights";
/// Section holding the eigenfunctions over the view bins.
pub const RTV_EIGEN: &str = "rtv.eigen";
/// Section holding the per-vertex PRT matrices.
pub const PRT_TRANSFER: &str = "prt.transfer";

/// What a package holds for global illumination besides the GDM.
pub struct GiPayload<'a> {
    /// Its manifest entry.
    pub info: GiInfo,
    /// The compressed RTV.
    pub rtv: &'a CompressedRtv,
    /// The PRT matrix of every base-mesh vertex.
    pub prt: &'a [ShMatrix],
}

/// The four GI sections' textures for `info` on the package's grids, in file order.
pub(super) fn textures(
    info: &GiInfo,
    dims: Dims,
    dirs: DirectionGrid,
) -> [(&'static str, Texture); 4] {
    let texture = |dimension, format, width, height, depth| Texture {
        dimension,
        format,
        width,
        height,
        depth,
    };
    use TexelFormat::{R16float, R32float, R32uint};
    use TextureDimension::{Buffer, D3};
    let per_sample = (MATRICES * info.compression.rank) as u32;
    let eigen = per_sample.saturating_mul(dirs.n_theta * dirs.n_phi);
    [
        (RTV_INDEX, texture(D3, R32uint, dims.x, dims.y, dims.z)),
        (
            RTV_WEIGHTS,
            texture(
                Buffer,
                R16float,
                info.samples.saturating_mul(per_sample),
                1,
                1,
            ),
        ),
        (RTV_EIGEN, texture(Buffer, R16float, eigen, 1, 1)),
        (
            PRT_TRANSFER,
            texture(
                Buffer,
                R32float,
                info.vertices.saturating_mul((COEFFS * COEFFS) as u32),
                1,
                1,
            ),
        ),
    ]
}

/// The GI sections of `gi` with their bytes, in file order.
pub(super) fn sections(gi: &GiPayload, dims: Dims, dirs: DirectionGrid) -> Vec<(Section, Vec<u8>)> {
    let halves = |values: &[f32]| -> Vec<u8> {
        values
            .iter()
            .flat_map(|&v| f16::from_f32(v).to_le_bytes())
            .collect()
    };
    let payloads = [
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
    ];
    textures(&gi.info, dims, dirs)
        .into_iter()
        .zip(payloads)
        .map(|((name, texture), bytes)| (Section::new(name, texture), bytes))
        .collect()
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
