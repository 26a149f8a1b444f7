//! The shell: the base mesh extruded along its vertex directions into one prism per triangle,
//! the space the mesostructure is mapped into.
//!
//! Texture space of a prism: barycentric coordinates (b₀, b₁, b₂) over the base triangle and
//! the height w ∈ [0, 1]. The exact object-space point is
//! P(b, w) = Σ bᵢ (Bᵢ + w·h·dᵢ) with Bᵢ the base vertices, dᵢ their extrusion directions and
//! h the thickness; its texture coordinate is (Σ bᵢ tᵢ, w), tᵢ the vertices' UVs times the
//! tiling. The side faces ("fins") are the bilinear patches over the triangle's edges; the
//! real-time algorithm approximates each by two triangles split along one diagonal, chosen by
//! the smallest welded vertex index so that the two prisms sharing a fin split it alike
//! (Dompierre et al.'s rule, which also splits each prism into three tetrahedra whose faces
//! match across neighbours).
//!
//! Winding: base triangles are counter-clockwise seen from the side the normals point to, so
//! (B₁−B₀)×(B₂−B₀) points out of the surface; every face triangle below is listed with its
//! outward normal by the right-hand rule.

use crate::surface::base_mesh::BaseMesh;
use glam::{DMat3, DVec2, DVec3};
use mesobake_core::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// How the base mesh is extruded.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShellParams {
    /// Shell thickness h in object units: texture z = 1 lies h along the extrusion direction.
    pub thickness: f64,
    /// Mesostructure tiles per UV unit along u and v.
    #[serde(default = "default_tiles")]
    pub tiles_per_uv: [f64; 2],
    /// Laplacian smoothing passes over the extrusion directions (0: the vertex normals). Where
    /// curvature is high, smoothed directions cross later, so fewer prisms fold.
    #[serde(default)]
    pub smoothing: u32,
}

fn default_tiles() -> [f64; 2] {
    [1.0, 1.0]
}

/// Largest accepted number of smoothing passes.
pub const MAX_SMOOTHING: u32 = 64;

/// One of a prism's eight face triangles, as object-space corners and the texture
/// coordinates (tile units in x, y; w in z) of those corners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceTriangle {
    /// Corners, counter-clockwise seen from outside the prism.
    pub corners: [DVec3; 3],
    /// Texture coordinates of the corners.
    pub texture: [DVec3; 3],
}

impl FaceTriangle {
    /// Unnormalized outward normal.
    pub fn normal(&self) -> DVec3 {
        (self.corners[1] - self.corners[0]).cross(self.corners[2] - self.corners[0])
    }

    /// Barycentric coordinates of `p` (projected onto the triangle's plane; extrapolated
    /// outside the triangle). Zero-area triangles give `None`.
    pub fn barycentric(&self, p: DVec3) -> Option<[f64; 3]> {
        let [a, b, c] = self.corners;
        let n = (b - a).cross(c - a);
        let nn = n.length_squared();
        if nn == 0.0 || !nn.is_finite() {
            return None;
        }
        let l1 = (c - b).cross(p - b).dot(n) / nn;
        let l2 = (a - c).cross(p - c).dot(n) / nn;
        Some([l1, l2, 1.0 - l1 - l2])
    }

    /// Texture coordinate at barycentric coordinates `l`.
    pub fn texture_at(&self, l: [f64; 3]) -> DVec3 {
        self.texture[0] * l[0] + self.texture[1] * l[1] + self.texture[2] * l[2]
    }
}

/// A side of a prism approximated by two triangles that share a diagonal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fin {
    /// The two triangles, outward normals.
    pub triangles: [FaceTriangle; 2],
    /// Whether the prism is locally the intersection of the two half-spaces (interior angle
    /// at the diagonal below 180°): the ray leaves the fin at the nearer plane. Otherwise
    /// (concave: the union) at the farther one.
    pub convex: bool,
}

