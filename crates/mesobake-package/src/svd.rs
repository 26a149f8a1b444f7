//! The `paper-svd` codec: the GDM as one truncated SVD, weight maps W(x, y, φ) (3D textures)
//! times eigenmaps E(z, θ) (2D textures), four components per texture. This module lays the
//! factors out as textures, checks a manifest's entry against them, and reconstructs the GDM
//! with the package's escape rule.

use crate::container::Section;
use crate::error::{Error, Result};
use crate::grid::{Dims, DirectionGrid, boundary_distance};
use crate::manifest::{Accuracy, FactorInfo, GdmInfo, RankChoice};
use crate::quantize::{Quantization, QuantizedFactor};
use crate::texture::{CHANNELS, TexelFormat, Texture, TextureDimension};
use rayon::prelude::*;

/// Largest relative escape margin μ a package may hold.
pub const MAX_ESCAPE_MARGIN: f32 = 0.5;

/// Whether a reconstructed value `d` at boundary distance `boundary` is an escape under the
/// package's relative `margin` μ: d ≥ (1 − μ)·b. Reconstruction blurs the boundary distance
/// that compressed GDMs store for escapes both ways, hence the margin.
pub fn is_escape(d: f32, boundary: f32, margin: f32) -> bool {
    d >= (1.0 - margin) * boundary
}

/// What the writer needs of a compressed GDM.
#[derive(Clone, Copy, Debug)]
pub struct SvdFactors<'a> {
    /// How the rank was chosen.
    pub rank_choice: RankChoice,
    /// All singular values of the GDM matrix, descending.
    pub spectrum: &'a [f64],
    /// W, rows (φ, y, x) × rank, quantized.
    pub weights: &'a QuantizedFactor,
    /// E, rows (θ, z) × rank, quantized like `weights`.
    pub eigen: &'a QuantizedFactor,
    /// Error of the quantized reconstruction, with the escape margin.
    pub accuracy: Accuracy,
    /// The optimal (unquantized) rank-k RMSE.
    pub svd_rmse: f64,
}

/// The texture holding components 4g..4g+3 of a rank-`rank` factor quantized with `q`:
/// weight maps as 3D textures W(x, y, φ), eigenmaps as 2D textures E(z, θ); the last group
/// in the narrowest format that holds what is left (r, rg or rgba).
pub fn factor_texture(
    weights: bool,
    q: Quantization,
    rank: usize,
    group: usize,
    dims: Dims,
    dirs: DirectionGrid,
) -> Texture {
    let format = TexelFormat::of(q, rank - group * CHANNELS);
    let (dimension, width, height, depth) = if weights {
        (TextureDimension::D3, dims.x, dims.y, dirs.n_phi)
    } else {
        (TextureDimension::D2, dims.z, dirs.n_theta, 1)
    };
    Texture {
        dimension,
        format,
        width,
        height,
        depth,
    }
}

/// The sections (with their bytes) and the manifest entry of `svd`.
pub(crate) fn sections(
    svd: &SvdFactors,
    dims: Dims,
    dirs: DirectionGrid,
) -> (GdmInfo, Vec<(Section, Vec<u8>)>) {
    let (q, rank) = (svd.weights.format, svd.weights.rank);
    let groups = rank.div_ceil(CHANNELS);
    let mut out = Vec::new();
    let mut factor_info = |name: &str, factor: &QuantizedFactor, weights: bool| {
        let names: Vec<String> = (0..groups).map(|g| format!("gdm.{name}.{g}")).collect();
        for (g, section) in names.iter().enumerate() {
            let texture = factor_texture(weights, q, rank, g, dims, dirs);
            let bytes = factor.pack_group(0..factor.rows, rank, g, &texture);
            out.push((Section::new(section, texture), bytes));
        }
        FactorInfo {
            sections: names,
            scale: factor.scale.clone(),
            bias: factor.bias.clone(),
        }
    };
    let weights = factor_info("weights", svd.weights, true);
    let eigen = factor_info("eigen", svd.eigen, false);
    let info = GdmInfo {
        rank_choice: svd.rank_choice,
        rank: rank as u32,
        spectrum: svd.spectrum.to_vec(),
        quantization: q,
        weights,
        eigen,
        accuracy: svd.accuracy,
        svd_rmse: svd.svd_rmse,
    };
    (info, out)
}

