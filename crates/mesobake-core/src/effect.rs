//! The effects a scene can call for: nothing else is baked or shaded.

use serde::{Deserialize, Serialize};

/// An effect a scene can call for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Mesostructure silhouettes: rays that leave the shell without a hit show the background.
    /// Intrinsic to GDM rendering, listed for completeness.
    Silhouettes,
    /// Shadows from point and directional lights.
    Shadows,
    /// Distant light from the scene's `environment`, through the macro-scale PRT and the
    /// mesostructure's radiance transfer volume (bounces included).
    EnvironmentLighting,
    /// The base mesh shadowing the environment light (shadowed PRT; without it, the PRT is a
    /// pure rotation).
    MacroShadows,
    /// The material's specular lobe under the environment light: a view-dependent RTV
    /// (without it, the RTV is Lambertian and view-independent).
    EnvironmentGloss,
    /// The mesostructure as a semi-transparent 3D texture: its opacity channel, or α = 1 in
    /// its solid voxels, rendered by the translucent-media pipeline (implied by a translucent
    /// mesostructure).
    Transparency,
}
