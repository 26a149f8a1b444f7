//! Translucent media: a volume's opacity and colour as the semi-transparent 3D texture
//! renderers read them.
//!
//! **Opacity is per voxel length, measured in texture space.** A voxel of opacity α absorbs
//! the fraction α of the light crossing one voxel length of it: a path of length ℓ voxels
//! through it transmits (1 − α)^ℓ, the paper's opacity correction α' = 1 − (1 − α)^ℓ. The
//! length is the texture-space length of the path, so a medium keeps its look when the shell
//! is scaled or thickened (the paper measures Δt·|V°| in object space, which equals this
//! where one voxel maps to one object unit). α = 0 is empty space, α = 1 is opaque: every
//! opaque volume is the medium with α = 1 in its solid voxels and 0 elsewhere.
//!
//! The medium is piecewise constant per voxel (voxel (i, j, k) is the box [i, i+1] ×
//! [j, j+1] × [k, k+1]), tiled in x and y, empty below and above the volume. [`Medium::walk`]
//! visits the voxels a texture-space segment crosses, exactly (a 3D DDA), so transmittance
//! along a segment is a closed-form product.

use crate::mesostructure::material::{MaterialVolume, linear_albedo};
use crate::mesostructure::volume::{Occupancy, Volume};
use glam::{DVec3, Vec3};
use mesobake_package::grid::{Dims, Wrap};
use std::ops::ControlFlow;

/// A translucent medium on a voxel grid.
#[derive(Clone, Debug)]
pub struct Medium {
    dims: Dims,
    wrap: [Wrap; 2],
    opacity: Vec<f32>,
    material: MaterialVolume,
}

impl Medium {
    /// The medium of `volume`: its opacity channel, or α = 1 in its solid voxels and 0
    /// elsewhere; colour from its albedo, else `default_albedo`; normals from the opacity's
    /// gradient ([`MaterialVolume::from_opacity`]).
    pub fn from_volume(volume: &Volume, default_albedo: DVec3) -> Medium {
        let dims = volume.dims();
        let opacity = match volume.opacity() {
            Some(a) => a.to_vec(),
            None => (0..dims.voxel_count() as usize)
                .map(|v| f32::from(volume.density()[v] >= volume.threshold()))
                .collect(),
        };
        let albedo = volume.albedo().map(linear_albedo);
        Medium::new(dims, opacity, albedo, default_albedo)
    }

    /// The opaque medium of an occupancy grid: α = 1 in its solid voxels, 0 elsewhere, in
    /// `default_albedo`.
    pub fn from_occupancy(solid: &Occupancy, default_albedo: DVec3) -> Medium {
        let dims = solid.dims();
        let opacity = (0..dims.z)
            .flat_map(|k| (0..dims.y).flat_map(move |j| (0..dims.x).map(move |i| (i, j, k))))
            .map(|(i, j, k)| f32::from(u8::from(solid.get(i, j, k))))
            .collect();
        Medium::new(dims, opacity, None, default_albedo)
    }

    fn new(dims: Dims, opacity: Vec<f32>, albedo: Option<Vec<Vec3>>, default: DVec3) -> Medium {
        let material = MaterialVolume::from_opacity(dims, &opacity, albedo, default);
        Medium {
            dims,
            wrap: [Wrap::new(dims.x), Wrap::new(dims.y)],
            opacity,
            material,
        }
    }

    /// A medium from stored parts (a medium package's level): per voxel (x fastest) linear
    /// colour and opacity, and the unnormalized outward normal.
    pub fn from_parts(dims: Dims, voxels: &[[f32; 4]], normals: &[[f32; 3]]) -> Medium {
        let albedo = voxels.iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect();
        let normal = normals.iter().map(|n| Vec3::from(*n)).collect();
        Medium {
            dims,
            wrap: [Wrap::new(dims.x), Wrap::new(dims.y)],
            opacity: voxels.iter().map(|v| v[3]).collect(),
            material: MaterialVolume::from_parts(dims, albedo, normal),
        }
    }