/// Checks the manifest entry of a compressed GDM against the grids and the sections.
pub(crate) fn validate(
    g: &GdmInfo,
    sections: &[Section],
    dims: Dims,
    dirs: DirectionGrid,
    bad: impl Fn(String) -> Error,
) -> Result<()> {
    let (m, n) = (
        dims.x as u64 * dims.y as u64 * dirs.n_phi as u64,
        dims.z as u64 * dirs.n_theta as u64,
    );
    let rank = g.rank as usize;
    if g.rank as u64 > m.min(n) {
        return Err(bad(format!("rank {} exceeds the matrix's {m}×{n}", g.rank)));
    }
    if g.spectrum.len() as u64 != m.min(n)
        || g.spectrum.iter().any(|s| !(s.is_finite() && *s >= 0.0))
        || g.spectrum.windows(2).any(|w| w[1] > w[0])
    {
        return Err(bad(
            "the spectrum must hold min(m, n) finite values ≥ 0, descending".into(),
        ));
    }
    if let RankChoice::MaxRmse(r) = g.rank_choice
        && !(r.is_finite() && r >= 0.0)
    {
        return Err(bad(format!(
            "the rank choice's max_rmse {r} is not finite ≥ 0"
        )));
    }
    let a = &g.accuracy;
    if ![a.rmse, a.max_abs, a.flip_rate, g.svd_rmse]
        .iter()
        .all(|v| v.is_finite() && *v >= 0.0)
        || a.flips > a.samples
    {
        return Err(bad(
            "the accuracy (rmse, max_abs, flip_rate, svd_rmse, flips of samples) must hold \
             finite values ≥ 0"
                .into(),
        ));
    }
    if !(0.0..=MAX_ESCAPE_MARGIN).contains(&a.escape_margin) {
        return Err(bad(format!("escape margin {} is invalid", a.escape_margin)));
    }
    for (name, info, weights) in [("weights", &g.weights, true), ("eigen", &g.eigen, false)] {
        if info.sections.len() != rank.div_ceil(CHANNELS)
            || info.scale.len() != rank
            || info.bias.len() != rank
            || info.scale.iter().chain(&info.bias).any(|v| !v.is_finite())
        {
            return Err(bad(format!(
                "the {name} factor must list {} sections and {rank} finite scales and biases",
                rank.div_ceil(CHANNELS)
            )));
        }
        for (group, section) in info.sections.iter().enumerate() {
            let expected = factor_texture(weights, g.quantization, rank, group, dims, dirs);
            crate::expect_section(sections, section, expected, &bad)?;
        }
    }
    Ok(())
}

/// A decoded `paper-svd` GDM: d(i, j, k, a, b) = Σ_c W_c(i, j, b) · E_c(k, a), with the escape
/// rule of its package.
#[derive(Clone, Debug)]
pub struct SvdGdm {
    dims: Dims,
    dirs: DirectionGrid,
    rank: usize,
    /// W, rows (b·Y + j)·X + i, `rank` values each.
    weights: Vec<f32>,
    /// E, rows a·Z + k, `rank` values each.
    eigen: Vec<f32>,
    margin: f32,
}

impl SvdGdm {
    /// Decodes quantized factors on the grids `dims` × `dirs` with escape margin `margin`.
    pub fn new(
        dims: Dims,
        dirs: DirectionGrid,
        weights: &QuantizedFactor,
        eigen: &QuantizedFactor,
        margin: f32,
    ) -> SvdGdm {
        SvdGdm {
            dims,
            dirs,
            rank: weights.rank,
            weights: weights.dequantize(),
            eigen: eigen.dequantize(),
            margin,
        }
    }

    /// The reconstructed value at voxel centre (i, j, k) along direction bin (a, b), in the
    /// boundary convention: an escape reads about its boundary distance.
    pub fn value(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> f32 {
        let (d, k_) = (self.dims, self.rank);
        let row = (b as usize * d.y as usize + j as usize) * d.x as usize + i as usize;
        let col = a as usize * d.z as usize + k as usize;
        let w = &self.weights[row * k_..][..k_];
        let e = &self.eigen[col * k_..][..k_];
        w.iter().zip(e).map(|(w, e)| w * e).sum()
    }

    /// The distance to the mesostructure from voxel centre (i, j, k) along direction bin
    /// (a, b) (θ_a, φ_b as [`DirectionGrid`] defines them), or `None` for an escape.
    pub fn distance(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> Option<f32> {
        let d = self.value(i, j, k, a, b);
        let boundary = boundary_distance(self.dims, &self.dirs, k, a);
        (!is_escape(d, boundary, self.margin)).then_some(d.max(0.0))
    }

    /// Every reconstructed value in the boundary convention, direction-major:
    /// `[((a·Nφ + b)·Z + k)·Y·X + j·X + i]`.
    pub fn values(&self) -> Vec<f32> {
        let (dims, dirs) = (self.dims, self.dirs);
        let stride = dims.voxel_count() as usize;
        let layer = (dims.x * dims.y) as usize;
        let mut values = vec![0.0f32; stride * dirs.count()];
        values
            .par_chunks_mut(layer)
            .enumerate()
            .for_each(|(l, out)| {
                let (d, k) = (l / dims.z as usize, (l % dims.z as usize) as u32);
                let (a, b) = (
                    (d / dirs.n_phi as usize) as u32,
                    (d % dirs.n_phi as usize) as u32,
                );
                for (t, v) in out.iter_mut().enumerate() {
                    let (i, j) = ((t % dims.x as usize) as u32, (t / dims.x as usize) as u32);
                    *v = self.value(i, j, k, a, b);
                }
            });
        values
    }

    /// The escape margin μ.
    pub fn escape_margin(&self) -> f32 {
        self.margin
    }
}
