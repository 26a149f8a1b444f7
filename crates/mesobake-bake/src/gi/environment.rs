//! Environment lighting: lat-long radiance maps (OpenEXR files or built-in procedural skies)
//! and their projection to 16 RGB spherical-harmonic coefficients.
//!
//! **Lat-long convention.** World space is y-up (as the scenes' cameras are). Texel (i, j) of a
//! W×H map covers azimuth φ ∈ [2πi/W, 2π(i+1)/W] and polar angle θ ∈ [πj/H, π(j+1)/H] from
//! +y, the direction being ω = (sin θ cos φ, cos θ, sin θ sin φ): row 0 is the zenith, the
//! middle row the horizon, column 0 looks along +x.
//!
//! **Projection quadrature.** Each texel is one node at its centre direction, weighted by its
//! exact solid angle Δφ·(cos θⱼ − cos θⱼ₊₁); the weights sum to 4π exactly. For a smooth
//! map the error falls as O(1/H²); a constant map projects exactly.

use super::sh::{self, COEFFS, Sh};
use glam::DVec3;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::Path;

/// An RGB lat-long radiance map.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    width: usize,
    height: usize,
    /// Linear RGB radiance, row-major from the zenith row.
    texels: Vec<[f32; 3]>,
}

/// SH coefficients of an RGB function: one [`Sh`] per channel.
pub type RgbSh = [Sh; 3];

/// The world direction of polar angle θ (from +y) and azimuth φ.
pub fn direction(theta: f64, phi: f64) -> DVec3 {
    let (s, c) = theta.sin_cos();
    DVec3::new(s * phi.cos(), c, s * phi.sin())
}

impl Environment {
    /// A map from texels (row-major, zenith row first), validated: both sides at least 1,
    /// every value finite and ≥ 0.
    pub fn new(width: usize, height: usize, texels: Vec<[f32; 3]>) -> Result<Environment> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return Err(Error::InvalidParameter(format!(
                "environment map: {} texels for {width}×{height}",
                texels.len()
            )));
        }
        if let Some(bad) = texels
            .iter()
            .position(|t| t.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
        {
            return Err(Error::InvalidParameter(format!(
                "environment map: texel ({}, {}) is {:?}; radiance must be finite and ≥ 0",
                bad % width,
                bad / width,
                texels[bad]
            )));
        }
        Ok(Environment {
            width,
            height,
            texels,
        })
    }

    /// Reads the first RGB(A) layer of an OpenEXR lat-long map, refusing sizes over `limits`
    /// before decoding.
    pub fn read_exr(path: &Path, limits: &Limits) -> Result<Environment> {
        let bad = |why: String| {
            Error::InvalidParameter(format!("environment map {}: {why}", path.display()))
        };
        let meta =
            exr::meta::MetaData::read_from_file(path, false).map_err(|e| bad(e.to_string()))?;
        let header = meta
            .headers
            .first()
            .ok_or_else(|| bad("no image layer".into()))?;
        let size = header.layer_size;
        limits.check_image("environment map", size.0 as u64, size.1 as u64)?;
        limits.check("environment texels", (size.0 * size.1) as u64, 12)?;
        let image = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |size, _| (size.0, vec![[0.0f32; 3]; size.0 * size.1]),
            |(width, texels), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                texels[pos.1 * *width + pos.0] = [r, g, b];
            },
        )
        .map_err(|e| bad(e.to_string()))?;
        let (width, texels) = image.layer_data.channel_data.pixels;
        let height = texels.len() / width.max(1);
        Environment::new(width, height, texels).map_err(|e| bad(e.to_string()))
    }

    /// Writes the map as an RGB OpenEXR file (f32).
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        exr::prelude::write_rgb_file(path, self.width, self.height, |x, y| {
            let t = self.texels[y * self.width + x];
            (t[0], t[1], t[2])
        })
        .map_err(|e| Error::InvalidParameter(format!("{}: EXR encoding: {e}", path.display())))
    }

    /// Samples `radiance` at the texel centres of a `width`×`height` map.
    pub fn from_fn(
        width: usize,
        height: usize,
        radiance: impl Fn(DVec3) -> [f64; 3],
    ) -> Result<Environment> {
        let texels = (0..width * height)
            .map(|t| {
                let (theta, phi) = texel_centre(t % width, t / width, width, height);
                radiance(direction(theta, phi)).map(|v| v as f32)
            })
            .collect();
        Environment::new(width, height, texels)
    }

    /// The radiance of the texel that direction `d` (unit) falls in.
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        self.texels[self.texel_index(d)].map(f64::from)
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The texels, row-major from the zenith row.
    pub fn texels(&self) -> &[[f32; 3]] {
        &self.texels
    }

    /// The row-major index of the texel that direction `d` (unit) falls in.
    pub fn texel_index(&self, d: DVec3) -> usize {
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let phi = d.z.atan2(d.x).rem_euclid(2.0 * PI);
        let i = ((phi / (2.0 * PI) * self.width as f64) as usize).min(self.width - 1);
        let j = ((theta / PI * self.height as f64) as usize).min(self.height - 1);
        j * self.width + i
    }

    /// The solid angle of a texel of row `j`.
    pub fn texel_solid_angle(&self, j: usize) -> f64 {
        let (t0, t1) = (
            PI * j as f64 / self.height as f64,
            PI * (j + 1) as f64 / self.height as f64,
        );
        2.0 * PI / self.width as f64 * (t0.cos() - t1.cos())
    }

    /// The 16 SH coefficients per channel, in world space, by the texel quadrature of the
    /// module doc.
    pub fn project(&self) -> RgbSh {
        let mut out = [[0.0; COEFFS]; 3];
        for j in 0..self.height {
            let weight = self.texel_solid_angle(j);
            for i in 0..self.width {
                let (theta, phi) = texel_centre(i, j, self.width, self.height);
                let y = sh::eval(direction(theta, phi));
                let t = self.texels[j * self.width + i];
                for (c, out) in out.iter_mut().enumerate() {
                    let v = f64::from(t[c]) * weight;
                    out.iter_mut().zip(&y).for_each(|(o, y)| *o += v * y);
                }
            }
        }
        out
    }
}

