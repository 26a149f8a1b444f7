//! The VDM software renderer: the paper's per-pixel algorithm for view-dependent displacement
//! maps, exactly as the shaders run it (the executable specification of the WGSL pipeline).
//!
//! The reference surface is the top of the shell: one triangle per base triangle, rendered
//! like a plain mesh. Each top triangle's frame M (object → texture: its edges to its UV
//! edges in tile units, the prism's mean extrusion to z, the shell's height from 0 at the
//! base to 1 at the top; [`mesobake_bake::surface::shell::Prism::top_frame`]) followed by S = diag(1, 1, depth) maps object
//! space to the VDM's space, where the relief is `depth` tiles deep and the VDM was baked;
//! A = S·M. (The prism's mean frame maps the base triangle's edges instead, shorter than the
//! top's by 1 − k·thickness on a surface of curvature k: on torus-bumps that frame cost
//! 0.9 dB against the truth.)
//!
//! Per camera ray and per front-facing top triangle it crosses, nearest first (a rasterized
//! fragment; the first one that is not a silhouette is shaded, as a depth test after discards
//! would keep):
//! 1. texture coordinate T (tile units) and, interpolated from the triangle's corners, the
//!    curvature c_V along the view: per corner the paper's c = k_max (V·C_max)² + k_min
//!    (V·C_min)² over 1 − (V·N)², with V the direction from the corner to the eye
//!    ([`VertexCurvature::along`]), in 1/object unit;
//! 2. the view in VDM space, D = A·dir: θ_V from the inward normal, φ_V its azimuth; the
//!    curvature in 1/tile, c_V · ℓ with ℓ = |A⁻¹·(cos φ_V, sin φ_V, 0)| the object length of
//!    one tile along the view's azimuth;
//! 3. silhouette determination: the VDM query ([`VdmQuery::sample`]) says none;
//! 4. real texture coordinate T' = T + d·sin θ_V·(cos φ_V, sin φ_V), the relief's depth
//!    there t' = depth·(1 − h(T')) (h bilinear, periodic), and the hit P' = P + A⁻¹·(T' − T,
//!    −t') (the flat offset); where the scene asks for `vdm.refine_texels`, steps 3 and 4
//!    settle the lookup's answer on the height field ([`super::vdm_refine`]);
//! 5. shading at P' with the normal of the height field at T' (central differences one texel
//!    apart, in VDM space (−depth·∂h/∂x, −depth·∂h/∂y, 1), mapped to object space by Aᵀ) and
//!    the scene's albedo;
//! 6. shadow determination, per light: the light's direction in VDM space, L = A·l (θ_L from
//!    the outward normal, φ_L), and its curvature c_L interpolated like c_V; the light ray
//!    from P' leaves the reference surface (bent to c_L along φ_L) at arc length σ from the
//!    point above P', where the surface normal has turned by c_L·σ, so it enters there at
//!    θ'' = θ_L − c_L·σ towards φ_L + π; the light reaches P' iff the VDM there,
//!    d_L = VDM(T' + σ·(cos φ_L, sin φ_L), θ'', φ_L + π, c_L), is not a silhouette and
//!    reaches P': d_L ≥ σ / sin θ'' − ε (for c_L = 0, σ = t'·tan θ_L and the bound is the
//!    paper's t'·sec θ_L), ε the [`shadow_tolerance`]: [`SHADOW_TOLERANCE`] texels for the
//!    interpolation plus [`SHADOW_ERROR_MULTIPLE`] times the compression's measured RMS
//!    displacement error (without it, rank 8 on torus-bumps, 2.5 texels RMS, shadows
//!    speckles over the lit bumps). A ray that never leaves a concave surface is shadowed.
//! 7. with `vdm.shadows: "shell"`, a light that passes step 6 is also followed past the
//!    reference surface: the straight ray from P' towards it is tested against every
//!    front-facing top triangle it crosses before the light (the top faces' BVH), and each
//!    crossing runs steps 1–4 as a fragment of a ray along the light, its curvature
//!    interpolated along the light; the first crossing that is not a silhouette blocks the
//!    light, so the far side of the base mesh and the relief on it cast shadows (the paper's
//!    test sees only the relief above the hit).

