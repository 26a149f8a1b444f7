//! VDM packages (`format` `"mesobake-vdm-package"`): a compressed view-dependent displacement
//! map d(x, y, θ, φ, c) with its maximal view polar angle map θ_MVM(x, y, φ, c), as the paper
//! stores them: one truncated SVD with shared weights, weight maps W(x, y, φ) as 3D textures,
//! the VDM's eigenmaps E(θ, c) and the MVM's E(c) as 2D textures, four components per texture.
//! The same container as GDM packages ([`crate::container`]); the byte-exact format is
//! specified in mesobake's `docs/package-format.md`.
//!
//! Units are tile units: the tile is 1 × 1 in texture space, distances and the relief's depth
//! are fractions of its edge, curvatures are in 1/tile.

use crate::container::{self, ContainerManifest, Contents};
use crate::error::{Error, Result};
use crate::manifest::{FactorInfo, InputInfo, Section, TexelFormat, Texture, TextureDimension};
use crate::quantize::{Quantization, QuantizedFactor};
use crate::texture::CHANNELS;
use std::f64::consts::{FRAC_PI_2, TAU};
use std::path::Path;

/// The value of [`VdmManifest::format`].
pub const VDM_FORMAT_NAME: &str = "mesobake-vdm-package";

/// The section of the height field.
pub const HEIGHT_SECTION: &str = "vdm.height";

/// Largest accepted direction or curvature count.
pub const MAX_AXIS: u32 = 1024;

/// Largest accepted height-field side (texels).
pub const MAX_SIDE: u32 = 16384;

/// Largest accepted oversampling of the paper's bake.
pub const MAX_OVERSAMPLING: u32 = 64;

/// Largest rank of a VDM factorization.
pub const MAX_VDM_RANK: usize = 64;

/// Smallest magnitude of a curvature other than 0 (1/tile): a surface bent less, of radius
/// over a million tiles, is flat for any use, and its radius 1/c would magnify rounding in
/// the bakes' formulas (R − (R − D)·x loses about 2·10⁻¹⁶·R to cancellation).
pub const MIN_CURVATURE: f64 = 1e-6;

/// The view and curvature sampling of a VDM: θ_a = (a + ½)·(π/2)/Nθ from the inward normal,
/// φ_b = (b + ½)·2π/Nφ, curvatures evenly from `c_min` to `c_max` (1/tile, positive convex).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmGrid {
    /// Polar angles over (0, π/2).
    pub n_theta: u32,
    /// Azimuths over (0, 2π).
    pub n_phi: u32,
    /// Curvatures from `c_min` to `c_max`.
    pub n_curvature: u32,
    /// The smallest curvature (1/tile).
    pub c_min: f64,
    /// The largest curvature (1/tile).
    pub c_max: f64,
}

impl VdmGrid {
    /// The paper's grid: 8 θ × 32 φ view directions, 16 curvatures from −2 to 3.
    pub const PAPER: VdmGrid = VdmGrid {
        n_theta: 8,
        n_phi: 32,
        n_curvature: 16,
        c_min: -2.0,
        c_max: 3.0,
    };

