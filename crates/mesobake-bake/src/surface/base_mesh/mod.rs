//! Base meshes: the triangle surfaces that mesostructure is mapped onto, read from OBJ or
//! glTF files ([`gltf_file`]) or built in ([`BuiltinMesh`]), validated and cleaned before use.
//!
//! # Conventions
//!
//! - Right-handed coordinates, +Y up.
//! - Triangles are counter-clockwise seen from the side the vertex normals point to; normals are
//!   unit length, one per vertex, and point out of closed surfaces.
//! - UV orientation: for every triangle that is not counted as flipped,
//!   (∂P/∂u × ∂P/∂v)·n > 0, i.e. texture x (u), texture y (v) and the normal form a right-handed
//!   frame. A triangle is *flipped* ([`MeshReport::flipped_uv_triangles`]) when the sign of its
//!   signed area in UV space is opposite to the sign of its geometric winding relative to the
//!   average of its three vertex normals. Flipped triangles are kept and counted.
//! - Zero-area: a triangle whose area is ≤ 1e-12·d², where d is the diagonal of the bounding box
//!   of the corners of all triangles with three distinct vertices and finite positions.
//! - Welding: vertices are welded *exactly* by position (bit-identical coordinates, −0 = +0) for
//!   computed normals and for the edge statistics, so that UV seams, where vertices are
//!   duplicated with different UVs, neither crease normals nor count as boundaries.
//! - Built-in meshes ([`BuiltinMesh`]): UVs span \[0,1\]² over each surface (over each patch for
//!   the teapot). Along a periodic direction the seam vertices are duplicated with u = 1 (or
//!   v = 1), not wrapped to 0, so every triangle's UVs are continuous; their positions are
//!   bit-identical to those at u = 0 so that the seam welds. The plane lies in x–z around the
//!   origin with height y = amplitude·sin(2π·waves·x/size)·cos(2π·waves·z/size), u along +x and
//!   v along −z, normals up; it is open (it has boundary edges).
//!
//! Validation ([`BaseMesh::validated`]) drops each unusable triangle and counts it under the
//! first of: non-finite (a NaN/Inf position, normal or UV, or a zero normal), degenerate (a
//! repeated vertex index), zero-area. Vertices no kept triangle uses are removed. A triangle
//! whose position or UV lies beyond ±[`MAX_COORDINATE`] is an error, not a drop: one such
//! vertex would make every other triangle zero-area against the mesh's extent.

mod builtin;
pub mod gltf_file;
mod grid;
mod teapot;

pub use builtin::BuiltinMesh;
pub use gltf_file::GltfSelection;

use glam::{DVec2, DVec3};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// Relative area threshold: a triangle with area ≤ this · (bounding-box diagonal)² is zero-area.
const ZERO_AREA_RELATIVE: f64 = 1e-12;

/// The largest magnitude of a base mesh's coordinates (object units) and UVs: f32 (the GPU's
/// and the BVHs' number) squares it without overflow, and no asset comes near it.
pub const MAX_COORDINATE: f64 = 1e9;

/// A triangle mesh with per-vertex unit normals and UVs: the surface mesostructure is mapped onto.
#[derive(Clone, Debug, PartialEq)]
pub struct BaseMesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Vertex normals, unit length, one per vertex.
    pub normals: Vec<DVec3>,
    /// Texture coordinates, one per vertex.
    pub uvs: Vec<DVec2>,
    /// Vertex indices of each triangle, counter-clockwise seen from the side the normals point to.
    pub triangles: Vec<[u32; 3]>,
}

/// What validation found (counts), printed by the CLI and returned in JSON.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MeshReport {
    /// Vertices of the cleaned mesh.
    pub vertices: usize,
    /// Triangles kept.
    pub triangles: usize,
    /// Dropped: a NaN/Inf position, normal or UV (or a zero normal).
    pub non_finite_triangles: usize,
    /// Dropped: a repeated vertex index.
    pub degenerate_triangles: usize,
    /// Dropped: area ≤ 1e-12·(bounding-box diagonal)² (collinear corners or a sliver to zero).
    pub zero_area_triangles: usize,
    /// Kept: UV winding opposite to the geometric winding (see the module documentation).
    pub flipped_uv_triangles: usize,
    /// Kept: edges (welded by position) shared by more than two triangles.
    pub non_manifold_edges: usize,
    /// Kept: edges (welded by position) used by one triangle; open surfaces have them.
    pub boundary_edges: usize,
    /// True when the normals were computed rather than read.
    pub computed_normals: bool,
}