/// The prism over one base triangle.
#[derive(Clone, Debug, PartialEq)]
pub struct Prism {
    /// Index of the base triangle in the base mesh.
    pub triangle: u32,
    /// Base corners Bᵢ (w = 0).
    pub bottom: [DVec3; 3],
    /// Offsets h·dᵢ from each base corner to its top corner (w = 1).
    pub extrusion: [DVec3; 3],
    /// Texture coordinates of the corners in tile units (UV × tiling).
    pub uv: [DVec2; 3],
    /// Fin k lies over the edge from corner k to corner k+1 (mod 3).
    pub fins: [Fin; 3],
    /// Welded vertex ids of the corners (equal positions share an id).
    pub welded: [u32; 3],
    /// Maps object-space vectors to texture vectors (tile units, w) with the prism's mean
    /// frame: base edges to UV edges, the mean extrusion to (0, 0, 1).
    pub to_texture: DMat3,
}

/// A point of a prism in its own coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrismPoint {
    /// Barycentric coordinates over the base triangle.
    pub bary: [f64; 3],
    /// Height in the shell, 0 at the base, 1 at the top.
    pub w: f64,
}

impl PrismPoint {
    /// How far outside the unit prism the point lies (0 inside): the largest violation of
    /// bᵢ ≥ 0 and 0 ≤ w ≤ 1.
    pub fn outside(&self) -> f64 {
        let b = self.bary.iter().fold(0.0f64, |m, &b| m.max(-b));
        b.max(-self.w).max(self.w - 1.0)
    }

    /// The same point with its coordinates clamped into the prism.
    pub fn clamped(&self) -> PrismPoint {
        let b = self.bary.map(|b| b.max(0.0));
        let s = b[0] + b[1] + b[2];
        let bary = if s > 0.0 {
            b.map(|b| b / s)
        } else {
            [1.0 / 3.0; 3]
        };
        PrismPoint {
            bary,
            w: self.w.clamp(0.0, 1.0),
        }
    }
}

impl Prism {
    /// Top corners Bᵢ + h·dᵢ.
    pub fn top(&self) -> [DVec3; 3] {
        [0, 1, 2].map(|i| self.bottom[i] + self.extrusion[i])
    }

    /// Maps object-space vectors to texture vectors (tile units, w) with the top triangle's
    /// frame: its edges to the UV edges, the mean extrusion to (0, 0, 1); `None` for a
    /// degenerate top.
    pub fn top_frame(&self) -> Option<DMat3> {
        let [a, b, c] = self.top();
        let mean_extrusion = (self.extrusion[0] + self.extrusion[1] + self.extrusion[2]) / 3.0;
        let object = DMat3::from_cols(b - a, c - a, mean_extrusion);
        let texture = DMat3::from_cols(
            (self.uv[1] - self.uv[0]).extend(0.0),
            (self.uv[2] - self.uv[0]).extend(0.0),
            DVec3::Z,
        );
        let det = object.determinant();
        (det != 0.0 && det.is_finite()).then(|| texture * object.inverse())
    }

    /// The exact object-space point of prism coordinates `q`.
    pub fn point(&self, q: PrismPoint) -> DVec3 {
        (0..3)
            .map(|i| (self.bottom[i] + self.extrusion[i] * q.w) * q.bary[i])
            .sum()
    }

    /// The texture coordinate (tile units, w) of prism coordinates `q`.
    pub fn texture(&self, q: PrismPoint) -> DVec3 {
        let uv: DVec2 = (0..3).map(|i| self.uv[i] * q.bary[i]).sum();
        uv.extend(q.w)
    }

    /// The prism coordinates of texture coordinate `t` (tile units, w): barycentric
    /// coordinates of (s, t) over the prism's UV triangle, and w. `None` where the UV
    /// triangle has no area.
    pub fn point_at_texture(&self, t: DVec3) -> Option<PrismPoint> {
        let (e1, e2) = (self.uv[1] - self.uv[0], self.uv[2] - self.uv[0]);
        let det = e1.perp_dot(e2);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let r = t.truncate() - self.uv[0];
        let (b1, b2) = (r.perp_dot(e2) / det, e1.perp_dot(r) / det);
        Some(PrismPoint {
            bary: [1.0 - b1 - b2, b1, b2],
            w: t.z,
        })
    }

