//! The accuracy knobs of the per-pixel GDM algorithm: each of the paper's approximations
//! that the CPU specification (`gdm_renderer`) and the WGSL pipeline can replace by a more
//! exact computation, chosen by the scene (`"quality"`, docs/scene-format.md) as a preset or
//! setting by setting. The GDM query itself is the package's codec (the default `occupancy`
//! codec marches the voxels exactly; `paper-svd` reconstructs the paper's factors).
//!
//! | knob | `paper` | `balanced` | `high` | what it replaces |
//! |---|---|---|---|---|
//! | `shadows` | `local` | `shell` | `shell` | the light's visibility: one GDM query along the light in the hit's prism (a locally flat volume), or the algorithm traced towards the light through the whole shell |
//! | `chords` | 1 | 1 | 8 | the ray's texture-space path in a prism: one straight segment, or the image of the ray split into n chords at points mapped with the exact inverse of the prism mapping |
//! | `frame` | `mean` | `jacobian` | `jacobian` | the shading frame at the hit: the prism's mean frame, or the inverse Jacobian of the prism mapping at the hit |
//!
//! Measured on torus-chain at 512² against the exact truth (docs/BENCHMARKS.md): `paper`
//! 17.9 dB, shell shadows alone 23.9 dB at 1.1× its time, `high` 32.5 dB and 0.15 % mask at
//! 2.7× (0.15 of the truth's time); 4 chords instead of 8 give 30.2 dB at 2×.

use crate::error::{Error, Result};
use serde::de::{self, Deserializer, MapAccess, Visitor};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Most GDM refinement queries per hit a scene may ask for (`gdm_refinements`).
pub const MAX_GDM_REFINEMENTS: u32 = 8;

/// Most chords a scene may ask for per prism segment.
pub const MAX_CHORDS: u32 = 16;

/// How the light's visibility is tested at a hit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShadowMethod {
    /// The paper's: one query along the light from the hit (GDM: in texture space, from one
    /// voxel off the hit; VDM: at the light's exit from the reference surface), so only
    /// mesostructure of the same neighbourhood casts shadows.
    #[default]
    Local,
    /// The per-pixel algorithm itself traced towards the light (GDM: the rest of the hit's
    /// prism, then every prism the ray enters; VDM: the local test, then every top triangle
    /// the ray enters), so curvature, distant mesostructure and the base mesh's other side
    /// cast shadows.
    Shell,
}

/// The frame that maps the shading normal to object space and lights to texture space.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShadingFrame {
    /// The paper's: the prism's mean frame (base edges to UV edges, mean extrusion to z).
    #[default]
    Mean,
    /// The inverse of the prism mapping's Jacobian at the hit.
    Jacobian,
}

/// The named presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// The paper's algorithm, unchanged.
    Paper,
    /// The two knobs that cost little: shell shadows and the Jacobian frame (one chord).
    Balanced,
    /// Every knob at its accurate setting (shell shadows, 8 chords, Jacobian frame).
    High,
}

impl Preset {
    /// Every preset, cheapest first.
    pub const ALL: [Preset; 3] = [Preset::Paper, Preset::Balanced, Preset::High];

    /// The settings of this preset.
    pub const fn quality(self) -> Quality {
        match self {
            Preset::Paper => Quality {
                shadows: ShadowMethod::Local,
                chords: 1,
                frame: ShadingFrame::Mean,
            },
            Preset::Balanced => Quality {
                shadows: ShadowMethod::Shell,
                chords: 1,
                frame: ShadingFrame::Jacobian,
            },
            Preset::High => Quality {
                shadows: ShadowMethod::Shell,
                chords: 8,
                frame: ShadingFrame::Jacobian,
            },
        }
    }

    /// The preset's name as scenes spell it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Paper => "paper",
            Preset::Balanced => "balanced",
            Preset::High => "high",
        }
    }
}

/// The settings of the per-pixel algorithm's accuracy knobs. In a scene: a preset's name
/// (`"high"`), or an object with an optional `preset` (default `paper`) and any settings
/// that override it (`{"preset": "paper", "chords": 8}`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Quality {
    /// The shadow test.
    pub shadows: ShadowMethod,
    /// Chords per prism segment (1 = the paper's straight segment; at most [`MAX_CHORDS`]).
    pub chords: u32,
    /// The shading frame.
    pub frame: ShadingFrame,
}

