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
//!    a hit inside the segment, query again from [`REFINEMENT_BACKOFF`] voxel short of it, up
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

use super::accel::BoxBvh;
use super::gdm_lookup::GdmLookup;
use super::lighting::{SHADOW_OFFSET, shade};
use super::truth::{TruthRenderer, light_start};
use crate::error::{Error, Result};
use crate::grid::Dims;
use crate::mesostructure::material::{ALBEDO_DEPTH, MaterialVolume};
use crate::scene::gi::GiShading;
use crate::scene::{Effect, Scene};
use crate::surface::shell::{FaceTriangle, Shell};
use glam::{DMat3, DVec3};

/// How far short of the previous estimate, in voxels, a refinement query is made: close enough
/// that the neighbouring samples agree on the remaining distance, far enough to stay in front
/// of the surface (measured on the torus + chain and flat chain scenes: 0.5 and 2 are 0.1 dB
/// worse).
pub const REFINEMENT_BACKOFF: f64 = 1.0;

/// How a reference run tests shadows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ShadowTest {
    /// The paper's: one GDM query along the light in texture space (flat base assumed;
    /// mesostructure of the same neighbourhood only).
    #[default]
    Local,
    /// This renderer's own algorithm traced towards the light through the whole shell (what
    /// a shadow map rendered with the GDM pipeline from the light computes): curvature,
    /// distant mesostructure and the base mesh's other side included.
    Shell,
    /// The ground truth's shadow rays.
    Exact,
}

/// Parts of the per-pixel algorithm that a reference run replaces, to measure what each
/// approximation costs (the error budget of `mesobake report render`): by its exact
/// counterpart, computed by the ground truth, or for shadows also by the GDM algorithm
/// through the shell. None of them is part of the real-time algorithm; the default is the
/// paper's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Substitutions {
    /// The GDM query: the mesostructure cast exactly along the fragment's straight
    /// texture-space segment, instead of the interpolated GDM.
    pub exact_query: bool,
    /// The shading frame: the exact Jacobian of the prism mapping at the hit, instead of the
    /// prism's mean frame (for the normal and, in local shadows, the light direction).
    pub exact_frame: bool,
    /// The shadow test.
    pub shadows: ShadowTest,
}

impl Substitutions {
    /// The error budget's rows: none, each part alone (shadows both ways), all exact.
    pub const BUDGET: [Substitutions; 6] = [
        Substitutions::of(false, false, ShadowTest::Local),
        Substitutions::of(true, false, ShadowTest::Local),
        Substitutions::of(false, true, ShadowTest::Local),
        Substitutions::of(false, false, ShadowTest::Shell),
        Substitutions::of(false, false, ShadowTest::Exact),
        Substitutions::of(true, true, ShadowTest::Exact),
    ];

    const fn of(exact_query: bool, exact_frame: bool, shadows: ShadowTest) -> Substitutions {
        Substitutions {
            exact_query,
            exact_frame,
            shadows,
        }
    }

    /// A short label: `none`, or the substituted parts joined by `+` (`query`, `frame`,
    /// `shell shadows`, `shadows`; all but shell shadows exact).
    pub fn label(&self) -> String {
        let names = [
            (self.exact_query, "query"),
            (self.exact_frame, "frame"),
            (self.shadows == ShadowTest::Shell, "shell shadows"),
            (self.shadows == ShadowTest::Exact, "shadows"),
        ];
        let on: Vec<&str> = names.iter().filter(|n| n.0).map(|n| n.1).collect();
        if on.is_empty() {
            "none".into()
        } else {
            on.join("+")
        }
    }
}

impl std::str::FromStr for Substitutions {
    type Err = Error;

    /// Parts separated by commas: `query`, `frame`, `shell-shadows` or `shadows` (the
    /// latter two exclusive); `none` or nothing for the paper's algorithm.
    fn from_str(text: &str) -> Result<Substitutions> {
        let mut subs = Substitutions::default();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let shadows = match part {
                "none" => continue,
                "query" => {
                    subs.exact_query = true;
                    continue;
                }
                "frame" => {
                    subs.exact_frame = true;
                    continue;
                }
                "shell-shadows" => ShadowTest::Shell,
                "shadows" => ShadowTest::Exact,
                _ => {
                    return Err(Error::InvalidParameter(format!(
                        "substitution {part:?}: expected query, frame, shell-shadows or shadows"
                    )));
                }
            };
            if subs.shadows != ShadowTest::Local && subs.shadows != shadows {
                return Err(Error::InvalidParameter(
                    "substitute shell-shadows or shadows, not both".into(),
                ));
            }
            subs.shadows = shadows;
        }
        Ok(subs)
    }
}

