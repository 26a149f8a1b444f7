//! The planner: the stages a scene's package needs, derived from the effects the scene calls
//! for, and the stages it skips with the reason. Nothing else is baked.

use crate::scene::{Effect, Scene};
use serde::{Deserialize, Serialize};

/// A stage the planner left out, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Skipped {
    /// The stage.
    pub stage: String,
    /// Why the scene does not need it.
    pub reason: String,
}

/// The stages a bake runs, in order, and those it skips.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Plan {
    /// Stages to run.
    pub stages: Vec<String>,
    /// Stages left out.
    pub skipped: Vec<Skipped>,
}

/// The stages of `scene`'s package: `load`, `bake_gdm`, `compress` always; `bake_prt`,
/// `bake_rtv`, `compress_rtv` with environment lighting; `encode` last. Parts of stages the
/// scene does not call for (`prt_visibility`, `rtv_gloss`) are listed as skipped too.
pub fn plan(scene: &Scene) -> Plan {
    let mut stages = vec!["load", "bake_gdm", "compress"];
    let mut skipped = Vec::new();
    let mut skip = |stage: &str, reason: &str| {
        skipped.push(Skipped {
            stage: stage.into(),
            reason: reason.into(),
        })
    };
    if scene.wants(Effect::EnvironmentLighting) {
        stages.extend(["bake_prt", "bake_rtv", "compress_rtv"]);
        if !scene.wants(Effect::MacroShadows) {
            skip(
                "prt_visibility",
                "the scene calls for no macro_shadows: the PRT is a pure rotation",
            );
        }
        if !scene.wants(Effect::EnvironmentGloss) {
            skip(
                "rtv_gloss",
                "the scene calls for no environment_gloss: the RTV is Lambertian",
            );
        }
    } else {
        for stage in ["bake_prt", "bake_rtv", "compress_rtv"] {
            skip(stage, "the scene calls for no environment_lighting");
        }
    }
    stages.push("encode");
    Plan {
        stages: stages.into_iter().map(String::from).collect(),
        skipped,
    }
}
