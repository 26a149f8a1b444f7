//! Which technique renders a scene's mesostructure: the generalized displacement map (GDM),
//! the view-dependent displacement map (VDM), or semi-transparent 3D textures
//! (`transparency`). A scene names one, or `auto`; [`choose`] resolves `auto` and records
//! why, and the plan ([`super::plan`]) bakes only that technique's stages.
//!
//! A translucent mesostructure (a built-in `medium`, a volume with an opacity channel) or
//! the `transparency` effect (any mesostructure as a medium, opaque voxels α = 1) is
//! rendered by `transparency` only: `auto` picks it, and naming `gdm` or `vdm` is an error.
//!
//! `auto` picks VDM where it applies and is the cheaper technique: a height-field
//! mesostructure (VDM represents nothing else), on a closed base surface (at an open
//! boundary the VDM has no side faces, so the relief is lost at the edges, which the GDM's
//! fins keep), lit by point and directional lights only (environment lighting needs the
//! RTV, which is baked from the GDM), with the GDM renderer's accuracy knobs at the paper's
//! setting (they set nothing in a VDM render), and a relief shallow enough for the VDM's
//! curvature range (|c|·depth < 1 in tiles). Everywhere else it picks GDM.

use super::{MesostructureSource, Scene};
use mesobake_bake::package::AnyPackage;
use mesobake_bake::surface::base_mesh::MeshReport;
use mesobake_bake::surface::shell::Shell;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::quality::Quality;
use serde::{Deserialize, Serialize};

/// The technique a scene asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Technique {
    /// VDM where it applies, GDM elsewhere (see the module documentation).
    #[default]
    Auto,
    /// The generalized displacement map: any mesostructure, fins at open boundaries.
    Gdm,
    /// The view-dependent displacement map: height fields only.
    Vdm,
    /// Semi-transparent 3D textures: the mesostructure as a translucent medium, rendered
    /// through the shell's cells with no precomputed visibility.
    Transparency,
}

impl Technique {
    /// The technique whose renderers read `package`: `gdm`, `vdm` or `transparency`.
    pub fn of_package(package: &AnyPackage) -> Technique {
        match package {
            AnyPackage::Gdm(_) => Technique::Gdm,
            AnyPackage::Vdm(_) => Technique::Vdm,
            AnyPackage::Medium(_) => Technique::Transparency,
        }
    }

    /// Whether this is `auto` (left out when a scene is written).
    pub fn is_auto(&self) -> bool {
        *self == Technique::Auto
    }

    /// `auto`, `gdm` or `vdm`.
    pub fn name(self) -> &'static str {
        match self {
            Technique::Auto => "auto",
            Technique::Gdm => "gdm",
            Technique::Vdm => "vdm",
            Technique::Transparency => "transparency",
        }
    }
}

/// The technique chosen for a scene (never `auto`) and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct TechniqueChoice {
    /// `gdm`, `vdm` or `transparency`.
    pub technique: Technique,
    /// Why: the scene named it, or what decided `auto`.
    pub reason: String,
}

impl Default for TechniqueChoice {
    /// GDM, the only technique of plans made before scenes could choose.
    fn default() -> Self {
        TechniqueChoice {
            technique: Technique::Gdm,
            reason: "the only technique when this plan was made".into(),
        }
    }
}

/// What the choice needs to know of a scene's surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Base-mesh edges used by one triangle (0: a closed surface).
    pub boundary_edges: usize,
    /// The relief's depth in tiles on the shell ([`super::vdm::relief_depth`]); none where the
    /// shell has no area to map a relief onto.
    pub relief_depth: Option<f64>,
    /// Whether the mesostructure as loaded is a translucent medium: what the scene's text does
    /// not tell of a volume file with an opacity channel.
    pub translucent: bool,
}