    /// Checks the counts (1 to [`MAX_AXIS`]), the curvature range (finite, ordered), that
    /// every curvature is 0 or at least [`MIN_CURVATURE`] from it, and that no curvature
    /// folds a relief of `depth`: |c|·depth < 1.
    pub fn validate(&self, depth: f64) -> Result<()> {
        for (name, n) in [
            ("θ", self.n_theta),
            ("φ", self.n_phi),
            ("curvature", self.n_curvature),
        ] {
            if n == 0 || n > MAX_AXIS {
                return Err(Error::InvalidParameter(format!(
                    "VDM grid: the {name} count must be 1 to {MAX_AXIS}, got {n}"
                )));
            }
        }
        if !(self.c_min.is_finite() && self.c_max.is_finite() && self.c_min <= self.c_max) {
            return Err(Error::InvalidParameter(format!(
                "VDM grid: curvatures {} to {} are not a finite, ordered range",
                self.c_min, self.c_max
            )));
        }
        if let Some(c) = self
            .curvatures()
            .into_iter()
            .find(|c| *c != 0.0 && c.abs() < MIN_CURVATURE)
        {
            return Err(Error::InvalidParameter(format!(
                "VDM grid: curvature {c:e} is too close to 0 to bend (|c| must be 0 or at least \
                 {MIN_CURVATURE:e} per tile; 0 is the flat surface)"
            )));
        }
        let worst = self.c_min.abs().max(self.c_max.abs());
        if worst * depth >= 1.0 {
            return Err(Error::InvalidParameter(format!(
                "VDM grid: curvature {worst} bends a relief {depth} deep past the centre of \
                 curvature (|c|·depth must stay below 1)"
            )));
        }
        Ok(())
    }

    /// Polar angle of bin `a`: (a + ½)·(π/2)/Nθ.
    pub fn theta(&self, a: u32) -> f64 {
        (f64::from(a) + 0.5) * FRAC_PI_2 / f64::from(self.n_theta)
    }

    /// Every bin's polar angle, in order.
    pub fn thetas(&self) -> Vec<f64> {
        (0..self.n_theta).map(|a| self.theta(a)).collect()
    }

    /// Every curvature, in order.
    pub fn curvatures(&self) -> Vec<f64> {
        (0..self.n_curvature).map(|k| self.curvature(k)).collect()
    }

    /// Azimuth of bin `b`: (b + ½)·2π/Nφ.
    pub fn phi(&self, b: u32) -> f64 {
        (f64::from(b) + 0.5) * TAU / f64::from(self.n_phi)
    }

    /// Curvature `k`: evenly from `c_min` to `c_max` (`c_min` when there is one); exactly 0
    /// where the spacing puts it within rounding of 0 (a few units in the last place of the
    /// range's ends: −0.1 to 0.2 in 4 samples gives 1.4·10⁻¹⁷ for the flat one).
    pub fn curvature(&self, k: u32) -> f64 {
        if self.n_curvature == 1 {
            return self.c_min;
        }
        let c =
            self.c_min + (self.c_max - self.c_min) * f64::from(k) / f64::from(self.n_curvature - 1);
        let rounding = 4.0 * f64::EPSILON * self.c_min.abs().max(self.c_max.abs());
        if c.abs() <= rounding { 0.0 } else { c }
    }
}

/// Which VDM bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VdmMethod {
    /// Every ray cast against the relief bent to its curvature.
    Exact,
    /// Zero-curvature casts bent and resampled over θ, as the paper does.
    Paper,
}

impl VdmMethod {
    /// The name on the command line, in manifests and in reports.
    pub fn name(self) -> &'static str {
        match self {
            VdmMethod::Exact => "exact",
            VdmMethod::Paper => "paper",
        }
    }
}

impl std::str::FromStr for VdmMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        [VdmMethod::Exact, VdmMethod::Paper]
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                Error::InvalidParameter(format!("VDM method {s:?}: expected exact or paper"))
            })
    }
}

/// What compression costs a VDM, measured against the bake.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmAccuracy {
    /// Samples (texel, view, curvature).
    pub samples: u64,
    /// Samples whose silhouette decision (θ > θ̃_MVM) differs from the bake's hit or miss.
    pub silhouette_flips: u64,
    /// `silhouette_flips` over `samples`.
    pub flip_rate: f64,
    /// RMS displacement error over the samples both call hits (tile units).
    pub rmse: f64,
    /// Largest displacement error there.
    pub max_abs: f64,
}

