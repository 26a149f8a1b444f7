//! Where an object stands in its scene: its base mesh scaled uniformly, rotated about the x,
//! then y, then z axis, then translated (after the scene's `mesh_scale`).

use glam::{DMat3, DVec3};
use mesobake_core::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// An object's placement: p ↦ translate + R·(scale·p), R = R_z·R_y·R_x.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectTransform {
    /// Added last, in scene units.
    pub translate: [f64; 3],
    /// Rotations about x, y and z in degrees, applied in that order.
    pub rotate_degrees: [f64; 3],
    /// Uniform scale, applied first (> 0).
    pub scale: f64,
}

impl Default for ObjectTransform {
    fn default() -> Self {
        ObjectTransform {
            translate: [0.0; 3],
            rotate_degrees: [0.0; 3],
            scale: 1.0,
        }
    }
}

impl ObjectTransform {
    /// Whether it leaves every point where it is.
    pub fn is_identity(&self) -> bool {
        *self == ObjectTransform::default()
    }

    /// Refuses a scale that is not finite and positive, or a non-finite angle or offset.
    pub fn validate(&self) -> Result<()> {
        let finite = self
            .translate
            .iter()
            .chain(&self.rotate_degrees)
            .all(|v| v.is_finite());
        if !(finite && self.scale.is_finite() && self.scale > 0.0) {
            return Err(Error::Scene(format!(
                "transform {self:?}: translate and rotate_degrees must be finite, scale finite \
                 and positive"
            )));
        }
        Ok(())
    }

    /// The rotation R = R_z·R_y·R_x.
    pub fn rotation(&self) -> DMat3 {
        let [x, y, z] = self.rotate_degrees.map(f64::to_radians);
        DMat3::from_rotation_z(z) * DMat3::from_rotation_y(y) * DMat3::from_rotation_x(x)
    }

    /// Moves the points and turns the unit normals.
    pub fn apply(&self, positions: &mut [DVec3], normals: &mut [DVec3]) {
        let r = self.rotation();
        let t = DVec3::from(self.translate);
        for p in positions {
            *p = t + r * (*p * self.scale);
        }
        for n in normals {
            *n = r * *n;
        }
    }
}
