//! The GDM codec options shared by `mesobake bake` and `mesobake preview`.

use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::RankChoice;
use mesobake_bake::package::bake::check_codec_options;
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::{Error, Result};
use mesobake_scene::package::ScenePackageParams;

/// How a baked package answers GDM queries, and the SVD's size for `paper-svd`.
#[derive(clap::Args)]
pub struct CodecOptions {
    /// What answers the renderers' GDM queries: occupancy (the voxels with their empty-space
    /// distances, ray-marched exactly) or paper-svd (the baked GDM as one truncated SVD, the
    /// paper's; --rank and --quant choose its size).
    #[arg(long, default_value = "occupancy")]
    pub gdm_codec: GdmCodec,
    /// SVD components to keep, paper-svd only [default: 8].
    #[arg(long)]
    pub rank: Option<usize>,
    /// Number format of weight maps and eigenmaps, paper-svd only: f32, f16, or u8 (per-map
    /// scale and bias) [default: f16].
    #[arg(long)]
    pub quant: Option<Quantization>,
}

impl CodecOptions {
    /// Checks the options as the server checks a job's ([`check_codec_options`]), and
    /// refuses `extra` (another SVD option, when given) for a codec without an SVD.
    pub fn check(&self, extra: Option<&str>) -> Result<()> {
        check_codec_options(self.gdm_codec, self.rank, self.quant)?;
        match extra {
            Some(flag) if self.gdm_codec != GdmCodec::PaperSvd => {
                Err(Error::InvalidParameter(format!(
                    "{flag} sizes the paper-svd codec's SVD, but the codec is {}: add \
                     --gdm-codec paper-svd",
                    self.gdm_codec
                )))
            }
            _ => Ok(()),
        }
    }

    /// The SVD's rank (8 unless given).
    pub fn rank(&self) -> usize {
        self.rank.unwrap_or(8)
    }

    /// Whether any of the options was given.
    pub fn is_chosen(&self) -> bool {
        self.rank.is_some() || self.quant.is_some() || self.gdm_codec != GdmCodec::default()
    }

    /// The package parameters of a scene's bake.
    pub fn scene_params(&self) -> ScenePackageParams {
        ScenePackageParams {
            codec: self.gdm_codec,
            rank: RankChoice::Rank(self.rank()),
            quantization: self.quant.unwrap_or_default(),
        }
    }
}
