//! The material volume: per-voxel albedo and surface normals of the mesostructure, sampled
//! the same way by every renderer (and, later, uploaded as a 3D texture by the preview).
//!
//! Normals are the negated gradient of the solid fraction, by a 3×3×3 Sobel filter over voxel
//! centres (periodic in x and y, clamped in z), trilinearly interpolated and normalized. The
//! fraction is a volume's density clamped to [0, 1] (the samples' 27-point coverage, which
//! gives smooth normals where binary occupancy gives facets), or 0/1 occupancy. The volume
//! under a height field takes the height field's own normals instead.
//! Albedo is looked up in the voxel a quarter voxel past the hit along the ray (inside the
//! solid that was hit), falling back to the scene's material albedo where the volume has none.

use crate::mesostructure::height_field::HeightField;
use crate::mesostructure::volume::{Occupancy, Volume};
use glam::{DVec3, Vec3};
use mesobake_core::color::srgb_to_linear;
use mesobake_package::grid::{Dims, Wrap, trilinear_corners};

/// How far past a hit, in voxels along the ray, the albedo is read.
pub const ALBEDO_DEPTH: f64 = 0.25;

/// Albedo and normal volumes over a voxel grid.
#[derive(Clone, Debug)]
pub struct MaterialVolume {
    dims: Dims,
    /// Linear albedo per voxel, or `None` for the uniform default.
    albedo: Option<Vec<Vec3>>,
    default_albedo: DVec3,
    /// Unnormalized outward normal (−∇ solid fraction) per voxel centre.
    normal: Vec<Vec3>,
}

impl MaterialVolume {
    /// From a volume: its occupancy and its sRGB albedo (converted to linear).
    pub fn from_volume(volume: &Volume, default_albedo: DVec3) -> Self {
        let dims = volume.dims();
        let density = volume.density();
        Self::from_field(
            dims,
            |i, j, k| density[dims.index(i, j, k)].clamp(0.0, 1.0),
            volume.albedo().map(linear_albedo),
            default_albedo,
        )
    }

    /// For the volume under a height field ([`HeightField::to_volume`]) on grid `dims`: the
    /// height field's own normal in every voxel of a column, from the gradient of the
    /// bilinear heights by central differences one pixel apart at the column's centre (in
    /// voxel units (−Z/X·∂h/∂u, −Z/Y·∂h/∂v, 1)), instead of the staircase's Sobel gradient;
    /// what a VDM renderer shades with.
    pub fn from_height_field(field: &HeightField, dims: Dims, default_albedo: DVec3) -> Self {
        let (w, h) = field.size();
        let (du, dv) = (1.0 / f64::from(w), 1.0 / f64::from(h));
        let column = |i: u32, j: u32| {
            let u = (f64::from(i) + 0.5) / f64::from(dims.x);
            let v = (f64::from(j) + 0.5) / f64::from(dims.y);
            let gu = (field.sample(u + du, v) - field.sample(u - du, v)) / (2.0 * du);
            let gv = (field.sample(u, v + dv) - field.sample(u, v - dv)) / (2.0 * dv);
            let z = f64::from(dims.z);
            Vec3::new(
                (-gu * z / f64::from(dims.x)) as f32,
                (-gv * z / f64::from(dims.y)) as f32,
                1.0,
            )
        };
        let columns: Vec<Vec3> = (0..dims.y)
            .flat_map(|j| (0..dims.x).map(move |i| (i, j)))
            .map(|(i, j)| column(i, j))
            .collect();
        let normal = (0..dims.z).flat_map(|_| columns.iter().copied()).collect();
        MaterialVolume {
            dims,
            albedo: None,
            default_albedo,
            normal,
        }
    }

    /// From an occupancy grid and optional per-voxel sRGB albedo.
    pub fn from_occupancy(
        occ: &Occupancy,
        albedo: Option<&[[u8; 3]]>,
        default_albedo: DVec3,
    ) -> Self {
        Self::from_field(
            occ.dims(),
            |i, j, k| occ.get(i, j, k) as u8 as f32,
            albedo.map(linear_albedo),
            default_albedo,
        )
    }

    /// For a translucent medium: normals from the gradient of `opacity` (per voxel, x fastest,
    /// in [0, 1]) as the solid fraction, and optional per-voxel linear albedo.
    pub fn from_opacity(
        dims: Dims,
        opacity: &[f32],
        albedo: Option<Vec<Vec3>>,
        default_albedo: DVec3,
    ) -> Self {
        Self::from_field(
            dims,
            |i, j, k| opacity[dims.index(i, j, k)],
            albedo,
            default_albedo,
        )
    }