    /// The coarser levels of the medium's opacity-aware mip-map ([`Medium::coarser`]),
    /// level 1 first (empty where the medium cannot be halved).
    pub fn coarser_levels(&self) -> Vec<Medium> {
        let mut levels: Vec<Medium> = Vec::new();
        while let Some(next) = levels.last().unwrap_or(self).coarser() {
            levels.push(next);
        }
        levels
    }

    /// The next level of the paper's opacity-aware mip-map, or `None` where a side is odd or
    /// the grid is one voxel thick. Each coarse voxel covers 2×2×2 voxels: along z the two
    /// layers of each column combine by the opacity equation, top over bottom
    /// (α = 1 − (1 − α_top)(1 − α_bottom), colour composited top over bottom); across x and y
    /// the four columns average, opacity plainly and colour weighted by opacity. Opacity
    /// stays per voxel length of its own level: a path crossing both layers is one coarse
    /// voxel long. Normals come from the coarse opacity's gradient.
    pub fn coarser(&self) -> Option<Medium> {
        let d = self.dims;
        if [d.x, d.y, d.z].iter().any(|n| !n.is_multiple_of(2)) || d.z < 2 {
            return None;
        }
        let coarse = Dims::new(d.x / 2, d.y / 2, d.z / 2).ok()?;
        let n = coarse.voxel_count() as usize;
        let (mut opacity, mut albedo) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for k in 0..coarse.z {
            for j in 0..coarse.y {
                for i in 0..coarse.x {
                    let (mut alpha, mut premultiplied) = (0.0, DVec3::ZERO);
                    for (di, dj) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let v = |dk| d.index(2 * i + di, 2 * j + dj, 2 * k + dk);
                        let (top, bottom) = (v(1), v(0));
                        let (a_top, a_bottom) = (self.opacity(top), self.opacity(bottom));
                        alpha += 1.0 - (1.0 - a_top) * (1.0 - a_bottom);
                        premultiplied += self.colour(top) * a_top
                            + self.colour(bottom) * ((1.0 - a_top) * a_bottom);
                    }
                    opacity.push((alpha / 4.0) as f32);
                    let colour = if alpha > 0.0 {
                        premultiplied / alpha
                    } else {
                        self.material.default_albedo()
                    };
                    albedo.push(colour.as_vec3());
                }
            }
        }
        Some(Medium::new(
            coarse,
            opacity,
            Some(albedo),
            self.material.default_albedo(),
        ))
    }

    /// The grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Opacity per voxel length of voxel `v` (an index from [`Medium::walk`]).
    pub fn opacity(&self, v: usize) -> f64 {
        f64::from(self.opacity[v])
    }

    /// Linear colour of voxel `v`.
    pub fn colour(&self, v: usize) -> DVec3 {
        self.material
            .albedo_voxels()
            .map_or(self.material.default_albedo(), |a| a[v].as_dvec3())
    }

    /// Colour and normals.
    pub fn material(&self) -> &MaterialVolume {
        &self.material
    }

    /// The voxel holding texture point `t` (voxel units; tiled in x and y), `None` below
    /// or above the volume.
    pub fn voxel_at(&self, t: DVec3) -> Option<usize> {
        let k = t.z.floor();
        if !(0.0..f64::from(self.dims.z)).contains(&k) {
            return None;
        }
        Some(self.dims.index(
            self.wrap[0].apply(t.x.floor() as i64) as u32,
            self.wrap[1].apply(t.y.floor() as i64) as u32,
            k as u32,
        ))
    }

    /// Transmittance of `length` voxels of voxel `v`: (1 − α)^length (1 for length 0, even
    /// where α = 1).
    pub fn transmittance(&self, v: usize, length: f64) -> f64 {
        (1.0 - self.opacity(v)).powf(length)
    }

    /// Visits the voxels that the texture-space segment from `origin` along unit `dir`, of
    /// length `len` (voxel units), crosses inside the volume's layers, in order: `f(voxel
    /// index, s0, s1)` with the distances along the segment where it enters and leaves the
    /// voxel. A point on a voxel face belongs to the voxel the segment goes on into. Stops
    /// when `f` breaks and returns what it broke with.
    pub fn walk<B>(
        &self,
        origin: DVec3,
        dir: DVec3,
        len: f64,
        mut f: impl FnMut(usize, f64, f64) -> ControlFlow<B>,
    ) -> ControlFlow<B> {
        let (o, d) = (origin.to_array(), dir.to_array());
        let mut cell = [0i64; 3];
        let mut next = [f64::INFINITY; 3];
        let mut delta = [f64::INFINITY; 3];
        let mut step = [0i64; 3];
        for a in 0..3 {
            let floor = o[a].floor();
            cell[a] = floor as i64;
            if d[a] > 0.0 {
                step[a] = 1;
                delta[a] = 1.0 / d[a];
                next[a] = (floor + 1.0 - o[a]) / d[a];
            } else if d[a] < 0.0 {
                step[a] = -1;
                delta[a] = -1.0 / d[a];
                if floor == o[a] {
                    // On a face, going down: the segment goes on into the voxel below.
                    cell[a] -= 1;
                    next[a] = delta[a];
                } else {
                    next[a] = (o[a] - floor) / -d[a];
                }
            }
        }
        let z = i64::from(self.dims.z);
        let mut s = 0.0;
        while s < len {
            let a = (0..3)
                .min_by(|&p, &q| next[p].total_cmp(&next[q]))
                .expect("three axes");
            let end = next[a].min(len);
            if (0..z).contains(&cell[2]) {
                let v = self.dims.index(
                    self.wrap[0].apply(cell[0]) as u32,
                    self.wrap[1].apply(cell[1]) as u32,
                    cell[2] as u32,
                );
                f(v, s, end)?;
            } else if (cell[2] < 0 && step[2] <= 0) || (cell[2] >= z && step[2] >= 0) {
                break;
            }
            s = end;
            cell[a] += step[a];
            next[a] += delta[a];
        }
        ControlFlow::Continue(())
    }

    /// Transmittance along the texture-space segment (see [`Medium::walk`]), stopping early
    /// once it falls below `floor`.
    pub fn segment_transmittance(&self, origin: DVec3, dir: DVec3, len: f64, floor: f64) -> f64 {
        let mut t = 1.0;
        let _ = self.walk(origin, dir, len, |v, s0, s1| {
            t *= self.transmittance(v, s1 - s0);
            if t < floor {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        t
    }
}

/// The error for `what` asked of a translucent mesostructure.
pub fn translucent_refusal(what: &str) -> String {
    format!(
        "the mesostructure is a translucent medium, and {what} represents opaque mesostructure \
         only; translucent media are rendered by the transparency technique (a scene's \
         `technique` auto or transparency; `mesobake render --method cells` or `--method \
         truth`)"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesobake_core::limits::Limits;

    fn layered(opacity_of_layer: impl Fn(u32) -> f32) -> Medium {
        let dims = Dims::new(4, 4, 8).unwrap();
        let v = Volume::from_fn(dims, &Limits::default(), |_, _, _| false).unwrap();
        let opacity = (0..dims.voxel_count() as u32)
            .map(|n| opacity_of_layer(n / 16))
            .collect();
        Medium::from_volume(&v.with_opacity(opacity).unwrap(), DVec3::ONE)
    }

    /// Down a uniform column the transmittance is (1 − α)^length, whatever the slant; the
    /// closed form against the walk's product over voxels, to 1e-12.
    #[test]
    fn uniform_medium_transmits_the_closed_form() {
        let alpha = 0.3;
        let m = layered(|_| alpha);
        for dir in [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::new(0.37, -0.21, -1.0).normalize(),
            DVec3::new(3.0, 2.0, -0.4).normalize(),
        ] {
            let origin = DVec3::new(1.3, 2.7, 8.0);
            let len = 8.0 / -dir.z;
            let t = m.segment_transmittance(origin, dir, len, 0.0);
            let exact = (1.0f64 - alpha as f64).powf(len);
            assert!((t - exact).abs() < 1e-12, "{dir}: {t} against {exact}");
        }
    }

    /// The walk visits contiguous pieces covering the segment exactly, each inside the voxel
    /// it names; layers outside the volume are skipped.
    #[test]
    fn walk_pieces_tile_the_segment_inside_their_voxels() {
        let m = layered(|k| k as f32 / 8.0);
        let origin = DVec3::new(-2.5, 7.25, 10.0);
        let dir = DVec3::new(0.8, -0.3, -0.6).normalize();
        let len = 25.0;
        let mut covered = 0.0;
        let mut last_end: Option<f64> = None;
        let _ = m.walk(origin, dir, len, |v, s0, s1| {
            assert!(s1 >= s0);
            if let Some(e) = last_end {
                let gap_is_outside = (origin + dir * e).z <= 0.0 || (origin + dir * e).z >= 8.0;
                assert!((s0 - e).abs() < 1e-9 || gap_is_outside, "gap {e}..{s0}");
            }
            let mid = origin + dir * (0.5 * (s0 + s1));
            let k = v / 16;
            assert_eq!(mid.z.floor() as usize, k, "piece {s0}..{s1} in layer {k}");
            let (i, j) = (v % 4, (v / 4) % 4);
            assert_eq!(mid.x.floor().rem_euclid(4.0) as usize, i);
            assert_eq!(mid.y.floor().rem_euclid(4.0) as usize, j);
            covered += s1 - s0;
            last_end = Some(s1);
            ControlFlow::<()>::Continue(())
        });
        // Inside the layers: from z = 8 down to 0 along dir.
        let inside = 8.0 / -dir.z;
        assert!(
            (covered - inside).abs() < 1e-9,
            "{covered} against {inside}"
        );
    }

    /// A segment starting on a voxel face going down belongs to the voxel below: an opaque
    /// layer under a face does not shadow a ray leaving upwards from it, and does absorb one
    /// going down.
    #[test]
    fn a_segment_on_a_face_belongs_to_the_voxel_it_enters() {
        let m = layered(|k| if k < 4 { 1.0 } else { 0.0 });
        let on_face = DVec3::new(1.5, 1.5, 4.0);
        let up = DVec3::new(0.3, 0.1, 1.0).normalize();
        assert_eq!(m.segment_transmittance(on_face, up, 10.0, 0.0), 1.0);
        assert_eq!(m.segment_transmittance(on_face, -up, 10.0, 0.0), 0.0);
        assert_eq!(m.segment_transmittance(on_face, -up, 0.0, 0.0), 1.0);
    }
    /// A mip level keeps what a vertical path transmits: through a layered column, the coarse
    /// level's product over its layers (half as many, each one coarse voxel long) equals the
    /// fine one's, to 1e-6 (f32 opacities); colours composite top over bottom.
    #[test]
    fn a_mip_level_keeps_vertical_transmittance_and_composites_colour() {
        let m = layered(|k| [0.1, 0.0, 0.5, 0.9, 0.3, 0.3, 0.0, 0.05][k as usize]);
        let c = m.coarser().unwrap();
        assert_eq!((c.dims().x, c.dims().y, c.dims().z), (2, 2, 4));
        let down = DVec3::new(0.0, 0.0, -1.0);
        let fine = m.segment_transmittance(DVec3::new(1.5, 1.5, 8.0), down, 8.0, 0.0);
        let coarse = c.segment_transmittance(DVec3::new(0.5, 0.5, 4.0), down, 4.0, 0.0);
        assert!((fine - coarse).abs() < 1e-6, "{fine} against {coarse}");
        // A half-transparent red layer over an opaque green one: half of each.
        let dims = Dims::new(2, 2, 2).unwrap();
        let opacity = vec![1.0, 1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5];
        let [red, green] = [Vec3::X, Vec3::Y];
        let albedo = [vec![green; 4], vec![red; 4]].concat();
        let two = Medium::new(dims, opacity, Some(albedo), DVec3::ONE);
        let one = two.coarser().unwrap();
        assert_eq!(one.opacity(0), 1.0);
        assert!((one.colour(0) - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-6);
        assert!(one.coarser().is_none(), "one voxel thick");
    }
}
