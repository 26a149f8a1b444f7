//! The GDM software renderer: the paper's per-pixel algorithm exactly as the shaders run it
//! (the executable specification of the WGSL pipeline).
//!
//! Per camera ray and per front-facing face triangle of a prism that it crosses (a
//! rasterized fragment):
//! 1. entry point P_in on that face, texture coordinate T_in by barycentric interpolation of
//!    the face's corner texture coordinates (voxel units);
//! 2. exit point: the ray meets the planes of the prism's back-facing face triangles; a fin
//!    gives the nearer of its two plane hits when convex, the farther when concave (and none
//!    when one of its planes faces the ray); top and bottom give their plane hit; P_out is the
//!    nearest of these, T_out the texture coordinate of P_out extrapolated over the face
//!    triangle whose plane it lies on — for a fin, over whichever of its two triangles holds
//!    P_out (its smallest barycentric coordinate is the larger), since the plane rule's
//!    choice between nearly coplanar triangles is decided by round-off;
//! 3. d_t = |T_out − T_in|, V_t = (T_out − T_in)/d_t, query d = GDM(T_in, V_t) — where T_in
//!    lies in the half voxel above the top sample layer (below the bottom one) and V_t points
//!    into the volume, the query is made on the ray at that layer's centre plane and the
//!    advance is added to d ([`advance_to_samples`]);
//! 4. refinement (a knob beyond the paper, 0 = the paper's single query): while the answer is
//!    a hit inside the segment, query again from [`REFINEMENT_BACKOFF`](crate::gdm_lookup::REFINEMENT_BACKOFF) voxel short of it, up
//!    to N times, keeping the last answer that hits (a refinement moves a hit, it never turns
//!    it into a miss); near the surface the interpolated neighbours agree, so blends of near
//!    and far hits (which land in empty space beside silhouettes) move onto a surface;
//!
//!    With a package of the `occupancy` codec, steps 3–4 are one exact march of its voxels
//!    along the segment instead ([`GdmLookup::segment_hit`] of `OccupancyLookup`), and every
//!    later query (the shadow test) marches too;
//! 5. hit iff the query does not escape and d < d_t: T = T_in + d·V_t and, by proportion,
//!    P = P_in + (d/d_t)·(P_out − P_in);
//! 6. the nearest hit over all fragments is shaded (depth test); no hit shows the background
//!    (silhouettes).
//!
//! Shading uses the prism's mean frame M (object → texture): the texture normal n_t of the
//! material volume becomes Mᵀ·n_t in object space, and a light direction L becomes M·L in
//! texture space, where the shadow test queries the GDM one voxel off the hit along the
//! texture normal: shadowed iff that query does not escape (local mesostructure shadows only,
//! as in the paper).
//!
//! The scene's [`Quality`] replaces three of these approximations (the `paper` preset keeps
//! all three; `render::quality` has the table):
//! - `chords` n > 1: step 3 queries n segments in order instead of one, between the texture
//!   coordinates of the points at fractions k/n of the way from P_in to P_out, mapped by the
//!   exact inverse mapping ([`PrismMap::texture_of`]: Newton steps, depth clamped into the
//!   volume); the first hit wins, its P by proportion along its own piece;
//! - `frame` `jacobian`: M is the inverse of the mapping's Jacobian ∂P/∂T at the hit
//!   ([`PrismMap::jacobian`]);
//! - `shadows` `shell`: a light is visible iff the algorithm itself, run on the shadow ray
//!   from one voxel off the hit (mapped to object space by M⁻¹), finds no hit nearer than
//!   the light: first on the rest of the hit's prism (the shadow ray's start and its texture
//!   coordinate as the fragment's entry), then on every front face the ray meets beyond its
//!   start (a BVH over the prisms) — what a shadow map rendered with this pipeline from the
//!   light would hold, without its resolution limit.