    /// From a solid fraction per voxel (`field(i, j, k)` in [0, 1]) and optional per-voxel
    /// linear albedo.
    fn from_field(
        dims: Dims,
        field: impl Fn(u32, u32, u32) -> f32,
        albedo: Option<Vec<Vec3>>,
        default_albedo: DVec3,
    ) -> Self {
        let (wx, wy) = (Wrap::new(dims.x), Wrap::new(dims.y));
        let at = |i: i64, j: i64, k: i64| -> f32 {
            let k = k.clamp(0, dims.z as i64 - 1) as u32;
            field(wx.apply(i) as u32, wy.apply(j) as u32, k)
        };
        let weight = [1.0f32, 2.0, 1.0];
        let mut normal = vec![Vec3::ZERO; dims.voxel_count() as usize];
        for k in 0..dims.z as i64 {
            for j in 0..dims.y as i64 {
                for i in 0..dims.x as i64 {
                    let mut g = Vec3::ZERO;
                    for a in -1i64..=1 {
                        for b in -1i64..=1 {
                            let w = weight[(a + 1) as usize] * weight[(b + 1) as usize];
                            g.x += w * (at(i + 1, j + a, k + b) - at(i - 1, j + a, k + b));
                            g.y += w * (at(i + a, j + 1, k + b) - at(i + a, j - 1, k + b));
                            g.z += w * (at(i + a, j + b, k + 1) - at(i + a, j + b, k - 1));
                        }
                    }
                    normal[dims.index(i as u32, j as u32, k as u32)] = -g;
                }
            }
        }
        MaterialVolume {
            dims,
            albedo,
            default_albedo,
            normal,
        }
    }

    /// From stored parts (a medium package's level): per-voxel linear albedo and
    /// unnormalized outward normals, x fastest, `dims.voxel_count()` each.
    pub fn from_parts(dims: Dims, albedo: Vec<Vec3>, normal: Vec<Vec3>) -> Self {
        debug_assert!(albedo.len() == normal.len() && normal.len() == dims.voxel_count() as usize);
        MaterialVolume {
            dims,
            albedo: Some(albedo),
            default_albedo: DVec3::ZERO,
            normal,
        }
    }

    /// The grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Unnormalized outward normals per voxel centre, x fastest (what the preview uploads).
    pub fn normal_voxels(&self) -> &[Vec3] {
        &self.normal
    }

    /// Linear albedo per voxel, x fastest, or `None` where the material is uniform.
    pub fn albedo_voxels(&self) -> Option<&[Vec3]> {
        self.albedo.as_deref()
    }

    /// The uniform albedo used where the volume has none.
    pub fn default_albedo(&self) -> DVec3 {
        self.default_albedo
    }

    /// Linear albedo of the voxel containing `t` (texture point in voxel units, x and y
    /// periodic, z clamped into the grid).
    pub fn albedo_at(&self, t: DVec3) -> DVec3 {
        match &self.albedo {
            None => self.default_albedo,
            Some(a) => {
                let d = self.dims;
                let i = Wrap::new(d.x).apply(t.x.floor() as i64) as u32;
                let j = Wrap::new(d.y).apply(t.y.floor() as i64) as u32;
                let k = (t.z.floor().max(0.0) as u32).min(d.z - 1);
                a[d.index(i, j, k)].as_dvec3()
            }
        }
    }

    /// Unit texture-space normal at `t` (voxel units), trilinear over voxel centres; `None`
    /// where the gradient vanishes (inside solid or in empty space).
    pub fn normal_at(&self, t: DVec3) -> Option<DVec3> {
        let d = self.dims;
        let mut n = DVec3::ZERO;
        for ([i, j, k], w) in trilinear_corners(d, t.to_array()) {
            if w != 0.0 {
                n += self.normal[d.index(i, j, k)].as_dvec3() * w;
            }
        }
        n.try_normalize()
    }
}

/// Per-voxel sRGB albedo as linear colours.
pub fn linear_albedo(albedo: &[[u8; 3]]) -> Vec<Vec3> {
    albedo
        .iter()
        .map(|c| Vec3::from(c.map(|v| srgb_to_linear(v as f32 / 255.0))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_normals_point_up_and_sphere_normals_radially() {
        // A slab solid below z = 8: the normal at its top face is +z to round-off.
        let dims = Dims::new(8, 8, 16).unwrap();
        let mut occ = Occupancy::empty(dims);
        for k in 0..8 {
            for j in 0..8 {
                for i in 0..8 {
                    occ.set(i, j, k);
                }
            }
        }
        let m = MaterialVolume::from_occupancy(&occ, None, DVec3::ONE);
        let n = m.normal_at(DVec3::new(3.3, 5.9, 8.0)).unwrap();
        assert!((n - DVec3::Z).length() < 1e-12, "{n}");
        assert!(
            m.normal_at(DVec3::new(3.3, 5.9, 2.0)).is_none(),
            "no gradient deep inside"
        );
        // A voxelized ball of radius 10: normals within 8° of radial on its surface (the
        // Sobel filter of a staircase; 8° is what a 3-voxel stencil resolves at this radius).
        let dims = Dims::new(32, 32, 32).unwrap();
        let c = DVec3::splat(16.0);
        let mut occ = Occupancy::empty(dims);
        for k in 0..32 {
            for j in 0..32 {
                for i in 0..32 {
                    let p = DVec3::new(i as f64, j as f64, k as f64) + 0.5;
                    if (p - c).length() < 10.0 {
                        occ.set(i, j, k);
                    }
                }
            }
        }
        let m = MaterialVolume::from_occupancy(&occ, None, DVec3::ONE);
        for dir in [
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, -2.0, 3.0),
        ] {
            let dir = dir.normalize();
            let n = m.normal_at(c + dir * 10.0).unwrap();
            assert!(n.dot(dir) > 8f64.to_radians().cos(), "{n} vs {dir}");
        }
    }
}