impl Surface {
    /// The facts of a base mesh validated as `base`, extruded into `shell`.
    pub fn of(base: &MeshReport, shell: &Shell) -> Surface {
        Surface {
            boundary_edges: base.boundary_edges,
            relief_depth: super::vdm::relief_depth(shell).ok(),
            translucent: false,
        }
    }

    /// This surface, with a mesostructure that is (or is not) a translucent medium.
    pub fn with_translucent(self, translucent: bool) -> Surface {
        Surface {
            translucent,
            ..self
        }
    }

    /// Why the scene's VDM grid cannot hold its relief on this surface, if it cannot.
    fn vdm_misfit(&self, scene: &Scene) -> Option<String> {
        let Some(depth) = self.relief_depth else {
            return Some("the shell's reference surface has no area to map a relief onto".into());
        };
        let e = scene.vdm.grid().validate(depth).err()?;
        Some(format!(
            "the relief is {depth:.3} tiles deep on this shell, too deep for the VDM's \
             curvature range ({e}); a thinner shell or a narrower vdm.curvature_range fits it"
        ))
    }
}

/// Checks that a scene whose technique is `choice` can bake it on `surface`: a VDM's grid
/// must hold the relief's depth; neither the GDM nor the VDM represents a translucent
/// medium; the translucent-media pipeline takes no environment lighting (a volume file's
/// opacity channel is found only here).
pub fn check(scene: &Scene, choice: &TechniqueChoice, surface: &Surface) -> Result<()> {
    if choice.technique == Technique::Transparency {
        if scene.wants(Effect::EnvironmentLighting) {
            return Err(Error::Scene(MEDIA_TAKE_NO_ENVIRONMENT.into()));
        }
        return Ok(());
    }
    if matches!(scene.mesostructure, MesostructureSource::Medium(_)) || surface.translucent {
        let what = match choice.technique {
            Technique::Vdm => "a VDM",
            _ => "a GDM",
        };
        return Err(Error::Scene(
            mesobake_bake::mesostructure::medium::translucent_refusal(what),
        ));
    }
    match surface.vdm_misfit(scene) {
        Some(why) if choice.technique == Technique::Vdm => {
            Err(Error::Scene(format!("technique vdm: {why}")))
        }
        _ => Ok(()),
    }
}

/// Whether the scene's mesostructure is a height field (a PNG or a built-in relief).
pub fn is_height_field(scene: &Scene) -> bool {
    matches!(
        scene.mesostructure,
        MesostructureSource::HeightField(_) | MesostructureSource::Relief(_)
    )
}

/// Why a translucent scene cannot have environment lighting.
const MEDIA_TAKE_NO_ENVIRONMENT: &str = "the translucent-media pipeline shades point, \
     directional and ambient lights: environment_lighting needs the RTV, which is baked from \
     the GDM of an opaque mesostructure";

/// Whether the scene calls for the translucent-media pipeline: it names the technique or the
/// `transparency` effect, or its mesostructure is a built-in medium. (A volume file with an
/// opacity channel is found translucent when it is read.)
pub fn is_translucent(scene: &Scene) -> bool {
    scene.technique == Technique::Transparency
        || scene.wants(Effect::Transparency)
        || matches!(scene.mesostructure, MesostructureSource::Medium(_))
}

/// Checks what a scene's technique needs of the scene alone: VDM renders height fields lit by
/// point and directional lights; the GDM and the VDM render no translucency; the
/// translucent-media pipeline takes no environment lighting.
pub fn validate(scene: &Scene) -> Result<()> {
    let opaque_only = matches!(scene.technique, Technique::Gdm | Technique::Vdm);
    if opaque_only && scene.wants(Effect::Transparency) {
        return Err(Error::Scene(format!(
            "technique {} renders opaque mesostructure only: the transparency effect needs \
             the transparency technique (or auto)",
            scene.technique.name()
        )));
    }
    if is_translucent(scene) && scene.wants(Effect::EnvironmentLighting) {
        return Err(Error::Scene(MEDIA_TAKE_NO_ENVIRONMENT.into()));
    }
    if scene.technique != Technique::Vdm {
        return Ok(());
    }
    if !is_height_field(scene) {
        return Err(Error::Scene(
            "technique vdm needs a height-field mesostructure (a height_field PNG or a built-in \
             relief); use gdm or auto for volumes and mesh tiles"
                .into(),
        ));
    }
    if scene.wants(Effect::EnvironmentLighting) {
        return Err(Error::Scene(
            "technique vdm shades point and directional lights only: environment_lighting \
             needs the RTV, which is baked from the GDM (use gdm or auto)"
                .into(),
        ));
    }
    Ok(())
}

