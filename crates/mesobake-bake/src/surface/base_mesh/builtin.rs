//! The built-in base meshes and the parametric surfaces they are made of.

use super::grid::grid;
use super::{BaseMesh, MeshReport, teapot};
use glam::DVec3;
use mesobake_core::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Most segments along one direction of a built-in surface.
const MAX_SEGMENTS: u32 = 4096;
/// Most subdivisions of a teapot patch along each side.
const MAX_SUBDIVISIONS: u32 = 256;
/// Height of the vase.
const VASE_HEIGHT: f64 = 1.5;

/// A built-in base mesh with its parameters, as written in the scene JSON: externally tagged by
/// its snake_case name, every field optional (defaults below), unknown fields refused; e.g.
/// `{"plane": {"size": 2.0, "segments": 64}}` or `{"teapot": {}}`. UVs span \[0,1\]² over each
/// surface (over each patch for the teapot); see the module documentation for the conventions.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum BuiltinMesh {
    /// An open undulating square in x–z around the origin, normals up (+Y side):
    /// y = amplitude·sin(2π·waves·x/size)·cos(2π·waves·z/size); u along +x, v along −z.
    Plane {
        /// Edge length, > 0 (default 2).
        #[serde(default = "plane_size")]
        size: f64,
        /// Amplitude of the undulation, ≥ 0 (default 0.15).
        #[serde(default = "plane_amplitude")]
        amplitude: f64,
        /// Periods of the undulation along each edge, ≥ 0 (default 2).
        #[serde(default = "plane_waves")]
        waves: f64,
        /// Quads along each edge, 1..=4096 (default 64).
        #[serde(default = "plane_segments")]
        segments: u32,
    },
    /// A cylinder about the Y axis from y = −height/2 to height/2, open at both ends, normals
    /// outward; u goes around counter-clockwise seen from +Y starting at +X, v upwards.
    Cylinder {
        /// Radius, > 0 (default 0.5).
        #[serde(default = "cylinder_radius")]
        radius: f64,
        /// Height, > 0 (default 2).
        #[serde(default = "cylinder_height")]
        height: f64,
        /// Segments around and along the axis, each 3..=4096 (default [64, 16]).
        #[serde(default = "cylinder_segments")]
        segments: [u32; 2],
    },
    /// A torus about the Y axis, centred on the origin, normals outward; u goes around the Y
    /// axis as for the cylinder, v around the tube (outside, top, inside, bottom).
    Torus {
        /// Distance from the Y axis to the centre of the tube, > minor_radius (default 1).
        #[serde(default = "torus_major_radius")]
        major_radius: f64,
        /// Radius of the tube, > 0 (default 0.4).
        #[serde(default = "torus_minor_radius")]
        minor_radius: f64,
        /// Segments around the Y axis and around the tube, each 3..=4096 (default [96, 48]).
        #[serde(default = "torus_segments")]
        segments: [u32; 2],
    },
    /// A vase: the surface of revolution about +Y of the profile radius
    /// r(t) = 0.55·sin(0.9πt) + 0.2t², height y(t) = 1.5·(1 − cos(πt/2)), t ∈ [0, 1]: a closed,
    /// rounded bottom (a pole at the origin) bulging to r ≈ 0.62 and narrowing to an open top
    /// of radius ≈ 0.37 at y = 1.5. Normals outward; u around as for the cylinder, v = t.
    Vase {
        /// Segments around and along the profile, each 3..=4096 (default [64, 48]).
        #[serde(default = "vase_segments")]
        segments: [u32; 2],
    },
    /// The Utah teapot (Newell's 32 Bézier patches, 306 control points), +Y up, spout towards
    /// +X, standing on y = 0, 3.15 high; UVs are each patch's own (u, v). Normals computed.
    /// Not watertight: the rim, the lid's edge and both ends of the handle and of the spout
    /// are boundaries; the poles of the knob and of the bottom give zero-area triangles,
    /// which are dropped and counted.
    Teapot {
        /// Quads along each side of each patch, 1..=256 (default 8).
        #[serde(default = "teapot_subdivisions")]
        subdivisions: u32,
    },
}