    /// The Jacobian ∂P/∂(texture) at `q`: columns ∂P/∂s, ∂P/∂t (tile units) and ∂P/∂w.
    /// `None` where the UV triangle has no area.
    pub fn jacobian(&self, q: PrismPoint) -> Option<DMat3> {
        // P = Σ bᵢ Qᵢ(w) with b = b(s, t) affine: ∂P/∂b₁ and ∂P/∂b₂ with b₀ = 1 − b₁ − b₂.
        let qw = [0, 1, 2].map(|i| self.bottom[i] + self.extrusion[i] * q.w);
        let (p1, p2) = (qw[1] - qw[0], qw[2] - qw[0]);
        let dw: DVec3 = (0..3).map(|i| self.extrusion[i] * q.bary[i]).sum();
        let (e1, e2) = (self.uv[1] - self.uv[0], self.uv[2] - self.uv[0]);
        let det = e1.perp_dot(e2);
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        // (b₁, b₂) = inverse([e1 e2]) · (s − s₀, t − t₀)
        let inv = [[e2.y / det, -e2.x / det], [-e1.y / det, e1.x / det]];
        let ds = p1 * inv[0][0] + p2 * inv[1][0];
        let dt = p1 * inv[0][1] + p2 * inv[1][1];
        Some(DMat3::from_cols(ds, dt, dw))
    }

    /// All the prism's coordinates whose point is `p` (up to round-off) with w in
    /// [−`slack`, 1 + `slack`]: the roots of the cubic det[Q₁(w)−Q₀(w), Q₂(w)−Q₀(w), P−Q₀(w)]
    /// = 0, i.e. the heights whose level triangle's plane contains `p`, each with its
    /// barycentric coordinates (possibly outside the triangle). A prism that does not fold
    /// has at most one root whose coordinates lie inside.
    pub fn locate_all(&self, p: DVec3, slack: f64) -> impl Iterator<Item = PrismPoint> {
        let [b0, b1, b2] = self.bottom;
        let [d0, d1, d2] = self.extrusion;
        let (e1, e2, r) = (b1 - b0, b2 - b0, p - b0);
        let (f1, f2) = (d1 - d0, d2 - d0);
        let n0 = e1.cross(e2);
        let n1 = e1.cross(f2) + f1.cross(e2);
        let n2 = f1.cross(f2);
        // det = (n0 + w n1 + w² n2)·(r − w d0)
        let c = [
            n0.dot(r),
            n1.dot(r) - n0.dot(d0),
            n2.dot(r) - n1.dot(d0),
            -n2.dot(d0),
        ];
        cubic_roots(c, -slack, 1.0 + slack)
            .into_iter()
            .filter_map(move |w| {
                let level = FaceTriangle {
                    corners: [b0 + d0 * w, b1 + d1 * w, b2 + d2 * w],
                    texture: [DVec3::ZERO; 3],
                };
                level.barycentric(p).map(|bary| PrismPoint { bary, w })
            })
    }