use super::accel::BoxBvh;
use super::gdm_lookup::GdmLookup;
use super::lighting::{Incident, SHADOW_OFFSET, shade};
use super::objects::ObjectRenderer;
use super::prepared_prism::{PreparedFace, PreparedPrism, intersect, prepare_prisms};
use super::prism_map::PrismMap;
use super::truth::{TruthRenderer, light_start};
use crate::gi_shading::GiShading;
use crate::shot::Shot;
use glam::{DMat3, DVec3};
use mesobake_bake::mesostructure::material::{ALBEDO_DEPTH, MaterialVolume};
use mesobake_bake::surface::shell::Shell;
use mesobake_core::effect::Effect;
use mesobake_core::error::{Error, Result};
use mesobake_core::quality::{Quality, ShadingFrame, ShadowMethod};

/// Parts of the per-pixel algorithm that a reference run replaces by their exact
/// counterparts, computed by the ground truth, to measure what each approximation that no
/// [`Quality`] knob removes still costs (the error budget of `mesobake report render`). None
/// of them is part of the real-time algorithm; the default substitutes nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Substitutions {
    /// The GDM query: the mesostructure cast exactly along each of the fragment's straight
    /// texture-space chords, instead of the package's query.
    pub exact_query: bool,
    /// The shadow test: the ground truth's shadow rays.
    pub exact_shadows: bool,
}

impl Substitutions {
    /// The error budget's rows: none, each part alone, both.
    pub const BUDGET: [Substitutions; 4] = [
        Substitutions::of(false, false),
        Substitutions::of(true, false),
        Substitutions::of(false, true),
        Substitutions::of(true, true),
    ];

    const fn of(exact_query: bool, exact_shadows: bool) -> Substitutions {
        Substitutions {
            exact_query,
            exact_shadows,
        }
    }

    /// A short label: `none`, or the substituted parts joined by `+` (`query`, `shadows`).
    pub fn label(&self) -> String {
        match (self.exact_query, self.exact_shadows) {
            (false, false) => "none",
            (true, false) => "query",
            (false, true) => "shadows",
            (true, true) => "query+shadows",
        }
        .into()
    }
}

impl std::str::FromStr for Substitutions {
    type Err = Error;

    /// Parts separated by commas: `query`, `shadows`; `none` or nothing for none.
    fn from_str(text: &str) -> Result<Substitutions> {
        let mut subs = Substitutions::default();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match part {
                "none" => {}
                "query" => subs.exact_query = true,
                "shadows" => subs.exact_shadows = true,
                _ => {
                    return Err(Error::InvalidParameter(format!(
                        "substitution {part:?}: expected query or shadows (the frame and shell \
                         shadows are quality settings: --quality)"
                    )));
                }
            }
        }
        Ok(subs)
    }
}

/// A ray's nearest mesostructure hit by the GDM algorithm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GdmHit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// The prism whose fragment produced it.
    pub prism: usize,
    /// Texture coordinate of the hit (voxel units).
    pub texture: DVec3,
    /// The texture-space view direction V_t.
    pub view: DVec3,
}

/// The GDM software renderer over one shell and one GDM.
pub struct GdmRenderer<'a> {
    prisms: Vec<PreparedPrism>,
    /// The prisms' mappings, for the chord and frame knobs.
    maps: Vec<Option<PrismMap>>,
    bvh: BoxBvh,
    lookup: &'a dyn GdmLookup,
    material: &'a MaterialVolume,
    refinements: u32,
    quality: Quality,
    gi: Option<&'a GiShading>,
    /// The substituted parts, and the ground truth that computes the exact ones.
    substitutions: Option<(Substitutions, &'a TruthRenderer<'a>)>,
}

