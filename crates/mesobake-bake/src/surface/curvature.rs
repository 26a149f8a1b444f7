//! Per-vertex principal curvatures of a triangle mesh.
//!
//! The estimator is Rusinkiewicz's ("Estimating Curvatures and Their Derivatives on Triangle
//! Meshes", 3DPVT 2004):
//!
//! 1. Per triangle, the second fundamental form II (a symmetric 2×2 tensor in an orthonormal
//!    frame (t, b) of the triangle's plane) is fitted by least squares to the three edges:
//!    II·(e·t, e·b) = (Δn·t, Δn·b), where Δn is the difference of the vertex normals at the ends
//!    of edge e (6 equations, 3 unknowns).
//! 2. Per vertex, each incident triangle's tensor is re-expressed in the vertex's tangent frame
//!    (the frame is rotated onto the triangle's plane about the axis normal × triangle normal,
//!    and the tensor is evaluated on the rotated axes) and accumulated with the vertex's
//!    mixed Voronoi area in that triangle as weight (Meyer, Desbrun, Schröder and Barr 2003:
//!    the Voronoi area in non-obtuse triangles; in an obtuse one, half its area for the obtuse
//!    corner and a quarter for each other), then divided by the sum of the weights.
//! 3. The 2×2 tensor is diagonalized in closed form: its eigenvalues are the principal
//!    curvatures, its eigenvectors the principal directions.
//!
//! Conventions:
//! - Sign: curvature is positive where the surface bends away from its normal (II = dn/dx, the
//!   derivative of the normal along the surface). A sphere of radius r with outward normals has
//!   both curvatures +1/r, with inward normals −1/r; a cylinder of radius r with outward normals
//!   has +1/r around and 0 along its axis. Only the vertex normals decide the sign: the
//!   triangles' winding is not used (each triangle's normal is taken on the side of its vertex
//!   normals).
//! - Units: 1 / the length unit of the positions.
//! - Welding: vertices with bit-identical positions (−0.0 and +0.0 counting as equal), such as
//!   the duplicates along a UV seam or at a pole, are one vertex for the estimate, whose normal
//!   is the normalized sum of their normals; every duplicate receives that vertex's result.
//! - Skipped triangles: degenerate ones (zero area up to rounding, or non-finite), ones with an
//!   index out of range and ones touching a vertex whose welded normal is zero or non-finite.
//!   A corner whose vertex normal faces away from its triangle (by 90° or more) is ignored. Open
//!   meshes need nothing special: a boundary vertex averages over the triangles it has.
//! - A vertex in no used triangle gets zero curvature and an arbitrary orthonormal tangent frame.
//!
//! Accuracy, measured with exact (analytic) vertex normals on the project's grid meshes:
//! - sphere, plane and cylinder: exact up to rounding (errors below 2e-15 / length, poles and
//!   open boundaries included), since there the normals vary linearly along every edge;
//! - torus (major radius 1, minor 0.3; segments around the axis × around the tube): the largest
//!   error on either curvature is second order in the edge length: 0.024, 0.0059, 0.0015
//!   (1/length) at 48×24, 96×48, 192×96, i.e. 0.7 %, 0.18 %, 0.04 % of 1/0.3; the principal
//!   directions are within 0.03° at 96×48;
//! - the same torus with every vertex moved along the surface by up to 20 % of an edge in each
//!   parameter direction: first order, 0.14, 0.068, 0.033 at the same resolutions (directions
//!   within 1.2° at 96×48).
//!
//! Normals that are themselves estimated (e.g. averaged face normals) add their own error.

use glam::{DMat3, DVec3};
use std::collections::HashMap;

/// Principal curvatures and directions at one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexCurvature {
    /// The larger principal curvature (1/length unit of the positions).
    pub k_max: f64,
    /// The smaller principal curvature.
    pub k_min: f64,
    /// Unit tangent direction of `k_max` (perpendicular to the vertex normal).
    pub dir_max: DVec3,
    /// Unit tangent direction of `k_min` (perpendicular to the vertex normal and `dir_max`).
    pub dir_min: DVec3,
}