/// The manifest of a VDM package.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmManifest {
    /// Always [`VDM_FORMAT_NAME`].
    pub format: String,
    /// The container version, equal to the header's.
    pub version: u32,
    /// The tool that wrote the package, `mesobake <version>`.
    pub generator: String,
    /// Unit of every distance: `"tile"` (the edge of the texture tile).
    pub units: String,
    /// The height field: `"height_field"` (a PNG file) or `"relief"` (a built-in relief,
    /// identified by the 16-bit PNG `mesobake relief` writes of it).
    pub input: InputInfo,
    /// The relief's size and depth.
    pub relief: ReliefInfo,
    /// How the VDM was baked.
    pub bake: VdmBakeInfo,
    /// The factorization, its decode parameters and accuracy.
    pub vdm: VdmInfo,
    /// The binary sections, in file order.
    pub sections: Vec<Section>,
}

impl ContainerManifest for VdmManifest {
    const FORMAT: &'static str = VDM_FORMAT_NAME;
    fn sections(&self) -> &[Section] {
        &self.sections
    }
    fn sections_mut(&mut self) -> &mut [Section] {
        &mut self.sections
    }
}

/// The height field under a VDM.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReliefInfo {
    /// Texels [W, H].
    pub size: [u32; 2],
    /// Depth of height 0 below the reference surface (tile units).
    pub depth: f64,
}

/// The bake parameters of a VDM.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmBakeInfo {
    /// The view and curvature grid.
    pub grid: VdmGrid,
    /// The baking algorithm.
    pub method: VdmMethod,
    /// The paper's bake: flat rays per θ bin before resampling (1 for the exact bake).
    pub oversampling: u32,
}

/// The joint factorization of a VDM and its MVM.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VdmInfo {
    /// Components of the VDM's reconstruction, K (the weight maps' count).
    pub vdm_rank: u32,
    /// Components of the MVM's reconstruction (the first ones, ≤ K).
    pub mvm_rank: u32,
    /// All singular values of the matrix [VDM, MVM], descending.
    pub spectrum: Vec<f64>,
    /// The number format of every factor.
    pub quantization: Quantization,
    /// Weight maps W_i(x, y, φ), i < K.
    pub weights: FactorInfo,
    /// The VDM's eigenmaps E_i(θ, c), i < K.
    pub eigen: FactorInfo,
    /// The MVM's eigenmaps E_i(c), i < `mvm_rank`.
    pub mvm: FactorInfo,
    /// The reconstruction's error against the bake.
    pub accuracy: VdmAccuracy,
}

/// What the writer needs of a compressed VDM.
#[derive(Clone, Copy, Debug)]
pub struct VdmContent<'a> {
    /// The relief's size and depth.
    pub relief: ReliefInfo,
    /// How it was baked.
    pub bake: VdmBakeInfo,
    /// The MVM's components (≤ the weights' rank).
    pub mvm_rank: usize,
    /// All singular values, descending.
    pub spectrum: &'a [f64],
    /// W, rows (φ, y, x) × K, quantized.
    pub weights: &'a QuantizedFactor,
    /// E, rows (c, θ) for the VDM then (c) for the MVM, × K, quantized like `weights`.
    pub eigen: &'a QuantizedFactor,
    /// The reconstruction's error against the bake.
    pub accuracy: VdmAccuracy,
    /// The height field h(i, j) in [0, 1], row by row (x fastest): its relief lies
    /// depth·(1 − h) below the reference surface.
    pub heights: &'a [f32],
}

/// The texture of the height-field section.
fn height_texture(size: [u32; 2]) -> Texture {
    Texture {
        dimension: TextureDimension::D2,
        format: TexelFormat::R32float,
        width: size[0],
        height: size[1],
        depth: 1,
    }
}

/// The three factors of a VDM package, as named in its sections.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Factor {
    Weights,
    Eigen,
    Mvm,
}

impl Factor {
    const ALL: [Factor; 3] = [Factor::Weights, Factor::Eigen, Factor::Mvm];

