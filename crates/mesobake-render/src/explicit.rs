//! The third CPU renderer, independent of the other two: the explicit geometry of a mesh tile
//! (its triangles clipped to every prism and mapped through the shell, [`export`]) ray cast
//! as an ordinary triangle mesh with an obvhs BVH. It shares no casting code with the ground
//! truth (no inverse mapping, no texture-space chords): camera and shadow rays meet object-
//! space triangles, and shadow rays start [`EXACT_SHADOW_OFFSET`] voxels (of the shell's
//! depth) off the surface, as the truth's do. A hit is shaded with the normal of the mapped
//! tile triangle at the hit, by central differences of the prism mapping along the
//! triangle's texture-space edges (the truth maps the triangle's normal by the inverse-
//! transpose Jacobian instead). The albedo is the material's at the hit's texture coordinate,
//! interpolated from the exported triangle's corners. What is left between the two is the
//! export's tolerance (10⁻⁴ of the thickness) and f32 traversal.

use super::lighting::shade;
use super::truth::EXACT_SHADOW_OFFSET;
use crate::shot::Shot;
use glam::DVec3;
use mesobake_bake::gdm::input::Mesostructure;
use mesobake_bake::mesostructure::material::{ALBEDO_DEPTH, MaterialVolume};
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::surface::explicit::{ExplicitParams, TriangleSource, export};
use mesobake_bake::surface::shell::{Prism, Shell};
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use obvhs::{
    BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, ray::Ray, ray::RayHit,
    triangle::Triangle,
};
use std::time::Duration;

/// Barycentric slack of the f64 ray–triangle test, so that a ray through a shared edge hits
/// one of its two triangles whatever the round-off.
const EDGE_SLACK: f64 = 1e-12;

/// The export's tolerance, as a fraction of the shell thickness.
pub const EXPLICIT_TOLERANCE: f64 = 1e-4;

/// A ray cast of the explicit geometry.
pub struct ExplicitRenderer<'a> {
    /// Over the triangles in f32 (culling only).
    bvh: CwBvh,
    /// Per triangle (BVH order): its corners in f64, and where it came from.
    corners: Vec<[DVec3; 3]>,
    sources: Vec<TriangleSource>,
    shell: &'a Shell,
    material: &'a MaterialVolume,
    /// Voxels per texture unit along s, t, w.
    scale: DVec3,
    /// Shadow-ray offset, object units.
    offset: f64,
}

/// A ray's first hit on the explicit geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Hit {
    t: f64,
    triangle: usize,
    bary: [f64; 3],
}

