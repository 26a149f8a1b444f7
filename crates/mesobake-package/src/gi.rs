//! The radiance-transfer sections of a package: the compressed RTV as a sample-index volume, a
//! weight buffer and an eigenfunction buffer, and the macro-scale PRT as one buffer of 16×16
//! matrices (see `docs/package-format.md`). [`RadianceTransfer`] is their decoded content.

use crate::GiContent;
use crate::error::{Error, Result};
use crate::grid::{Dims, DirectionGrid};
use crate::manifest::{GiInfo, TexelFormat, Texture, TextureDimension};
use half::f16;

/// Spherical-harmonic coefficients of the light and view bases (order 4).
pub const SH_COEFFS: usize = 16;
/// Matrices per RTV sample: 3 colour channels × [`SH_COEFFS`] light coefficients.
pub const RTV_MATRICES: usize = 3 * SH_COEFFS;
/// Most SVD components per RTV matrix: the view basis has 16 functions, so 16 is exact.
pub const MAX_RTV_RANK: usize = SH_COEFFS;

/// The sample index of a voxel that is not an RTV sample.
pub const NO_SAMPLE: u32 = u32::MAX;

/// Section holding the sample index of every voxel (`u32::MAX`: not a sample).
pub const RTV_INDEX: &str = "rtv.index";
/// Section holding the weights of every sample, matrix and component.
pub const RTV_WEIGHTS: &str = "rtv.weights";
/// Section holding the eigenfunctions over the view bins.
pub const RTV_EIGEN: &str = "rtv.eigen";
/// Section holding the per-vertex PRT matrices.
pub const PRT_TRANSFER: &str = "prt.transfer";

/// The four GI sections' textures for `info` on the package's grids, in file order.
pub fn textures(info: &GiInfo, dims: Dims, dirs: DirectionGrid) -> [(&'static str, Texture); 4] {
    let texture = |dimension, format, width, height, depth| Texture {
        dimension,
        format,
        width,
        height,
        depth,
    };
    use TexelFormat::{R16float, R32float, R32uint};
    use TextureDimension::{Buffer, D3};
    let per_sample = (RTV_MATRICES * info.compression.rank) as u32;
    let eigen = per_sample.saturating_mul(dirs.n_theta * dirs.n_phi);
    let buffer = |format, len| texture(Buffer, format, len, 1, 1);
    [
        (RTV_INDEX, texture(D3, R32uint, dims.x, dims.y, dims.z)),
        (
            RTV_WEIGHTS,
            buffer(R16float, info.samples.saturating_mul(per_sample)),
        ),
        (RTV_EIGEN, buffer(R16float, eigen)),
        (
            PRT_TRANSFER,
            buffer(
                R32float,
                info.vertices.saturating_mul((SH_COEFFS * SH_COEFFS) as u32),
            ),
        ),
    ]
}

/// A package's radiance transfer, decoded from its four sections: the compressed RTV's sample
/// map, weights and eigenfunctions (f16 in the file, widened here), and the PRT matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct RadianceTransfer {
    /// The voxel grid of the sample map.
    pub dims: Dims,
    /// The view grid of the eigenfunctions.
    pub dirs: DirectionGrid,
    /// Components per matrix.
    pub rank: usize,
    /// Per voxel (x fastest), its sample index or [`NO_SAMPLE`].
    pub sample_of: Vec<u32>,
    /// Component k of sample s, matrix m = 16·c + i (channel c, light coefficient i), at
    /// (s·[`RTV_MATRICES`] + m)·rank + k.
    pub weights: Vec<f32>,
    /// Component k of matrix m at view bin (a, b) at (m·Nθ·Nφ + a·Nφ + b)·rank + k.
    pub eigen: Vec<f32>,
    /// The PRT matrix of every base-mesh vertex, row-major [`SH_COEFFS`]², vertex after vertex.
    pub prt: Vec<f32>,
}

