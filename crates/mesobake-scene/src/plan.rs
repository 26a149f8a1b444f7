//! The planner: the stages a scene's package needs, derived from the technique chosen for it
//! ([`super::technique`]) and the effects the scene calls for, and the stages it skips with
//! the reason. Nothing else is baked.

use crate::Scene;
use crate::technique::{Technique, TechniqueChoice, is_height_field};
use mesobake_bake::package::manifest::GdmCodec;
use mesobake_core::effect::Effect;
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
    /// The technique the package is for, and why.
    #[serde(default)]
    pub technique: TechniqueChoice,
    /// Stages to run.
    pub stages: Vec<String>,
    /// Stages left out.
    pub skipped: Vec<Skipped>,
}

impl Plan {
    /// Whether the plan runs `stage`.
    pub fn runs(&self, stage: &str) -> bool {
        self.stages.iter().any(|s| s == stage)
    }
}

/// The stages of `scene`'s package for `technique`, with `codec` for a GDM: `load` first and
/// `encode` last. A translucent medium's package (the `transparency` technique): `load`
/// makes the medium (colour, opacity and normals), `medium_mips` its mip-map where the scene
/// filters, `encode` quantizes and writes them; no GDM, VDM or RTV stage. A VDM package:
/// `bake_vdm`, `compress_vdm`, and none of the GDM's stages. A GDM package: `bake_gdm`,
/// `compress` for `paper-svd`, `occupancy` for the occupancy codec; `bake_prt`, `bake_rtv`
/// (after `bake_gdm`, which it needs), `compress_rtv` with environment lighting; a height
/// field's `bake_vdm` is listed as skipped. Parts of stages the scene does not call for
/// (`prt_visibility`, `rtv_gloss`) are listed as skipped too.
pub fn plan(scene: &Scene, codec: GdmCodec, technique: TechniqueChoice) -> Plan {
    let mut stages = Stages {
        run: vec!["load"],
        skipped: Vec::new(),
    };
    match technique.technique {
        Technique::Transparency => stages.transparency(scene, &technique),
        Technique::Vdm => stages.vdm(&technique),
        Technique::Gdm | Technique::Auto => stages.gdm(scene, codec, &technique),
    }
    stages.run.push("encode");
    Plan {
        technique,
        stages: stages.run.into_iter().map(String::from).collect(),
        skipped: stages.skipped,
    }
}

/// The stages a plan runs and skips, as they are decided.
struct Stages {
    run: Vec<&'static str>,
    skipped: Vec<Skipped>,
}

impl Stages {
    fn skip(&mut self, stage: &str, reason: &str) {
        self.skipped.push(Skipped {
            stage: stage.into(),
            reason: reason.into(),
        });
    }

    /// The radiance transfer's stages, skipped: the technique takes no environment
    /// lighting (scene validation refuses it, and `auto` never picks the technique with it).
    fn skip_radiance_transfer(&mut self) {
        for stage in ["bake_prt", "bake_rtv", "compress_rtv"] {
            self.skip(stage, "the scene calls for no environment_lighting");
        }
    }

    fn transparency(&mut self, scene: &Scene, technique: &TechniqueChoice) {
        let why = format!(
            "the technique is transparency ({}): the medium is rendered from its voxels, with \
             no precomputed visibility",
            technique.reason
        );
        for stage in ["bake_gdm", "occupancy", "compress"] {
            self.skip(stage, &why);
        }
        if is_height_field(scene) {
            self.skip("bake_vdm", &why);
        }
        self.skip_radiance_transfer();
        if scene.transparency.mipmap {
            self.run.push("medium_mips");
        } else {
            self.skip(
                "medium_mips",
                "the scene's transparency.mipmap is off: its renderers read level 0 only",
            );
        }
    }

    fn vdm(&mut self, technique: &TechniqueChoice) {
        self.run.extend(["bake_vdm", "compress_vdm"]);
        let why = format!("the technique is vdm ({})", technique.reason);
        for stage in ["bake_gdm", "occupancy", "compress"] {
            self.skip(stage, &why);
        }
        self.skip_radiance_transfer();
    }

    fn gdm(&mut self, scene: &Scene, codec: GdmCodec, technique: &TechniqueChoice) {
        if is_height_field(scene) {
            self.skip(
                "bake_vdm",
                &format!("the technique is gdm ({})", technique.reason),
            );
        }
        let environment = scene.wants(Effect::EnvironmentLighting);
        match codec {
            GdmCodec::PaperSvd => {
                self.run.extend(["bake_gdm", "compress"]);
                self.skip(
                    "occupancy",
                    "the codec is paper-svd: queries read the compressed GDM",
                );
            }
            GdmCodec::Occupancy => {
                if environment {
                    self.run.push("bake_gdm");
                } else {
                    self.skip(
                        "bake_gdm",
                        "the occupancy codec answers GDM queries by ray marching, and the scene \
                         calls for no environment_lighting (whose RTV needs the baked GDM)",
                    );
                }
                self.run.push("occupancy");
                self.skip("compress", "the codec is occupancy: no GDM is stored");
            }
        }
        if !environment {
            self.skip_radiance_transfer();
            return;
        }
        self.run.extend(["bake_prt", "bake_rtv", "compress_rtv"]);
        if !scene.wants(Effect::MacroShadows) {
            self.skip(
                "prt_visibility",
                "the scene calls for no macro_shadows: the PRT is a pure rotation",
            );
        }
        if !scene.wants(Effect::EnvironmentGloss) {
            self.skip(
                "rtv_gloss",
                "the scene calls for no environment_gloss: the RTV is Lambertian",
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::technique::tests::{RELIEF, TORUS, VOLUME, chosen, scene};
    use mesobake_bake::package::manifest::GdmCodec;

    #[test]
    fn a_vdm_plan_runs_only_the_vdm_stages_and_a_gdm_plan_skips_them() {
        let s = scene(RELIEF, TORUS, "").unwrap();
        let vdm = plan(&s, GdmCodec::Occupancy, chosen(&s));
        assert_eq!(vdm.stages, ["load", "bake_vdm", "compress_vdm", "encode"]);
        let skipped: Vec<&str> = vdm.skipped.iter().map(|k| k.stage.as_str()).collect();
        assert_eq!(
            skipped,
            [
                "bake_gdm",
                "occupancy",
                "compress",
                "bake_prt",
                "bake_rtv",
                "compress_rtv"
            ]
        );
        assert!(
            vdm.skipped[0]
                .reason
                .contains("the technique is vdm (auto: ")
        );

        let s = scene(RELIEF, TORUS, r#", "technique": "gdm""#).unwrap();
        let gdm = plan(&s, GdmCodec::Occupancy, chosen(&s));
        assert_eq!(gdm.stages, ["load", "occupancy", "encode"]);
        assert_eq!(gdm.skipped[0].stage, "bake_vdm");
        assert_eq!(
            gdm.skipped[0].reason,
            "the technique is gdm (the scene asks for gdm)"
        );
        // A volume never had VDM to skip.
        let s = scene(VOLUME, TORUS, "").unwrap();
        let volume = plan(&s, GdmCodec::Occupancy, chosen(&s));
        assert!(volume.skipped.iter().all(|k| k.stage != "bake_vdm"));
    }
}