impl<'a> ExplicitRenderer<'a> {
    /// Exports `mesostructure`'s mesh tile (on a `dims` grid) through `shell` and builds the
    /// BVH; hits are coloured by `material`. A mesostructure of voxels is refused: its
    /// explicit geometry is the voxel boxes the truth already casts exactly.
    pub fn new(
        shell: &'a Shell,
        mesostructure: &Mesostructure,
        material: &'a MaterialVolume,
        dims: Dims,
        limits: &Limits,
    ) -> Result<Self> {
        let tile: &TriMesh = mesostructure.tile_mesh().ok_or_else(|| {
            Error::InvalidParameter(
                "the explicit renderer needs a mesh tile (mesostructure {\"tile\": \"x.obj\"}); \
                 this scene's mesostructure is voxels"
                    .into(),
            )
        })?;
        let thickness = shell.params.thickness;
        let params = ExplicitParams {
            tile_height: f64::from(dims.z) / f64::from(dims.x),
            tolerance: EXPLICIT_TOLERANCE * thickness,
            record_texture: true,
        };
        let explicit = export(shell, tile, &params, limits, &())?;
        let mesh = &explicit.mesh;
        // Per triangle: f64 corners, its source, an f32 copy and the BVH's share.
        limits.check("explicit triangles", mesh.triangles.len() as u64, 256)?;
        let sources = explicit.sources.expect("export records sources when asked");
        let corners: Vec<[DVec3; 3]> = (0..mesh.triangles.len())
            .map(|n| mesh.corners(n).map(DVec3::from_array))
            .collect();
        let tris: Vec<Triangle> = corners
            .iter()
            .map(|c| Triangle {
                v0: c[0].as_vec3a(),
                v1: c[1].as_vec3a(),
                v2: c[2].as_vec3a(),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let order = |i: &u32| *i as usize;
        Ok(ExplicitRenderer {
            corners: bvh
                .primitive_indices
                .iter()
                .map(|i| corners[order(i)])
                .collect(),
            sources: bvh
                .primitive_indices
                .iter()
                .map(|i| sources[order(i)])
                .collect(),
            bvh,
            shell,
            material,
            scale: DVec3::new(dims.x as f64, dims.y as f64, dims.z as f64),
            offset: EXACT_SHADOW_OFFSET * thickness / f64::from(dims.z),
        })
    }

    /// The first hit along `origin + t·dir` (unit `dir`) with t ≤ `t_max`.
    fn trace(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<Hit> {
        // obvhs mis-traverses directions with negative zeros; adding +0 makes them positive.
        let ray = Ray::new(
            origin.as_vec3a(),
            (dir + DVec3::ZERO).as_vec3a(),
            0.0,
            if t_max.is_finite() {
                t_max as f32 * 1.000_001 + 1e-30
            } else {
                f32::INFINITY
            },
        );
        // The BVH culls in f32; each candidate is intersected in f64 (f32 Möller–Trumbore
        // missed rays within 2·10⁻⁵ of an edge on the torus + chain mesh, so rays slipped
        // between neighbouring triangles).
        let mut hit = RayHit::none();
        let mut best: Option<Hit> = None;
        self.bvh.ray_traverse(ray, &mut hit, |_, id| {
            match intersect(&self.corners[id], origin, dir) {
                Some((t, bary))
                    if t >= 0.0
                        && t <= t_max
                        && bary.iter().all(|&b| b >= -EDGE_SLACK)
                        && best.is_none_or(|b| t < b.t) =>
                {
                    best = Some(Hit {
                        t,
                        triangle: id,
                        bary,
                    });
                    t as f32
                }
                _ => f32::INFINITY,
            }
        });
        best
    }

    /// The shaded radiance along the camera ray, or `None` for a miss.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let hit = self.trace(origin, dir, f64::INFINITY)?;
        let c = &self.corners[hit.triangle];
        let flat = (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero();
        let source = &self.sources[hit.triangle];
        let tile: DVec3 = (0..3).map(|k| source.texture[k] * hit.bary[k]).sum();
        let mut n = match mapped_normal(&self.shell.prisms[source.prism as usize], source, tile) {
            Some(m) if m.dot(flat) < 0.0 => -m,
            Some(m) => m,
            None => flat,
        };
        if n.dot(dir) > 0.0 {
            n = -n;
        }
        let p = origin + dir * hit.t;
        let texture = tile * self.scale;
        let albedo = self
            .material
            .albedo_at(texture + self.texture_view(source.prism, texture, dir) * ALBEDO_DEPTH);
        let shadows = shot.wants(Effect::Shadows);
        let start = p + n * self.offset;
        Some(shade(
            &shot.lights,
            &shot.material,
            p,
            n,
            albedo,
            -dir,
            |inc| {
                !shadows
                    || self
                        .trace(start, inc.direction, inc.distance)
                        .is_none_or(|h| h.t >= inc.distance)
            },
        ))
    }

    /// The unit texture-space (voxel units) direction of object direction `dir` at `texture`
    /// in prism `prism`, by the mapping's exact Jacobian; `dir` itself where it is singular.
    fn texture_view(&self, prism: u32, texture: DVec3, dir: DVec3) -> DVec3 {
        let prism = &self.shell.prisms[prism as usize];
        prism
            .point_at_texture(texture / self.scale)
            .and_then(|q| prism.jacobian(q))
            .filter(|j| j.determinant() != 0.0)
            .and_then(|j| {
                (glam::DMat3::from_diagonal(self.scale) * j.inverse() * dir).try_normalize()
            })
            .unwrap_or(dir)
    }
}

/// The unit normal (either orientation) of `source`'s tile triangle mapped through `prism`,
/// at texture point `tile` (tile units), by central differences of the mapping along the
/// triangle's texture-space edges.
fn mapped_normal(prism: &Prism, source: &TriangleSource, tile: DVec3) -> Option<DVec3> {
    const STEP: f64 = 1e-5;
    let map = |t: DVec3| prism.point_at_texture(t).map(|q| prism.point(q));
    let [t0, t1, t2] = source.texture;
    let along = |e: DVec3| -> Option<DVec3> {
        let e = e.try_normalize()? * STEP;
        Some(map(tile + e)? - map(tile - e)?)
    };
    along(t1 - t0)?.cross(along(t2 - t0)?).try_normalize()
}

/// The ray parameter and barycentric coordinates where `origin + t·dir` meets the plane of
/// `corners` (Möller–Trumbore in f64); `None` if the ray is parallel to it.
pub(super) fn intersect(
    corners: &[DVec3; 3],
    origin: DVec3,
    dir: DVec3,
) -> Option<(f64, [f64; 3])> {
    let (e1, e2) = (corners[1] - corners[0], corners[2] - corners[0]);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let s = origin - corners[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = dir.dot(q) / det;
    let t = e2.dot(q) / det;
    Some((t, [1.0 - u - v, u, v]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_f64_intersection_finds_the_plane_point_and_its_barycentrics() {
        let c = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(2.0, 0.0, 1.0),
            DVec3::new(0.0, 4.0, 1.0),
        ];
        let (t, b) = intersect(&c, DVec3::new(0.5, 1.0, 3.0), DVec3::NEG_Z).unwrap();
        assert!((t - 2.0).abs() < 1e-12);
        // (0.5, 1) = 0.25·(2, 0) + 0.25·(0, 4).
        for (got, want) in b.iter().zip([0.5, 0.25, 0.25]) {
            assert!((got - want).abs() < 1e-12, "{b:?}");
        }
        assert!(intersect(&c, DVec3::ZERO, DVec3::X).is_none());
    }
}
