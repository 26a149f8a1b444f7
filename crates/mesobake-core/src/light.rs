//! Lights and the surface's reflectance: what the renderers shade with.

use crate::error::{Error, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Blinn–Phong reflectance; the diffuse albedo comes from the volume where it has one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MaterialParams {
    /// Linear diffuse albedo where the mesostructure has none.
    pub albedo: [f64; 3],
    /// Linear specular colour of the Blinn–Phong lobe.
    pub specular: [f64; 3],
    /// Blinn–Phong exponent.
    pub shininess: f64,
}

impl Default for MaterialParams {
    fn default() -> Self {
        MaterialParams {
            albedo: [0.7, 0.7, 0.7],
            specular: [0.15, 0.15, 0.15],
            shininess: 32.0,
        }
    }
}

/// A light source. Radiometric quantities are linear RGB.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Light {
    /// An isotropic point light: irradiance intensity / r² at distance r.
    Point {
        /// Position.
        position: [f64; 3],
        /// Radiant intensity.
        intensity: [f64; 3],
    },
    /// A distant light.
    Directional {
        /// The direction the light travels (from the light towards the scene).
        direction: [f64; 3],
        /// Irradiance on a surface facing the light.
        irradiance: [f64; 3],
    },
    /// Constant light from everywhere, never shadowed: adds albedo × radiance.
    Ambient {
        /// Ambient radiance.
        radiance: [f64; 3],
    },
}

impl Light {
    /// Refuses non-finite positions and negative or non-finite colours, naming the light.
    pub fn validate(&self) -> Result<()> {
        let (vectors, colour): (Vec<[f64; 3]>, [f64; 3]) = match *self {
            Light::Point {
                position,
                intensity,
            } => (vec![position], intensity),
            Light::Directional {
                direction,
                irradiance,
            } => {
                if DVec3::from(direction).length_squared() == 0.0 {
                    return Err(Error::Scene("directional light: zero direction".into()));
                }
                (vec![direction], irradiance)
            }
            Light::Ambient { radiance } => (vec![], radiance),
        };
        if !vectors.iter().flatten().all(|c| c.is_finite())
            || !colour.iter().all(|c| c.is_finite() && *c >= 0.0)
        {
            return Err(Error::Scene(format!(
                "light {self:?}: coordinates must be finite and colours finite and non-negative"
            )));
        }
        Ok(())
    }
}