use super::accel::BoxBvh;
use super::lighting::{Incident, shade};
use super::objects::ObjectRenderer;
use super::prepared_prism::intersect;
use super::truth::TruthRenderer;
use super::vdm_refine::{BentRay, FLAT_CURVATURE};
use crate::shot::Shot;
use glam::{DMat3, DVec2, DVec3};
use mesobake_bake::surface::curvature::{VertexCurvature, vertex_curvatures};
use mesobake_bake::surface::shell::{FaceTriangle, Shell};
use mesobake_bake::vdm::Relief;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::quality::ShadowMethod;
use mesobake_package::vdm::VdmQuery;
use std::f64::consts::FRAC_PI_2;

/// How far short of the light's entry point the VDM may answer, in texels, and still let the
/// light through: the interpolated VDM's error near the surface it reaches.
pub const SHADOW_TOLERANCE: f64 = 1.0;

/// How many times the compression's RMS displacement error the shadow test also forgives.
pub const SHADOW_ERROR_MULTIPLE: f64 = 2.0;

/// The shadow test's tolerance ε in tiles for `query` (see the module documentation).
pub fn shadow_tolerance(query: &VdmQuery) -> f64 {
    SHADOW_TOLERANCE / f64::from(query.size().0) + SHADOW_ERROR_MULTIPLE * query.rmse()
}

/// One top triangle prepared for the per-pixel algorithm (what the shaders receive).
#[derive(Clone, Debug)]
pub struct TopFace {
    /// Corners (counter-clockwise from outside) and texture coordinates (tiles; w = 1).
    pub triangle: FaceTriangle,
    /// Object → VDM space, A = S·M.
    pub to_vdm: DMat3,
    /// A⁻¹.
    pub from_vdm: DMat3,
    /// The curvature at each corner.
    pub curvature: [VertexCurvature; 3],
}

impl TopFace {
    /// The triangle's bounding box (lower and upper corners).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let c = self.triangle.corners;
        (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]))
    }
}

/// The top triangles of `shell` prepared for a VDM of a relief `depth` tiles deep.
pub fn prepare_top_faces(shell: &Shell, depth: f64) -> Vec<TopFace> {
    let scale = DMat3::from_diagonal(DVec3::new(1.0, 1.0, depth));
    shell
        .prisms
        .iter()
        .zip(top_curvatures(shell))
        .map(|(p, curvature)| {
            let to_vdm = scale * p.top_frame().unwrap_or(p.to_texture);
            TopFace {
                triangle: p.faces()[0],
                to_vdm,
                from_vdm: to_vdm.inverse(),
                curvature,
            }
        })
        .collect()
}

/// The least depth of `relief` below the reference surface (tiles): depth · (1 − max h).
pub fn top_depth(relief: Relief) -> f64 {
    let top = relief
        .field
        .heights()
        .iter()
        .copied()
        .fold(0.0f32, f32::max);
    relief.depth * (1.0 - f64::from(top))
}

/// Renders a shell's reference surface with a compressed VDM.
pub struct VdmRenderer<'a> {
    faces: Vec<TopFace>,
    bvh: BoxBvh,
    query: &'a VdmQuery,
    relief: Relief<'a>,
    /// The relief's least depth (tiles), where the refinement's search of a miss begins.
    top_depth: f64,
    /// The ground truth that answers steps 6 and 7 instead, in a reference run.
    exact_shadows: Option<&'a TruthRenderer<'a>>,
}

/// The principal curvatures at the top corners of `shell`'s prisms, estimated on the top
/// surface (corners welded as the shell welds them, normals along the extrusion).
pub fn top_curvatures(shell: &Shell) -> Vec<[VertexCurvature; 3]> {
    let vertices = shell
        .prisms
        .iter()
        .flat_map(|p| p.welded)
        .max()
        .map_or(0, |m| m as usize + 1);
    let mut positions = vec![DVec3::ZERO; vertices];
    let mut normals = vec![DVec3::ZERO; vertices];
    for p in &shell.prisms {
        for (c, &id) in p.welded.iter().enumerate() {
            positions[id as usize] = p.bottom[c] + p.extrusion[c];
            normals[id as usize] += p.extrusion[c].normalize_or_zero();
        }
    }
    let normals: Vec<DVec3> = normals.iter().map(|n| n.normalize_or_zero()).collect();
    let triangles: Vec<[u32; 3]> = shell.prisms.iter().map(|p| p.welded).collect();
    let curvature = vertex_curvatures(&positions, &normals, &triangles);
    shell
        .prisms
        .iter()
        .map(|p| p.welded.map(|id| curvature[id as usize]))
        .collect()
}