impl<'a> GdmRenderer<'a> {
    /// Prepares `shell` for rendering with `lookup` (whose grid gives the voxel scale), making
    /// `refinements` extra GDM queries per hit (see [`Scene::gdm_refinements`]), with the
    /// paper's settings of the other knobs ([`GdmRenderer::with_quality`]).
    pub fn new(
        shell: &Shell,
        lookup: &'a dyn GdmLookup,
        material: &'a MaterialVolume,
        refinements: u32,
    ) -> Self {
        let prisms = prepare_prisms(shell, lookup.dims());
        let boxes = prisms.iter().map(PreparedPrism::bounds).collect();
        GdmRenderer {
            maps: prisms.iter().map(PrismMap::new).collect(),
            prisms,
            bvh: BoxBvh::new(boxes),
            lookup,
            material,
            refinements,
            quality: Quality::default(),
            gi: None,
            substitutions: None,
        }
    }

    /// Renders with the accuracy knobs set to `quality` (a scene's `quality`).
    pub fn with_quality(mut self, quality: Quality) -> Self {
        self.quality = quality;
        self
    }

    /// Also shades environment light with `gi` (baked for the same shell and grid).
    pub fn with_gi(mut self, gi: &'a GiShading) -> Self {
        self.gi = Some(gi);
        self
    }

    /// Substitutes parts of the algorithm (`truth`, over the same shell and mesostructure,
    /// computes the exact ones): a reference run, not the real-time algorithm.
    pub fn with_substitutions(mut self, subs: Substitutions, truth: &'a TruthRenderer<'a>) -> Self {
        self.substitutions = Some((subs, truth));
        self
    }

    /// The ground truth, when the substitutions pass `select`.
    fn exact(&self, select: impl Fn(&Substitutions) -> bool) -> Option<&'a TruthRenderer<'a>> {
        self.substitutions
            .filter(|(subs, _)| select(subs))
            .map(|(_, truth)| truth)
    }