fn plane_size() -> f64 {
    2.0
}
fn plane_amplitude() -> f64 {
    0.15
}
fn plane_waves() -> f64 {
    2.0
}
fn plane_segments() -> u32 {
    64
}
fn cylinder_radius() -> f64 {
    0.5
}
fn cylinder_height() -> f64 {
    2.0
}
fn cylinder_segments() -> [u32; 2] {
    [64, 16]
}
fn torus_major_radius() -> f64 {
    1.0
}
fn torus_minor_radius() -> f64 {
    0.4
}
fn torus_segments() -> [u32; 2] {
    [96, 48]
}
fn vase_segments() -> [u32; 2] {
    [64, 48]
}
fn teapot_subdivisions() -> u32 {
    8
}

impl BuiltinMesh {
    /// How many triangles [`BuiltinMesh::build`] makes (before validation drops the
    /// degenerate ones), from the parameters alone: what a server checks before building.
    pub fn triangle_count(&self) -> u64 {
        let quads = |a: u32, b: u32| u64::from(a) * u64::from(b);
        match *self {
            BuiltinMesh::Plane { segments, .. } => 2 * quads(segments, segments),
            BuiltinMesh::Cylinder {
                segments: [a, b], ..
            }
            | BuiltinMesh::Torus {
                segments: [a, b], ..
            } => 2 * quads(a, b),
            // The pole's row of quads gives one triangle each.
            BuiltinMesh::Vase { segments: [a, b] } => 2 * quads(a, b) - u64::from(a),
            BuiltinMesh::Teapot { subdivisions } => 64 * quads(subdivisions, subdivisions),
        }
    }

    /// Builds and validates the mesh. Lengths must be finite and positive (the plane's
    /// amplitude and waves finite and ≥ 0, the torus's minor radius below its major radius),
    /// segment counts 3..=4096 (plane: 1..=4096), subdivisions 1..=256; an
    /// [`Error::InvalidParameter`] naming the field otherwise.
    pub fn build(&self) -> Result<(BaseMesh, MeshReport)> {
        let mesh = match *self {
            BuiltinMesh::Plane {
                size,
                amplitude,
                waves,
                segments,
            } => {
                positive("plane.size", size)?;
                non_negative("plane.amplitude", amplitude)?;
                non_negative("plane.waves", waves)?;
                in_range("plane.segments", segments, 1, MAX_SEGMENTS)?;
                plane(size, amplitude, waves, segments)
            }
            BuiltinMesh::Cylinder {
                radius,
                height,
                segments: [around, along],
            } => {
                positive("cylinder.radius", radius)?;
                positive("cylinder.height", height)?;
                in_range("cylinder.segments[0]", around, 3, MAX_SEGMENTS)?;
                in_range("cylinder.segments[1]", along, 3, MAX_SEGMENTS)?;
                revolve(around, along, false, |j| Profile {
                    radius,
                    y: height * (f64::from(j) / f64::from(along) - 0.5),
                    d_radius: 0.0,
                    d_y: height,
                })
            }
            BuiltinMesh::Torus {
                major_radius,
                minor_radius,
                segments: [around, tube],
            } => {
                positive("torus.major_radius", major_radius)?;
                positive("torus.minor_radius", minor_radius)?;
                if minor_radius >= major_radius {
                    return Err(Error::InvalidParameter(format!(
                        "torus.minor_radius ({minor_radius}) must be below torus.major_radius \
                         ({major_radius})"
                    )));
                }
                in_range("torus.segments[0]", around, 3, MAX_SEGMENTS)?;
                in_range("torus.segments[1]", tube, 3, MAX_SEGMENTS)?;
                let ring = circle(tube);
                revolve(around, tube, false, |j| {
                    let (c, s) = ring[j as usize];
                    Profile {
                        radius: major_radius + minor_radius * c,
                        y: minor_radius * s,
                        d_radius: -minor_radius * s,
                        d_y: minor_radius * c,
                    }
                })
            }
            BuiltinMesh::Vase {
                segments: [around, along],
            } => {
                in_range("vase.segments[0]", around, 3, MAX_SEGMENTS)?;
                in_range("vase.segments[1]", along, 3, MAX_SEGMENTS)?;
                revolve(around, along, true, |j| {
                    let t = f64::from(j) / f64::from(along);
                    Profile {
                        radius: 0.55 * (0.9 * PI * t).sin() + 0.2 * t * t,
                        y: VASE_HEIGHT * (1.0 - (FRAC_PI_2 * t).cos()),
                        d_radius: 0.55 * 0.9 * PI * (0.9 * PI * t).cos() + 0.4 * t,
                        d_y: VASE_HEIGHT * FRAC_PI_2 * (FRAC_PI_2 * t).sin(),
                    }
                })
            }
            BuiltinMesh::Teapot { subdivisions } => {
                in_range("teapot.subdivisions", subdivisions, 1, MAX_SUBDIVISIONS)?;
                let (mesh, mut report) = teapot::tessellate(subdivisions).validated()?;
                report.computed_normals = true;
                return Ok((mesh, report));
            }
        };
        mesh.validated()
    }