/// A face triangle with its texture coordinates in voxel units and its plane.
#[derive(Clone, Copy, Debug)]
pub struct PreparedFace {
    /// Object-space corners and texture coordinates (voxel units).
    pub triangle: FaceTriangle,
    /// Unit outward normal.
    pub normal: DVec3,
    /// n·x on the plane.
    pub offset: f64,
}

/// A prism prepared for the per-pixel algorithm (what the shaders receive per prism).
#[derive(Clone, Debug)]
pub struct PreparedPrism {
    /// Top, bottom, then the two triangles of fins 0, 1, 2.
    pub faces: [PreparedFace; 8],
    /// Whether each fin is convex.
    pub convex: [bool; 3],
    /// Object → texture (voxel units).
    pub frame: DMat3,
}

/// The prisms of `shell` prepared for a GDM on the voxel grid `dims`.
pub fn prepare_prisms(shell: &Shell, dims: Dims) -> Vec<PreparedPrism> {
    let scale = DVec3::new(dims.x as f64, dims.y as f64, dims.z as f64);
    shell
        .prisms
        .iter()
        .map(|p| PreparedPrism {
            faces: p.faces().map(|f| {
                let triangle = FaceTriangle {
                    corners: f.corners,
                    texture: f.texture.map(|t| t * scale),
                };
                let normal = triangle.normal().normalize_or_zero();
                PreparedFace {
                    triangle,
                    normal,
                    offset: normal.dot(f.corners[0]),
                }
            }),
            convex: p.fins.map(|f| f.convex),
            frame: DMat3::from_diagonal(scale) * p.to_texture,
        })
        .collect()
}

/// The longest texture-space segment (voxel units) a fragment of any of `prisms` can have.
/// In texture space a prism is the convex hull of its six corners (its base triangle's texture
/// coordinates at w = 0 and w = Z), a fragment's segment joins two points of its boundary,
/// so no segment is longer than the largest distance between two corners.
pub fn longest_segment(prisms: &[PreparedPrism]) -> f64 {
    let mut longest = 0.0f64;
    for p in prisms {
        let corners = p.faces.iter().flat_map(|f| f.triangle.texture);
        for a in corners.clone() {
            for b in corners.clone() {
                longest = longest.max(a.distance(b));
            }
        }
    }
    longest
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
    bvh: BoxBvh,
    lookup: &'a dyn GdmLookup,
    material: &'a MaterialVolume,
    refinements: u32,
    gi: Option<&'a GiShading>,
    /// The substituted parts, and the ground truth that computes the exact ones.
    substitutions: Option<(Substitutions, &'a TruthRenderer<'a>)>,
}