impl<'a> VdmRenderer<'a> {
    /// Prepares `shell`'s top triangles for `query`, the VDM of `relief`.
    pub fn new(shell: &Shell, query: &'a VdmQuery, relief: Relief<'a>) -> Result<Self> {
        if query.size() != relief.field.size() {
            return Err(Error::InvalidParameter(format!(
                "the VDM's {:?} texels are not its height field's {:?}",
                query.size(),
                relief.field.size()
            )));
        }
        let faces = prepare_top_faces(shell, relief.depth);
        let bvh = BoxBvh::new(faces.iter().map(TopFace::bounds).collect());
        Ok(VdmRenderer {
            faces,
            bvh,
            query,
            relief,
            top_depth: top_depth(relief),
            exact_shadows: None,
        })
    }

    /// Answers the shadow test with `truth`'s shadow rays (over the same shell and relief)
    /// from one texel off the hit along its normal: a reference run for the error budget,
    /// not the real-time algorithm.
    pub fn with_exact_shadows(mut self, truth: &'a TruthRenderer<'a>) -> Self {
        self.exact_shadows = Some(truth);
        self
    }

    /// The shaded radiance along the camera ray, or `None` where it shows the background.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        self.radiance_with(shot, origin, dir, &|_, _| true)
    }

    /// Steps 1–5 along the ray `origin + t·dir` seen from `eye` (the camera's, or for a ray
    /// that is not the camera's, its origin): the nearest fragment that is not a silhouette,
    /// and where it hits the relief.
    fn first_hit(
        &self,
        origin: DVec3,
        eye: DVec3,
        dir: DVec3,
        refine_texels: u32,
    ) -> Option<VdmHit<'_>> {
        let mut fragments = Vec::new();
        self.bvh
            .candidates(origin, dir, 0.0, f64::INFINITY, |f, _| {
                let tri = &self.faces[f].triangle;
                if tri.normal().dot(dir) < 0.0
                    && let Some((t, bary)) = intersect(tri, origin, dir)
                {
                    fragments.push((t, f, bary));
                }
            });
        fragments.sort_by(|a, b| a.0.total_cmp(&b.0));
        fragments.into_iter().find_map(|(t, f, bary)| {
            let face = &self.faces[f];
            let p = origin + dir * t;
            let tex = face.triangle.texture_at(bary).truncate();
            let c_v = corner_curvature(face, bary, &|corner| eye - corner);
            let (view, sigma) = self.lookup(face, tex, dir, c_v, refine_texels)?;
            let offset = view.azimuth * sigma;
            let t_hit = tex + offset;
            let depth = self.relief.surface_depth(t_hit.x, t_hit.y);
            Some(VdmHit {
                face,
                bary,
                t_hit,
                depth,
                point: p + face.from_vdm * offset.extend(-depth),
            })
        })
    }

    /// Step 6 at `hit`, seen along `dir`: a light reaches it where its own shadow test and
    /// `elsewhere` both say so.
    fn shade_hit(
        &self,
        shot: &Shot,
        hit: &VdmHit,
        dir: DVec3,
        elsewhere: &dyn Fn(DVec3, &Incident) -> bool,
    ) -> DVec3 {
        let face = hit.face;
        let n_vdm = self.relief_normal(hit.t_hit);
        let normal = (face.to_vdm.transpose() * n_vdm)
            .try_normalize()
            .unwrap_or(-dir);
        let shadows = shot.wants(Effect::Shadows);
        let texel = 1.0 / f64::from(self.relief.field.size().0);
        let exact_start = hit.point + face.from_vdm * (n_vdm.normalize() * texel);
        shade(
            &shot.lights,
            &shot.material,
            hit.point,
            normal,
            DVec3::from(shot.material.albedo),
            -dir,
            |inc| {
                if !shadows {
                    return true;
                }
                if !elsewhere(exact_start, inc) {
                    return false;
                }
                if let Some(truth) = self.exact_shadows {
                    return !truth.blocked(exact_start, inc.direction, inc.distance);
                }
                let c_l = corner_curvature(face, hit.bary, &|_| inc.direction);
                self.lit(face, hit.t_hit, hit.depth, inc.direction, c_l)
                    && (shot.vdm_shadows == ShadowMethod::Local
                        || !self.blocked_elsewhere(shot, hit.point, inc.direction, inc.distance))
            },
        )
    }

    /// Steps 2–4 for a ray along `dir` (object space) entering `face` at texture coordinate
    /// `t` where the surface's curvature along it is `c` (1/object unit): the ray in VDM
    /// space and the arc length σ from `t` to its hit, or `None` for a silhouette.
    fn lookup(
        &self,
        face: &TopFace,
        t: DVec2,
        dir: DVec3,
        c: f64,
        refine_texels: u32,
    ) -> Option<(Direction, f64)> {
        let view = Direction::new(face, dir)?;
        if view.inward_z <= 0.0 {
            return None;
        }
        let c_v = c * view.tile_length;
        let d = self.query.sample(t.x, t.y, view.theta, view.phi, c_v);
        let ray = || BentRay {
            relief: self.relief,
            top_depth: self.top_depth,
            entry: t,
            azimuth: view.azimuth,
            theta: view.theta,
            c: c_v,
        };
        let sigma = match (d, refine_texels) {
            (d, 0) => f64::from(d?) * view.theta.sin(),
            (Some(d), n) => ray().refine_hit(f64::from(d), n),
            (None, n) => ray().refine_miss(n)?,
        };
        Some((view, sigma))
    }

    /// Step 7: whether the straight ray from `hit` along the light's direction `l` enters the
    /// top surface within `distance` at a fragment that is not a silhouette.
    fn blocked_elsewhere(&self, shot: &Shot, hit: DVec3, l: DVec3, distance: f64) -> bool {
        let mut blocked = false;
        self.bvh.candidates(hit, l, 0.0, distance, |f, _| {
            let face = &self.faces[f];
            let tri = &face.triangle;
            if blocked || tri.normal().dot(l) >= 0.0 {
                return;
            }
            if let Some((t, bary)) = intersect(tri, hit, l)
                && t < distance
            {
                let c = (0..3).map(|i| bary[i] * face.curvature[i].along(l)).sum();
                let entry = tri.texture_at(bary).truncate();
                blocked = self
                    .lookup(face, entry, l, c, shot.vdm_refine_texels)
                    .is_some();
            }
        });
        blocked
    }

    /// The height field's normal at T' in VDM space (see the module documentation).
    fn relief_normal(&self, t: DVec2) -> DVec3 {
        let (w, h) = self.relief.field.size();
        let (dx, dy) = (1.0 / f64::from(w), 1.0 / f64::from(h));
        let field = self.relief.field;
        let gx = (field.sample(t.x + dx, t.y) - field.sample(t.x - dx, t.y)) / (2.0 * dx);
        let gy = (field.sample(t.x, t.y + dy) - field.sample(t.x, t.y - dy)) / (2.0 * dy);
        DVec3::new(-self.relief.depth * gx, -self.relief.depth * gy, 1.0)
    }

    /// Step 6: whether light from object direction `l` reaches the hit at T' (`depth` below
    /// the reference surface), the surface bent to `c_l` (1/object unit) along the light.
    fn lit(&self, face: &TopFace, t_hit: DVec2, depth: f64, l: DVec3, c_l: f64) -> bool {
        // The light as a view from above: its direction reversed is a ray into the surface.
        let Some(light) = Direction::new(face, -l) else {
            return true;
        };
        if light.inward_z <= 0.0 {
            return false; // below the reference surface's horizon
        }
        let c = c_l * light.tile_length;
        let Some(sigma) = exit_arc(depth, light.theta, c) else {
            return false;
        };
        let theta = (light.theta - c * sigma).clamp(0.0, FRAC_PI_2);
        let entry = t_hit - light.azimuth * sigma;
        let tolerance = shadow_tolerance(self.query);
        match self.query.sample(entry.x, entry.y, theta, light.phi, c) {
            Some(d) => f64::from(d) >= sigma / theta.sin().max(1e-9) - tolerance,
            None => true,
        }
    }
}