    /// All five built-ins with default parameters, with their names ("plane", "cylinder",
    /// "torus", "vase", "teapot"), for tests and the CLI.
    pub fn all_defaults() -> Vec<(&'static str, BuiltinMesh)> {
        vec![
            (
                "plane",
                BuiltinMesh::Plane {
                    size: plane_size(),
                    amplitude: plane_amplitude(),
                    waves: plane_waves(),
                    segments: plane_segments(),
                },
            ),
            (
                "cylinder",
                BuiltinMesh::Cylinder {
                    radius: cylinder_radius(),
                    height: cylinder_height(),
                    segments: cylinder_segments(),
                },
            ),
            (
                "torus",
                BuiltinMesh::Torus {
                    major_radius: torus_major_radius(),
                    minor_radius: torus_minor_radius(),
                    segments: torus_segments(),
                },
            ),
            (
                "vase",
                BuiltinMesh::Vase {
                    segments: vase_segments(),
                },
            ),
            (
                "teapot",
                BuiltinMesh::Teapot {
                    subdivisions: teapot_subdivisions(),
                },
            ),
        ]
    }
}

fn positive(field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter(format!(
            "{field} must be a finite number > 0, got {value}"
        )))
    }
}

fn non_negative(field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter(format!(
            "{field} must be a finite number ≥ 0, got {value}"
        )))
    }
}

fn in_range(field: &str, value: u32, min: u32, max: u32) -> Result<()> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(Error::InvalidParameter(format!(
            "{field} must be in {min}..={max}, got {value}"
        )))
    }
}

/// The undulating plane (see [`BuiltinMesh::Plane`]) with analytic normals.
fn plane(size: f64, amplitude: f64, waves: f64, segments: u32) -> BaseMesh {
    let k = TAU * waves / size;
    let n = f64::from(segments);
    grid(segments, segments, false, |i, j| {
        let x = size * (f64::from(i) / n - 0.5);
        let z = size * (0.5 - f64::from(j) / n);
        let (sx, cx) = (k * x).sin_cos();
        let (sz, cz) = (k * z).sin_cos();
        let (dy_dx, dy_dz) = (amplitude * k * cx * cz, -amplitude * k * sx * sz);
        (
            DVec3::new(x, amplitude * sx * cz, z),
            DVec3::new(-dy_dx, 1.0, -dy_dz).normalize(),
        )
    })
}