    fn name(self) -> &'static str {
        match self {
            Factor::Weights => "weights",
            Factor::Eigen => "eigen",
            Factor::Mvm => "mvm",
        }
    }

    /// The texture holding components 4g.. of this factor with `components` in all:
    /// `vdm.weights.g` W × H × Nφ (3D), `vdm.eigen.g` Nθ × Nc, `vdm.mvm.g` Nc × 1.
    fn texture(
        self,
        q: Quantization,
        components: usize,
        group: usize,
        info: &ReliefGrid,
    ) -> Texture {
        let (size, g) = (info.size, info.grid);
        let (dimension, width, height, depth) = match self {
            Factor::Weights => (TextureDimension::D3, size[0], size[1], g.n_phi),
            Factor::Eigen => (TextureDimension::D2, g.n_theta, g.n_curvature, 1),
            Factor::Mvm => (TextureDimension::D2, g.n_curvature, 1, 1),
        };
        Texture {
            dimension,
            format: TexelFormat::of(q, components - group * CHANNELS),
            width,
            height,
            depth,
        }
    }

    fn info(self, info: &VdmInfo) -> &FactorInfo {
        match self {
            Factor::Weights => &info.weights,
            Factor::Eigen => &info.eigen,
            Factor::Mvm => &info.mvm,
        }
    }

    fn components(self, info: &VdmInfo) -> usize {
        match self {
            Factor::Mvm => info.mvm_rank as usize,
            _ => info.vdm_rank as usize,
        }
    }
}

/// The relief size and grid, which shape every texture.
struct ReliefGrid {
    size: [u32; 2],
    grid: VdmGrid,
}

/// A validated VDM package in memory.
#[derive(Debug)]
pub struct VdmPackage {
    manifest: VdmManifest,
    contents: Contents,
}

impl VdmPackage {
    /// Encodes a compressed VDM with its provenance into package bytes (deterministic: the
    /// same content gives the same bytes).
    pub fn encode(input: InputInfo, content: VdmContent) -> Vec<u8> {
        let shape = ReliefGrid {
            size: content.relief.size,
            grid: content.bake.grid,
        };
        let (q, rank) = (content.weights.format, content.weights.rank);
        let vdm_rows = (shape.grid.n_curvature * shape.grid.n_theta) as usize;
        let mut sections = vec![Section::new(HEIGHT_SECTION, height_texture(shape.size))];
        let mut payloads = vec![
            content
                .heights
                .iter()
                .flat_map(|h| h.to_le_bytes())
                .collect(),
        ];
        let mut factor = |factor: Factor| {
            let (source, rows, components) = match factor {
                Factor::Weights => (content.weights, 0..content.weights.rows, rank),
                Factor::Eigen => (content.eigen, 0..vdm_rows, rank),
                Factor::Mvm => (
                    content.eigen,
                    vdm_rows..content.eigen.rows,
                    content.mvm_rank,
                ),
            };
            let names: Vec<String> = (0..components.div_ceil(CHANNELS))
                .map(|g| format!("vdm.{}.{g}", factor.name()))
                .collect();
            for (g, name) in names.iter().enumerate() {
                let texture = factor.texture(q, components, g, &shape);
                payloads.push(source.pack_group(rows.clone(), components, g, &texture));
                sections.push(Section::new(name, texture));
            }
            FactorInfo {
                sections: names,
                scale: source.scale[..components].to_vec(),
                bias: source.bias[..components].to_vec(),
            }
        };
        let (weights, eigen, mvm) = (
            factor(Factor::Weights),
            factor(Factor::Eigen),
            factor(Factor::Mvm),
        );
        let mut manifest = VdmManifest {
            format: VDM_FORMAT_NAME.into(),
            version: container::VERSION,
            generator: format!("mesobake {}", env!("CARGO_PKG_VERSION")),
            units: "tile".into(),
            input,
            relief: content.relief,
            bake: content.bake,
            vdm: VdmInfo {
                vdm_rank: rank as u32,
                mvm_rank: content.mvm_rank as u32,
                spectrum: content.spectrum.to_vec(),
                quantization: q,
                weights,
                eigen,
                mvm,
                accuracy: content.accuracy,
            },
            sections,
        };
        container::assemble(&mut manifest, &payloads)
    }