impl VertexCurvature {
    /// The normal curvature along tangent `direction` (projected onto the tangent plane and
    /// normalized; Euler's formula k_max·cos²α + k_min·sin²α); 0 for a direction along the
    /// normal.
    pub fn along(&self, direction: DVec3) -> f64 {
        let (c, s) = (direction.dot(self.dir_max), direction.dot(self.dir_min));
        let length2 = c * c + s * s;
        if length2 > 0.0 {
            (self.k_max * c * c + self.k_min * s * s) / length2
        } else {
            0.0
        }
    }
}

/// Estimates the principal curvatures of every vertex (see the module documentation).
///
/// Returns one entry per position. A missing normal (`normals` shorter than `positions`)
/// counts as zero.
pub fn vertex_curvatures(
    positions: &[DVec3],
    normals: &[DVec3],
    triangles: &[[u32; 3]],
) -> Vec<VertexCurvature> {
    let (welded_index, points, frames) = weld(positions, normals);
    // Per welded vertex: the weighted sum of (II(u, u), II(u, v), II(v, v)) in its frame, and
    // the sum of the weights.
    let mut sums = vec![(DVec3::ZERO, 0.0); points.len()];
    for triangle in triangles {
        let [Some(a), Some(b), Some(c)] = triangle.map(|i| welded_index.get(i as usize).copied())
        else {
            continue;
        };
        let ids = [a, b, c];
        let Some(face) = Face::fit(ids.map(|i| points[i]), ids.map(|i| frames[i].normal)) else {
            continue;
        };
        for (&id, weight) in ids.iter().zip(face.corner_areas) {
            let frame = &frames[id];
            let cos = frame.normal.dot(face.normal);
            if cos <= 0.0 {
                continue;
            }
            let u = rotate_tangent(frame.u, frame.normal, face.normal, cos);
            let v = rotate_tangent(frame.v, frame.normal, face.normal, cos);
            let tensor = DVec3::new(face.form(u, u), face.form(u, v), face.form(v, v));
            sums[id].0 += weight * tensor;
            sums[id].1 += weight;
        }
    }
    let results: Vec<VertexCurvature> = frames
        .iter()
        .zip(sums)
        .map(|(frame, (tensor, weight))| {
            frame.principal(if weight > 0.0 {
                tensor / weight
            } else {
                DVec3::ZERO
            })
        })
        .collect();
    welded_index.iter().map(|&id| results[id]).collect()
}

/// A welded vertex's unit normal (zero if it has none) and orthonormal tangent frame (u, v),
/// right-handed: u × v = normal.
struct Frame {
    normal: DVec3,
    u: DVec3,
    v: DVec3,
}

impl Frame {
    fn new(normal_sum: DVec3) -> Frame {
        let normal = normal_sum.normalize_or_zero();
        let axis = if normal == DVec3::ZERO {
            DVec3::Z
        } else {
            normal
        };
        let u = axis.any_orthonormal_vector();
        Frame {
            normal,
            u,
            v: axis.cross(u),
        }
    }

    /// Principal curvatures and directions of the symmetric tensor (II(u, u), II(u, v),
    /// II(v, v)) given in this frame.
    fn principal(&self, tensor: DVec3) -> VertexCurvature {
        let (a, b, c) = tensor.into();
        let (mean, half_difference) = (0.5 * (a + c), 0.5 * (a - c));
        let radius = half_difference.hypot(b);
        // The eigenvector of the larger eigenvalue is at angle θ from u, tan 2θ = 2b / (a − c).
        let (sin, cos) = (0.5 * b.atan2(half_difference)).sin_cos();
        VertexCurvature {
            k_max: mean + radius,
            k_min: mean - radius,
            dir_max: cos * self.u + sin * self.v,
            dir_min: cos * self.v - sin * self.u,
        }
    }
}

/// Welds the vertices with bit-identical positions (±0.0 equal): the welded index of every
/// vertex, and each welded vertex's position and frame (from the sum of its copies' normals).
fn weld(positions: &[DVec3], normals: &[DVec3]) -> (Vec<usize>, Vec<DVec3>, Vec<Frame>) {
    let mut ids = HashMap::new();
    let mut points = Vec::new();
    let mut normal_sums = Vec::new();
    let index = positions
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let key = p.to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
            let id = *ids.entry(key).or_insert_with(|| {
                points.push(p);
                normal_sums.push(DVec3::ZERO);
                points.len() - 1
            });
            normal_sums[id] += normals.get(i).copied().unwrap_or_default();
            id
        })
        .collect();
    (
        index,
        points,
        normal_sums.into_iter().map(Frame::new).collect(),
    )
}