    /// The prism coordinates of `p` that lie inside the prism within `tolerance` (in units of
    /// barycentric coordinates and w), the one nearest `hint` when the prism folds so that
    /// several do.
    pub fn locate(&self, p: DVec3, tolerance: f64, hint: Option<PrismPoint>) -> Option<PrismPoint> {
        let distance = |q: &PrismPoint| match hint {
            Some(h) => {
                (0..3).map(|i| (q.bary[i] - h.bary[i]).abs()).sum::<f64>() + (q.w - h.w).abs()
            }
            None => q.outside(),
        };
        self.locate_all(p, tolerance)
            .filter(|q| q.outside() <= tolerance)
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    /// The prism's eight face triangles: top, bottom, then the two triangles of each fin.
    pub fn faces(&self) -> [FaceTriangle; 8] {
        let top = self.top();
        let tex = |i: usize, w: f64| self.uv[i].extend(w);
        let [f0, f1, f2] = self.fins;
        [
            FaceTriangle {
                corners: top,
                texture: [tex(0, 1.0), tex(1, 1.0), tex(2, 1.0)],
            },
            FaceTriangle {
                corners: [self.bottom[0], self.bottom[2], self.bottom[1]],
                texture: [tex(0, 0.0), tex(2, 0.0), tex(1, 0.0)],
            },
            f0.triangles[0],
            f0.triangles[1],
            f1.triangles[0],
            f1.triangles[1],
            f2.triangles[0],
            f2.triangles[1],
        ]
    }

    /// The split into three tetrahedra (corners as (corner index, is top)), consistent with
    /// the fin diagonals: with corners sorted a < b < c by welded id, (Ba,Bb,Bc,Uc),
    /// (Ba,Bb,Ub,Uc), (Ba,Ua,Ub,Uc).
    pub fn tetrahedra(&self) -> [[(usize, bool); 4]; 3] {
        let mut order = [0usize, 1, 2];
        order.sort_by_key(|&i| (self.welded[i], i));
        let [a, b, c] = order;
        [
            [(a, false), (b, false), (c, false), (c, true)],
            [(a, false), (b, false), (b, true), (c, true)],
            [(a, false), (a, true), (b, true), (c, true)],
        ]
    }

    /// det ∂P/∂(b₁, b₂, w) at `q`, positive where the prism maps with the base triangle's
    /// orientation.
    fn orientation(&self, q: PrismPoint) -> f64 {
        let qw = [0, 1, 2].map(|i| self.bottom[i] + self.extrusion[i] * q.w);
        let dw: DVec3 = (0..3).map(|i| self.extrusion[i] * q.bary[i]).sum();
        (qw[1] - qw[0]).cross(qw[2] - qw[0]).dot(dw)
    }
}

/// What building a shell found.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ShellReport {
    /// Prisms built (one per base triangle with area and a usable UV triangle).
    pub prisms: usize,
    /// Base triangles skipped because their UV triangle has no area.
    pub skipped_uv_degenerate: usize,
    /// Prisms whose top triangle faces the opposite way to their base triangle.
    pub inverted: usize,
    /// Prisms whose mapping folds somewhere inside (the Jacobian changes sign at one of the
    /// sampled points: corners and centre at heights 0, ½ and 1): the shell crosses itself.
    pub folded: usize,
    /// Fins classified convex (counted once per prism side).
    pub convex_fins: usize,
    /// Fins classified concave.
    pub concave_fins: usize,
}

/// The extruded base mesh.
#[derive(Clone, Debug)]
pub struct Shell {
    /// One prism per usable base triangle.
    pub prisms: Vec<Prism>,
    /// The parameters it was built with.
    pub params: ShellParams,
    /// What building it found.
    pub report: ShellReport,
}

impl Shell {
    /// Extrudes `mesh` (already validated: finite, no zero-area triangles).
    pub fn new(mesh: &BaseMesh, params: ShellParams) -> Result<Shell> {
        check_params(&params)?;
        let welded = weld(&mesh.positions);
        let directions = extrusion_directions(mesh, &welded, params.smoothing);
        let tiles = DVec2::from(params.tiles_per_uv);
        let mut report = ShellReport::default();
        let mut prisms = Vec::with_capacity(mesh.triangles.len());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let idx = tri.map(|i| i as usize);
            let bottom = idx.map(|i| mesh.positions[i]);
            let extrusion = idx.map(|i| directions[i] * params.thickness);
            let uv = idx.map(|i| mesh.uvs[i] * tiles);
            let uv_area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
            if uv_area == 0.0 || !uv_area.is_finite() {
                report.skipped_uv_degenerate += 1;
                continue;
            }
            let ids = idx.map(|i| welded[i]);
            let fins = [0, 1, 2].map(|k| make_fin(&bottom, &extrusion, &uv, &ids, k));
            let mean_extrusion = (extrusion[0] + extrusion[1] + extrusion[2]) / 3.0;
            let object =
                DMat3::from_cols(bottom[1] - bottom[0], bottom[2] - bottom[0], mean_extrusion);
            let texture = DMat3::from_cols(
                (uv[1] - uv[0]).extend(0.0),
                (uv[2] - uv[0]).extend(0.0),
                DVec3::Z,
            );
            let det = object.determinant();
            let to_texture = if det != 0.0 && det.is_finite() {
                texture * object.inverse()
            } else {
                DMat3::ZERO
            };
            let prism = Prism {
                triangle: t as u32,
                bottom,
                extrusion,
                uv,
                fins,
                welded: ids,
                to_texture,
            };
            for f in &prism.fins {
                if f.convex {
                    report.convex_fins += 1;
                } else {
                    report.concave_fins += 1;
                }
            }
            let top = prism.top();
            let base_normal = (bottom[1] - bottom[0]).cross(bottom[2] - bottom[0]);
            if (top[1] - top[0]).cross(top[2] - top[0]).dot(base_normal) <= 0.0 {
                report.inverted += 1;
            }
            if folds(&prism) {
                report.folded += 1;
            }
            prisms.push(prism);
        }
        report.prisms = prisms.len();
        if prisms.is_empty() {
            return Err(Error::InvalidParameter(
                "the base mesh has no triangle with a usable UV mapping".into(),
            ));
        }
        Ok(Shell {
            prisms,
            params,
            report,
        })
    }
}