    /// Validates `bytes` as a VDM package: the container, the relief, the grid, the bake
    /// parameters, the ranks, the spectrum, the decode parameters, the accuracy and every
    /// section's texture.
    pub fn parse(bytes: Vec<u8>) -> Result<VdmPackage> {
        VdmPackage::parse_within(bytes, crate::DEFAULT_MAX_MEMORY)
    }

    /// `parse`, refusing before allocating a package whose reading would take more than
    /// `max_memory` bytes ([`container::memory_needed`]).
    pub fn parse_within(bytes: Vec<u8>, max_memory: u64) -> Result<VdmPackage> {
        let manifest: VdmManifest = container::parse(&bytes)?;
        let contents = Contents::inflate(bytes, &manifest.sections, max_memory)?;
        let bad = |what: String| Error::Package(format!("manifest: {what}"));
        manifest.input.check().map_err(bad)?;
        let ReliefInfo { size, depth } = manifest.relief;
        if size.iter().any(|&n| n == 0 || n > MAX_SIDE) {
            return Err(bad(format!(
                "relief size {}×{} is not 1 to {MAX_SIDE} per side",
                size[0], size[1]
            )));
        }
        if !(depth.is_finite() && depth > 0.0) {
            return Err(bad(format!(
                "relief depth {depth} is not finite and positive"
            )));
        }
        let bake = manifest.bake;
        bake.grid.validate(depth).map_err(|e| bad(e.to_string()))?;
        let oversampling_ok = match bake.method {
            VdmMethod::Exact => bake.oversampling == 1,
            VdmMethod::Paper => (1..=MAX_OVERSAMPLING).contains(&bake.oversampling),
        };
        if !oversampling_ok {
            return Err(bad(format!(
                "oversampling {} is invalid for the {} bake",
                bake.oversampling,
                bake.method.name()
            )));
        }
        let info = &manifest.vdm;
        let (k, mvm) = (info.vdm_rank as usize, info.mvm_rank as usize);
        let g = bake.grid;
        let rows = u64::from(size[0]) * u64::from(size[1]) * u64::from(g.n_phi);
        let cols = u64::from(g.n_curvature) * u64::from(g.n_theta + 1);
        if !(1..=MAX_VDM_RANK).contains(&k) || k as u64 > rows.min(cols) || !(1..=k).contains(&mvm)
        {
            return Err(bad(format!(
                "ranks {k} (VDM) and {mvm} (MVM): the VDM's must be 1 to min({MAX_VDM_RANK}, \
                 {rows}, {cols}) and the MVM's 1 to the VDM's"
            )));
        }
        if info.spectrum.len() as u64 != rows.min(cols)
            || info.spectrum.iter().any(|s| !(s.is_finite() && *s >= 0.0))
        {
            return Err(bad(format!(
                "the spectrum must hold min({rows}, {cols}) finite values ≥ 0"
            )));
        }
        let a = info.accuracy;
        if ![a.flip_rate, a.rmse, a.max_abs]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
            || a.silhouette_flips > a.samples
        {
            return Err(bad(
                "the accuracy must hold finite, consistent values".into()
            ));
        }
        let shape = ReliefGrid { size, grid: g };
        for factor in Factor::ALL {
            let (f, n) = (factor.info(info), factor.components(info));
            if f.sections.len() != n.div_ceil(CHANNELS)
                || f.scale.len() != n
                || f.bias.len() != n
                || f.scale.iter().chain(&f.bias).any(|v| !v.is_finite())
            {
                return Err(bad(format!(
                    "the {} factor must list {} sections and {n} finite scales and biases",
                    factor.name(),
                    n.div_ceil(CHANNELS)
                )));
            }
            for (group, section) in f.sections.iter().enumerate() {
                let expected = factor.texture(info.quantization, n, group, &shape);
                crate::expect_section(&manifest.sections, section, expected, bad)?;
            }
        }
        crate::expect_section(
            &manifest.sections,
            HEIGHT_SECTION,
            height_texture(size),
            bad,
        )?;
        let package = VdmPackage { manifest, contents };
        if package.heights().iter().any(|h| !(0.0..=1.0).contains(h)) {
            return Err(bad("the height field holds values outside [0, 1]".into()));
        }
        Ok(package)
    }

