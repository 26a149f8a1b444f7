//! Shader variants: the WGSL module of the preview is composed from `shaders/` for what the
//! scene calls for, so that an effect it does not call for is absent from the pipeline (not
//! switched off at run time). The variant matrix is documented in ARCHITECTURE.md.

use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::effect::Effect;
use mesobake_core::quality::MAX_GDM_REFINEMENTS;
use mesobake_core::quality::{MAX_CHORDS, ShadingFrame, ShadowMethod};
use mesobake_render::shot::Shot;
use serde::Serialize;

/// What every real-time pipeline's source starts with (`shaders/common.wgsl`).
pub const COMMON: &str = include_str!("../../../shaders/common.wgsl");
const PIPELINE: &str = include_str!("../../../shaders/gdm_preview.wgsl");
/// What the hit passes of every object share (`shaders/hit_targets.wgsl`).
pub const HIT_TARGETS: &str = include_str!("../../../shaders/hit_targets.wgsl");
const QUERY_SVD: &str = include_str!("../../../shaders/query_svd.wgsl");
const QUERY_OCCUPANCY: &str = include_str!("../../../shaders/query_occupancy.wgsl");
const SHADOWS_LOCAL: &str = include_str!("../../../shaders/shadows_local.wgsl");
const SHADOWS_SHELL: &str = include_str!("../../../shaders/shadows_shell.wgsl");
const SHADOWS_OFF: &str = include_str!("../../../shaders/shadows_off.wgsl");
const SHELL_TRACE: &str = include_str!("../../../shaders/shell_trace.wgsl");
/// The occlusion between objects (`shaders/objects_on.wgsl`), whatever their technique.
pub const OBJECTS_ON: &str = include_str!("../../../shaders/objects_on.wgsl");
/// No occlusion between objects (`shaders/objects_off.wgsl`).
pub const OBJECTS_OFF: &str = include_str!("../../../shaders/objects_off.wgsl");
const GI_ON: &str = include_str!("../../../shaders/gi_on.wgsl");
const GI_OFF: &str = include_str!("../../../shaders/gi_off.wgsl");

/// The fragment entry point as `shaders/gdm_preview.wgsl` declares it.
const FRAGMENT_ENTRY: &str = "@fragment\nfn fs_main";

/// The name of the function that only the shadow variants contain.
pub const SHADOW_QUERY_FN: &str = "shadow_query";

/// A binding that only the shell-shadow variant declares.
pub const BVH_BINDING: &str = "bvh_nodes";

/// The entry point that only the variants of an object among several with shadows declare.
pub const OCCLUDE_ENTRY: &str = "fs_occlude";

/// A binding that only the environment-lighting variant declares.
pub const GI_BINDING: &str = "rtv_weights";

/// One variant of the preview's shader.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ShaderVariant {
    /// The package's GDM codec: which query file answers `segment_hit` and `escapes`.
    pub codec: GdmCodec,
    /// The shadow test (the scene's `shadows` effect, by its quality's method), or none.
    pub shadows: Option<ShadowMethod>,
    /// Environment light through the PRT and the RTV (the scene's `environment_lighting`).
    pub environment: bool,
    /// One object among several with shadows: other objects' shells block its shadow rays,
    /// and its shell theirs (`objects_on.wgsl`).
    pub occluders: bool,
    /// GDM refinement queries per hit (the scene's `gdm_refinements`; 0 for the occupancy
    /// codec, whose march is exact), unrolled as a constant.
    pub refinements: u32,
    /// Chords per prism segment (the scene's quality), a constant (1: the loop runs once and
    /// maps no point).
    pub chords: u32,
    /// The shading frame (the scene's quality), a constant.
    pub frame: ShadingFrame,
    /// Declares the fragment depth conservative (`greater_equal`: a hit lies behind the face
    /// it was found through), so that the depth test can run before the fragment shader
    /// (where the adapter has the feature `SHADER_EARLY_DEPTH_TEST`).
    pub early_depth_test: bool,
}

