//! Direct lighting shared by every renderer: Lambert plus a normalized Blinn–Phong lobe,
//! f = albedo/π + specular·(s + 8)/(8π)·(n·h)^s, times the irradiance E·max(0, n·l) of each
//! point or directional light that is visible, plus albedo × the ambient radiance.

use glam::DVec3;
use mesobake_core::light::Light;
use mesobake_core::light::MaterialParams;
use std::f64::consts::PI;

/// Where every renderer's shadow test starts, in voxels from the hit along the unit
/// texture-space shading normal: clear of the surface that was hit, so that neither the
/// voxel staircase under a smooth normal (ground truth: dotted self-shadowing along the chain's
/// rings when rays started half a voxel back along the camera ray) nor the interpolation
/// footprint of the samples inside that surface (GDM: 0.5 voxel loses 0.5 dB on the torus +
/// chain scene, 1.5 gains nothing) shadows it.
pub const SHADOW_OFFSET: f64 = 1.0;

/// A light as seen from a shaded point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit direction from the point towards the light.
    pub direction: DVec3,
    /// Distance to the light (+∞ for directional lights).
    pub distance: f64,
    /// Irradiance on a surface facing the light.
    pub irradiance: DVec3,
}

/// The incident light of a point or directional `light` at `p`; `None` for ambient light
/// or a point light at `p` itself.
pub fn incident(light: &Light, p: DVec3) -> Option<Incident> {
    match *light {
        Light::Point {
            position,
            intensity,
        } => {
            let to = DVec3::from(position) - p;
            let r2 = to.length_squared();
            (r2 > 0.0).then(|| Incident {
                direction: to / r2.sqrt(),
                distance: r2.sqrt(),
                irradiance: DVec3::from(intensity) / r2,
            })
        }
        Light::Directional {
            direction,
            irradiance,
        } => Some(Incident {
            direction: -DVec3::from(direction).normalize(),
            distance: f64::INFINITY,
            irradiance: DVec3::from(irradiance),
        }),
        Light::Ambient { .. } => None,
    }
}

/// Outgoing radiance towards `to_eye` (unit) of a point with unit normal `n` and linear
/// `albedo`; `visible` says whether an incident light reaches the point (the shadow test),
/// and is only asked for lights in front of the surface.
pub fn shade(
    lights: &[Light],
    material: &MaterialParams,
    p: DVec3,
    n: DVec3,
    albedo: DVec3,
    to_eye: DVec3,
    mut visible: impl FnMut(&Incident) -> bool,
) -> DVec3 {
    shade_transmitted(lights, material, p, Some(n), albedo, to_eye, |_, inc| {
        f64::from(u8::from(visible(inc)))
    })
}

/// [`shade`] with fractional visibility: `transmittance(light index, incident)` says which
/// fraction of an incident light reaches the point. A point without a normal (`None`: a translucent medium where
/// its opacity does not vary) scatters every light as a surface facing it would.
pub fn shade_transmitted(
    lights: &[Light],
    material: &MaterialParams,
    p: DVec3,
    n: Option<DVec3>,
    albedo: DVec3,
    to_eye: DVec3,
    mut transmittance: impl FnMut(usize, &Incident) -> f64,
) -> DVec3 {
    let mut out = DVec3::ZERO;
    let specular = DVec3::from(material.specular);
    let s = material.shininess;
    for (index, light) in lights.iter().enumerate() {
        if let Light::Ambient { radiance } = light {
            out += albedo * DVec3::from(*radiance);
            continue;
        }
        let Some(inc) = incident(light, p) else {
            continue;
        };
        let n = n.unwrap_or(inc.direction);
        let cos = n.dot(inc.direction);
        if cos <= 0.0 {
            continue;
        }
        let visible = transmittance(index, &inc);
        if visible <= 0.0 {
            continue;
        }
        let h = (inc.direction + to_eye).normalize_or_zero();
        let lobe = specular * ((s + 8.0) / (8.0 * PI) * n.dot(h).max(0.0).powf(s));
        out += (albedo / PI + lobe) * inc.irradiance * (cos * visible);
    }
    out
}