/// The technique for `scene` on `surface`: the scene's own, or `auto` resolved as the
/// module documentation says.
pub fn choose(scene: &Scene, surface: &Surface) -> TechniqueChoice {
    let open = match surface.boundary_edges {
        0 => None,
        edges => Some(format!(
            "the base mesh is open ({edges} boundary edges), where VDM loses the relief at the \
             edges and the GDM's fins keep it"
        )),
    };
    let (technique, reason) = match scene.technique {
        Technique::Transparency => (
            Technique::Transparency,
            "the scene asks for transparency".to_owned(),
        ),
        Technique::Auto if is_translucent(scene) || surface.translucent => (
            Technique::Transparency,
            if scene.wants(Effect::Transparency) {
                "auto: the scene calls for the transparency effect"
            } else {
                "auto: the mesostructure is a translucent medium, which only semi-transparent \
                 3D textures represent"
            }
            .to_owned(),
        ),
        Technique::Gdm => (Technique::Gdm, "the scene asks for gdm".to_owned()),
        Technique::Vdm => (
            Technique::Vdm,
            match open {
                Some(why) => format!("the scene asks for vdm, although {why}"),
                None => "the scene asks for vdm".to_owned(),
            },
        ),
        Technique::Auto => {
            let gdm = if !is_height_field(scene) {
                Some(
                    "the mesostructure is not a height field, which only the GDM represents"
                        .to_owned(),
                )
            } else if scene.wants(Effect::EnvironmentLighting) {
                Some("environment_lighting needs the RTV, which is baked from the GDM".to_owned())
            } else if scene.quality != Quality::default() || scene.gdm_refinements > 0 {
                Some(
                    "the scene sets the GDM renderer's accuracy knobs (quality or \
                     gdm_refinements)"
                        .to_owned(),
                )
            } else {
                open.or_else(|| surface.vdm_misfit(scene))
            };
            match gdm {
                Some(why) => (Technique::Gdm, format!("auto: {why}")),
                None => (
                    Technique::Vdm,
                    "auto: a height field on a closed surface under point and directional \
                     lights, which VDM renders with one triangle per base triangle and the \
                     surface's curvature"
                        .to_owned(),
                ),
            }
        }
    };
    TechniqueChoice { technique, reason }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A small scene of `mesostructure` on the built-in `mesh`, with `extra` keys.
    pub(crate) fn scene(mesostructure: &str, mesh: &str, extra: &str) -> Result<Scene> {
        Scene::from_json(&format!(
            r#"{{
                "base_mesh": {{ "builtin": {mesh} }},
                "mesostructure": {mesostructure},
                "resolution": [16, 16, 8],
                "shell": {{ "thickness": 0.05, "tiles_per_uv": [4, 2] }},
                "camera": {{ "eye": [0, 2, 3], "target": [0, 0, 0], "fov_y_degrees": 40,
                             "width": 8, "height": 8 }},
                "environment": {{ "sky": {{ "overcast": {{ "zenith": [1, 1, 1], "ground": [0, 0, 0] }} }} }}
                {extra}
            }}"#
        ))
    }

    pub(crate) const TORUS: &str = r#"{ "torus": {} }"#;
    const PLANE: &str = r#"{ "plane": {} }"#;
    pub(crate) const RELIEF: &str = r#"{ "relief": "bumps" }"#;
    pub(crate) const VOLUME: &str = r#"{ "sample": "weave" }"#;

    fn surface(s: &Scene) -> Surface {
        let (base, report) = match &s.base_mesh {
            crate::BaseMeshSource::Builtin(b) => b.build().unwrap(),
            _ => unreachable!(),
        };
        Surface::of(&report, &Shell::new(&base, s.shell).unwrap())
    }

    /// The technique `s` gets.
    pub(crate) fn chosen(s: &Scene) -> TechniqueChoice {
        choose(s, &surface(s))
    }

    #[test]
    fn auto_picks_vdm_only_for_a_height_field_on_a_closed_surface_under_point_lights() {
        let vdm = chosen(&scene(RELIEF, TORUS, "").unwrap());
        assert_eq!(vdm.technique, Technique::Vdm, "{vdm:?}");
        assert!(vdm.reason.starts_with("auto: a height field"), "{vdm:?}");
        for (s, why) in [
            (scene(VOLUME, TORUS, ""), "not a height field"),
            (
                scene(RELIEF, PLANE, ""),
                "the base mesh is open (256 boundary edges)",
            ),
            (
                scene(RELIEF, TORUS, r#", "effects": ["environment_lighting"]"#),
                "environment_lighting needs the RTV",
            ),
            (
                scene(RELIEF, TORUS, r#", "quality": "high""#),
                "accuracy knobs",
            ),
            (
                scene(RELIEF, TORUS, r#", "gdm_refinements": 2"#),
                "accuracy knobs",
            ),
            (
                scene(
                    RELIEF,
                    TORUS,
                    r#", "vdm": { "curvature_range": [-30, 30] }"#,
                ),
                "too deep for the VDM's curvature range",
            ),
        ] {
            let c = chosen(&s.unwrap());
            assert_eq!(c.technique, Technique::Gdm, "{c:?}");
            assert!(
                c.reason.starts_with("auto: ") && c.reason.contains(why),
                "{c:?}"
            );
        }
    }

    #[test]
    fn a_named_technique_is_kept_and_vdm_on_an_open_surface_says_what_it_loses() {
        let s = scene(RELIEF, TORUS, r#", "technique": "gdm""#).unwrap();
        assert_eq!(chosen(&s).technique, Technique::Gdm);
        let c = chosen(&scene(RELIEF, PLANE, r#", "technique": "vdm""#).unwrap());
        assert_eq!(c.technique, Technique::Vdm);
        assert!(c.reason.contains("loses the relief at the edges"), "{c:?}");
        // Asked for where its grid cannot hold the relief: an error naming both.
        let s = scene(
            RELIEF,
            TORUS,
            r#", "technique": "vdm", "vdm": { "curvature_range": [-30, 30] }"#,
        )
        .unwrap();
        let e = check(&s, &chosen(&s), &surface(&s))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("technique vdm: the relief is") && e.contains("|c|·depth"),
            "{e}"
        );
        let s = scene(RELIEF, TORUS, "").unwrap();
        check(&s, &chosen(&s), &surface(&s)).unwrap();
    }

    #[test]
    fn vdm_is_refused_for_volumes_and_environment_lighting_by_name() {
        let e = scene(VOLUME, TORUS, r#", "technique": "vdm""#).unwrap_err();
        assert!(e.to_string().contains("needs a height-field"), "{e}");
        let extra = r#", "technique": "vdm", "effects": ["environment_lighting"]"#;
        let e = scene(RELIEF, TORUS, extra).unwrap_err();
        assert!(e.to_string().contains("environment_lighting"), "{e}");
        let e = scene(RELIEF, TORUS, r#", "technique": "vdn""#).unwrap_err();
        assert!(e.to_string().contains("unknown variant"), "{e}");
    }
}