impl RadianceTransfer {
    /// The sections of this transfer as the writer takes them, with manifest entry `info`
    /// (weights and eigenfunctions rounded to f16).
    pub fn encode(&self, info: GiInfo) -> GiContent {
        let halves = |values: &[f32]| -> Vec<u8> {
            (values.iter())
                .flat_map(|&v| f16::from_f32(v).to_le_bytes())
                .collect()
        };
        let words = |values: &[u32]| values.iter().flat_map(|v| v.to_le_bytes()).collect();
        GiContent {
            info,
            sections: [
                words(&self.sample_of),
                halves(&self.weights),
                halves(&self.eigen),
                self.prt.iter().flat_map(|v| v.to_le_bytes()).collect(),
            ],
        }
    }

    /// Decodes the four sections (bytes in [`textures`] order, their sizes already checked
    /// against `info` on the grids `dims` and `dirs`) and validates them: every sample index
    /// names one of `info.samples`, every value is finite.
    pub fn decode(
        info: &GiInfo,
        (dims, dirs): (Dims, DirectionGrid),
        sections: [&[u8]; 4],
    ) -> Result<RadianceTransfer> {
        let bad = |what: &str| Err(Error::Package(format!("radiance transfer: {what}")));
        let [index, weights, eigen, prt] = sections;
        let halves = |bytes: &[u8]| -> Vec<f32> {
            (bytes.chunks_exact(2))
                .map(|h| f16::from_le_bytes([h[0], h[1]]).to_f32())
                .collect()
        };
        let words = |bytes: &[u8]| -> Vec<[u8; 4]> {
            (bytes.chunks_exact(4))
                .map(|b| [b[0], b[1], b[2], b[3]])
                .collect()
        };
        let transfer = RadianceTransfer {
            dims,
            dirs,
            rank: info.compression.rank,
            sample_of: words(index).into_iter().map(u32::from_le_bytes).collect(),
            weights: halves(weights),
            eigen: halves(eigen),
            prt: words(prt).into_iter().map(f32::from_le_bytes).collect(),
        };
        if let Some(s) = (transfer.sample_of.iter()).find(|&&s| s != NO_SAMPLE && s >= info.samples)
        {
            return bad(&format!(
                "the sample map names sample {s} of {}",
                info.samples
            ));
        }
        if transfer
            .weights
            .iter()
            .chain(&transfer.eigen)
            .any(|v| !v.is_finite())
        {
            return bad("a weight or eigenfunction value is not finite");
        }
        if transfer.prt.iter().any(|v| !v.is_finite()) {
            return bad("a PRT value is not finite");
        }
        Ok(transfer)
    }

    /// The transfer vector of voxel (i, j, k) towards the centre of view bin (a, b): per
    /// channel c, the weights of the 16 light coefficients, Σₖ Wₘₖ(s)·Eₘₖ(a, b) with
    /// m = 16·c + i; `None` where the voxel is not an RTV sample. Coordinates must lie on the
    /// grids.
    pub fn transfer_at_bin(
        &self,
        [i, j, k]: [u32; 3],
        [a, b]: [u32; 2],
    ) -> Option<[[f32; SH_COEFFS]; 3]> {
        let (dims, dirs, rank) = (self.dims, self.dirs, self.rank);
        let voxel = (k as usize * dims.y as usize + j as usize) * dims.x as usize + i as usize;
        let s = self.sample_of[voxel];
        if s == NO_SAMPLE {
            return None;
        }
        let views = dirs.n_theta as usize * dirs.n_phi as usize;
        let view = (a * dirs.n_phi + b) as usize;
        let weights = &self.weights[s as usize * RTV_MATRICES * rank..][..RTV_MATRICES * rank];
        Some(std::array::from_fn(|c| {
            std::array::from_fn(|l| {
                let m = c * SH_COEFFS + l;
                let eigen = &self.eigen[(m * views + view) * rank..][..rank];
                (weights[m * rank..][..rank].iter().zip(eigen))
                    .map(|(w, e)| w * e)
                    .sum()
            })
        }))
    }

    /// The PRT matrix of base-mesh vertex `vertex` (row-major), `None` past the last vertex.
    pub fn prt_matrix(&self, vertex: usize) -> Option<&[f32]> {
        let n = SH_COEFFS * SH_COEFFS;
        self.prt.get(vertex * n..(vertex + 1) * n)
    }
}