    /// The height field h(i, j), row by row (x fastest).
    pub fn heights(&self) -> Vec<f32> {
        let bytes = self.section(HEIGHT_SECTION).expect("validated");
        bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect()
    }

    /// Reads and validates the VDM package at `path`, refusing before reading a file over
    /// `max_bytes` and before decoding one whose reading would take more memory than that.
    pub fn read(path: &Path, max_bytes: u64) -> Result<VdmPackage> {
        VdmPackage::parse_within(crate::read_limited(path, max_bytes)?, max_bytes)
    }

    /// The manifest.
    pub fn manifest(&self) -> &VdmManifest {
        &self.manifest
    }

    /// The texels of section `name`, if present.
    pub fn section(&self, name: &str) -> Option<&[u8]> {
        self.contents.section(&self.manifest.sections, name)
    }

    /// The whole package's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.contents.file()
    }

    /// The quantized factor `factor` as its sections hold it.
    fn factor(&self, factor: Factor) -> QuantizedFactor {
        let (info, g) = (&self.manifest.vdm, self.manifest.bake.grid);
        let f = factor.info(info);
        let [w, h] = self.manifest.relief.size;
        let rows = match factor {
            Factor::Weights => (w * h * g.n_phi) as usize,
            Factor::Eigen => (g.n_curvature * g.n_theta) as usize,
            Factor::Mvm => g.n_curvature as usize,
        };
        let groups = crate::groups(&self.manifest.sections, &self.contents, &f.sections);
        QuantizedFactor::unpack(
            &groups,
            rows,
            info.quantization,
            f.scale.clone(),
            f.bias.clone(),
        )
    }

    /// The decoded VDM, answering queries as a renderer does.
    pub fn query(&self) -> VdmQuery {
        let info = &self.manifest.vdm;
        let [w, h] = self.manifest.relief.size;
        VdmQuery {
            size: (w, h),
            grid: self.manifest.bake.grid,
            vdm_rank: info.vdm_rank as usize,
            mvm_rank: info.mvm_rank as usize,
            weights: self.factor(Factor::Weights).dequantize(),
            eigen: self.factor(Factor::Eigen).dequantize(),
            mvm: self.factor(Factor::Mvm).dequantize(),
            rmse: info.accuracy.rmse,
        }
    }
}

/// A compressed VDM's dequantized factors at the baked samples:
/// θ̃_MVM(i, j, b, k) = Σ_{n<mvm_rank} W_n(i, j, b)·E_MVM,n(k) and
/// d̃(i, j, a, b, k) = Σ_{n<K} W_n(i, j, b)·E_n(a, k), a silhouette (no hit) where
/// θ_a > θ̃_MVM.
#[derive(Clone, Debug)]
pub struct VdmQuery {
    size: (u32, u32),
    grid: VdmGrid,
    vdm_rank: usize,
    mvm_rank: usize,
    /// Rows (b·H + j)·W + i, `vdm_rank` values each.
    weights: Vec<f32>,
    /// Rows k·Nθ + a, `vdm_rank` values each.
    eigen: Vec<f32>,
    /// Rows k, `mvm_rank` values each.
    mvm: Vec<f32>,
    /// The RMS displacement error the factors were measured at (tile units; 0 unknown).
    rmse: f64,
}

