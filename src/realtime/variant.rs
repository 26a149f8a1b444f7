//! Shader variants: the WGSL module of the preview is composed from `shaders/` for what the
//! scene calls for, so that an effect it does not call for is absent from the pipeline (not
//! switched off at run time). The variant matrix is documented in ARCHITECTURE.md.

use crate::package::manifest::GdmCodec;
use crate::scene::{Effect, MAX_GDM_REFINEMENTS, Scene};
use serde::Serialize;

const PIPELINE: &str = include_str!("../../shaders/gdm_preview.wgsl");
const QUERY_SVD: &str = include_str!("../../shaders/query_svd.wgsl");
const QUERY_OCCUPANCY: &str = include_str!("../../shaders/query_occupancy.wgsl");
const SHADOWS_ON: &str = include_str!("../../shaders/shadows_on.wgsl");
const SHADOWS_OFF: &str = include_str!("../../shaders/shadows_off.wgsl");
const GI_ON: &str = include_str!("../../shaders/gi_on.wgsl");
const GI_OFF: &str = include_str!("../../shaders/gi_off.wgsl");

/// The fragment entry point as `shaders/gdm_preview.wgsl` declares it.
const FRAGMENT_ENTRY: &str = "@fragment\nfn fs_main";

/// The name of the function that only the shadow variant contains.
pub const SHADOW_QUERY_FN: &str = "shadow_query";

/// A binding that only the environment-lighting variant declares.
pub const GI_BINDING: &str = "rtv_weights";

/// One variant of the preview's shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ShaderVariant {
    /// The package's GDM codec: which query file answers `segment_hit` and `escapes`.
    pub codec: GdmCodec,
    /// Shadow queries along the lights (the scene's `shadows` effect).
    pub shadows: bool,
    /// Environment light through the PRT and the RTV (the scene's `environment_lighting`).
    pub environment: bool,
    /// GDM refinement queries per hit (the scene's `gdm_refinements`; 0 for the occupancy
    /// codec, whose march is exact), unrolled as a constant.
    pub refinements: u32,
    /// Declares the fragment depth conservative (`greater_equal`: a hit lies behind the face
    /// it was found through), so that the depth test can run before the fragment shader
    /// (where the adapter has the feature `SHADER_EARLY_DEPTH_TEST`).
    pub early_depth_test: bool,
}

impl ShaderVariant {
    /// The variant a scene calls for with a package of `codec`.
    pub fn for_scene(scene: &Scene, codec: GdmCodec, early_depth_test: bool) -> ShaderVariant {
        ShaderVariant {
            codec,
            shadows: scene.wants(Effect::Shadows),
            environment: scene.wants(Effect::EnvironmentLighting),
            refinements: match codec {
                GdmCodec::PaperSvd => scene.gdm_refinements,
                GdmCodec::Occupancy => 0,
            },
            early_depth_test,
        }
    }

    /// Every variant a valid scene and package can ask for.
    pub fn all() -> impl Iterator<Item = ShaderVariant> {
        let flags = [(false, false), (false, true), (true, false), (true, true)];
        GdmCodec::ALL.into_iter().flat_map(move |codec| {
            let refinements = match codec {
                GdmCodec::PaperSvd => MAX_GDM_REFINEMENTS,
                GdmCodec::Occupancy => 0,
            };
            flags.into_iter().flat_map(move |(shadows, environment)| {
                (0..=refinements).flat_map(move |refinements| {
                    [false, true].map(|early_depth_test| ShaderVariant {
                        codec,
                        shadows,
                        environment,
                        refinements,
                        early_depth_test,
                    })
                })
            })
        })
    }

    /// A short name, e.g. `paper-svd+shadows+env+refine2+earlyz`.
    pub fn name(&self) -> String {
        format!(
            "{}+{}{}+refine{}{}",
            self.codec,
            if self.shadows { "shadows" } else { "noshadows" },
            if self.environment { "+env" } else { "" },
            self.refinements,
            if self.early_depth_test { "+earlyz" } else { "" }
        )
    }

    /// The complete WGSL source of this variant.
    pub fn source(&self) -> String {
        let shadows = if self.shadows {
            SHADOWS_ON
        } else {
            SHADOWS_OFF
        };
        let pipeline = if self.early_depth_test {
            PIPELINE.replace(
                FRAGMENT_ENTRY,
                &format!("@early_depth_test(greater_equal)\n{FRAGMENT_ENTRY}"),
            )
        } else {
            PIPELINE.to_owned()
        };
        let query = match self.codec {
            GdmCodec::PaperSvd => QUERY_SVD,
            GdmCodec::Occupancy => QUERY_OCCUPANCY,
        };
        format!(
            "// Variant {}.\nconst REFINEMENTS: u32 = {}u;\n\n{pipeline}\n{query}\n{shadows}\n{}",
            self.name(),
            self.refinements,
            if self.environment { GI_ON } else { GI_OFF }
        )
    }
}