impl ShaderVariant {
    /// The variant `shot` calls for with a package of `codec`, for one object of a scene of
    /// `objects`.
    pub fn for_shot(
        shot: &Shot,
        codec: GdmCodec,
        objects: usize,
        early_depth_test: bool,
    ) -> ShaderVariant {
        ShaderVariant {
            codec,
            shadows: shot.wants(Effect::Shadows).then_some(shot.quality.shadows),
            environment: shot.wants(Effect::EnvironmentLighting),
            occluders: objects > 1 && shot.wants(Effect::Shadows),
            refinements: match codec {
                GdmCodec::PaperSvd => shot.gdm_refinements,
                GdmCodec::Occupancy => 0,
            },
            chords: shot.quality.chords,
            frame: shot.quality.frame,
            early_depth_test,
        }
    }

    /// Every variant a valid scene and package can ask for, with two chord counts standing
    /// for all (1 and [`MAX_CHORDS`]: the count is only a loop bound); occluders only with
    /// shadows and without environment light (which scenes of several objects refuse).
    pub fn all() -> impl Iterator<Item = ShaderVariant> {
        let shadows = [None, Some(ShadowMethod::Local), Some(ShadowMethod::Shell)];
        let frames = [ShadingFrame::Mean, ShadingFrame::Jacobian];
        GdmCodec::ALL.into_iter().flat_map(move |codec| {
            let refinements = match codec {
                GdmCodec::PaperSvd => MAX_GDM_REFINEMENTS,
                GdmCodec::Occupancy => 0,
            };
            shadows.into_iter().flat_map(move |shadows| {
                [(false, false), (false, true), (true, false)]
                    .into_iter()
                    .filter(move |&(_, occluders)| !occluders || shadows.is_some())
                    .flat_map(move |(environment, occluders)| {
                        (0..=refinements).flat_map(move |refinements| {
                            [1, MAX_CHORDS].into_iter().flat_map(move |chords| {
                                frames.into_iter().flat_map(move |frame| {
                                    [false, true].map(|early_depth_test| ShaderVariant {
                                        codec,
                                        shadows,
                                        environment,
                                        occluders,
                                        refinements,
                                        chords,
                                        frame,
                                        early_depth_test,
                                    })
                                })
                            })
                        })
                    })
            })
        })
    }

    /// A short name, e.g. `paper-svd+shadows+env+refine2+chords4+jacobian+earlyz`
    /// (`+occluders` for an object among several with shadows).
    pub fn name(&self) -> String {
        format!(
            "{}+{}{}{}+refine{}+chords{}{}{}",
            self.codec,
            match self.shadows {
                None => "noshadows",
                Some(ShadowMethod::Local) => "shadows",
                Some(ShadowMethod::Shell) => "shellshadows",
            },
            if self.environment { "+env" } else { "" },
            if self.occluders { "+occluders" } else { "" },
            self.refinements,
            self.chords,
            match self.frame {
                ShadingFrame::Mean => "",
                ShadingFrame::Jacobian => "+jacobian",
            },
            if self.early_depth_test { "+earlyz" } else { "" }
        )
    }

    /// The complete WGSL source of this variant.
    pub fn source(&self) -> String {
        let shell_shadows = self.shadows == Some(ShadowMethod::Shell);
        let mut shadows = String::new();
        if shell_shadows || self.occluders {
            shadows.push_str(SHELL_TRACE);
        }
        shadows.push_str(match self.shadows {
            None => SHADOWS_OFF,
            Some(ShadowMethod::Local) => SHADOWS_LOCAL,
            Some(ShadowMethod::Shell) => SHADOWS_SHELL,
        });
        shadows.push_str(if self.occluders {
            OBJECTS_ON
        } else {
            OBJECTS_OFF
        });
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
            "// Variant {}.\nconst REFINEMENTS: u32 = {}u;\nconst CHORDS: u32 = {}u;\n\
             const JACOBIAN_FRAME: bool = {};\n\n{COMMON}\n{pipeline}\n{HIT_TARGETS}\n{query}\n{shadows}\n{}",
            self.name(),
            self.refinements,
            self.chords.max(1),
            self.frame == ShadingFrame::Jacobian,
            if self.environment { GI_ON } else { GI_OFF }
        )
    }
}

/// The source of a variant that holds every struct of the GDM pipeline (the paper-svd
/// query, environment light and shell shadows), for the layout tests.
#[cfg(test)]
pub(crate) fn source_with_every_struct() -> String {
    ShaderVariant::all()
        .find(|v| {
            v.codec == GdmCodec::PaperSvd && v.environment && v.shadows == Some(ShadowMethod::Shell)
        })
        .expect("the variant exists")
        .source()
}
