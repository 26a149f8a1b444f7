//! Built-in procedural mesostructure samples, after the GDM paper's examples: `chain`
//! (interlocking torus links), `weave` (threads going over and under), `grid` (a two-level
//! grate), `squama` (overlapping scales) and `bark` (furrowed, with overhangs).
//!
//! Each sample is a set of analytic primitives on the unit tile, periodic in x and y, designed
//! for a height `design_height` and scaled in z to the requested grid's height Z/X. The same
//! primitives give the voxel volume (3×3×3 supersampled inside tests per voxel) and the OBJ tile
//! (closed parametric surfaces), so both are deterministic and agree up to tessellation and
//! voxelization.

use crate::mesostructure::trimesh::TriMesh;
use crate::mesostructure::volume::Volume;
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use rayon::prelude::*;
use std::f64::consts::{PI, TAU};

/// The built-in samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum SampleKind {
    /// Chain mail: tilted torus links, each passing through its neighbours.
    Chain,
    /// Plain weave: threads along x and y alternating over and under.
    Weave,
    /// A grate of square bars along x and, above them, along y.
    Grid,
    /// Overlapping flattened scales in offset rows.
    Squama,
    /// Bark: a furrowed slab whose ridges overhang (not a height field).
    Bark,
}

impl SampleKind {
    /// Every sample, in documentation order.
    pub const ALL: [SampleKind; 5] = [
        SampleKind::Chain,
        SampleKind::Weave,
        SampleKind::Grid,
        SampleKind::Squama,
        SampleKind::Bark,
    ];

    /// The sample's lower-case name.
    pub fn name(&self) -> &'static str {
        match self {
            SampleKind::Chain => "chain",
            SampleKind::Weave => "weave",
            SampleKind::Grid => "grid",
            SampleKind::Squama => "squama",
            SampleKind::Bark => "bark",
        }
    }
}

/// A 3×3 rotation as columns (e1, e2, e3).
type Frame = [[f64; 3]; 3];

/// One analytic solid of a sample, in design units (tile = 1 in x and y).
#[derive(Clone, Debug)]
enum Primitive {
    /// Torus around `frame[2]` through `centre`.
    Torus {
        centre: [f64; 3],
        frame: Frame,
        major: f64,
        minor: f64,
    },
    /// Ellipsoid with semi-axes `radii` along the frame's columns.
    Ellipsoid {
        centre: [f64; 3],
        frame: Frame,
        radii: [f64; 3],
    },
    /// A tube of radius `radius` along the periodic curve (s along `axis`, `offset` across,
    /// z = z0 + amplitude·sin(2πs + phase)).
    Thread {
        axis: usize,
        offset: f64,
        z0: f64,
        amplitude: f64,
        phase: f64,
        radius: f64,
    },
    /// An infinite square bar along `axis`: across ∈ [lo[0], hi[0]], z ∈ [lo[1], hi[1]].
    Bar {
        axis: usize,
        lo: [f64; 2],
        hi: [f64; 2],
    },
    /// Solid from z = 0 up to the sheared furrowed surface z = h(x + shear·z, y).
    Bark { shear: f64 },
}

fn rotation_x(angle: f64) -> Frame {
    let (s, c) = angle.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]
}

fn to_local(frame: &Frame, p: [f64; 3], centre: [f64; 3]) -> [f64; 3] {
    let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
    frame.map(|e| e[0] * d[0] + e[1] * d[1] + e[2] * d[2])
}

fn to_world(frame: &Frame, q: [f64; 3], centre: [f64; 3]) -> [f64; 3] {
    let mut p = centre;
    for (e, s) in frame.iter().zip(q) {
        for a in 0..3 {
            p[a] += e[a] * s;
        }
    }
    p
}

/// Bark surface height over (u, y), in design units (0..1).
fn bark_height(u: f64, y: f64) -> f64 {
    let furrow = (PI * (3.0 * u + 0.25 * (TAU * 2.0 * y).sin()))
        .sin()
        .abs()
        .powf(0.6);
    0.3 + 0.5 * furrow + 0.07 * (TAU * (5.0 * u + 3.0 * y)).sin() + 0.05 * (TAU * 7.0 * y).sin()
}