impl ShellParams {
    /// Checks the parameters (thickness, tiling, smoothing passes).
    pub fn validate(&self) -> Result<()> {
        check_params(self)
    }
}

fn check_params(p: &ShellParams) -> Result<()> {
    if !(p.thickness.is_finite() && p.thickness > 0.0) {
        return Err(Error::InvalidParameter(format!(
            "shell thickness must be finite and positive, got {}",
            p.thickness
        )));
    }
    if !p
        .tiles_per_uv
        .iter()
        .all(|t| t.is_finite() && *t > 0.0 && *t <= 1e6)
    {
        return Err(Error::InvalidParameter(format!(
            "tiles per UV unit must be finite, positive and at most 1e6, got {:?}",
            p.tiles_per_uv
        )));
    }
    if p.smoothing > MAX_SMOOTHING {
        return Err(Error::InvalidParameter(format!(
            "at most {MAX_SMOOTHING} smoothing passes, got {}",
            p.smoothing
        )));
    }
    Ok(())
}

/// Welded vertex ids: vertices with bit-identical positions share the smallest index among
/// them, so UV seams (duplicated vertices) neither crease extrusions nor split fins apart.
fn weld(positions: &[DVec3]) -> Vec<u32> {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let key = p.to_array().map(|c| (c + 0.0).to_bits());
            *first.entry(key).or_insert(i as u32)
        })
        .collect()
}

/// Per-vertex unit extrusion directions: the normals averaged over welded copies, then
/// `passes` of Laplacian smoothing over the welded edge graph, never turning more than 90°
/// from the vertex normal.
fn extrusion_directions(mesh: &BaseMesh, welded: &[u32], passes: u32) -> Vec<DVec3> {
    let n = mesh.positions.len();
    let mut dir = vec![DVec3::ZERO; n];
    for (i, &w) in welded.iter().enumerate() {
        dir[w as usize] += mesh.normals[i];
    }
    let mut neighbours: Vec<Vec<u32>> = Vec::new();
    if passes > 0 {
        neighbours = vec![Vec::new(); n];
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (welded[t[k] as usize], welded[t[(k + 1) % 3] as usize]);
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
    }
    let normalize = |v: DVec3, fallback: DVec3| v.try_normalize().unwrap_or(fallback);
    for (i, &w) in welded.iter().enumerate() {
        if w as usize == i {
            dir[i] = normalize(dir[i], mesh.normals[i]);
        }
    }
    for _ in 0..passes {
        let previous = dir.clone();
        for (i, &w) in welded.iter().enumerate() {
            if w as usize != i || neighbours[i].is_empty() {
                continue;
            }
            let sum: DVec3 = neighbours[i].iter().map(|&j| previous[j as usize]).sum();
            let mean = normalize(sum / neighbours[i].len() as f64, previous[i]);
            let smoothed = normalize(previous[i] + mean, previous[i]);
            dir[i] = if smoothed.dot(mesh.normals[i]) > 0.0 {
                smoothed
            } else {
                previous[i]
            };
        }
    }
    (0..n).map(|i| dir[welded[i] as usize]).collect()
}