/// A direction expressed in a top face's VDM space.
struct Direction {
    /// Polar angle from the inward normal.
    theta: f64,
    /// Azimuth of the texture-space motion.
    phi: f64,
    /// (cos φ, sin φ).
    azimuth: DVec2,
    /// The normalized direction's component into the surface (cos θ).
    inward_z: f64,
    /// Object length of one tile along the azimuth.
    tile_length: f64,
}

impl Direction {
    /// `dir` (object space, pointing into the surface) in `face`'s VDM space.
    fn new(face: &TopFace, dir: DVec3) -> Option<Direction> {
        let d = (face.to_vdm * dir).try_normalize()?;
        let inward_z = -d.z;
        let phi = d.y.atan2(d.x);
        let azimuth = DVec2::new(phi.cos(), phi.sin());
        Some(Direction {
            theta: inward_z.clamp(-1.0, 1.0).acos(),
            phi,
            azimuth,
            inward_z,
            tile_length: (face.from_vdm * azimuth.extend(0.0)).length(),
        })
    }
}

/// The arc length σ ≥ 0 along the reference surface (curvature `c`, 1/tile, positive convex)
/// from the point above a point `depth` below it to where the ray from that point, leaving
/// at angle `theta` from the outward normal towards +σ, crosses the surface; `None` when it
/// never does (a concave surface closing over it).
pub fn exit_arc(depth: f64, theta: f64, c: f64) -> Option<f64> {
    let (s, co) = theta.sin_cos();
    if c.abs() < FLAT_CURVATURE {
        return Some(depth * s / co.max(1e-12));
    }
    // The ray from (0, −depth) along (sin θ, cos θ) meets the circle of radius R = 1/c about
    // (0, −R) where s² + 2s·(R − depth)·cos θ + depth² − 2R·depth = 0; the roots in the
    // forms that do not cancel.
    let r = 1.0 / c;
    let half_b = (r - depth) * co;
    let q0 = depth * depth - 2.0 * r * depth;
    let disc = half_b * half_b - q0;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    // Convex: the one positive root; concave: the nearer crossing.
    let s_ray = if r > 0.0 {
        -q0 / (half_b + root)
    } else {
        q0 / (root - half_b)
    };
    if s_ray < 0.0 {
        return None;
    }
    let q = DVec2::new(s_ray * s, -depth + s_ray * co);
    // Arc length of the crossing: R times its angle about the centre.
    Some(r * (r.signum() * q.x).atan2(r.signum() * (q.y + r)))
}