    /// The nearest hit along `origin + t·dir` (unit `dir`), t > 0.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<GdmHit> {
        let mut best: Option<GdmHit> = None;
        self.bvh.nearest(origin, dir, |p| {
            let mut nearest: Option<GdmHit> = None;
            for (f, face) in self.prisms[p].faces.iter().enumerate() {
                if face.normal.dot(dir) >= 0.0 {
                    continue; // back-facing: not rasterized
                }
                let Some((t_in, bary)) = intersect(&face.triangle, origin, dir) else {
                    continue;
                };
                // Fragments behind the nearest hit so far fail the depth test.
                if nearest.or(best).is_some_and(|b| b.t <= t_in) {
                    continue;
                }
                let t_in_tex = self.prisms[p].faces[f].triangle.texture_at(bary);
                if let Some(hit) = self.fragment(p, origin, dir, t_in, t_in_tex)
                    && nearest.is_none_or(|b| hit.t < b.t)
                {
                    nearest = Some(hit);
                }
            }
            let hit = nearest?;
            if best.is_none_or(|b| hit.t < b.t) {
                best = Some(hit);
            }
            Some(hit.t)
        });
        best
    }

    /// Steps 2–5 for a fragment of prism `p` entered at `o + t_in·dir` with texture
    /// coordinate `t_in_tex` (step 1: a face's interpolation, or a shadow ray's start).
    fn fragment(
        &self,
        p: usize,
        o: DVec3,
        dir: DVec3,
        t_in: f64,
        t_in_tex: DVec3,
    ) -> Option<GdmHit> {
        let prism = &self.prisms[p];
        let plane_hit = |face: &PreparedFace| -> Option<f64> {
            let cos = face.normal.dot(dir);
            (cos > 0.0).then(|| (face.offset - face.normal.dot(o)) / cos)
        };
        let mut exit = (f64::INFINITY, usize::MAX);
        let mut consider = |t: f64, face: usize| {
            if t < exit.0 {
                exit = (t, face);
            }
        };
        for face in 0..2 {
            if let Some(t) = plane_hit(&prism.faces[face]) {
                consider(t, face);
            }
        }
        for (k, &convex) in prism.convex.iter().enumerate() {
            let (a, b) = (2 + 2 * k, 3 + 2 * k);
            match (plane_hit(&prism.faces[a]), plane_hit(&prism.faces[b])) {
                (Some(ta), Some(tb)) => {
                    let pick = if (ta <= tb) == convex {
                        (ta, a)
                    } else {
                        (tb, b)
                    };
                    consider(pick.0, pick.1);
                }
                (Some(t), None) if convex => consider(t, a),
                (None, Some(t)) if convex => consider(t, b),
                _ => {}
            }
        }
        let (t_out, exit_face) = exit;
        if !t_out.is_finite() {
            return None;
        }
        let t_out = t_out.max(t_in);
        let p_out = o + dir * t_out;
        let t_out_tex = if exit_face < 2 {
            let tri = &prism.faces[exit_face].triangle;
            tri.texture_at(tri.barycentric(p_out)?)
        } else {
            // A fin: the triangle that holds P_out. Where its two planes nearly coincide
            // (planar fins, e.g. along a torus's meridians) the other triangle's texture map
            // would be wrong, and the plane rule's choice is decided by round-off: 0.09 % of
            // the torus + chain pixels flipped under a 1-ulp change of their rays.
            let a = 2 + (exit_face - 2) / 2 * 2;
            let [ta, tb] = [a, a + 1].map(|f| &prism.faces[f].triangle);
            let (ba, bb) = (ta.barycentric(p_out)?, tb.barycentric(p_out)?);
            let inside = |b: [f64; 3]| b[0].min(b[1]).min(b[2]);
            if inside(ba) >= inside(bb) {
                ta.texture_at(ba)
            } else {
                tb.texture_at(bb)
            }
        };
        let (s, texture, view) = self.path_hit(p, o + dir * t_in, t_in_tex, p_out, t_out_tex)?;
        Some(GdmHit {
            t: t_in + s * (t_out - t_in),
            prism: p,
            texture,
            view,
        })
    }

    /// Steps 3–5 along the texture-space path from `t_in_tex` (at object point `p_in`) to
    /// `t_out_tex` (at `p_out`) in prism `p`: the paper's one straight segment, or with n
    /// chords (the quality's `chords`) the points at object-space fractions k/n of the way
    /// mapped with the exact inverse mapping ([`PrismMap::texture_of`], guessed on the
    /// straight segment, depth clamped into the volume) and the segments between them queried
    /// in order. The first hit: its fraction of the way from `p_in` to `p_out`, its texture
    /// coordinate and the texture-space direction of its chord.
    fn path_hit(
        &self,
        p: usize,
        p_in: DVec3,
        t_in_tex: DVec3,
        p_out: DVec3,
        t_out_tex: DVec3,
    ) -> Option<(f64, DVec3, DVec3)> {
        let n = self.quality.chords.max(1);
        let map = self.maps[p].filter(|_| n > 1);
        let depth = self.lookup.dims().z as f64;
        let mut start = t_in_tex;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            let end = match map {
                Some(m) if k < n => {
                    let t = m.texture_of(p_in.lerp(p_out, s), t_in_tex.lerp(t_out_tex, s));
                    t.with_z(t.z.clamp(0.0, depth))
                }
                _ if k < n => t_in_tex.lerp(t_out_tex, s),
                _ => t_out_tex,
            };
            let chord = end - start;
            let length = chord.length();
            if length > 0.0 {
                let view = chord / length;
                if let Some(d) = self.segment_hit(start, view, length) {
                    let s0 = (k - 1) as f64 / n as f64;
                    return Some((s0 + d / length / n as f64, start + view * d, view));
                }
            }
            start = end;
        }
        None
    }

    /// Steps 3–5 on the texture-space segment from `start` along `view` of length `d_t`: the
    /// hit distance, or `None` when the ray leaves the segment first.
    fn segment_hit(&self, start: DVec3, view: DVec3, d_t: f64) -> Option<f64> {
        if let Some(truth) = self.exact(|s| s.exact_query) {
            let z = self.lookup.dims().z as f64;
            return truth.cast(start.with_z(start.z.clamp(0.0, z)), view, d_t);
        }
        self.lookup.segment_hit(start, view, d_t, self.refinements)
    }

    /// The shading frame at `hit` (object → texture, voxel units): the prism's mean frame,
    /// or with the Jacobian knob the inverse of ∂P/∂T at the hit (the mean frame where that
    /// is singular).
    fn frame(&self, hit: &GdmHit) -> DMat3 {
        let mean = self.prisms[hit.prism].frame;
        match self.quality.frame {
            ShadingFrame::Mean => mean,
            ShadingFrame::Jacobian => self.maps[hit.prism]
                .and_then(|m| m.jacobian(hit.texture))
                .map_or(mean, |j| j.inverse()),
        }
    }

    /// Whether the shell blocks the light `dir` within `distance` of object point `start`
    /// (texture coordinate `start_tex` in prism `p`): the per-pixel algorithm on the rest of
    /// prism `p` from the start, then on every prism the ray enters. A start above the
    /// prism's top (or below its base), one voxel off a hit on the volume's top layer, lies
    /// outside the prism: only the prisms the ray enters count (the rest of prism `p` from
    /// there would run the chord from outside back down to the top face, into the solid).
    fn shell_blocked(
        &self,
        p: usize,
        start: DVec3,
        start_tex: DVec3,
        dir: DVec3,
        distance: f64,
    ) -> bool {
        let within = |hit: GdmHit| hit.t < distance;
        let inside = start_tex.z > 0.0 && start_tex.z < self.lookup.dims().z as f64;
        (inside
            && self
                .fragment(p, start, dir, 0.0, start_tex)
                .is_some_and(within))
            || self.trace(start, dir).is_some_and(within)
    }

    /// Step 6: the shaded radiance along the camera ray, or `None` for a miss.
    pub fn radiance(&self, shot: &Shot, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        self.radiance_with(shot, origin, dir, &|_, _| true)
    }
}