/// (θ, φ) of the centre of texel (i, j).
fn texel_centre(i: usize, j: usize, width: usize, height: usize) -> (f64, f64) {
    (
        PI * (j as f64 + 0.5) / height as f64,
        2.0 * PI * (i as f64 + 0.5) / width as f64,
    )
}

/// A built-in procedural sky, for scenes without an EXR map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Sky {
    /// The CIE overcast sky, L(θ) = L_z·(1 + 2 cos θ)/3 above the horizon, over uniform ground.
    Overcast {
        /// Zenith radiance L_z.
        zenith: [f64; 3],
        /// Radiance below the horizon.
        ground: [f64; 3],
    },
    /// A clear sky: a zenith-to-horizon gradient, uniform ground and a sun disc.
    Clear {
        /// Direction towards the sun (normalized; above the horizon or not).
        sun_direction: [f64; 3],
        /// Radiance of the sun disc.
        sun_radiance: [f64; 3],
        /// Angular radius of the sun disc in degrees (0.1–20).
        sun_radius_degrees: f64,
        /// Sky radiance at the zenith.
        zenith: [f64; 3],
        /// Sky radiance at the horizon.
        horizon: [f64; 3],
        /// Radiance below the horizon.
        ground: [f64; 3],
    },
}

impl Sky {
    /// The radiance towards world direction `d` (unit).
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        match *self {
            Sky::Overcast { zenith, ground } => {
                if d.y < 0.0 {
                    ground
                } else {
                    zenith.map(|z| z * (1.0 + 2.0 * d.y) / 3.0)
                }
            }
            Sky::Clear {
                sun_direction,
                sun_radiance,
                sun_radius_degrees,
                zenith,
                horizon,
                ground,
            } => {
                let sun = DVec3::from(sun_direction).normalize();
                if d.dot(sun) >= sun_radius_degrees.to_radians().cos() {
                    sun_radiance
                } else if d.y < 0.0 {
                    ground
                } else {
                    let t = d.y.sqrt();
                    std::array::from_fn(|c| horizon[c] + (zenith[c] - horizon[c]) * t)
                }
            }
        }
    }

    /// Checks the parameters: radiances finite and ≥ 0, a non-zero sun direction, a sun
    /// radius in 0.1–20°.
    pub fn validate(&self) -> Result<()> {
        let bad = |why: String| Err(Error::InvalidParameter(format!("sky: {why}")));
        let colours: Vec<[f64; 3]> = match *self {
            Sky::Overcast { zenith, ground } => vec![zenith, ground],
            Sky::Clear {
                sun_direction,
                sun_radiance,
                sun_radius_degrees,
                zenith,
                horizon,
                ground,
            } => {
                let d = DVec3::from(sun_direction);
                if !(d.is_finite() && d.length() > 1e-9) {
                    return bad(format!(
                        "sun_direction {sun_direction:?} is not a direction"
                    ));
                }
                if !(0.1..=20.0).contains(&sun_radius_degrees) {
                    return bad(format!(
                        "sun_radius_degrees {sun_radius_degrees} is outside 0.1–20"
                    ));
                }
                vec![sun_radiance, zenith, horizon, ground]
            }
        };
        match colours
            .iter()
            .find(|c| c.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
        {
            Some(c) => bad(format!("radiance {c:?} must be finite and ≥ 0")),
            None => Ok(()),
        }
    }

    /// The sky as a `width`×`height` lat-long map (the same map the path tracer samples).
    pub fn to_map(&self, width: usize, height: usize) -> Result<Environment> {
        self.validate()?;
        Environment::from_fn(width, height, |d| self.radiance(d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_solid_angles_sum_to_the_sphere_and_constants_project_exactly() {
        let env = Environment::new(7, 5, vec![[2.0, 1.0, 0.5]; 35]).unwrap();
        let sh = env.project();
        let root = (4.0 * PI).sqrt();
        for (c, value) in [2.0, 1.0, 0.5].into_iter().enumerate() {
            assert!((sh[c][0] - value * root).abs() < 1e-12);
            // Band 1 of a constant: the texel directions cancel exactly by symmetry.
            for (i, v) in sh[c].iter().enumerate().take(4).skip(1) {
                assert!(v.abs() < 1e-12, "{c} {i}: {v}");
            }
        }
    }

    #[test]
    fn lookups_find_the_texel_of_a_direction() {
        let env = Environment::from_fn(8, 4, |d| [d.x, d.y, d.z].map(|v| v + 1.0)).unwrap();
        for (i, j) in [(0, 0), (3, 1), (7, 3), (5, 2)] {
            let (theta, phi) = texel_centre(i, j, 8, 4);
            let d = direction(theta, phi);
            let expected = [d.x + 1.0, d.y + 1.0, d.z + 1.0];
            assert_eq!(env.radiance(d), expected.map(|v| f64::from(v as f32)));
        }
        // The poles are in the first and last rows.
        assert!((env.radiance(DVec3::Y)[1] - 1.0 - (PI / 8.0).cos()).abs() < 1e-6);
        assert!((env.radiance(-DVec3::Y)[1] - 1.0 + (PI / 8.0).cos()).abs() < 1e-6);
    }

    #[test]
    fn bad_maps_and_skies_are_refused() {
        let e = Environment::new(2, 1, vec![[0.0; 3], [f32::NAN, 0.0, 0.0]]).unwrap_err();
        assert!(e.to_string().contains("texel (1, 0)"), "{e}");
        assert!(Environment::new(2, 2, vec![[0.0; 3]; 3]).is_err());
        assert!(Environment::new(1, 1, vec![[-1.0, 0.0, 0.0]]).is_err());
        let sky = Sky::Clear {
            sun_direction: [0.0; 3],
            sun_radiance: [1.0; 3],
            sun_radius_degrees: 1.0,
            zenith: [1.0; 3],
            horizon: [1.0; 3],
            ground: [1.0; 3],
        };
        assert!(
            sky.validate()
                .unwrap_err()
                .to_string()
                .contains("sun_direction")
        );
    }
}
