//! The JSON manifest of a package (see `docs/package-format.md`). Every map is a struct or a
//! list, so serialization order is fixed and identical packages are byte-identical.

pub use crate::container::Section;
use crate::error::{Error, Result};
use crate::quantize::Quantization;
pub use crate::texture::{TexelFormat, Texture, TextureDimension};

/// The value of [`Manifest::format`].
pub const FORMAT_NAME: &str = "mesobake-package";

/// Everything a loader needs to interpret the binary sections, and how they were made.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// The container version, equal to the header's.
    pub version: u32,
    /// The tool that wrote the package, `mesobake <version>`.
    pub generator: String,
    /// Unit of every distance: `"voxel"` (the edge of one mesostructure voxel).
    pub units: String,
    /// The mesostructure input.
    pub input: InputInfo,
    /// How the GDM was baked.
    pub bake: BakeInfo,
    /// What answers the renderers' GDM queries: `gdm` for `paper-svd`, `occupancy` for
    /// `occupancy`.
    pub codec: GdmCodec,
    /// The SVD-compressed GDM (codec `paper-svd`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gdm: Option<GdmInfo>,
    /// The voxel occupancy with its empty-space distances (codec `occupancy`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occupancy: Option<OccupancyInfo>,
    /// The radiance transfer, present when the scene called for environment lighting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gi: Option<GiInfo>,
    /// The binary sections, in file order.
    pub sections: Vec<Section>,
}

impl crate::container::ContainerManifest for Manifest {
    const FORMAT: &'static str = FORMAT_NAME;
    fn sections(&self) -> &[Section] {
        &self.sections
    }
    fn sections_mut(&mut self) -> &mut [Section] {
        &mut self.sections
    }
}

/// Identity of the input file.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputInfo {
    /// `"volume"` (`.mbvol`) or `"mesh"` (OBJ tile).
    pub kind: String,
    /// Size of the input file in bytes.
    pub bytes: u64,
    /// BLAKE3 hash of the input file's bytes, lowercase hex.
    pub blake3: String,
}

impl InputInfo {
    /// Longest `kind` a reader accepts.
    pub const MAX_KIND: usize = 32;

    /// Checks what readers rely on: a short lowercase `kind` (letters, digits, `_`, `-`)
    /// and a `blake3` of lowercase hex digits, at most 64 (a BLAKE3 hash has 64); the
    /// problem, named, where not.
    pub fn check(&self) -> std::result::Result<(), String> {
        let kind_ok = (1..=Self::MAX_KIND).contains(&self.kind.len())
            && (self.kind.bytes()).all(|b| matches!(b, b'a'..=b'z' | b'0'..=b'9' | b'_' | b'-'));
        if !kind_ok {
            return Err(format!(
                "input kind {:?} is not 1 to {} lowercase letters, digits, _ or -",
                self.kind.chars().take(40).collect::<String>(),
                Self::MAX_KIND
            ));
        }
        let hex = (1..=64).contains(&self.blake3.len())
            && (self.blake3.bytes()).all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'));
        if !hex {
            return Err(format!(
                "input blake3 {:?} is not 1 to 64 lowercase hex digits",
                self.blake3.chars().take(80).collect::<String>()
            ));
        }
        Ok(())
    }
}

/// How a package answers the per-pixel algorithm's GDM queries d(x, y, z, θ, φ).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum GdmCodec {
    /// The paper's: the baked GDM as one truncated SVD, weight maps W(x, y, φ) times
    /// eigenmaps E(θ, z), each query an interpolated reconstruction.
    PaperSvd,
    /// The voxel occupancy with its empty-space distances, ray-marched exactly along each
    /// query (see `compress::occupancy`): the default.
    #[default]
    Occupancy,
}

impl GdmCodec {
    /// Every codec, the default first.
    pub const ALL: [GdmCodec; 2] = [GdmCodec::Occupancy, GdmCodec::PaperSvd];

    /// The name used in manifests, on the command line and in job requests.
    pub fn name(self) -> &'static str {
        match self {
            GdmCodec::PaperSvd => "paper-svd",
            GdmCodec::Occupancy => "occupancy",
        }
    }
}

impl std::str::FromStr for GdmCodec {
    type Err = Error;

    fn from_str(text: &str) -> Result<GdmCodec> {
        GdmCodec::ALL
            .into_iter()
            .find(|c| c.name() == text)
            .ok_or_else(|| {
                Error::InvalidParameter(format!(
                    "GDM codec {text:?}: expected occupancy or paper-svd"
                ))
            })
    }
}

impl std::fmt::Display for GdmCodec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The occupancy codec's section.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OccupancyInfo {
    /// The section holding one `r8uint` texel per voxel: 0 solid, else the Chebyshev
    /// distance in voxels to the nearest solid voxel (periodic in x and y, layers outside the
    /// grid empty), 255 meaning at least 255.
    pub section: String,
    /// Solid voxels (the zeros of the section).
    pub solid_voxels: u64,
}

/// The bake parameters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakeInfo {
    /// Voxel grid [X, Y, Z].
    pub res: [u32; 3],
    /// Direction grid [Nθ, Nφ] (θ_a = (a + ½)·π/Nθ, φ_b = (b + ½)·2π/Nφ).
    pub dirs: [u32; 2],
    /// The baking algorithm.
    pub method: Method,
    /// The fast method's knobs (absent for exact bakes).
    pub fast: Option<FastParams>,
    /// Whether an open OBJ tile was accepted as thin sheets.
    pub allow_open: bool,
}