impl ObjectRenderer for GdmRenderer<'_> {
    fn hit_distance(&self, _: &Shot, origin: DVec3, dir: DVec3) -> Option<f64> {
        self.trace(origin, dir).map(|hit| hit.t)
    }

    fn radiance_with(
        &self,
        shot: &Shot,
        origin: DVec3,
        dir: DVec3,
        elsewhere: &dyn Fn(DVec3, &Incident) -> bool,
    ) -> Option<DVec3> {
        let hit = self.trace(origin, dir)?;
        let frame = self.frame(&hit);
        let n_tex = self.material.normal_at(hit.texture).unwrap_or(-hit.view);
        let n = (frame.transpose() * n_tex).try_normalize().unwrap_or(-dir);
        let albedo = self
            .material
            .albedo_at(hit.texture + hit.view * ALBEDO_DEPTH);
        let shadows = shot.wants(Effect::Shadows);
        let shadow_origin = hit.texture + n_tex * SHADOW_OFFSET;
        let p = origin + dir * hit.t;
        let start = || light_start(frame.inverse(), p, n_tex);
        let environment = self.gi.map_or(DVec3::ZERO, |gi| {
            gi.radiance(hit.prism, hit.texture, hit.view)
        });
        Some(
            environment
                + shade(&shot.lights, &shot.material, p, n, albedo, -dir, |inc| {
                    if !shadows {
                        return true;
                    }
                    if !elsewhere(start(), inc) {
                        return false;
                    }
                    if let Some(truth) = self.exact(|s| s.exact_shadows) {
                        return !truth.blocked(start(), inc.direction, inc.distance);
                    }
                    match self.quality.shadows {
                        ShadowMethod::Local => match (frame * inc.direction).try_normalize() {
                            Some(l) => self.lookup.escapes(shadow_origin, l),
                            None => true,
                        },
                        ShadowMethod::Shell => !self.shell_blocked(
                            hit.prism,
                            start(),
                            shadow_origin,
                            inc.direction,
                            inc.distance,
                        ),
                    }
                }),
        )
    }
}