impl VdmQuery {
    /// Dequantized factors: `weights` rows (φ, y, x) × K and `eigen` rows (c, θ) then (c) × K
    /// (the SVD's layout), the MVM using the first `mvm_rank` components.
    pub fn new(
        size: (u32, u32),
        grid: VdmGrid,
        mvm_rank: usize,
        weights: &QuantizedFactor,
        eigen: &QuantizedFactor,
    ) -> VdmQuery {
        let k = weights.rank;
        let all = eigen.dequantize();
        let split = (grid.n_curvature * grid.n_theta) as usize * k;
        VdmQuery {
            size,
            grid,
            vdm_rank: k,
            mvm_rank,
            weights: weights.dequantize(),
            eigen: all[..split].to_vec(),
            mvm: all[split..]
                .chunks_exact(k)
                .flat_map(|row| &row[..mvm_rank])
                .copied()
                .collect(),
            rmse: 0.0,
        }
    }

    /// The same query, its factors measured at `rmse` (see [`VdmAccuracy::rmse`]).
    pub fn with_rmse(self, rmse: f64) -> VdmQuery {
        VdmQuery { rmse, ..self }
    }

    /// The RMS displacement error of the reconstruction, in tile units, as measured against
    /// the bake (0 where it was not measured).
    pub fn rmse(&self) -> f64 {
        self.rmse
    }

    /// The texels [W, H] of the VDM.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The view and curvature grid.
    pub fn grid(&self) -> VdmGrid {
        self.grid
    }

    /// Components of the VDM's and of the MVM's reconstruction.
    pub fn ranks(&self) -> (usize, usize) {
        (self.vdm_rank, self.mvm_rank)
    }

    /// The dequantized factors, for upload: W (rows (b·H + j)·W + i), E (rows k·Nθ + a),
    /// each row `vdm_rank` values, and E_MVM (rows k, `mvm_rank` values).
    pub fn factors(&self) -> [&[f32]; 3] {
        [&self.weights, &self.eigen, &self.mvm]
    }

    fn weights(&self, i: u32, j: u32, b: u32) -> &[f32] {
        let (w, h) = self.size;
        let row = ((b * h + j) * w + i) as usize;
        &self.weights[row * self.vdm_rank..][..self.vdm_rank]
    }

    /// The reconstructed θ_MVM at texel (i, j), azimuth b, curvature k.
    pub fn max_theta(&self, i: u32, j: u32, b: u32, k: u32) -> f32 {
        let e = &self.mvm[k as usize * self.mvm_rank..][..self.mvm_rank];
        self.weights(i, j, b)
            .iter()
            .zip(e)
            .map(|(w, e)| w * e)
            .sum()
    }