/// `x`, perpendicular to unit `from`, rotated by the smallest rotation taking `from` to unit
/// `to`, given `cos` = from · to > −1.
fn rotate_tangent(x: DVec3, from: DVec3, to: DVec3, cos: f64) -> DVec3 {
    x - (from + to) * (x.dot(to) / (1.0 + cos))
}

/// One triangle's fitted second fundamental form.
struct Face {
    /// Unit normal of the triangle's plane, on the side of its vertex normals.
    normal: DVec3,
    /// Orthonormal frame of the plane (t × b = normal).
    t: DVec3,
    b: DVec3,
    /// (II(t, t), II(t, b), II(b, b)).
    form: DVec3,
    /// Mixed Voronoi area of each corner (Meyer et al. 2003).
    corner_areas: [f64; 3],
}

impl Face {
    /// Fits II to the corners' positions and unit normals; `None` for a degenerate triangle,
    /// a zero normal, or normals whose sum lies in the triangle's plane.
    fn fit(p: [DVec3; 3], n: [DVec3; 3]) -> Option<Face> {
        // Edge i is opposite corner i.
        let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
        let cross = e[0].cross(e[1]);
        let area = 0.5 * cross.length();
        let longest2 = e.iter().map(|e| e.length_squared()).fold(0.0, f64::max);
        let side = cross.dot(n[0] + n[1] + n[2]);
        let unit_normals = !n.contains(&DVec3::ZERO);
        if !(area.is_finite() && area > f64::EPSILON * longest2 && side != 0.0 && unit_normals) {
            return None;
        }
        let normal = cross * (side.signum() / (2.0 * area));
        let t = e[0].normalize();
        let b = normal.cross(t);
        // Normal equations AᵀA·(II_tt, II_tb, II_bb) = Aᵀy of the 6 equations
        // II_tt·e_t + II_tb·e_b = Δn_t and II_tb·e_t + II_bb·e_b = Δn_b.
        let mut lhs = DMat3::ZERO;
        let mut rhs = DVec3::ZERO;
        for (i, edge) in e.iter().enumerate() {
            let (et, eb) = (edge.dot(t), edge.dot(b));
            let dn = n[(i + 2) % 3] - n[(i + 1) % 3];
            let (nt, nb) = (dn.dot(t), dn.dot(b));
            lhs += DMat3::from_cols_array(&[
                et * et,
                et * eb,
                0.0,
                et * eb,
                et * et + eb * eb,
                et * eb,
                0.0,
                et * eb,
                eb * eb,
            ]);
            rhs += DVec3::new(nt * et, nt * eb + nb * et, nb * eb);
        }
        let form = lhs.inverse() * rhs;
        form.is_finite().then(|| Face {
            normal,
            t,
            b,
            form,
            corner_areas: corner_areas(e, area),
        })
    }

    /// II(x, y) for vectors in the triangle's plane.
    fn form(&self, x: DVec3, y: DVec3) -> f64 {
        let (xt, xb, yt, yb) = (x.dot(self.t), x.dot(self.b), y.dot(self.t), y.dot(self.b));
        self.form.x * xt * yt + self.form.y * (xt * yb + xb * yt) + self.form.z * xb * yb
    }
}