/// Where a ray meets the relief: its fragment (face and barycentrics), the hit's VDM
/// texture coordinate T' and depth, and the hit point in object space.
struct VdmHit<'f> {
    face: &'f TopFace,
    bary: [f64; 3],
    t_hit: DVec2,
    depth: f64,
    point: DVec3,
}

/// The surface's curvature at the fragment `bary` of `face` along `towards(corner)`,
/// interpolated from its corners.
fn corner_curvature(face: &TopFace, bary: [f64; 3], towards: &dyn Fn(DVec3) -> DVec3) -> f64 {
    (0..3)
        .map(|i| bary[i] * face.curvature[i].along(towards(face.triangle.corners[i])))
        .sum()
}

impl ObjectRenderer for VdmRenderer<'_> {
    /// The hit point's ray parameter; the ray's origin stands for the eye.
    fn hit_distance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<f64> {
        let hit = self.first_hit(origin, origin, dir, shot.vdm_refine_texels)?;
        Some((hit.point - origin).dot(dir))
    }

    /// Also where the ray meets a top face from behind: the relief is solid down to the
    /// shell's base, so a ray arriving from under the top surface is inside the object.
    fn occludes(&self, shot: &Shot, start: DVec3, dir: DVec3, distance: f64) -> bool {
        let mut behind = false;
        self.bvh.candidates(start, dir, 0.0, distance, |f, _| {
            let tri = &self.faces[f].triangle;
            behind |= tri.normal().dot(dir) > 0.0
                && intersect(tri, start, dir).is_some_and(|(t, _)| t < distance);
        });
        behind
            || self
                .hit_distance(shot, start, dir)
                .is_some_and(|t| t < distance)
    }

    fn radiance_with(
        &self,
        shot: &Shot,
        origin: DVec3,
        dir: DVec3,
        elsewhere: &dyn Fn(DVec3, &Incident) -> bool,
    ) -> Option<DVec3> {
        let eye = DVec3::from(shot.camera.eye);
        let hit = self.first_hit(origin, eye, dir, shot.vdm_refine_texels)?;
        Some(self.shade_hit(shot, &hit, dir, elsewhere))
    }
}