impl Default for Quality {
    /// The paper's algorithm.
    fn default() -> Self {
        Preset::Paper.quality()
    }
}

impl Quality {
    /// Whether these are the paper's settings.
    pub fn is_paper(&self) -> bool {
        *self == Quality::default()
    }

    /// The preset these settings equal, if any.
    pub fn preset(&self) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.quality() == *self)
    }

    /// A short label: the preset's name, or the settings, e.g. `shell+chords4+jacobian`.
    pub fn label(&self) -> String {
        if let Some(p) = self.preset() {
            return p.name().into();
        }
        format!(
            "{}+chords{}+{}",
            match self.shadows {
                ShadowMethod::Local => "local",
                ShadowMethod::Shell => "shell",
            },
            self.chords,
            match self.frame {
                ShadingFrame::Mean => "mean",
                ShadingFrame::Jacobian => "jacobian",
            }
        )
    }

    /// Checks the settings' ranges.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_CHORDS).contains(&self.chords) {
            return Err(Error::Scene(format!(
                "quality.chords must be between 1 and {MAX_CHORDS}, got {}",
                self.chords
            )));
        }
        Ok(())
    }
}

/// The object form of a scene's `quality`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct QualityObject {
    #[serde(default)]
    preset: Option<Preset>,
    shadows: Option<ShadowMethod>,
    chords: Option<u32>,
    frame: Option<ShadingFrame>,
}

impl<'de> Deserialize<'de> for Quality {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> std::result::Result<Self, D::Error> {
        struct QualityVisitor;
        impl<'de> Visitor<'de> for QualityVisitor {
            type Value = Quality;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a preset name (paper, balanced or high) or an object of settings")
            }

            fn visit_str<E: de::Error>(self, name: &str) -> std::result::Result<Quality, E> {
                Preset::deserialize(de::value::StrDeserializer::<E>::new(name)).map(Preset::quality)
            }

            fn visit_map<A: MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Quality, A::Error> {
                let o = QualityObject::deserialize(de::value::MapAccessDeserializer::new(map))?;
                let base = o.preset.unwrap_or(Preset::Paper).quality();
                Ok(Quality {
                    shadows: o.shadows.unwrap_or(base.shadows),
                    chords: o.chords.unwrap_or(base.chords),
                    frame: o.frame.unwrap_or(base.frame),
                })
            }
        }
        deserializer.deserialize_any(QualityVisitor)
    }
}

impl std::str::FromStr for Preset {
    type Err = Error;

    /// `paper`, `balanced` or `high`.
    fn from_str(text: &str) -> Result<Preset> {
        serde_json::from_value(serde_json::Value::String(text.trim().to_owned())).map_err(|_| {
            Error::InvalidParameter(format!(
                "quality preset {text:?}: expected paper, balanced or high"
            ))
        })
    }
}

impl std::str::FromStr for Quality {
    type Err = Error;

    /// A preset's name, or JSON as in a scene file.
    fn from_str(text: &str) -> Result<Quality> {
        let json = if text.trim_start().starts_with('{') {
            text.to_owned()
        } else {
            serde_json::to_string(text.trim()).expect("a string serializes")
        };
        let quality: Quality = serde_json::from_str(&json)
            .map_err(|e| Error::InvalidParameter(format!("quality {text:?}: {e}")))?;
        quality.validate().map(|()| quality)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_and_overrides_parse() {
        let q: Quality = "high".parse().unwrap();
        assert_eq!(q, Preset::High.quality());
        let q: Quality = r#"{"chords": 8}"#.parse().unwrap();
        assert_eq!(q.chords, 8);
        assert_eq!(q.shadows, ShadowMethod::Local);
        assert_eq!(q.label(), "local+chords8+mean");
        let q: Quality = r#"{"preset": "high", "frame": "mean"}"#.parse().unwrap();
        assert_eq!(
            (q.shadows, q.chords, q.frame),
            (ShadowMethod::Shell, 8, ShadingFrame::Mean)
        );
        for bad in [
            "ultra",
            r#"{"chords": 0}"#,
            r#"{"chords": 99}"#,
            r#"{"chord": 2}"#,
        ] {
            assert!(bad.parse::<Quality>().is_err(), "{bad}");
        }
        // The serialized form reads back.
        let q = Preset::High.quality();
        let back: Quality = serde_json::from_str(&serde_json::to_string(&q).unwrap()).unwrap();
        assert_eq!(back, q);
    }
}