impl BaseMesh {
    /// Parses OBJ text (all objects merged, faces triangulated as fans; points and lines
    /// ignored). UVs are required on every face vertex (an error naming the object otherwise).
    /// Normals are read when every face vertex has one and all are finite and non-zero (they
    /// are then normalized); otherwise all normals are computed with
    /// [`compute_normals`](Self::compute_normals). Non-finite, degenerate and zero-area
    /// triangles are dropped and counted; it is an error if none is left.
    pub fn from_obj(text: &str) -> Result<(BaseMesh, MeshReport)> {
        check_face_indices(text)?;
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| Error::BaseMesh(format!("cannot parse OBJ: {e}")))?;
        let mut mesh = BaseMesh::empty();
        let mut normals_read = true;
        for model in &models {
            let m = &model.mesh;
            let count = m.positions.len() / 3;
            if count == 0 {
                continue;
            }
            if m.texcoords.len() != 2 * count {
                let what = if m.texcoords.is_empty() {
                    "has no UV coordinates (vt)"
                } else {
                    "has face vertices without UV coordinates (vt)"
                };
                return Err(Error::BaseMesh(format!(
                    "object {:?} {what}; a base mesh needs a UV on every face vertex",
                    model.name
                )));
            }
            let base = u32::try_from(mesh.positions.len() + count)
                .map(|end| end - count as u32)
                .map_err(|_| Error::BaseMesh("more than 2³² vertices".into()))?;
            mesh.positions.extend(
                m.positions
                    .chunks_exact(3)
                    .map(|p| DVec3::new(p[0], p[1], p[2])),
            );
            mesh.uvs
                .extend(m.texcoords.chunks_exact(2).map(|t| DVec2::new(t[0], t[1])));
            if m.normals.len() == 3 * count {
                mesh.normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| DVec3::new(n[0], n[1], n[2])),
                );
            } else {
                normals_read = false;
                mesh.normals.resize(mesh.positions.len(), DVec3::ZERO);
            }
            mesh.triangles.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
            );
        }
        if mesh.triangles.is_empty() {
            return Err(Error::BaseMesh("the OBJ text has no faces".into()));
        }
        normals_read &= mesh
            .normals
            .iter()
            .all(|n| n.is_finite() && *n != DVec3::ZERO);
        if !normals_read {
            mesh.compute_normals();
        }
        let (mesh, mut report) = mesh.validated()?;
        report.computed_normals = !normals_read;
        Ok((mesh, report))
    }

    /// Reads and parses an OBJ file (see [`from_obj`](Self::from_obj)), refusing files larger
    /// than `limits.memory_bytes / 8` before reading them.
    pub fn read_obj(path: &Path, limits: &Limits) -> Result<(BaseMesh, MeshReport)> {
        let bytes = mesobake_core::fs::read_bounded(path, "OBJ file", limits.memory_bytes / 8)?;
        let in_file = |message: String| Error::BaseMesh(format!("{}: {message}", path.display()));
        if bytes.starts_with(b"glTF") {
            return Err(in_file(
                "a binary glTF (GLB), not OBJ text: name it as {\"gltf\": …}".into(),
            ));
        }
        let text =
            std::str::from_utf8(&bytes).map_err(|e| in_file(format!("not UTF-8 text: {e}")))?;
        Self::from_obj(text).map_err(|e| match e {
            Error::BaseMesh(message) => in_file(message),
            other => other,
        })
    }

    /// Errors naming the first vertex a triangle uses whose position or UV lies beyond
    /// ±[`MAX_COORDINATE`] (non-finite ones are validation's to drop).
    pub fn check_coordinates(&self) -> Result<()> {
        let too_far = |v: f64| v.is_finite() && v.abs() > MAX_COORDINATE;
        let far = (self.triangles.iter().flatten().map(|&i| i as usize)).find(|&i| {
            self.positions[i].to_array().into_iter().any(too_far)
                || self.uvs[i].to_array().into_iter().any(too_far)
        });
        let list = |c: &[f64]| {
            c.iter()
                .map(|c| format!("{c:e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        match far {
            Some(i) => Err(Error::BaseMesh(format!(
                "vertex {i} lies at [{}] with UV [{}]: coordinates beyond ±{MAX_COORDINATE:e} are \
                 refused",
                list(&self.positions[i].to_array()),
                list(&self.uvs[i].to_array())
            ))),
            None => Ok(()),
        }
    }

    /// Validates the mesh: errors when the attribute arrays differ in length or a triangle
    /// refers to a missing vertex; normalizes the normals; drops and counts non-finite,
    /// degenerate and zero-area triangles (an error if none is left); removes unused vertices;
    /// and counts flipped-UV triangles, non-manifold and boundary edges of what is kept.
    /// The report's `computed_normals` is false (callers that computed them set it).
    pub fn validated(self) -> Result<(BaseMesh, MeshReport)> {
        let n = self.positions.len();
        if self.normals.len() != n || self.uvs.len() != n {
            return Err(Error::BaseMesh(format!(
                "{n} positions but {} normals and {} UVs",
                self.normals.len(),
                self.uvs.len()
            )));
        }
        if let Some((t, &i)) = self
            .triangles
            .iter()
            .enumerate()
            .find_map(|(t, tri)| tri.iter().find(|&&i| i as usize >= n).map(|i| (t, i)))
        {
            return Err(Error::BaseMesh(format!(
                "triangle {t} refers to vertex {i}, but there are only {n} vertices"
            )));
        }
        self.check_coordinates()?;
        let normals: Vec<DVec3> = self
            .normals
            .iter()
            .map(|v| v.try_normalize().unwrap_or(DVec3::NAN))
            .collect();
        let finite = |i: u32| {
            let i = i as usize;
            self.positions[i].is_finite() && normals[i].is_finite() && self.uvs[i].is_finite()
        };
        let threshold = zero_area_threshold(&self.positions, &self.triangles);
        let mut report = MeshReport::default();
        let mut kept = Vec::with_capacity(self.triangles.len());
        for &t in &self.triangles {
            if !t.iter().all(|&i| finite(i)) {
                report.non_finite_triangles += 1;
            } else if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                report.degenerate_triangles += 1;
            } else if triangle_area(corners(&self.positions, t)) <= threshold {
                report.zero_area_triangles += 1;
            } else {
                kept.push(t);
            }
        }
        if kept.is_empty() {
            return Err(Error::BaseMesh(format!(
                "no usable triangle ({} non-finite, {} degenerate and {} zero-area dropped)",
                report.non_finite_triangles,
                report.degenerate_triangles,
                report.zero_area_triangles
            )));
        }

        // Keep only the vertices that kept triangles use, in their original order.
        let mut remap = vec![u32::MAX; n];
        for t in &kept {
            for &i in t {
                remap[i as usize] = 0;
            }
        }
        let mut mesh = BaseMesh::empty();
        for (i, slot) in remap.iter_mut().enumerate() {
            if *slot == 0 {
                // Used vertices have distinct u32 indices, so there are at most 2³² of them.
                *slot = mesh.positions.len() as u32;
                mesh.positions.push(self.positions[i]);
                mesh.normals.push(normals[i]);
                mesh.uvs.push(self.uvs[i]);
            }
        }
        mesh.triangles
            .extend(kept.iter().map(|t| t.map(|i| remap[i as usize])));

        let (ids, _) = weld(&mesh.positions);
        let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(mesh.triangles.len() * 2);
        for &t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (ids[t[k] as usize], ids[t[(k + 1) % 3] as usize]);
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
            let p = corners(&mesh.positions, t);
            let winding = (p[1] - p[0])
                .cross(p[2] - p[0])
                .dot(t.iter().map(|&i| mesh.normals[i as usize]).sum());
            let [a, b, c] = t.map(|i| mesh.uvs[i as usize]);
            if winding * (b - a).perp_dot(c - a) < 0.0 {
                report.flipped_uv_triangles += 1;
            }
        }
        report.boundary_edges = edges.values().filter(|&&c| c == 1).count();
        report.non_manifold_edges = edges.values().filter(|&&c| c > 2).count();
        report.vertices = mesh.positions.len();
        report.triangles = mesh.triangles.len();
        Ok((mesh, report))
    }

    /// Replaces the normals (resized to one per vertex) by angle-weighted vertex normals
    /// computed over positions welded exactly, so that UV seams, where vertices are duplicated,
    /// do not crease them. Each triangle adds its unit normal times its corner angle to its
    /// three corners; zero-area triangles and triangles with a repeated or missing vertex or a
    /// non-finite corner contribute nothing. A vertex with no valid neighbour gets the normal
    /// of any incident triangle whose normal is defined, or +Y.
    pub fn compute_normals(&mut self) {
        let (ids, welded) = weld(&self.positions);
        let threshold = zero_area_threshold(&self.positions, &self.triangles);
        let mut sums = vec![DVec3::ZERO; welded];
        let mut fallback: Vec<Option<DVec3>> = vec![None; self.positions.len()];
        for &t in &self.triangles {
            let Some(p) = usable_corners(&self.positions, t) else {
                continue;
            };
            let cross = (p[1] - p[0]).cross(p[2] - p[0]);
            let Some(face) = cross.try_normalize() else {
                continue;
            };
            for &i in &t {
                fallback[i as usize].get_or_insert(face);
            }
            if 0.5 * cross.length() <= threshold {
                continue;
            }
            for k in 0..3 {
                let e1 = p[(k + 1) % 3] - p[k];
                let e2 = p[(k + 2) % 3] - p[k];
                let angle = e1.cross(e2).length().atan2(e1.dot(e2));
                sums[ids[t[k] as usize] as usize] += angle * face;
            }
        }
        self.normals = (0..self.positions.len())
            .map(|i| {
                sums[ids[i] as usize]
                    .try_normalize()
                    .or(fallback[i])
                    .unwrap_or(DVec3::Y)
            })
            .collect();
    }

    /// Bounding box (min, max) of the positions, ignoring NaN coordinates; (+∞, −∞) when
    /// there is no position.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.positions
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// OBJ text: each line of `comment` as a `#` line, then `v`, `vt` and `vn` lines with 9
    /// decimals and `f v/vt/vn` triangles (1-based, the same index for all three). Deterministic.
    pub fn to_obj(&self, comment: &str) -> String {
        let mut s = String::with_capacity(self.positions.len() * 110 + self.triangles.len() * 40);
        for line in comment.lines() {
            let _ = writeln!(s, "# {line}");
        }
        for p in &self.positions {
            let _ = writeln!(s, "v {:.9} {:.9} {:.9}", p.x, p.y, p.z);
        }
        for t in &self.uvs {
            let _ = writeln!(s, "vt {:.9} {:.9}", t.x, t.y);
        }
        for n in &self.normals {
            let _ = writeln!(s, "vn {:.9} {:.9} {:.9}", n.x, n.y, n.z);
        }
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| i + 1);
            let _ = writeln!(s, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
        }
        s
    }

    /// A mesh with nothing in it.
    fn empty() -> BaseMesh {
        BaseMesh {
            positions: Vec::new(),
            normals: Vec::new(),
            uvs: Vec::new(),
            triangles: Vec::new(),
        }
    }

    /// Appends `other`, re-indexing its triangles.
    fn append(&mut self, other: BaseMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        self.uvs.extend(other.uvs);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }
}