/// The mixed Voronoi area of each corner of a non-degenerate triangle with edges `e` (edge i
/// opposite corner i) and area `area` (Meyer et al. 2003, figure 4).
fn corner_areas(e: [DVec3; 3], area: f64) -> [f64; 3] {
    // The dot product of the two edges leaving each corner: negative at an obtuse corner.
    let dot = [0, 1, 2].map(|i| -e[(i + 1) % 3].dot(e[(i + 2) % 3]));
    if let Some(obtuse) = dot.iter().position(|&d| d < 0.0) {
        return [0, 1, 2].map(|i| if i == obtuse { 0.5 } else { 0.25 } * area);
    }
    // (|e_j|²·cot θ_j + |e_k|²·cot θ_k) / 8 over the two edges at corner i, cot θ = dot / 2·area.
    [0, 1, 2].map(|i| {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        (e[j].length_squared() * dot[j] + e[k].length_squared() * dot[k]) / (16.0 * area)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// Major and minor radius of the test torus.
    const MAJOR: f64 = 1.0;
    const MINOR: f64 = 0.3;

    struct Mesh {
        positions: Vec<DVec3>,
        normals: Vec<DVec3>,
        triangles: Vec<[u32; 3]>,
    }

    impl Mesh {
        fn curvatures(&self) -> Vec<VertexCurvature> {
            vertex_curvatures(&self.positions, &self.normals, &self.triangles)
        }

        /// The largest |k − expected| over both curvatures of the vertices `which`.
        fn max_error(
            &self,
            curvatures: &[VertexCurvature],
            which: impl Fn(usize) -> bool,
            expected: impl Fn(DVec3) -> [f64; 2],
        ) -> f64 {
            let errors = curvatures.iter().enumerate().filter(|&(i, _)| which(i));
            errors.fold(0.0, |max, (i, c)| {
                let [k_max, k_min] = expected(self.positions[i]);
                max.max((c.k_max - k_max).abs())
                    .max((c.k_min - k_min).abs())
            })
        }

        /// The smallest |direction · expected| over both directions of the vertices `which`.
        fn min_alignment(
            &self,
            curvatures: &[VertexCurvature],
            which: impl Fn(usize) -> bool,
            expected: impl Fn(DVec3) -> [DVec3; 2],
        ) -> f64 {
            let alignments = curvatures.iter().enumerate().filter(|&(i, _)| which(i));
            alignments.fold(1.0, |min, (i, c)| {
                let [dir_max, dir_min] = expected(self.positions[i]);
                min.min(c.dir_max.dot(dir_max).abs())
                    .min(c.dir_min.dot(dir_min).abs())
            })
        }
    }

    /// The project's grid: (nu + 1)·(nv + 1) vertices `vertex(i, j)` (position, normal), row j
    /// after row j − 1, two counter-clockwise triangles per quad; zero-area ones are kept.
    fn grid(nu: u32, nv: u32, vertex: impl Fn(u32, u32) -> (DVec3, DVec3)) -> Mesh {
        let (positions, normals) = (0..=nv)
            .flat_map(|j| (0..=nu).map(move |i| (i, j)))
            .map(|(i, j)| vertex(i, j))
            .unzip();
        let index = move |i: u32, j: u32| j * (nu + 1) + i;
        let triangles = (0..nv)
            .flat_map(|j| (0..nu).map(move |i| (i, j)))
            .flat_map(|(i, j)| {
                let (a, b) = (index(i, j), index(i + 1, j));
                let (c, d) = (index(i + 1, j + 1), index(i, j + 1));
                [[a, b, c], [a, c, d]]
            })
            .collect();
        Mesh {
            positions,
            normals,
            triangles,
        }
    }

    /// The horizontal unit vector at `steps` of n around +Y (counter-clockwise seen from +Y,
    /// from +X). Seams pass `i % n`, so that their duplicates are bit-identical.
    fn radial(steps: f64, n: u32) -> DVec3 {
        let (s, c) = (TAU * steps / f64::from(n)).sin_cos();
        DVec3::new(c, 0.0, -s)
    }

    /// A UV sphere about the origin with outward normals; each pole is a row of duplicates.
    fn sphere(radius: f64, nu: u32, nv: u32) -> Mesh {
        grid(nu, nv, |i, j| {
            // The sine from the nearer pole, so that both poles lie exactly on the axis (with
            // ±0.0 coordinates).
            let ring = (PI * f64::from(j.min(nv - j)) / f64::from(nv)).sin();
            let height = -(PI * f64::from(j) / f64::from(nv)).cos();
            let n = ring * radial(f64::from(i % nu), nu) + height * DVec3::Y;
            (radius * n, n)
        })
    }

    /// An open cylinder about +Y, from y = −height/2 to height/2, outward normals.
    fn cylinder(radius: f64, height: f64, nu: u32, nv: u32) -> Mesh {
        grid(nu, nv, |i, j| {
            let n = radial(f64::from(i % nu), nu);
            let y = height * (f64::from(j) / f64::from(nv) - 0.5);
            (radius * n + y * DVec3::Y, n)
        })
    }

    /// The torus (MAJOR, MINOR) about +Y with outward normals, u around the axis, v around the
    /// tube from the outer equator; each vertex is moved along the surface by up to `jitter`
    /// parameter steps in u and in v (a fixed pseudo-random sequence; the same at duplicates).
    fn torus(nu: u32, nv: u32, jitter: f64) -> Mesh {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            jitter * ((state >> 11) as f64 / (1_u64 << 53) as f64 * 2.0 - 1.0)
        };
        let offsets: Vec<[f64; 2]> = (0..nu * nv).map(|_| [random(), random()]).collect();
        grid(nu, nv, |i, j| {
            let (i, j) = (i % nu, j % nv);
            let [du, dv] = offsets[(j * nu + i) as usize];
            let out = radial(f64::from(i) + du, nu);
            let (sv, cv) = (TAU * (f64::from(j) + dv) / f64::from(nv)).sin_cos();
            let n = cv * out + sv * DVec3::Y;
            (MAJOR * out + MINOR * n, n)
        })
    }

    /// The torus's exact [k_max, k_min] at `p`: 1/r around the tube, cos v / (R + r·cos v)
    /// around the axis (negative on the inner, saddle-shaped half).
    fn torus_curvatures(p: DVec3) -> [f64; 2] {
        let rho = p.x.hypot(p.z);
        [1.0 / MINOR, (rho - MAJOR) / (MINOR * rho)]
    }

    /// The torus's exact principal directions at `p`: around the tube, around the axis.
    fn torus_directions(p: DVec3) -> [DVec3; 2] {
        let around = DVec3::Y.cross(p).normalize();
        let n = (p - MAJOR * DVec3::new(p.x, 0.0, p.z).normalize()) / MINOR;
        [n.cross(around), around]
    }

    #[test]
    fn sphere_is_exact_at_every_vertex_poles_included() {
        // Exact normals make every face's fit exact: tolerance 1e-12 (1/length), all vertices.
        let mut mesh = sphere(2.0, 64, 32);
        let error = mesh.max_error(&mesh.curvatures(), |_| true, |_| [0.5, 0.5]);
        assert!(
            error < 1e-12,
            "sphere r = 2, 64×32: max |k − 0.5| = {error:e} ≥ 1e-12"
        );
        mesh.normals.iter_mut().for_each(|n| *n = -*n);
        let error = mesh.max_error(&mesh.curvatures(), |_| true, |_| [-0.5, -0.5]);
        assert!(
            error < 1e-12,
            "inward sphere: max |k + 0.5| = {error:e} ≥ 1e-12"
        );
    }

    #[test]
    fn cylinder_curves_around_not_along() {
        let (nu, nv) = (64, 16);
        let mesh = cylinder(0.5, 2.0, nu, nv);
        let curvatures = mesh.curvatures();
        let interior = |i: usize| (1..nv as usize).contains(&(i / (nu as usize + 1)));
        let directions = |p: DVec3| [DVec3::Y.cross(p).normalize(), DVec3::Y];
        // Exact up to rounding on the boundary rows (which see triangles on one side only) as
        // well as inside: tolerance 1e-12 (1/length), directions |cos| > 1 − 1e-9.
        for boundary in [false, true] {
            let which = |i| interior(i) != boundary;
            let error = mesh.max_error(&curvatures, which, |_| [2.0, 0.0]);
            assert!(
                error < 1e-12,
                "cylinder (boundary: {boundary}): max error {error:e}"
            );
            let alignment = mesh.min_alignment(&curvatures, which, directions);
            assert!(
                alignment > 1.0 - 1e-9,
                "cylinder: min |dir·expected| {alignment}"
            );
        }
    }

    #[test]
    fn torus_matches_its_closed_form_with_both_signs() {
        let mesh = torus(96, 48, 0.0);
        let curvatures = mesh.curvatures();
        // Tolerance 0.01 (1/length, 0.3 % of 1/r; measured 0.0059); directions within 0.25°
        // (|cos| > 0.99999; measured 0.03°).
        let error = mesh.max_error(&curvatures, |_| true, torus_curvatures);
        assert!(error < 0.01, "torus 96×48: max error {error:e} ≥ 0.01");
        let alignment = mesh.min_alignment(&curvatures, |_| true, torus_directions);
        assert!(
            alignment > 0.99999,
            "torus: min |dir·expected| {alignment} ≤ 0.99999"
        );
        // The inner half is a saddle: k_min has the sign of the exact one wherever that is
        // clearly non-zero (|k| > 0.1); both signs occur.
        let signs = curvatures
            .iter()
            .zip(&mesh.positions)
            .filter_map(|(c, &p)| {
                let k = torus_curvatures(p)[1];
                (k.abs() > 0.1).then_some((k > 0.0, c.k_min > 0.0))
            });
        let (mut positive, mut negative) = (0, 0);
        for (expected, estimated) in signs {
            assert_eq!(expected, estimated, "torus: sign of k_min");
            *if expected {
                &mut positive
            } else {
                &mut negative
            } += 1;
        }
        assert!(
            positive > 0 && negative > 0,
            "torus: {positive} convex, {negative} saddle"
        );
    }

    #[test]
    fn torus_error_converges() {
        // Each doubling of the segments divides the max error by more than 3.5 on the regular
        // torus (second order; measured 0.024, 0.0059, 0.0015: ratios 4.0) and by more than
        // 1.6 on the jittered one (first order; measured 0.14, 0.068, 0.033: ratios 2.0).
        for (jitter, min_ratio) in [(0.0, 3.5), (0.2, 1.6)] {
            let errors = [24, 48, 96].map(|n| {
                let mesh = torus(2 * n, n, jitter);
                mesh.max_error(&mesh.curvatures(), |_| true, torus_curvatures)
            });
            for pair in errors.windows(2) {
                let ratio = pair[0] / pair[1];
                assert!(
                    ratio > min_ratio,
                    "torus, jitter {jitter}: errors {errors:?}"
                );
            }
        }
    }

    #[test]
    fn jittered_torus_stays_close() {
        let mesh = torus(96, 48, 0.2);
        let curvatures = mesh.curvatures();
        // Vertices moved along the surface by up to 20 % of an edge in u and in v: tolerance
        // 0.1 (1/length, 3 % of 1/r; measured 0.068), directions within 2.5° (|cos| > 0.999;
        // measured 1.2°).
        let error = mesh.max_error(&curvatures, |_| true, torus_curvatures);
        assert!(error < 0.1, "jittered torus 96×48: max error {error} ≥ 0.1");
        let alignment = mesh.min_alignment(&curvatures, |_| true, torus_directions);
        assert!(
            alignment > 0.999,
            "jittered torus: min |dir·expected| {alignment} ≤ 0.999"
        );
    }

    #[test]
    fn plane_is_flat() {
        let mesh = grid(8, 8, |i, j| {
            let p = DVec3::new(f64::from(i) / 4.0 - 1.0, 0.0, 1.0 - f64::from(j) / 4.0);
            (p, DVec3::Y)
        });
        // Tolerance 1e-12 (1/length): the normals do not change.
        let error = mesh.max_error(&mesh.curvatures(), |_| true, |_| [0.0, 0.0]);
        assert!(error < 1e-12, "plane: max |k| = {error:e} ≥ 1e-12");
    }

    #[test]
    fn along_follows_eulers_formula() {
        let mesh = cylinder(0.5, 2.0, 64, 16);
        let curvatures = mesh.curvatures();
        // A vertex in the middle row.
        let i = 8 * 65 + 5;
        let (c, p) = (curvatures[i], mesh.positions[i]);
        let around = DVec3::Y.cross(p).normalize();
        // Tolerance 1e-12 (1/length), as for the cylinder: 1/(2r) = 1 at 45°, whatever the
        // length of the direction or its normal part.
        let diagonal = c.along(3.0 * (around + DVec3::Y));
        assert!(
            (diagonal - 1.0).abs() < 1e-12,
            "along 45°: {diagonal}, expected 1 ± 1e-12"
        );
        let tilted = c.along(around + DVec3::Y + 5.0 * mesh.normals[i]);
        assert!(
            (tilted - 1.0).abs() < 1e-12,
            "along 45° + normal: {tilted}, expected 1"
        );
        assert_eq!(c.along(c.dir_max), c.k_max);
        assert_eq!(c.along(mesh.normals[i]), 0.0, "along the normal");
    }

    #[test]
    fn duplicates_get_identical_curvatures() {
        // Seams of a jittered torus (no symmetry to hide a difference) and the sphere's poles
        // (coordinates ±0.0) must be welded: tolerance exact equality.
        for mesh in [torus(24, 12, 0.2), sphere(1.0, 16, 8)] {
            let curvatures = mesh.curvatures();
            let mut first = HashMap::new();
            let mut duplicates = 0;
            for (i, p) in mesh.positions.iter().enumerate() {
                let key = p.to_array().map(|x| (x + 0.0).to_bits());
                let j = *first.entry(key).or_insert(i);
                duplicates += usize::from(j != i);
                assert_eq!(curvatures[i], curvatures[j], "vertices {j} and {i} at {p}");
            }
            assert!(duplicates >= 24, "only {duplicates} duplicates");
        }
    }

    #[test]
    fn bad_input_gives_finite_results() {
        let positions = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::new(1.0, 1.0, 0.2),
            2.0 * DVec3::X,
            DVec3::splat(5.0),
            DVec3::NAN,
        ];
        let normals = [
            DVec3::Z,
            DVec3::new(0.1, 0.0, 1.0).normalize(),
            DVec3::new(0.0, 0.1, 1.0).normalize(),
            DVec3::new(-0.1, -0.1, 1.0).normalize(),
            DVec3::Z,
            DVec3::Z,
        ];
        // An open mesh of two triangles, a zero-area one (0, 1, 4 are collinear), a repeated
        // index, an index out of range, a NaN position; vertex 5 is unused, 6 has no normal.
        let triangles = [
            [0, 1, 2],
            [1, 3, 2],
            [0, 1, 4],
            [1, 1, 3],
            [0, 1, 99],
            [0, 6, 1],
        ];
        let curvatures = vertex_curvatures(&positions, &normals, &triangles);
        assert_eq!(curvatures.len(), positions.len());
        for c in &curvatures {
            let [k_max, k_min, x, y] = [c.k_max, c.k_min, c.dir_max.length(), c.dir_min.length()];
            let orthogonal = c.dir_max.dot(c.dir_min);
            assert!(k_max.is_finite() && k_min.is_finite(), "{c:?}");
            // Tolerance 1e-12: an orthonormal frame.
            let frame = (x - 1.0).abs().max((y - 1.0).abs()).max(orthogonal.abs());
            assert!(frame < 1e-12, "not orthonormal: {c:?}");
        }
        assert!(
            curvatures[0].k_max > 0.0,
            "vertex 0 bends: {:?}",
            curvatures[0]
        );
        for unused in [4, 5, 6] {
            let c = curvatures[unused];
            assert_eq!((c.k_max, c.k_min), (0.0, 0.0), "vertex {unused}");
        }
        assert!(vertex_curvatures(&[], &[], &triangles).is_empty());
    }

    #[test]
    fn corner_areas_are_mixed_voronoi() {
        let areas = |p: [DVec3; 3]| {
            let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
            let area = 0.5 * e[0].cross(e[1]).length();
            (corner_areas(e, area), area)
        };
        // A right triangle (Voronoi; tolerance 1e-15, absolute for an area of 0.5): the right
        // corner's region is a quarter of the square, half the triangle. An obtuse one: exact.
        let (right, area) = areas([DVec3::ZERO, DVec3::X, DVec3::Y]);
        let expected = [0.5, 0.25, 0.25].map(|share| share * area);
        let error = (0..3)
            .map(|i| (right[i] - expected[i]).abs())
            .fold(0.0, f64::max);
        assert!(
            error < 1e-15,
            "right triangle: {right:?}, expected {expected:?} ± 1e-15"
        );
        let (obtuse, area) = areas([DVec3::ZERO, DVec3::X, DVec3::new(-0.5, 0.2, 0.0)]);
        assert_eq!(obtuse, [0.5 * area, 0.25 * area, 0.25 * area]);
    }
}