fn make_fin(
    bottom: &[DVec3; 3],
    extrusion: &[DVec3; 3],
    uv: &[DVec2; 3],
    ids: &[u32; 3],
    k: usize,
) -> Fin {
    let (i, j) = (k, (k + 1) % 3);
    let b = |c: usize| (bottom[c], uv[c].extend(0.0));
    let u = |c: usize| (bottom[c] + extrusion[c], uv[c].extend(1.0));
    let tri = |v: [(DVec3, DVec3); 3]| FaceTriangle {
        corners: v.map(|x| x.0),
        texture: v.map(|x| x.1),
    };
    // The quad Bi, Bj, Uj, Ui is counter-clockwise seen from outside; the diagonal starts at
    // the bottom corner with the smaller welded id.
    let triangles = if (ids[i], i) < (ids[j], j) {
        [tri([b(i), b(j), u(j)]), tri([b(i), u(j), u(i)])]
    } else {
        [tri([b(i), b(j), u(i)]), tri([b(j), u(j), u(i)])]
    };
    // The corner of the second triangle off the diagonal, against the first one's plane.
    let far = if (ids[i], i) < (ids[j], j) {
        u(i).0
    } else {
        u(j).0
    };
    // Planar within round-off (a sine of 1e-9) counts as convex, so that the classification
    // of flat fins does not depend on the model's scale.
    let n = triangles[0].normal();
    let offset = far - triangles[0].corners[0];
    let side = n.dot(offset);
    Fin {
        triangles,
        convex: side <= 1e-9 * n.length() * offset.length(),
    }
}

fn folds(prism: &Prism) -> bool {
    let corners = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0 / 3.0; 3],
    ];
    let mut sign = 0.0f64;
    for bary in corners {
        for w in [0.0, 0.5, 1.0] {
            let d = prism.orientation(PrismPoint { bary, w });
            if d == 0.0 || (sign != 0.0 && d.signum() != sign) {
                return true;
            }
            sign = d.signum();
        }
    }
    false
}

/// The real roots of a cubic in an interval: at most three, ascending, without allocating
/// (the shell walk solves one per prism face it crosses).
#[derive(Clone, Copy, Debug, Default)]
pub struct CubicRoots {
    values: [f64; 3],
    len: usize,
}

impl CubicRoots {
    fn push(&mut self, x: f64) {
        self.values[self.len] = x;
        self.len += 1;
    }
}

impl std::ops::Deref for CubicRoots {
    type Target = [f64];

    fn deref(&self) -> &[f64] {
        &self.values[..self.len]
    }
}

impl IntoIterator for CubicRoots {
    type Item = f64;
    type IntoIter = std::iter::Take<std::array::IntoIter<f64, 3>>;

    fn into_iter(self) -> Self::IntoIter {
        self.values.into_iter().take(self.len)
    }
}