/// Refuses face indices that tobj would silently misread or overflow on: 0 (OBJ counts from 1),
/// negative indices reaching before the first element of their kind, and indices beyond
/// u32 (no mesh that fits in memory has that many vertices). Everything else is left to tobj.
fn check_face_indices(text: &str) -> Result<()> {
    const KINDS: [&str; 3] = ["position (v)", "UV (vt)", "normal (vn)"];
    let mut seen = [0i64; 3];
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => seen[0] += 1,
            Some("vt") => seen[1] += 1,
            Some("vn") => seen[2] += 1,
            Some("f") => {
                for word in words {
                    for (kind, part) in word.split('/').take(3).enumerate() {
                        let Ok(index) = part.parse::<i64>() else {
                            continue; // empty, or a parse error that tobj reports
                        };
                        let ok = if index < 0 {
                            seen[kind] + index >= 0
                        } else {
                            index >= 1 && index <= i64::from(u32::MAX)
                        };
                        if !ok {
                            return Err(Error::BaseMesh(format!(
                                "line {}: {} index {index} is out of range",
                                number + 1,
                                KINDS[kind]
                            )));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Ids, one per position, equal exactly when the positions are bit-identical (−0 and +0 are
/// the same), and the number of distinct ids.
fn weld(positions: &[DVec3]) -> (Vec<u32>, usize) {
    let mut map: HashMap<[u64; 3], u32> = HashMap::with_capacity(positions.len());
    let ids = positions
        .iter()
        .map(|p| {
            let key = p
                .to_array()
                .map(|c| if c == 0.0 { 0u64 } else { c.to_bits() });
            let next = map.len() as u32;
            *map.entry(key).or_insert(next)
        })
        .collect();
    (ids, map.len())
}

/// The corner positions of triangle `t` (its indices must be in range).
fn corners(positions: &[DVec3], t: [u32; 3]) -> [DVec3; 3] {
    t.map(|i| positions[i as usize])
}

/// The corners of `t` when its indices are distinct and in range and its corners finite.
fn usable_corners(positions: &[DVec3], t: [u32; 3]) -> Option<[DVec3; 3]> {
    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return None;
    }
    let p = [
        *positions.get(t[0] as usize)?,
        *positions.get(t[1] as usize)?,
        *positions.get(t[2] as usize)?,
    ];
    p.iter().all(|q| q.is_finite()).then_some(p)
}

/// Area of a triangle.
fn triangle_area(p: [DVec3; 3]) -> f64 {
    0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
}

/// The area at or below which a triangle is zero-area: 1e-12 · d², d the diagonal of the
/// bounding box of the corners of all triangles with [`usable_corners`].
fn zero_area_threshold(positions: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
    let (lo, hi) = triangles
        .iter()
        .filter_map(|&t| usable_corners(positions, t))
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    if lo.x > hi.x {
        0.0
    } else {
        ZERO_AREA_RELATIVE * (hi - lo).length_squared()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A unit square in x–z (normal +Y) as two triangles, with UVs u = x, v = −z.
    const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

    fn approx(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn square_parses_with_computed_normals() {
        let (mesh, report) = BaseMesh::from_obj(SQUARE).unwrap();
        assert_eq!(report.vertices, 4);
        assert_eq!(report.triangles, 2);
        assert!(report.computed_normals);
        assert_eq!(report.boundary_edges, 4);
        assert_eq!(report.flipped_uv_triangles, 0);
        // Exact: a flat mesh's face normals are exactly +Y.
        assert!(mesh.normals.iter().all(|&n| n == DVec3::Y));
        assert_eq!(
            mesh.bounds(),
            (DVec3::new(0.0, 0.0, -1.0), DVec3::new(1.0, 0.0, 0.0))
        );
    }

    /// One vertex far out (the probe's 1e308 panicked in the BVH build; 1e20 made every
    /// triangle zero-area against the extent): a clear error naming it, the limit just
    /// inside accepted.
    #[test]
    fn far_vertices_and_uvs_are_refused_naming_them() {
        for (far, what) in [("1e308", "v"), ("1e20", "v"), ("1e10", "vt")] {
            let obj = match what {
                "v" => SQUARE.replace("v 1 0 -1", &format!("v {far} {far} {far}")),
                _ => SQUARE.replace("vt 1 1", &format!("vt {far} 0")),
            };
            let e = BaseMesh::from_obj(&obj).unwrap_err().to_string();
            assert!(
                e.contains("vertex 2 lies at") && e.contains("beyond ±1e9"),
                "{e}"
            );
            assert!(e.contains(far) && e.len() < 200, "{e}");
        }
        let near = SQUARE.replace("v 1 0 -1", "v 1e9 0 -1e9");
        assert!(BaseMesh::from_obj(&near).is_ok());
    }

    /// A cube corner at the origin (outward normal −(1,1,1)/√3), with the x = 0 face split in
    /// two triangles: angle weighting gives each face π/2 in total and hence the symmetric
    /// normal, whereas area weighting would give (−1, −½, −½)/‖·‖ and count weighting
    /// (−2, −1, −1)/‖·‖. Tolerance 1e-12.
    #[test]
    fn angle_weighted_normals_at_a_cube_corner() {
        let x = DVec3::X;
        let y = DVec3::Y;
        let z = DVec3::Z;
        let mut mesh = BaseMesh {
            positions: vec![DVec3::ZERO, x, y, z, y + z],
            normals: vec![],
            uvs: vec![DVec2::ZERO; 5],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 4], [0, 4, 2]],
        };
        mesh.compute_normals();
        let expected = -DVec3::ONE / 3f64.sqrt();
        assert!(
            approx(mesh.normals[0], expected, 1e-12),
            "{}",
            mesh.normals[0]
        );
        // The corner at y + z (vertex 4) has only the x = 0 face: exactly −X.
        assert!(approx(mesh.normals[4], -x, 1e-12));
    }

    /// A vertex duplicated at a UV seam gets the same normal as its twin; a zero-area
    /// triangle contributes nothing; a vertex with no valid neighbour falls back.
    #[test]
    fn normals_weld_across_seams_and_ignore_zero_area() {
        // Two triangles of a roof (faces tilted ±45° about x) that share the ridge edge
        // through duplicated vertices 1/4 and 2/5 (different UVs).
        let mut mesh = BaseMesh {
            positions: vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 0.0, -1.0),
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                // Zero-area sliver along the ridge (collinear) and an isolated collinear one.
                DVec3::new(0.5, 1.0, 0.0),
                DVec3::new(5.0, 5.0, 5.0),
                DVec3::new(6.0, 6.0, 6.0),
                DVec3::new(7.0, 7.0, 7.0),
            ],
            normals: vec![],
            uvs: (0..10).map(|i| DVec2::new(i as f64, 0.0)).collect(),
            triangles: vec![[0, 2, 1], [3, 4, 5], [1, 6, 2], [7, 8, 9]],
        };
        mesh.compute_normals();
        // The faces' normals are (0, 1, 1)/√2 and (0, 1, −1)/√2 and, mirror images of each
        // other, they have the same corner angles at the ridge (90° at x = 0, arccos(1/√3) at
        // x = 1), so the ridge normal is +Y (tolerance 1e-12) on both sides of the seam.
        for i in [1, 2, 4, 5] {
            assert!(
                approx(mesh.normals[i], DVec3::Y, 1e-12),
                "{i}: {}",
                mesh.normals[i]
            );
        }
        assert_eq!(mesh.normals[1], mesh.normals[4]);
        // Vertex 6 lies only on the zero-area sliver but welds with nothing: fallback +Y
        // (the sliver has no defined normal).
        assert_eq!(mesh.normals[6], DVec3::Y);
        assert_eq!(mesh.normals[8], DVec3::Y);
        let (_, report) = mesh.validated().unwrap();
        assert_eq!(report.zero_area_triangles, 2);
        assert_eq!(report.triangles, 2);
    }

    #[test]
    fn missing_uvs_are_an_error_naming_them() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let e = BaseMesh::from_obj(text).unwrap_err().to_string();
        assert!(e.contains("UV"), "{e}");
        let partial = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3\n";
        let e = BaseMesh::from_obj(partial).unwrap_err().to_string();
        assert!(e.contains("UV"), "{e}");
    }

    /// tobj parses "nan" (Rust's float parser accepts it), so the triangle is dropped and
    /// counted rather than refused.
    #[test]
    fn nan_coordinates_drop_their_triangles() {
        let text = format!("{SQUARE}v 2 0 nan\nvt 0 0\nf 2/2 5/5 3/3\n");
        let (mesh, report) = BaseMesh::from_obj(&text).unwrap();
        assert_eq!(report.non_finite_triangles, 1);
        assert_eq!(report.triangles, 2);
        assert_eq!(report.vertices, 4);
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        let uv_nan = format!("{SQUARE}vt inf 0\nf 1/1 2/5 3/3\n");
        assert_eq!(
            BaseMesh::from_obj(&uv_nan).unwrap().1.non_finite_triangles,
            1
        );
    }

    #[test]
    fn degenerate_and_zero_area_triangles_are_counted() {
        let text = format!(
            "{SQUARE}v 0.5 0 0\nvt 0 0\n\
             f 1/1 1/1 2/2\n\
             f 1/1 5/5 2/2\n"
        );
        let (_, report) = BaseMesh::from_obj(&text).unwrap();
        assert_eq!(report.degenerate_triangles, 1);
        assert_eq!(report.zero_area_triangles, 1);
        assert_eq!(report.triangles, 2);
        // Nothing usable left is an error.
        let none = "v 0 0 0\nv 1 0 0\nvt 0 0\nf 1/1 2/1 2/1\n";
        let e = BaseMesh::from_obj(none).unwrap_err().to_string();
        assert!(e.contains("no usable triangle"), "{e}");
    }

    #[test]
    fn non_manifold_edges_and_flipped_uvs_are_counted() {
        // A third triangle on the diagonal edge 1–3 of the square, standing up in +Y; its
        // UVs are mirrored, so it is also flipped.
        let text = format!("{SQUARE}v 0.5 1 -0.5\nvt 0.5 -1\nf 1/1 3/3 5/5\n");
        let (_, report) = BaseMesh::from_obj(&text).unwrap();
        assert_eq!(report.non_manifold_edges, 1);
        assert_eq!(report.triangles, 3);
        // The square's 4 outer edges and the new triangle's 2 free edges.
        assert_eq!(report.boundary_edges, 6);
        let mirrored = SQUARE
            .replace("vt 1 1\n", "vt 1 -1\n")
            .replace("vt 0 1\n", "vt 0 -1\n");
        let (_, report) = BaseMesh::from_obj(&mirrored).unwrap();
        assert_eq!(report.flipped_uv_triangles, 2);
    }

    #[test]
    fn read_normals_are_used_and_normalized() {
        let text = format!("{SQUARE}vn 0 2 0\n").replace(
            "f 1/1 2/2 3/3\nf 1/1 3/3 4/4",
            "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1",
        );
        let (mesh, report) = BaseMesh::from_obj(&text).unwrap();
        assert!(!report.computed_normals);
        assert!(mesh.normals.iter().all(|&n| n == DVec3::Y));
        // A zero normal makes all of them computed.
        let zero = text.replace("vn 0 2 0", "vn 0 0 0");
        assert!(BaseMesh::from_obj(&zero).unwrap().1.computed_normals);
    }

    #[test]
    fn bad_indices_are_errors() {
        for face in [
            "f 1/1 2/2 0/3",
            "f 1/1 2/-9 3/3",
            "f 1/1 2/2 3/3/-7",
            "f 1/1 2/2 99/3",
        ] {
            let text = SQUARE.replace("f 1/1 3/3 4/4", face);
            assert!(BaseMesh::from_obj(&text).is_err(), "{face}");
        }
        let relative = SQUARE.replace("f 1/1 3/3 4/4", "f -4/-4 -2/-2 -1/-1");
        assert_eq!(BaseMesh::from_obj(&relative).unwrap().1.triangles, 2);
    }

    #[test]
    fn validated_rejects_inconsistent_meshes() {
        let mesh = BaseMesh {
            positions: vec![DVec3::ZERO; 3],
            normals: vec![DVec3::Y; 2],
            uvs: vec![DVec2::ZERO; 3],
            triangles: vec![[0, 1, 2]],
        };
        assert!(mesh.validated().is_err());
        let mesh = BaseMesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Z],
            normals: vec![DVec3::Y; 3],
            uvs: vec![DVec2::ZERO; 3],
            triangles: vec![[0, 1, 3]],
        };
        let e = mesh.validated().unwrap_err().to_string();
        assert!(e.contains("vertex 3"), "{e}");
    }

    /// to_obj → from_obj: per triangle corner, positions and UVs agree to 1e-9 (9 decimals
    /// round by ≤ 5e-10); normals to 2e-9 (the rounded normal is renormalized on reading,
    /// which can add up to |n·e| ≤ √3·5e-10 to the 5e-10 of rounding).
    #[test]
    fn obj_round_trip() {
        let (mesh, _) = BuiltinMesh::Torus {
            major_radius: 1.0,
            minor_radius: 0.4,
            segments: [12, 8],
        }
        .build()
        .unwrap();
        let text = mesh.to_obj("torus\nround trip");
        assert!(text.starts_with("# torus\n# round trip\nv "));
        let (back, report) = BaseMesh::from_obj(&text).unwrap();
        assert!(!report.computed_normals);
        assert_eq!(back.triangles.len(), mesh.triangles.len());
        for (t, u) in mesh.triangles.iter().zip(&back.triangles) {
            for k in 0..3 {
                let (i, j) = (t[k] as usize, u[k] as usize);
                assert!(approx(mesh.positions[i], back.positions[j], 1e-9));
                assert!((mesh.uvs[i] - back.uvs[j]).abs().max_element() <= 1e-9);
                assert!(approx(mesh.normals[i], back.normals[j], 2e-9));
            }
        }
    }

    #[test]
    fn read_obj_checks_the_size_first() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("square.obj");
        std::fs::write(&path, SQUARE).unwrap();
        let (_, report) = BaseMesh::read_obj(&path, &Limits::default()).unwrap();
        assert_eq!(report.triangles, 2);
        let small = Limits {
            memory_bytes: 8 * 10,
            ..Limits::default()
        };
        assert!(matches!(
            BaseMesh::read_obj(&path, &small),
            Err(Error::MemoryLimit { needed, limit: 10, .. }) if needed == SQUARE.len() as u64
        ));
        std::fs::write(&path, "v 0 0 0\n").unwrap();
        let e = BaseMesh::read_obj(&path, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("square.obj") && e.contains("no faces"), "{e}");
    }

    /// Lines of random words (keywords, numbers, index triples, junk).
    fn garbage_line() -> impl Strategy<Value = String> {
        let keyword = proptest::sample::select(vec![
            "v", "vt", "vn", "f", "l", "p", "o", "g", "mtllib", "usemtl", "nan", "-inf", "/", "#",
        ])
        .prop_map(String::from);
        let word = prop_oneof![
            keyword.clone(),
            any::<i64>().prop_map(|i| i.to_string()),
            (-5i32..6).prop_map(|i| i.to_string()),
            (-5i32..6, -5i32..6, -5i32..6).prop_map(|(a, b, c)| format!("{a}/{b}/{c}")),
            (-5i32..6, -5i32..6).prop_map(|(a, b)| format!("{a}//{b}")),
            any::<f64>().prop_map(|x| x.to_string()),
            "[a-z0-9./ -]{0,6}",
        ];
        (keyword, proptest::collection::vec(word, 0..7))
            .prop_map(|(first, rest)| format!("{first} {}", rest.join(" ")))
    }

    /// Well-formed lines with awkward values: coordinates that are NaN, infinite, huge or
    /// repeated, and faces with small (possibly relative, repeated or missing) indices.
    fn plausible_line() -> impl Strategy<Value = String> {
        let number = prop_oneof![
            (-2i32..3).prop_map(|i| i.to_string()),
            proptest::sample::select(vec!["nan", "inf", "-inf", "0.5", "1e300", "-0"])
                .prop_map(String::from),
        ];
        let index = || prop_oneof![4 => 1i32..7, 1 => -3i32..0];
        let corner = prop_oneof![
            1 => index().prop_map(|v| v.to_string()),
            4 => (index(), index()).prop_map(|(v, t)| format!("{v}/{t}")),
            4 => (index(), index(), index()).prop_map(|(v, t, n)| format!("{v}/{t}/{n}")),
        ];
        prop_oneof![
            proptest::collection::vec(number.clone(), 3).prop_map(|c| format!("v {}", c.join(" "))),
            proptest::collection::vec(number.clone(), 2)
                .prop_map(|c| format!("vt {}", c.join(" "))),
            proptest::collection::vec(number, 3).prop_map(|c| format!("vn {}", c.join(" "))),
            proptest::collection::vec(corner, 3..6).prop_map(|c| format!("f {}", c.join(" "))),
        ]
    }

    /// What every successfully parsed mesh satisfies.
    fn check_parsed(text: &str) -> std::result::Result<(), TestCaseError> {
        if let Ok((mesh, report)) = BaseMesh::from_obj(text) {
            prop_assert_eq!(report.triangles, mesh.triangles.len());
            prop_assert_eq!(report.vertices, mesh.positions.len());
            prop_assert!(mesh.positions.iter().all(|p| p.is_finite()));
            prop_assert!(mesh.uvs.iter().all(|t| t.is_finite()));
            prop_assert!(
                mesh.normals
                    .iter()
                    .all(|n| (n.length() - 1.0).abs() < 1e-12)
            );
            let n = mesh.positions.len();
            prop_assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
        }
        Ok(())
    }

    proptest! {
        /// Random OBJ-like garbage after a valid square, or alone, never panics: it parses (to
        /// a clean mesh: finite, unit normals (1e-12), indices in range) or is an error.
        #[test]
        fn garbage_never_panics(
            lines in proptest::collection::vec(prop_oneof![garbage_line(), plausible_line()], 0..30)
        ) {
            check_parsed(&format!("{SQUARE}{}", lines.join("\n")))?;
            check_parsed(&lines.join("\n"))?;
        }

        /// Well-formed lines with NaN/∞ coordinates and repeated or relative indices (about a
        /// third of the cases parse, exercising every drop counter) never panic either.
        #[test]
        fn awkward_values_never_panic(lines in proptest::collection::vec(plausible_line(), 0..12)) {
            check_parsed(&format!("{SQUARE}{}", lines.join("\n")))?;
        }
    }
}