/// The least of `dist2` near `s0` (a thread's squared distance to its curve point at s),
/// whose least lies within `reach` of s0: 33 samples across, then 20 halvings around the best.
fn scanned_least(dist2: impl Fn(f64) -> f64, s0: f64, reach: f64) -> f64 {
    let mut best = (s0, dist2(s0));
    for n in -16..=16 {
        let s = s0 + reach * n as f64 / 16.0;
        let d = dist2(s);
        if d < best.1 {
            best = (s, d);
        }
    }
    let mut h = reach / 16.0;
    for _ in 0..20 {
        for s in [best.0 - h, best.0 + h] {
            let d = dist2(s);
            if d < best.1 {
                best = (s, d);
            }
        }
        h *= 0.5;
    }
    best.1
}

impl Primitive {
    /// Whether design-space point `p` (already wrapped to one periodic copy) is inside.
    fn inside_once(&self, p: [f64; 3]) -> bool {
        match self {
            Primitive::Torus {
                centre,
                frame,
                major,
                minor,
            } => {
                let q = to_local(frame, p, *centre);
                let ring = (q[0] * q[0] + q[1] * q[1]).sqrt() - major;
                ring * ring + q[2] * q[2] <= minor * minor
            }
            Primitive::Ellipsoid {
                centre,
                frame,
                radii,
            } => {
                let q = to_local(frame, p, *centre);
                (0..3).map(|a| (q[a] / radii[a]).powi(2)).sum::<f64>() <= 1.0
            }
            Primitive::Thread {
                axis,
                offset,
                z0,
                amplitude,
                phase,
                radius,
            } => {
                let (s0, across) = (p[*axis], p[1 - axis]);
                let across2 = (across - offset).powi(2);
                let height = |s: f64| z0 + amplitude * (TAU * s + phase).sin();
                let dist2 = |s: f64| (s - s0).powi(2) + across2 + (p[2] - height(s)).powi(2);
                // Decided without the scan where the distance at s0 lies within the radius,
                // or where even the nearest a curve of slope at most L = 2π·amplitude can
                // come, a² + v²/(1 + L²) (a the distance across, v the height above or below
                // the curve at s0), lies outside it: the scan's answer either way.
                let above2 = (p[2] - height(s0)).powi(2);
                if across2 + above2 <= radius * radius {
                    return true;
                }
                let slope = TAU * amplitude;
                if across2 + above2 / (1.0 + slope * slope) > radius * radius {
                    return false;
                }
                scanned_least(dist2, s0, radius + amplitude) <= radius * radius
            }
            Primitive::Bar { axis, lo, hi } => {
                let across = p[1 - axis];
                across >= lo[0] && across <= hi[0] && p[2] >= lo[1] && p[2] <= hi[1]
            }
            Primitive::Bark { shear } => {
                p[2] >= 0.0 && p[2] <= bark_height(p[0] + shear * p[2], p[1])
            }
        }
    }