/// A point of a profile curve and its derivative (any positive multiple of it).
#[derive(Clone, Copy)]
struct Profile {
    radius: f64,
    y: f64,
    d_radius: f64,
    d_y: f64,
}

/// The surface of revolution about +Y of `profile(j)`, j = 0..=along, with analytic normals:
/// u goes once around, counter-clockwise seen from +Y, starting at +X (the point at angle θ is
/// (r·cos θ, y, −r·sin θ)); v follows the profile. ∂P/∂u × ∂P/∂v is a positive multiple of
/// y'·radial − r'·Y (for r > 0), the normal used: outward where the profile rises on the outside.
fn revolve(
    around: u32,
    along: u32,
    pole_at_v0: bool,
    profile: impl Fn(u32) -> Profile,
) -> BaseMesh {
    let angles = circle(around);
    let rows: Vec<Profile> = (0..=along).map(profile).collect();
    grid(around, along, pole_at_v0, |i, j| {
        let (c, s) = angles[i as usize];
        let p = rows[j as usize];
        let radial = DVec3::new(c, 0.0, -s);
        (
            p.radius * radial + DVec3::new(0.0, p.y, 0.0),
            (p.d_y * radial - p.d_radius * DVec3::Y).normalize(),
        )
    })
}

/// (cos, sin) of 2π·i/n for i in 0..=n; the last is exactly the first, so that the vertices
/// duplicated at a seam have bit-identical positions.
fn circle(n: u32) -> Vec<(f64, f64)> {
    (0..=n)
        .map(|i| {
            let (s, c) = (TAU * f64::from(i % n) / f64::from(n)).sin_cos();
            (c, s)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

    /// The angle between two vectors, accurate for small angles too (unlike an arccosine).
    fn angle(a: DVec3, b: DVec3) -> f64 {
        a.cross(b).length().atan2(a.dot(b))
    }

    fn build(json: &str) -> Result<(BaseMesh, MeshReport)> {
        serde_json::from_str::<BuiltinMesh>(json).unwrap().build()
    }

    /// Every built-in at its defaults: finite, unit normals (||n| − 1| < 1e-12), UVs spanning
    /// exactly [0,1]², no flipped UV triangle, no non-manifold edge, nothing non-finite or
    /// degenerate, and zero-area triangles only on the teapot.
    #[test]
    fn triangle_counts_are_known_before_building() {
        for (name, builtin) in BuiltinMesh::all_defaults() {
            let (_, report) = builtin.build().unwrap();
            let made = report.triangles
                + report.non_finite_triangles
                + report.degenerate_triangles
                + report.zero_area_triangles;
            assert_eq!(made as u64, builtin.triangle_count(), "{name}");
        }
    }

    #[test]
    fn defaults_are_clean() {
        for (name, builtin) in BuiltinMesh::all_defaults() {
            let (mesh, report) = builtin.build().unwrap();
            assert!(mesh.positions.iter().all(|p| p.is_finite()), "{name}");
            for n in &mesh.normals {
                assert!((n.length() - 1.0).abs() < 1e-12, "{name}: {n}");
            }
            let lo = mesh.uvs.iter().fold(DVec2::INFINITY, |a, &b| a.min(b));
            let hi = mesh.uvs.iter().fold(DVec2::NEG_INFINITY, |a, &b| a.max(b));
            assert_eq!((lo, hi), (DVec2::ZERO, DVec2::ONE), "{name}");
            assert_eq!(report.flipped_uv_triangles, 0, "{name}");
            assert_eq!(report.non_manifold_edges, 0, "{name}");
            assert_eq!(report.non_finite_triangles, 0, "{name}");
            assert_eq!(report.degenerate_triangles, 0, "{name}");
            assert_eq!(report.computed_normals, name == "teapot", "{name}");
            if name != "teapot" {
                assert_eq!(report.zero_area_triangles, 0, "{name}");
            }
            assert_eq!(report.vertices, mesh.positions.len());
            assert_eq!(report.triangles, mesh.triangles.len());
        }
    }

    /// Plane: the analytic normal recomputed from each position's x and z agrees to 1e-12 rad;
    /// heights follow the formula to 1e-12; the open square has 4·64 boundary edges.
    #[test]
    fn plane_matches_its_formula() {
        let (mesh, report) = build(r#"{"plane": {}}"#).unwrap();
        assert_eq!(report.boundary_edges, 4 * 64);
        assert_eq!(report.vertices, 65 * 65);
        let k = TAU * 2.0 / 2.0;
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let y = 0.15 * (k * p.x).sin() * (k * p.z).cos();
            assert!((p.y - y).abs() < 1e-12);
            let gradient = DVec3::new(
                0.15 * k * (k * p.x).cos() * (k * p.z).cos(),
                -1.0,
                -0.15 * k * (k * p.x).sin() * (k * p.z).sin(),
            );
            assert!(angle(*n, -gradient) < 1e-12, "{p}: {n}");
        }
        let (lo, hi) = mesh.bounds();
        assert_eq!((lo.x, lo.z, hi.x, hi.z), (-1.0, -1.0, 1.0, 1.0));
        // One segment: a single quad with zero amplitude is allowed.
        let (_, report) = build(r#"{"plane": {"segments": 1, "amplitude": 0}}"#).unwrap();
        assert_eq!((report.vertices, report.triangles), (4, 2));
    }

    /// Cylinder: radius 0.5 and radial normals to 1e-12; 2·64 boundary edges (both rims),
    /// none at the u seam.
    #[test]
    fn cylinder_is_open_at_both_ends_only() {
        let (mesh, report) = build(r#"{"cylinder": {}}"#).unwrap();
        assert_eq!(report.boundary_edges, 2 * 64);
        assert_eq!(report.vertices, 65 * 17);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let radial = DVec3::new(p.x, 0.0, p.z);
            assert!((radial.length() - 0.5).abs() < 1e-12);
            assert!(angle(*n, radial) < 1e-12);
            assert!(p.y.abs() <= 1.0);
        }
        let (lo, hi) = mesh.bounds();
        assert_eq!((lo.y, hi.y), (-1.0, 1.0));
    }

    /// Torus: every point at distance 0.4 from the core circle (1e-12) and every normal along
    /// the outward direction from it (angle < 1e-9 rad); closed: no boundary edge.
    #[test]
    fn torus_is_closed_with_outward_normals() {
        let (mesh, report) = build(r#"{"torus": {}}"#).unwrap();
        assert_eq!(report.boundary_edges, 0);
        assert_eq!(report.vertices, 97 * 49);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            let core = DVec3::new(p.x, 0.0, p.z).normalize();
            let out = *p - core;
            assert!((out.length() - 0.4).abs() < 1e-12);
            assert!(angle(*n, out) < 1e-9, "{p}: {n}");
        }
        // UVs: u = 0.25 is a quarter turn counter-clockwise seen from +Y, i.e. towards −Z.
        let quarter = mesh
            .uvs
            .iter()
            .position(|uv| *uv == DVec2::new(0.25, 0.0))
            .unwrap();
        assert!((mesh.positions[quarter] - DVec3::new(0.0, 0.0, -1.4)).length() < 1e-12);
    }

    /// Vase: closed bottom (normal −Y at the pole), one boundary loop at the top (64 edges);
    /// the analytic normals agree with the angle-weighted ones computed from the mesh to
    /// 0.02 rad (the discretization error of the computed ones at 64×48 segments).
    #[test]
    fn vase_normals_agree_with_computed_ones() {
        let (mesh, report) = build(r#"{"vase": {}}"#).unwrap();
        assert_eq!(report.boundary_edges, 64);
        assert_eq!(report.zero_area_triangles, 0);
        let mut computed = mesh.clone();
        computed.compute_normals();
        let worst = mesh
            .normals
            .iter()
            .zip(&computed.normals)
            .map(|(a, b)| angle(*a, *b))
            .fold(0.0, f64::max);
        assert!(worst < 0.02, "{worst}");
        let pole = mesh
            .positions
            .iter()
            .position(|p| *p == DVec3::ZERO)
            .unwrap();
        assert_eq!(mesh.normals[pole], -DVec3::Y);
        let (lo, hi) = mesh.bounds();
        assert_eq!(lo.y, 0.0);
        assert!((hi.y - VASE_HEIGHT).abs() < 1e-12);
    }

    /// The teapot at 8 subdivisions: the 8 pole patches (4 of the knob, 4 of the bottom) give
    /// one zero-area triangle per quad along the pole, 64 in all, dropped; the boundary is the
    /// rim, the lid's edge and both ends of handle and spout, 4 patch edges each: 16·8 edges.
    /// Positions: the bounding box of Newell's data (x from the handle's −3 to the spout tip,
    /// y from 0 to the knob's 3.15, z ±2 at the body's widest), to 1e-9; at 8 subdivisions
    /// the spout tip's extreme x is the vertex at v = 3/8 on its Bézier curve
    /// (3.3, 3.525, 3.45, 3.2), 3.433154296875, below the curve's maximum at
    /// t = (0.6 − √0.2475)/0.25, ≈ 3.4340751.
    #[test]
    fn teapot_is_newells() {
        let (mesh, report) = build(r#"{"teapot": {}}"#).unwrap();
        assert_eq!(report.zero_area_triangles, 64);
        assert_eq!(report.degenerate_triangles, 0);
        assert_eq!(report.triangles, 32 * 8 * 8 * 2 - 64);
        assert_eq!(report.boundary_edges, 16 * 8);
        assert_eq!(report.non_manifold_edges, 0);
        let (lo, hi) = mesh.bounds();
        assert!(
            (lo - DVec3::new(-3.0, 0.0, -2.0)).abs().max_element() < 1e-9,
            "{lo}"
        );
        assert!(
            (hi - DVec3::new(3.433154296875, 3.15, 2.0))
                .abs()
                .max_element()
                < 1e-9,
            "{hi}"
        );
        let t = (0.6 - 0.2475f64.sqrt()) / 0.25;
        let s = 1.0 - t;
        let x_max =
            3.3 * s * s * s + 3.0 * 3.525 * t * s * s + 3.0 * 3.45 * t * t * s + 3.2 * t * t * t;
        assert!((x_max - 3.434075125).abs() < 1e-9 && hi.x < x_max);
        // Corners of patches lie on the surface: rim (inner, outer), body at its widest, knob
        // top, bottom centre, spout (root top, tip), handle (outermost), lid edge.
        for known in [
            [1.4, 2.4, 0.0],
            [1.5, 2.4, 0.0],
            [2.0, 0.9, 0.0],
            [0.0, 3.15, 0.0],
            [0.0, 0.0, 0.0],
            [1.7, 1.425, 0.0],
            [3.3, 2.4, 0.0],
            [-3.0, 1.8, 0.0],
            [0.0, 2.4, 1.3],
        ] {
            let known = DVec3::from_array(known);
            assert!(
                mesh.positions.iter().any(|p| (*p - known).length() < 1e-9),
                "{known}"
            );
        }
        // The knob's pole is welded: its normal is exactly up; the bottom's exactly down.
        let top = mesh.positions.iter().position(|p| p.y == 3.15).unwrap();
        assert!(angle(mesh.normals[top], DVec3::Y) < 1e-12);
        let bottom = mesh
            .positions
            .iter()
            .position(|p| *p == DVec3::ZERO)
            .unwrap();
        assert!(angle(mesh.normals[bottom], -DVec3::Y) < 1e-12);
    }

    #[test]
    fn scene_json_form() {
        let defaults = BuiltinMesh::all_defaults();
        for (name, builtin) in &defaults {
            let parsed: BuiltinMesh =
                serde_json::from_str(&format!("{{\"{name}\": {{}}}}")).unwrap();
            assert_eq!(&parsed, builtin);
            let text = serde_json::to_string(builtin).unwrap();
            assert!(text.starts_with(&format!("{{\"{name}\":{{")), "{text}");
            assert_eq!(
                &serde_json::from_str::<BuiltinMesh>(&text).unwrap(),
                builtin
            );
        }
        let torus: BuiltinMesh =
            serde_json::from_str(r#"{"torus": {"minor_radius": 0.3, "segments": [8, 4]}}"#)
                .unwrap();
        assert_eq!(
            torus,
            BuiltinMesh::Torus {
                major_radius: 1.0,
                minor_radius: 0.3,
                segments: [8, 4]
            }
        );
        for bad in [
            r#"{"torus": {"radius": 1.0}}"#,
            r#"{"sphere": {}}"#,
            r#"{"plane": {"segments": -1}}"#,
            r#"{"cylinder": {"segments": [3]}}"#,
        ] {
            assert!(serde_json::from_str::<BuiltinMesh>(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn invalid_parameters_name_the_field() {
        for (json, field) in [
            (r#"{"plane": {"size": 0}}"#, "plane.size"),
            (r#"{"plane": {"amplitude": -0.1}}"#, "plane.amplitude"),
            (r#"{"plane": {"segments": 0}}"#, "plane.segments"),
            (r#"{"plane": {"segments": 4097}}"#, "plane.segments"),
            (r#"{"cylinder": {"radius": -1}}"#, "cylinder.radius"),
            (
                r#"{"cylinder": {"segments": [2, 16]}}"#,
                "cylinder.segments[0]",
            ),
            (r#"{"torus": {"minor_radius": 1.0}}"#, "torus.minor_radius"),
            (
                r#"{"torus": {"segments": [96, 4097]}}"#,
                "torus.segments[1]",
            ),
            (r#"{"vase": {"segments": [64, 2]}}"#, "vase.segments[1]"),
            (r#"{"teapot": {"subdivisions": 0}}"#, "teapot.subdivisions"),
            (
                r#"{"teapot": {"subdivisions": 257}}"#,
                "teapot.subdivisions",
            ),
        ] {
            let e = build(json).unwrap_err();
            assert!(matches!(e, Error::InvalidParameter(_)), "{json}");
            assert!(e.to_string().contains(field), "{json}: {e}");
        }
        let nan = BuiltinMesh::Plane {
            size: 2.0,
            amplitude: f64::NAN,
            waves: 2.0,
            segments: 4,
        };
        assert!(
            nan.build()
                .unwrap_err()
                .to_string()
                .contains("plane.amplitude")
        );
    }

    /// Smallest sizes build cleanly too; the teapot from 3 subdivisions on (below, its
    /// triangles are too coarse for their winding to follow the averaged normals everywhere:
    /// at 1, both halves of the handle and of the spout collapse onto the same flat quad).
    #[test]
    fn small_counts_build() {
        for json in [
            r#"{"cylinder": {"segments": [3, 3]}}"#,
            r#"{"torus": {"segments": [3, 3]}}"#,
            r#"{"vase": {"segments": [3, 3]}}"#,
            r#"{"teapot": {"subdivisions": 3}}"#,
        ] {
            let (_, report) = build(json).unwrap();
            assert_eq!(report.flipped_uv_triangles, 0, "{json}");
            assert_eq!(report.non_manifold_edges, 0, "{json}");
        }
        let (_, teapot) = build(r#"{"teapot": {"subdivisions": 3}}"#).unwrap();
        assert_eq!(
            (teapot.zero_area_triangles, teapot.boundary_edges),
            (8 * 3, 16 * 3)
        );
        let (_, teapot) = build(r#"{"teapot": {"subdivisions": 1}}"#).unwrap();
        assert!(teapot.zero_area_triangles >= 8);
    }
}