/// Real roots in [lo, hi] of c₀ + c₁x + c₂x² + c₃x³, ascending: the interval is split at the
/// critical points, and each monotone piece with a sign change is solved by safeguarded
/// Newton iteration to full precision. Scale-free (coefficients are normalized).
pub fn cubic_roots(c: [f64; 4], lo: f64, hi: f64) -> CubicRoots {
    let mut roots = CubicRoots::default();
    let scale = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return roots;
    }
    let c = c.map(|x| x / scale);
    let f = |x: f64| ((c[3] * x + c[2]) * x + c[1]) * x + c[0];
    let df = |x: f64| (3.0 * c[3] * x + 2.0 * c[2]) * x + c[1];
    // Critical points: 3c₃x² + 2c₂x + c₁ = 0.
    let (qa, qb, qc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut crit = [f64::NAN; 2];
    if qa.abs() > 1e-300 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let s = disc.sqrt();
            let q = -0.5 * (qb + qb.signum() * s);
            crit = if q != 0.0 {
                [q / qa, qc / q]
            } else {
                [0.0, f64::NAN]
            };
        }
    } else if qb.abs() > 1e-300 {
        crit[0] = -qc / qb;
    }
    if crit[1] < crit[0] {
        crit.swap(0, 1);
    }
    // lo, the critical points inside (lo, hi) ascending, hi (NaN fails the test).
    let mut cuts = [lo; 4];
    let mut count = 1;
    for x in crit {
        if x > lo && x < hi {
            cuts[count] = x;
            count += 1;
        }
    }
    cuts[count] = hi;
    for pair in cuts[..=count].windows(2) {
        let (mut a, mut b) = (pair[0], pair[1]);
        let (fa, fb) = (f(a), f(b));
        if fa == 0.0 {
            if roots.last() != Some(&a) {
                roots.push(a);
            }
            continue;
        }
        if fb == 0.0 {
            roots.push(b);
            continue;
        }
        if fa.signum() == fb.signum() {
            continue;
        }
        let rising = fb > 0.0;
        let mut x = 0.5 * (a + b);
        for _ in 0..100 {
            let fx = f(x);
            if fx == 0.0 {
                break;
            }
            if (fx > 0.0) == rising {
                b = x;
            } else {
                a = x;
            }
            let d = df(x);
            let newton = x - fx / d;
            x = if d != 0.0 && newton > a && newton < b {
                newton
            } else {
                0.5 * (a + b)
            };
            if b - a <= 4.0 * f64::EPSILON * (1.0 + x.abs()) {
                break;
            }
        }
        roots.push(x);
    }
    roots
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat_prism(skew: DVec3) -> Prism {
        let mesh = BaseMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            normals: vec![DVec3::Z; 3],
            uvs: vec![DVec2::ZERO, DVec2::X, DVec2::Y],
            triangles: vec![[0, 1, 2]],
        };
        let mut shell = Shell::new(
            &mesh,
            ShellParams {
                thickness: 0.5,
                tiles_per_uv: [1.0, 1.0],
                smoothing: 0,
            },
        )
        .unwrap();
        let mut p = shell.prisms.remove(0);
        p.extrusion[1] += skew;
        p.fins = [0, 1, 2].map(|k| make_fin(&p.bottom, &p.extrusion, &p.uv, &p.welded, k));
        p
    }

    #[test]
    fn cubic_roots_match_known_roots() {
        // (x − 0.1)(x − 0.5)(x − 0.9), scaled: roots to 1e-14.
        let (a, b, c) = (0.1, 0.5, 0.9);
        let k = 1e-9;
        let coeffs = [
            -a * b * c * k,
            (a * b + b * c + a * c) * k,
            -(a + b + c) * k,
            k,
        ];
        let r = cubic_roots(coeffs, 0.0, 1.0);
        assert_eq!(r.len(), 3);
        for (x, y) in r.iter().zip([a, b, c]) {
            assert!((x - y).abs() < 1e-14, "{x} vs {y}");
        }
        // A linear polynomial (c₂ = c₃ = 0) and a double root at 0.5.
        assert!((cubic_roots([-0.25, 1.0, 0.0, 0.0], 0.0, 1.0)[0] - 0.25).abs() < 1e-15);
        let double = cubic_roots([0.25, -1.0, 1.0, 0.0], 0.0, 1.0);
        assert!(double.iter().any(|x| (x - 0.5).abs() < 1e-12), "{double:?}");
    }

    #[test]
    fn locate_inverts_point_on_a_skewed_prism() {
        // Non-parallel extrusions make the mapping truly trilinear; locate must invert it
        // to round-off (1e-12) everywhere inside.
        let p = flat_prism(DVec3::new(0.2, -0.1, 0.3));
        for &w in &[0.0, 0.3, 0.999, 1.0] {
            for &bary in &[
                [1.0, 0.0, 0.0],
                [0.2, 0.3, 0.5],
                [0.0, 0.5, 0.5],
                [1.0 / 3.0; 3],
            ] {
                let q = PrismPoint { bary, w };
                let x = p.point(q);
                let back = p.locate(x, 1e-12, None).expect("inside");
                assert!((back.w - w).abs() < 1e-12, "w {} vs {w}", back.w);
                for (got, want) in back.bary.iter().zip(bary) {
                    assert!((got - want).abs() < 1e-12);
                }
            }
        }
        assert!(p.locate(DVec3::new(0.2, 0.2, 2.0), 1e-9, None).is_none());
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let p = flat_prism(DVec3::new(0.2, -0.1, 0.3));
        let q = PrismPoint {
            bary: [0.3, 0.3, 0.4],
            w: 0.4,
        };
        let j = p.jacobian(q).unwrap();
        let h = 1e-6;
        // Texture s moves b₁ (uv = (s, t) on the unit triangle), t moves b₂, w moves w.
        let moved = |db1: f64, db2: f64, dw: f64| {
            p.point(PrismPoint {
                bary: [q.bary[0] - db1 - db2, q.bary[1] + db1, q.bary[2] + db2],
                w: q.w + dw,
            })
        };
        let fd = [
            (moved(h, 0.0, 0.0) - moved(-h, 0.0, 0.0)) / (2.0 * h),
            (moved(0.0, h, 0.0) - moved(0.0, -h, 0.0)) / (2.0 * h),
            (moved(0.0, 0.0, h) - moved(0.0, 0.0, -h)) / (2.0 * h),
        ];
        for (c, f) in [j.x_axis, j.y_axis, j.z_axis].iter().zip(fd) {
            assert!((*c - f).length() < 1e-8, "{c} vs {f}");
        }
    }

    #[test]
    fn fin_classification_follows_the_extrusion() {
        // Extrusions spreading apart make the sides lean outwards: a bilinear side whose
        // diagonal split bends one way or the other, depending on the twist.
        let straight = flat_prism(DVec3::ZERO);
        for f in &straight.fins {
            // Planar quads: both triangles coplanar, classified convex (either rule agrees).
            assert!(f.convex);
            let (n0, n1) = (f.triangles[0].normal(), f.triangles[1].normal());
            assert!(n0.normalize().dot(n1.normalize()) > 1.0 - 1e-12);
        }
        let twisted = flat_prism(DVec3::new(0.0, 0.3, 0.0));
        let fin = &twisted.fins[0]; // edge 0 → 1, its top corner 1 moved along +y (inwards)
        let centre = twisted.point(PrismPoint {
            bary: [1.0 / 3.0; 3],
            w: 0.5,
        });
        for t in &fin.triangles {
            assert!(
                t.normal().dot(t.corners[0] - centre) > 0.0,
                "outward normals"
            );
        }
        // Moving corner 1's top inwards bends the fin into the prism: the far corner of the
        // second triangle (top of corner 0) lies outside the first triangle's plane.
        assert!(!fin.convex);
        let outwards = flat_prism(DVec3::new(0.0, -0.3, 0.0));
        assert!(outwards.fins[0].convex);
    }

    #[test]
    fn tetrahedra_fill_the_prism_and_share_faces_with_fins() {
        let p = flat_prism(DVec3::ZERO);
        let top = p.top();
        let corner = |(i, t): (usize, bool)| if t { top[i] } else { p.bottom[i] };
        let volume: f64 = p
            .tetrahedra()
            .iter()
            .map(|t| {
                let v = t.map(corner);
                ((v[1] - v[0]).cross(v[2] - v[0]).dot(v[3] - v[0]) / 6.0).abs()
            })
            .sum();
        // A right prism over a triangle of area ½ and height 0.5.
        assert!((volume - 0.25).abs() < 1e-15);
        // Every fin triangle is a face of one tetrahedron.
        for fin in &p.fins {
            for tri in &fin.triangles {
                let found = p.tetrahedra().iter().any(|t| {
                    let v = t.map(corner);
                    tri.corners.iter().all(|c| v.contains(c))
                });
                assert!(
                    found,
                    "fin triangle {:?} is no tetrahedron face",
                    tri.corners
                );
            }
        }
    }
}