    /// A box containing the primitive (infinite along a periodic axis).
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let inf = f64::INFINITY;
        match self {
            Primitive::Torus {
                centre,
                major,
                minor,
                ..
            } => {
                let r = major + minor;
                (centre.map(|c| c - r), centre.map(|c| c + r))
            }
            Primitive::Ellipsoid { centre, radii, .. } => {
                let r = radii.iter().cloned().fold(0.0, f64::max);
                (centre.map(|c| c - r), centre.map(|c| c + r))
            }
            Primitive::Thread {
                axis,
                offset,
                z0,
                amplitude,
                radius,
                ..
            } => {
                let (mut lo, mut hi) = ([-inf; 3], [inf; 3]);
                lo[1 - axis] = offset - radius;
                hi[1 - axis] = offset + radius;
                lo[2] = z0 - amplitude - radius;
                hi[2] = z0 + amplitude + radius;
                (lo, hi)
            }
            Primitive::Bar { axis, lo, hi } => {
                let (mut a, mut b) = ([-inf; 3], [inf; 3]);
                a[1 - axis] = lo[0];
                b[1 - axis] = hi[0];
                a[2] = lo[1];
                b[2] = hi[1];
                (a, b)
            }
            Primitive::Bark { .. } => ([-inf, -inf, 0.0], [inf, inf, 1.0]),
        }
    }

    /// Whether `p` is inside any periodic copy.
    fn inside(&self, p: [f64; 3]) -> bool {
        let (lo, hi) = self.bounds();
        let wrapped = [p[0].rem_euclid(1.0), p[1].rem_euclid(1.0), p[2]];
        if p[2] < lo[2] || p[2] > hi[2] {
            return false;
        }
        // Along an unbounded (periodic) axis one copy is enough.
        let copies = |a: usize| if lo[a].is_infinite() { 0..=0 } else { -1..=1 };
        copies(1).any(|dy| {
            copies(0).any(|dx| {
                let q = [wrapped[0] + dx as f64, wrapped[1] + dy as f64, p[2]];
                (0..2).all(|a| q[a] >= lo[a] && q[a] <= hi[a]) && self.inside_once(q)
            })
        })
    }

    /// A closed tessellation (closed on the tiling for periodic primitives), each surface
    /// turned to face outward.
    fn mesh(&self) -> TriMesh {
        let mut out = TriMesh::default();
        for mut surface in self.surfaces() {
            self.orient_outward(&mut surface);
            out.append(&surface);
        }
        out
    }

    /// Flips `surface` when most of a sample of its triangles face inward (the inside test a
    /// small step behind the triangle says solid, in front says empty, when facing out).
    fn orient_outward(&self, surface: &mut TriMesh) {
        let n = surface.triangles.len();
        let mut votes = 0i32;
        for t in (0..n).step_by((n / 64).max(1)) {
            let [a, b, c] = surface.corners(t);
            let normal = crate::mesostructure::trimesh::cross(
                crate::mesostructure::trimesh::sub(b, a),
                crate::mesostructure::trimesh::sub(c, a),
            );
            let len = crate::mesostructure::trimesh::dot(normal, normal).sqrt();
            if len == 0.0 {
                continue;
            }
            let centroid: [f64; 3] = std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0);
            // Probe a quarter of the longest edge off the facet: farther than the chord's sag
            // below a curved surface (L²/8R < L/4 while L < 2R), so the probes straddle it.
            let longest = [(a, b), (b, c), (c, a)]
                .map(|(p, q)| {
                    let e = crate::mesostructure::trimesh::sub(q, p);
                    crate::mesostructure::trimesh::dot(e, e).sqrt()
                })
                .into_iter()
                .fold(0.0, f64::max);
            let step: [f64; 3] = normal.map(|x| x / len * 0.25 * longest);
            let behind = self.inside(std::array::from_fn(|i| centroid[i] - step[i]));
            let front = self.inside(std::array::from_fn(|i| centroid[i] + step[i]));
            votes += match (behind, front) {
                (true, false) => 1,
                (false, true) => -1,
                _ => 0,
            };
        }
        if votes < 0 {
            for t in &mut surface.triangles {
                t.swap(1, 2);
            }
        }
    }

    /// The closed surfaces of the primitive, in any orientation.
    fn surfaces(&self) -> Vec<TriMesh> {
        vec![match self {
            Primitive::Torus {
                centre,
                frame,
                major,
                minor,
            } => grid_surface(96, 32, |u, v| {
                let (su, cu) = (TAU * u).sin_cos();
                let (sv, cv) = (TAU * v).sin_cos();
                let q = [
                    (major + minor * cv) * cu,
                    (major + minor * cv) * su,
                    minor * sv,
                ];
                to_world(frame, q, *centre)
            }),
            Primitive::Ellipsoid {
                centre,
                frame,
                radii,
            } => grid_surface(64, 32, |u, v| {
                let (su, cu) = (TAU * u).sin_cos();
                let (sv, cv) = (PI * v).sin_cos();
                let q = [radii[0] * sv * cu, radii[1] * sv * su, -radii[2] * cv];
                to_world(frame, q, *centre)
            }),
            Primitive::Thread {
                axis,
                offset,
                z0,
                amplitude,
                phase,
                radius,
            } => {
                grid_surface(128, 24, |u, v| {
                    let slope = amplitude * TAU * (TAU * u + phase).cos();
                    let z = z0 + amplitude * (TAU * u + phase).sin();
                    // Normal in the (axis, z) plane, and the across direction.
                    let n = 1.0 / (1.0 + slope * slope).sqrt();
                    let (sa, ca) = (TAU * v).sin_cos();
                    let along = u + radius * ca * (-slope * n);
                    let up = z + radius * ca * n;
                    let across = offset + radius * sa;
                    let mut p = [0.0, 0.0, up];
                    p[*axis] = along;
                    p[1 - axis] = across;
                    p
                })
            }
            Primitive::Bar { axis, lo, hi } => {
                // The square section walked around, swept along one period in 8 segments.
                let corners = [
                    [lo[0], lo[1]],
                    [hi[0], lo[1]],
                    [hi[0], hi[1]],
                    [lo[0], hi[1]],
                ];
                grid_surface(8, 4, |u, v| {
                    let side = ((v * 4.0).round() as usize) % 4;
                    let c = corners[side];
                    let mut p = [0.0, 0.0, c[1]];
                    p[*axis] = u;
                    p[1 - axis] = c[0];
                    p
                })
            }
            Primitive::Bark { shear } => {
                let top = grid_surface(160, 160, |u, y| {
                    let h = bark_height(u, y);
                    [u - shear * h, y, h]
                });
                let bottom = grid_surface(4, 4, |u, y| [y, u, 0.0]);
                return vec![top, bottom];
            }
        }]
    }
}