/// The GDM's factorization and its accuracy.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GdmInfo {
    /// How the rank was chosen.
    pub rank_choice: RankChoice,
    /// Components kept, k.
    pub rank: u32,
    /// All singular values of the GDM matrix, descending.
    pub spectrum: Vec<f64>,
    /// The number format of both factors.
    pub quantization: Quantization,
    /// Weight maps W_i(x, y, φ): per-component decode and the sections that hold them.
    pub weights: FactorInfo,
    /// Eigenmaps E_i(z, θ): per-component decode and the sections that hold them.
    pub eigen: FactorInfo,
    /// Error of the quantized reconstruction against the baked GDM; its `escape_margin` is the
    /// escape rule's relative margin μ (d̃ ≥ (1 − μ)·b is an escape).
    pub accuracy: Accuracy,
    /// The optimal (unquantized) rank-k RMSE, sqrt(Σ_{i>k} σᵢ² / (m·n)).
    pub svd_rmse: f64,
}

/// The radiance transfer of a package: the compressed RTV (sections `rtv.index`,
/// `rtv.weights`, `rtv.eigen`) and the macro-scale PRT (section `prt.transfer`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GiInfo {
    /// RTV sample voxels.
    pub samples: u32,
    /// Interreflection bounces baked into the RTV.
    pub bounces: u32,
    /// The specular lobe, when the scene called for environment gloss.
    pub glossy: Option<Glossy>,
    /// The RTV's SVD: rank, error and spectra.
    pub compression: RtvCompression,
    /// Base-mesh vertices of the PRT.
    pub vertices: u32,
    /// Whether the PRT includes base-mesh self-shadowing.
    pub macro_shadows: bool,
    /// BLAKE3 of the base mesh's geometry (mesobake's `geometry_hash`: positions and triangles): the mesh the
    /// PRT belongs to.
    pub base_mesh: String,
}

/// Decode parameters of one factor.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FactorInfo {
    /// Section names, one per group of four components (group g holds components 4g..4g+3
    /// in channels r, g, b, a).
    pub sections: Vec<String>,
    /// Per component: value = bias + scale · stored (stored = code / 255 for u8).
    pub scale: Vec<f32>,
    /// Per component: see `scale`.
    pub bias: Vec<f32>,
}

/// Which baking algorithm made the GDM.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// One exact ray per sample and direction.
    Exact,
    /// Per-direction layer sweeps reusing the layer above (knobs: [`FastParams`]).
    Fast,
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "exact" => Ok(Method::Exact),
            "fast" => Ok(Method::Fast),
            _ => Err(Error::InvalidParameter(format!(
                "method {s:?}: expected exact or fast"
            ))),
        }
    }
}

/// The knobs of the fast bake.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FastParams {
    /// Layers crossed exactly before reading the layer already baked (≥ 1).
    pub stride: u32,
    /// Hit distances of the four neighbours may differ by this many voxels and still be
    /// interpolated; beyond it (and where neighbours disagree on hit or escape, or more than
    /// half their weight lies in solid) the ray is traced exactly to the end.
    pub max_spread: f32,
}

impl Default for FastParams {
    fn default() -> Self {
        FastParams {
            stride: 2,
            max_spread: 1.0,
        }
    }
}

/// How many SVD components to keep.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RankChoice {
    /// Exactly this many (fewer if the matrix has lower numerical rank).
    Rank(usize),
    /// The fewest whose optimal root-mean-square error over all entries is at most this.
    MaxRmse(f64),
}

/// Error statistics of a reconstructed GDM against its bake, in voxels.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Accuracy {
    /// Root-mean-square error over all samples (escapes compared as boundary distances).
    pub rmse: f64,
    /// Largest absolute error.
    pub max_abs: f64,
    /// The relative escape margin μ: a reconstructed d̃ ≥ (1 − μ)·b is an escape
    /// ([`crate::svd::is_escape`]).
    pub escape_margin: f32,
    /// Samples whose hit/escape classification differs from the bake's.
    pub flips: u64,
    /// `flips` over all samples.
    pub flip_rate: f64,
    /// Samples compared.
    pub samples: u64,
}

/// The specular lobe of the RTV's material.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Glossy {
    /// Linear specular colour k_s.
    pub specular: [f64; 3],
    /// Phong exponent s about the mirror direction (a Blinn–Phong exponent is about 4·s).
    pub exponent: f64,
}

/// What compressing an RTV kept and cost.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RtvCompression {
    /// Components kept per matrix.
    pub rank: usize,
    /// RMS difference between the transfer values at the bin centres and their f16
    /// reconstruction, over all samples, views, channels and light coefficients.
    pub rmse: f64,
    /// `rmse` over the RMS of the transfer values.
    pub relative_rmse: f64,
    /// The optimal rank-r RMSE before rounding, sqrt(Σ_{k>r} σₖ² / entries).
    pub svd_rmse: f64,
    /// Per matrix m = 16·c + i, its singular values, descending (at most 16 are non-zero).
    pub spectra: Vec<Vec<f64>>,
}