    /// The reconstructed displacement at texel (i, j), view (a, b), curvature k, or `None`
    /// where the reconstructed MVM calls the view a silhouette.
    pub fn distance(&self, i: u32, j: u32, a: u32, b: u32, k: u32) -> Option<f32> {
        if self.grid.theta(a) as f32 > self.max_theta(i, j, b, k) {
            return None;
        }
        let col = (k * self.grid.n_theta + a) as usize;
        let e = &self.eigen[col * self.vdm_rank..][..self.vdm_rank];
        Some(
            self.weights(i, j, b)
                .iter()
                .zip(e)
                .map(|(w, e)| w * e)
                .sum(),
        )
    }
    /// The displacement a renderer reads between the samples, or `None` for a silhouette: each
    /// factor filtered as a GPU's linear sampler filters its texture (see
    /// `docs/package-format.md`): W(x, y, φ) trilinearly with x, y and φ periodic, E(θ, c)
    /// bilinearly and E_MVM(c) linearly with θ and c clamped to the first and last samples;
    /// the silhouette test θ > θ̃_MVM takes W at the texel holding (x, y) (the paper's
    /// nearest sample), still linear in φ. x, y in tiles, θ from the inward normal, φ in
    /// radians, c in 1/tile.
    pub fn sample(&self, x: f64, y: f64, theta: f64, phi: f64, c: f64) -> Option<f32> {
        let (w, h) = self.size;
        let g = self.grid;
        let periodic = |t: f64, n: u32| {
            let f = t * f64::from(n) - 0.5;
            let i0 = f.floor();
            let i = i0.rem_euclid(f64::from(n)) as u32 % n;
            (i, (i + 1) % n, (f - i0) as f32)
        };
        let clamped = |f: f64, n: u32| {
            let f = f.clamp(0.0, f64::from(n - 1));
            let i = (f.floor() as u32).min(n - 1);
            (i, (i + 1).min(n - 1), (f - f64::from(i)) as f32)
        };
        let k_f = if g.n_curvature > 1 && g.c_max > g.c_min {
            (c - g.c_min) / (g.c_max - g.c_min) * f64::from(g.n_curvature - 1)
        } else {
            0.0
        };
        let (k0, k1, wk) = clamped(k_f, g.n_curvature);
        let b = periodic(phi / TAU, g.n_phi);
        // The silhouette: W at the texel holding (x, y), linear in φ.
        let texel = |t: f64, n: u32| (t * f64::from(n)).floor().rem_euclid(f64::from(n)) as u32 % n;
        let (i, j) = (texel(x, w), texel(y, h));
        let mut weights = [0.0f32; MAX_VDM_RANK];
        self.blend(&mut weights, &[(i, j, b.0, 1.0 - b.2), (i, j, b.1, b.2)]);
        let mvm = |k: u32| &self.mvm[k as usize * self.mvm_rank..][..self.mvm_rank];
        let max_theta: f32 = (0..self.mvm_rank)
            .map(|l| weights[l] * (mvm(k0)[l] * (1.0 - wk) + mvm(k1)[l] * wk))
            .sum();
        if theta as f32 > max_theta {
            return None;
        }
        let (xi, yj) = (periodic(x, w), periodic(y, h));
        let mut corners = Vec::with_capacity(8);
        for (bb, wb) in [(b.0, 1.0 - b.2), (b.1, b.2)] {
            for (jj, wj) in [(yj.0, 1.0 - yj.2), (yj.1, yj.2)] {
                for (ii, wi) in [(xi.0, 1.0 - xi.2), (xi.1, xi.2)] {
                    corners.push((ii, jj, bb, wi * wj * wb));
                }
            }
        }
        weights = [0.0; MAX_VDM_RANK];
        self.blend(&mut weights, &corners);
        let (a0, a1, wa) = clamped(theta / FRAC_PI_2 * f64::from(g.n_theta) - 0.5, g.n_theta);
        let eigen = |k: u32, a: u32| {
            let col = (k * g.n_theta + a) as usize;
            &self.eigen[col * self.vdm_rank..][..self.vdm_rank]
        };
        let (e00, e01, e10, e11) = (eigen(k0, a0), eigen(k0, a1), eigen(k1, a0), eigen(k1, a1));
        Some(
            (0..self.vdm_rank)
                .map(|l| {
                    let low = e00[l] * (1.0 - wa) + e01[l] * wa;
                    let high = e10[l] * (1.0 - wa) + e11[l] * wa;
                    weights[l] * (low * (1.0 - wk) + high * wk)
                })
                .sum(),
        )
    }

    /// Adds Σ weight·W(i, j, b) over `corners` (i, j, b, weight) to `out`.
    fn blend(&self, out: &mut [f32; MAX_VDM_RANK], corners: &[(u32, u32, u32, f32)]) {
        for &(i, j, b, weight) in corners {
            for (o, w) in out.iter_mut().zip(self.weights(i, j, b)) {
                *o += weight * w;
            }
        }
    }
}