impl<'a> GdmRenderer<'a> {
    /// Prepares `shell` for rendering with `lookup` (whose grid gives the voxel scale), making
    /// `refinements` extra GDM queries per hit (see [`Scene::gdm_refinements`]).
    pub fn new(
        shell: &Shell,
        lookup: &'a dyn GdmLookup,
        material: &'a MaterialVolume,
        refinements: u32,
    ) -> Self {
        let prisms = prepare_prisms(shell, lookup.dims());
        let boxes = prisms
            .iter()
            .map(|p| {
                let corners = p.faces[0]
                    .triangle
                    .corners
                    .iter()
                    .chain(&p.faces[1].triangle.corners);
                let lo = corners.clone().fold(DVec3::INFINITY, |a, &c| a.min(c));
                let hi = corners.fold(DVec3::NEG_INFINITY, |a, &c| a.max(c));
                (lo, hi)
            })
            .collect();
        GdmRenderer {
            prisms,
            bvh: BoxBvh::new(boxes),
            lookup,
            material,
            refinements,
            gi: None,
            substitutions: None,
        }
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
                if let Some(hit) = self.fragment(p, f, origin, dir, t_in, bary)
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

    /// Steps 1–5 for the fragment of face `f` of prism `p`.
    fn fragment(
        &self,
        p: usize,
        f: usize,
        o: DVec3,
        dir: DVec3,
        t_in: f64,
        bary: [f64; 3],
    ) -> Option<GdmHit> {
        let prism = &self.prisms[p];
        let t_in_tex = prism.faces[f].triangle.texture_at(bary);
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
        let segment = t_out_tex - t_in_tex;
        let d_t = segment.length();
        if d_t.is_nan() || d_t <= 0.0 {
            return None;
        }
        let view = segment / d_t;
        let d = self.segment_hit(t_in_tex, view, d_t)?;
        Some(GdmHit {
            t: t_in + d / d_t * (t_out - t_in),
            prism: p,
            texture: t_in_tex + view * d,
            view,
        })
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

    /// Step 6: the shaded radiance along the camera ray, or `None` for a miss.
    pub fn radiance(&self, scene: &Scene, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let hit = self.trace(origin, dir)?;
        let shadow_test = self
            .substitutions
            .map_or(ShadowTest::Local, |(s, _)| s.shadows);
        let jacobian = self
            .exact(|s| s.exact_frame || s.shadows == ShadowTest::Exact)
            .and_then(|truth| truth.jacobian(hit.prism, hit.texture));
        let frame = match jacobian {
            Some(j) if self.exact(|s| s.exact_frame).is_some() => j.inverse(),
            _ => self.prisms[hit.prism].frame,
        };
        let n_tex = self.material.normal_at(hit.texture).unwrap_or(-hit.view);
        let n = (frame.transpose() * n_tex).try_normalize().unwrap_or(-dir);
        let albedo = self
            .material
            .albedo_at(hit.texture + hit.view * ALBEDO_DEPTH);
        let shadows = scene.wants(Effect::Shadows);
        let shadow_origin = hit.texture + n_tex * SHADOW_OFFSET;
        let p = origin + dir * hit.t;
        let environment = self.gi.map_or(DVec3::ZERO, |gi| {
            gi.radiance(hit.prism, hit.texture, hit.view)
        });
        Some(
            environment
                + shade(&scene.lights, &scene.material, p, n, albedo, -dir, |inc| {
                    if !shadows {
                        return true;
                    }
                    let start = || light_start(jacobian.unwrap_or(frame.inverse()), p, n_tex);
                    match shadow_test {
                        ShadowTest::Local => match (frame * inc.direction).try_normalize() {
                            Some(l) => self.lookup.escapes(shadow_origin, l),
                            None => true,
                        },
                        ShadowTest::Shell => self
                            .trace(start(), inc.direction)
                            .is_none_or(|h| h.t >= inc.distance),
                        ShadowTest::Exact => self.exact(|_| true).is_none_or(|truth| {
                            !truth.blocked(start(), inc.direction, inc.distance)
                        }),
                    }
                }),
        )
    }
}

/// How far along `view` the query point moves from `t` (voxel units) to reach the centre
/// plane of the top layer (z = Z − ½) when it enters from the half voxel above it, or of the
/// bottom layer (z = ½) from below; 0 otherwise, or when that plane lies beyond the segment's
/// length `d_t`. Samples sit at voxel centres, so this keeps the query on the ray instead of
/// clamping it half a voxel away.
pub fn advance_to_samples(t: DVec3, view: DVec3, z: f64, d_t: f64) -> f64 {
    let s = if view.z < 0.0 && t.z > z - 0.5 {
        (t.z - (z - 0.5)) / -view.z
    } else if view.z > 0.0 && t.z < 0.5 {
        (0.5 - t.z) / view.z
    } else {
        0.0
    };
    if s < d_t { s } else { 0.0 }
}

/// Ray–triangle intersection (Möller–Trumbore in f64, edges inclusive so that rays through
/// shared edges and vertices hit at least one neighbour): ray parameter t > 0 and the
/// barycentric coordinates of the hit.
pub fn intersect(tri: &FaceTriangle, o: DVec3, d: DVec3) -> Option<(f64, [f64; 3])> {
    let [a, b, c] = tri.corners;
    let (e1, e2) = (b - a, c - a);
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(pv) * inv;
    let qv = s.cross(e1);
    let v = d.dot(qv) * inv;
    const EDGE: f64 = 1e-12;
    if u < -EDGE || v < -EDGE || u + v > 1.0 + EDGE {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0).then_some((t, [1.0 - u - v, u, v]))
}