/// The (nu+1)×(nv+1) vertex grid of `f` over [0,1]², two triangles per quad. Periodic
/// surfaces repeat their first row/column as the last; validation welds them (modulo the
/// tiling lattice).
fn grid_surface(nu: usize, nv: usize, f: impl Fn(f64, f64) -> [f64; 3]) -> TriMesh {
    let mut mesh = TriMesh::default();
    for j in 0..=nv {
        for i in 0..=nu {
            mesh.positions
                .push(f(i as f64 / nu as f64, j as f64 / nv as f64));
        }
    }
    let id = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
    for j in 0..nv {
        for i in 0..nu {
            mesh.triangles
                .push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            mesh.triangles
                .push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    mesh
}

/// A sample's primitives, colours and design height.
struct Design {
    parts: Vec<(Primitive, [f64; 3])>,
    height: f64,
}

fn design(kind: SampleKind) -> Design {
    let steel = [0.62, 0.64, 0.68];
    match kind {
        SampleKind::Chain => {
            let tilt = 35f64.to_radians();
            let ring = |x: f64, y: f64, sign: f64, shade: f64| {
                (
                    Primitive::Torus {
                        centre: [x, y, 0.25],
                        frame: rotation_x(sign * tilt),
                        major: 0.26,
                        minor: 0.05,
                    },
                    steel.map(|c| c * shade),
                )
            };
            Design {
                parts: vec![
                    ring(0.25, 0.25, 1.0, 1.0),
                    ring(0.75, 0.75, 1.0, 0.9),
                    ring(0.75, 0.25, -1.0, 0.95),
                    ring(0.25, 0.75, -1.0, 0.85),
                ],
                height: 0.5,
            }
        }
        SampleKind::Weave => {
            let thread = |axis: usize, offset: f64, phase: f64, colour: [f64; 3]| {
                (
                    Primitive::Thread {
                        axis,
                        offset,
                        z0: 0.25,
                        amplitude: 0.08,
                        phase,
                        radius: 0.075,
                    },
                    colour,
                )
            };
            let (warp, weft) = ([0.72, 0.18, 0.14], [0.90, 0.85, 0.70]);
            Design {
                parts: vec![
                    thread(0, 0.25, 0.0, warp),
                    thread(0, 0.75, PI, warp),
                    thread(1, 0.25, PI, weft),
                    thread(1, 0.75, 0.0, weft),
                ],
                height: 0.5,
            }
        }
        SampleKind::Grid => Design {
            parts: vec![
                (
                    Primitive::Bar {
                        axis: 0,
                        lo: [0.4, 0.08],
                        hi: [0.6, 0.28],
                    },
                    steel,
                ),
                (
                    Primitive::Bar {
                        axis: 1,
                        lo: [0.15, 0.22],
                        hi: [0.35, 0.42],
                    },
                    [0.55, 0.45, 0.35],
                ),
                (
                    Primitive::Bar {
                        axis: 1,
                        lo: [0.65, 0.22],
                        hi: [0.85, 0.42],
                    },
                    [0.55, 0.45, 0.35],
                ),
            ],
            height: 0.5,
        },
        SampleKind::Squama => {
            let scale = |x: f64, y: f64, shade: f64| {
                (
                    Primitive::Ellipsoid {
                        centre: [x, y, 0.2],
                        frame: rotation_x(-0.35),
                        radii: [0.3, 0.24, 0.06],
                    },
                    [0.25 * shade, 0.55 * shade, 0.35 * shade],
                )
            };
            Design {
                parts: vec![
                    scale(0.25, 0.0, 1.0),
                    scale(0.75, 0.0, 0.9),
                    scale(0.0, 0.5, 0.95),
                    scale(0.5, 0.5, 0.85),
                ],
                height: 0.5,
            }
        }
        SampleKind::Bark => Design {
            parts: vec![(Primitive::Bark { shear: 0.12 }, [0.42, 0.30, 0.20])],
            height: 1.0,
        },
    }
}

/// The height Z/X of a square tile on `dims`, in tile units; grids a sample cannot be laid
/// out on (X ≠ Y) are an error.
pub fn tile_height(dims: Dims) -> Result<f64> {
    if dims.x != dims.y {
        return Err(Error::InvalidParameter(format!(
            "samples are square tiles: the resolution needs X = Y for cubic voxels, got {dims}"
        )));
    }
    Ok(dims.z as f64 / dims.x as f64)
}

/// The sample as a voxel volume on `dims` (density = fraction of 3×3×3 sub-samples inside, an
/// odd count that includes the centre so there are no ties; threshold ½; albedo of the last
/// primitive found, darkened towards the base).
pub fn volume(kind: SampleKind, dims: Dims, limits: &Limits) -> Result<Volume> {
    let height = tile_height(dims)?;
    limits.check("sample volume", dims.voxel_count(), 16)?;
    let design = design(kind);
    let z_scale = design.height / height;
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    let voxel = 1.0 / dims.x as f64;
    let layers: Vec<(Vec<f32>, Vec<[u8; 3]>)> = (0..dims.z as usize)
        .into_par_iter()
        .map(|k| {
            let mut density = Vec::with_capacity(nx * ny);
            let mut albedo = Vec::with_capacity(nx * ny);
            for j in 0..ny {
                for i in 0..nx {
                    let mut inside = 0;
                    let mut colour = [0.0; 3];
                    for s in 0..27 {
                        let o = [(s % 3) as f64, ((s / 3) % 3) as f64, (s / 9) as f64];
                        let p = [
                            (i as f64 + (o[0] + 0.5) / 3.0) * voxel,
                            (j as f64 + (o[1] + 0.5) / 3.0) * voxel,
                            (k as f64 + (o[2] + 0.5) / 3.0) * voxel * z_scale,
                        ];
                        if let Some((_, c)) = design.parts.iter().find(|(prim, _)| prim.inside(p)) {
                            inside += 1;
                            colour = *c;
                        }
                    }
                    let shade = 0.55 + 0.45 * (k as f64 + 0.5) / dims.z as f64;
                    density.push(inside as f32 / 27.0);
                    albedo
                        .push(colour.map(|c| (c * shade * 255.0).round().clamp(0.0, 255.0) as u8));
                }
            }
            (density, albedo)
        })
        .collect();
    let (density, albedo): (Vec<_>, Vec<_>) = layers.into_iter().unzip();
    Volume::new(dims, density.concat(), 0.5, Some(albedo.concat()))
}

/// The sample as a closed OBJ-ready triangle mesh in tile units: x, y over the unit tile
/// (parts may cross its borders), z in [0, Z/X].
pub fn mesh(kind: SampleKind, dims: Dims) -> Result<TriMesh> {
    let height = tile_height(dims)?;
    let design = design(kind);
    let z_scale = height / design.height;
    let mut out = TriMesh::default();
    for (prim, _) in &design.parts {
        out.append(&prim.mesh());
    }
    out.map_positions(|p| [p[0], p[1], p[2] * z_scale]);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thread's shortcuts decide as the scan does, on a grid of points over a whole
    /// period of the thread and across its bounding slab (where `inside` asks).
    #[test]
    fn a_threads_shortcuts_agree_with_its_scan() {
        let (z0, amplitude, radius, phase) = (0.25, 0.08, 0.075, 0.7);
        let thread = Primitive::Thread {
            axis: 0,
            offset: 0.5,
            z0,
            amplitude,
            phase,
            radius,
        };
        let (mut inside, mut points) = (0, 0);
        for i in 0..=200 {
            for j in 0..=40 {
                for k in 0..=60 {
                    let p = [
                        i as f64 / 200.0,
                        0.5 + radius * (j as f64 / 20.0 - 1.0),
                        z0 + (amplitude + radius) * (k as f64 / 30.0 - 1.0),
                    ];
                    let dist2 = |s: f64| {
                        let z = z0 + amplitude * (TAU * s + phase).sin();
                        (s - p[0]).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - z).powi(2)
                    };
                    let scanned = scanned_least(dist2, p[0], radius + amplitude) <= radius * radius;
                    assert_eq!(thread.inside_once(p), scanned, "at {p:?}");
                    inside += usize::from(scanned);
                    points += 1;
                }
            }
        }
        // Both answers occur often: the grid spans the thread, not one side of it.
        assert!(
            inside > points / 10 && inside < points * 9 / 10,
            "{inside} of {points}"
        );
    }
}
