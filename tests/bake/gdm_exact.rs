//! Exact GDM paths against analytic references, and the hard cases of traversal.
//!
//! Tolerances: distances are computed in f64 and stored as f32, so stored values are compared
//! with a relative tolerance of 1e-6 (f32 rounding is 6e-8 relative) plus 1e-6 voxel; direct
//! f64 traces are compared at 1e-9 voxel. The mesh path works in f32 (obvhs), so it is compared
//! at 2e-3 voxel over distances of at most a few hundred voxels.

use mesobake_bake::gdm::caster::{Caster, Trace};
use mesobake_bake::gdm::mesh_caster::MeshCaster;
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::gdm::{self, EscapeConvention, Gdm, Method};
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};
use proptest::prelude::*;

fn dims(x: u32, y: u32, z: u32) -> Dims {
    Dims::new(x, y, z).unwrap()
}

fn volume(d: Dims, solid: impl Fn(u32, u32, u32) -> bool) -> VolumeCaster {
    VolumeCaster::new(&Volume::from_fn(d, &Limits::default(), solid).unwrap())
}

fn bake(c: &dyn Caster, dirs: DirectionGrid, method: Method) -> Gdm {
    gdm::bake(c, dirs, method, Default::default(), &Limits::default(), &()).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

/// Visits every (i, j, k, a, b) with its value.
fn each(g: &Gdm, mut f: impl FnMut(u32, u32, u32, u32, u32, f32)) {
    let (d, r) = (g.dims(), g.dirs());
    for a in 0..r.n_theta {
        for b in 0..r.n_phi {
            for k in 0..d.z {
                for j in 0..d.y {
                    for i in 0..d.x {
                        f(i, j, k, a, b, g.get(i, j, k, a, b));
                    }
                }
            }
        }
    }
}

#[test]
fn empty_volume_escapes_everywhere() {
    let c = volume(dims(8, 8, 4), |_, _, _| false);
    for method in [Method::Exact, Method::Fast] {
        let g = bake(&c, DirectionGrid::new(8, 16).unwrap(), method);
        assert!(g.data().iter().all(|v| v.is_infinite()), "{method:?}");
    }
}

#[test]
fn solid_volume_is_zero_everywhere() {
    let c = volume(dims(8, 8, 4), |_, _, _| true);
    for method in [Method::Exact, Method::Fast] {
        let g = bake(&c, DirectionGrid::new(8, 16).unwrap(), method);
        assert!(g.data().iter().all(|&v| v == 0.0), "{method:?}");
    }
}

/// A horizontal slab (layers 3..=5 of 10): closed form for every sample and direction, both
/// exact and fast (the slab makes interpolation exact: every neighbour has the same value).
#[test]
fn horizontal_slab_matches_closed_form() {
    let c = volume(dims(6, 5, 10), |_, _, k| (3..=5).contains(&k));
    let dirs = DirectionGrid::new(16, 8).unwrap();
    for method in [Method::Exact, Method::Fast] {
        let g = bake(&c, dirs, method);
        each(&g, |_, _, k, a, _, v| {
            let cz = dirs.theta(a).cos();
            let z = k as f64 + 0.5;
            let want = if (3..=5).contains(&k) {
                0.0
            } else if k < 3 && cz > 0.0 {
                (3.0 - z) / cz
            } else if k > 5 && cz < 0.0 {
                (z - 6.0) / -cz
            } else {
                f64::INFINITY
            };
            if want.is_infinite() {
                assert!(v.is_infinite(), "{method:?} k={k} a={a}: {v} should escape");
            } else {
                assert!(
                    close(v as f64, want, 1e-6),
                    "{method:?} k={k} a={a}: {v} vs {want}"
                );
            }
        });
    }
}

/// Exact distance from `o` along `v` to the closed axis-aligned box [lo, hi], or ∞.
fn ray_box(o: [f64; 3], v: [f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if v[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return f64::INFINITY;
            }
        } else {
            let (ta, tb) = ((lo[a] - o[a]) / v[a], (hi[a] - o[a]) / v[a]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    if t0 <= t1 { t0 } else { f64::INFINITY }
}

/// Analytic first hit on a periodic tiling of boxes (period `p` in x and y), within the slab.
fn ray_tiled_boxes(
    o: [f64; 3],
    v: [f64; 3],
    boxes: &[([f64; 3], [f64; 3])],
    p: f64,
    z_top: f64,
) -> f64 {
    let t_exit = if v[2] > 0.0 {
        (z_top - o[2]) / v[2]
    } else {
        -o[2] / v[2]
    };
    let reach = (t_exit * (v[0].hypot(v[1])) / p).ceil() as i64 + 1;
    let mut best = f64::INFINITY;
    for m in -reach..=reach {
        for n in -reach..=reach {
            for (lo, hi) in boxes {
                let s = [m as f64 * p, n as f64 * p, 0.0];
                let t = ray_box(
                    o,
                    v,
                    [lo[0] + s[0], lo[1] + s[1], lo[2]],
                    [hi[0] + s[0], hi[1] + s[1], hi[2]],
                );
                if t <= t_exit {
                    best = best.min(t);
                }
            }
        }
    }
    best
}

fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> TriMesh {
    let p = |m: usize| {
        [
            if m & 1 != 0 { hi[0] } else { lo[0] },
            if m & 2 != 0 { hi[1] } else { lo[1] },
            if m & 4 != 0 { hi[2] } else { lo[2] },
        ]
    };
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut m = TriMesh {
        positions: (0..8).map(p).collect(),
        triangles: vec![],
    };
    for q in quads {
        m.triangles.push([q[0], q[1], q[2]]);
        m.triangles.push([q[0], q[2], q[3]]);
    }
    m
}

/// A tile with one axis-aligned box on the voxel grid: the exact volume path and the mesh
/// path both match the analytic ray–box distance on the tiling, and agree with each other.
#[test]
fn box_tile_volume_and_mesh_match_ray_box() {
    let d = dims(16, 16, 8);
    let (lo, hi) = ([4.0, 6.0, 2.0], [9.0, 10.0, 5.0]);
    let c = volume(d, |i, j, k| {
        let p = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
        (0..3).all(|a| p[a] > lo[a] && p[a] < hi[a])
    });
    let tile = MeshTile::new(box_mesh(lo.map(|x| x / 16.0), hi.map(|x| x / 16.0)), false).unwrap();
    let m = MeshCaster::new(&tile, d, &Limits::default()).unwrap();
    assert_eq!(
        m.centres_inside(),
        c.centres_inside(),
        "inside classification"
    );
    let dirs = DirectionGrid::new(8, 16).unwrap();
    let gv = bake(&c, dirs, Method::Exact);
    let gm = bake(&m, dirs, Method::Exact);
    each(&gv, |i, j, k, a, b, v| {
        let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
        let want = if c.centres_inside().get(i, j, k) {
            0.0
        } else {
            ray_tiled_boxes(o, dirs.vector(a, b), &[(lo, hi)], 16.0, 8.0)
        };
        let mv = gm.get(i, j, k, a, b);
        if want.is_infinite() {
            assert!(
                v.is_infinite() && mv.is_infinite(),
                "({i},{j},{k},{a},{b}) {v} {mv}"
            );
        } else {
            assert!(
                close(v as f64, want, 1e-6),
                "volume ({i},{j},{k},{a},{b}) {v} vs {want}"
            );
            assert!(
                (mv as f64 - want).abs() < 2e-3,
                "mesh ({i},{j},{k},{a},{b}) {mv} vs {want}"
            );
        }
    });
}

/// Analytic first hit on periodic spheres (centre c, radius r, period p), within the slab.
fn ray_tiled_sphere(
    o: [f64; 3],
    v: [f64; 3],
    c: [f64; 3],
    r: f64,
    p: f64,
    z_top: f64,
) -> (f64, f64) {
    let t_exit = if v[2] > 0.0 {
        (z_top - o[2]) / v[2]
    } else {
        -o[2] / v[2]
    };
    let reach = (t_exit * v[0].hypot(v[1]) / p).ceil() as i64 + 1;
    let mut best = (f64::INFINITY, 1.0);
    for m in -reach..=reach {
        for n in -reach..=reach {
            let oc = [
                o[0] - c[0] - m as f64 * p,
                o[1] - c[1] - n as f64 * p,
                o[2] - c[2],
            ];
            let bq = oc[0] * v[0] + oc[1] * v[1] + oc[2] * v[2];
            let cq = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - r * r;
            let disc = bq * bq - cq;
            if disc >= 0.0 {
                let t = -bq - disc.sqrt();
                if t >= 0.0 && t <= t_exit && t < best.0 {
                    // Cosine between the ray and the surface normal at the hit.
                    best = (t, disc.sqrt() / r);
                }
            }
        }
    }
    best
}

/// A tile with a sphere: the mesh path against the analytic ray–sphere distance. The tile is a
/// 256×128 UV sphere, whose chords deviate from the sphere by at most r(1−cos(π/128)) = 1.2e-3
/// voxel; a ray meeting the surface at incidence cosine μ sees that deviation amplified by
/// about 1/μ, so rays with μ ≥ 0.2 are held to 0.02 voxel, and grazing rays are only required
/// to classify as hit or escape the same way in 99 % of cases.
#[test]
fn sphere_tile_mesh_matches_ray_sphere() {
    let d = dims(16, 16, 12);
    let (c, r) = ([8.0, 8.0, 6.0], 4.0);
    let mut mesh = TriMesh::default();
    let (nu, nv) = (256, 128);
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (
                std::f64::consts::TAU * i as f64 / nu as f64,
                std::f64::consts::PI * j as f64 / nv as f64,
            );
            mesh.positions.push([
                (c[0] + r * v.sin() * u.cos()) / 16.0,
                (c[1] + r * v.sin() * u.sin()) / 16.0,
                (c[2] - r * v.cos()) / 16.0,
            ]);
        }
    }
    for j in 0..nv {
        for i in 0..nu {
            let id = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
            mesh.triangles
                .push([id(i, j), id(i, j + 1), id(i + 1, j + 1)]);
            mesh.triangles
                .push([id(i, j), id(i + 1, j + 1), id(i + 1, j)]);
        }
    }
    let tile = MeshTile::new(mesh, false).unwrap();
    assert!(tile.report.is_closed());
    let m = MeshCaster::new(&tile, d, &Limits::default()).unwrap();
    let dirs = DirectionGrid::new(8, 16).unwrap();
    let g = bake(&m, dirs, Method::Exact);
    let (mut graze_total, mut graze_bad) = (0, 0);
    each(&g, |i, j, k, a, b, v| {
        let o = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
        let dc = ((o[0] - c[0]).powi(2) + (o[1] - c[1]).powi(2) + (o[2] - c[2]).powi(2)).sqrt();
        if (dc - r).abs() < 0.05 {
            return; // centre within the tessellation band
        }
        if dc < r {
            assert_eq!(v, 0.0, "inside sample ({i},{j},{k})");
            return;
        }
        let (want, mu) = ray_tiled_sphere(o, dirs.vector(a, b), c, r, 16.0, 12.0);
        if mu >= 0.2 && want.is_finite() {
            assert!(
                (v as f64 - want).abs() < 0.02,
                "({i},{j},{k},{a},{b}) {v} vs {want}"
            );
        } else {
            graze_total += 1;
            if v.is_finite() != want.is_finite() {
                graze_bad += 1;
            }
        }
    });
    assert!(
        graze_bad * 100 <= graze_total,
        "{graze_bad} of {graze_total} grazing rays misclassified"
    );
}

/// A grazing ray crossing 12 tiles before it meets the only solid voxel's copy.
#[test]
fn grazing_ray_crosses_many_tiles() {
    let c = volume(dims(8, 8, 4), |i, j, k| (i, j, k) == (0, 0, 3));
    let cot: f64 = 96.0 / 2.5; // reaches z = 3 at x = 96.5, inside the copy of voxel 0 in tile 12
    let (s, co) = (
        1.0 / (1.0 + cot * cot).sqrt(),
        cot / (1.0 + cot * cot).sqrt(),
    );
    let t = c.trace([0.5, 0.5, 0.5], [co, 0.0, s], f64::INFINITY);
    assert_eq!(t, Trace::Hit((3.0 - 0.5) / s));
    let tile = MeshTile::new(
        box_mesh([0.0, 0.0, 3.0 / 8.0], [1.0 / 8.0, 1.0 / 8.0, 0.5]),
        false,
    )
    .unwrap();
    let m = MeshCaster::new(&tile, dims(8, 8, 4), &Limits::default()).unwrap();
    match m.trace([0.5, 0.5, 0.5], [co, 0.0, s], f64::INFINITY) {
        Trace::Hit(t) => assert!((t - 2.5 / s).abs() < 2e-3 * 2.5 / s, "{t}"),
        other => panic!("mesh path: {other:?}"),
    }
}

/// Closed voxel boxes: rays along faces, along edges and through corners touch the voxels that
/// share that face, edge or corner; the result is exact (f64, 1e-12).
#[test]
fn rays_along_faces_edges_and_through_corners() {
    let d = dims(16, 16, 8);
    let s2 = std::f64::consts::FRAC_1_SQRT_2;
    type Case = ((u32, u32, u32), [f64; 3], [f64; 3], Option<f64>);
    let cases: Vec<Case> = vec![
        // Along the face plane y = 1 (v_y = 0): voxels on either side touch.
        ((5, 0, 2), [0.5, 1.0, 2.5], [1.0, 0.0, 0.0], Some(4.5)),
        ((5, 1, 2), [0.5, 1.0, 2.5], [1.0, 0.0, 0.0], Some(4.5)),
        ((5, 2, 2), [0.5, 1.0, 2.5], [1.0, 0.0, 0.0], None),
        // Along the edge y = 1, z = 3: all four voxels around it touch.
        ((3, 0, 2), [0.5, 1.0, 3.0], [1.0, 0.0, 0.0], Some(2.5)),
        ((3, 1, 3), [0.5, 1.0, 3.0], [1.0, 0.0, 0.0], Some(2.5)),
        ((3, 2, 3), [0.5, 1.0, 3.0], [1.0, 0.0, 0.0], None),
        // Diagonally through the edge x = 1, y = 1: the side neighbours touch it.
        ((0, 1, 2), [0.5, 0.5, 2.5], [s2, s2, 0.0], Some(0.5 / s2)),
        ((1, 0, 2), [0.5, 0.5, 2.5], [s2, s2, 0.0], Some(0.5 / s2)),
        ((1, 1, 2), [0.5, 0.5, 2.5], [s2, s2, 0.0], Some(0.5 / s2)),
        ((2, 0, 2), [0.5, 0.5, 2.5], [s2, s2, 0.0], None),
    ];
    for (n, (solid, o, v, want)) in cases.into_iter().enumerate() {
        let c = volume(d, |i, j, k| (i, j, k) == solid);
        let got = c.trace(o, v, f64::INFINITY);
        match want {
            Some(t) => assert!(
                matches!(got, Trace::Hit(h) if (h - t).abs() < 1e-12),
                "case {n}: {got:?}"
            ),
            None => assert!(
                !matches!(got, Trace::Hit(h) if h < 20.0),
                "case {n}: {got:?}"
            ),
        }
    }
    // Through a corner: (1,1,1) is shared by 8 voxels; each one on the far side is hit there.
    let v3 = 1.0 / 3f64.sqrt();
    for solid in [
        (1, 0, 0),
        (0, 1, 0),
        (0, 0, 1),
        (1, 1, 0),
        (1, 0, 1),
        (0, 1, 1),
        (1, 1, 1),
    ] {
        let c = volume(d, |i, j, k| (i, j, k) == solid);
        let got = c.trace([0.5, 0.5, 0.5], [v3, v3, v3], f64::INFINITY);
        assert!(
            matches!(got, Trace::Hit(h) if (h - 0.5 / v3).abs() < 1e-12),
            "{solid:?}: {got:?}"
        );
    }
    // A point on a solid face is inside.
    let c = volume(d, |i, j, k| (i, j, k) == (2, 2, 2));
    assert_eq!(
        c.trace([2.0, 2.5, 2.5], [-1.0, 0.0, 0.0], f64::INFINITY),
        Trace::Inside
    );
}

/// Directions next to the poles and next to the horizon (θ = 1e-6, π − 1e-6, π/2 ± 1e-6) and
/// exactly horizontal.
#[test]
fn near_pole_and_near_horizon_directions() {
    let c = volume(dims(8, 8, 8), |i, j, k| {
        (i == 3 && j == 3 && k == 6) || k == 0
    });
    let from = [3.5, 3.5, 2.5];
    for (theta, want) in [(1e-6, Some(3.5)), (std::f64::consts::PI - 1e-6, Some(1.5))] {
        let v = mesobake_package::grid::spherical_to_vector(theta, 0.3);
        match c.trace(from, v, f64::INFINITY) {
            Trace::Hit(t) => assert!(
                (t - want.unwrap() / theta.cos().abs()).abs() < 1e-9,
                "θ={theta}: {t}"
            ),
            other => panic!("θ={theta}: {other:?}"),
        }
    }
    // Just below the horizon the floor (layer 0, top at z = 1) is hit after 1.5/sin(1e-6).
    let v = mesobake_package::grid::spherical_to_vector(std::f64::consts::FRAC_PI_2 + 1e-6, 0.7);
    match c.trace(from, v, f64::INFINITY) {
        Trace::Hit(t) => assert!((t - 1.5 / v[2].abs()).abs() < 1e-6 * t, "{t}"),
        other => panic!("{other:?}"),
    }
    // Exactly horizontal in layer 2: nothing there, reported as an escape to infinity.
    assert_eq!(
        c.trace(from, [0.6, 0.8, 0.0], f64::INFINITY),
        Trace::Escape(f64::INFINITY)
    );
    // Exactly horizontal in layer 6 along +x from (0.5, 3.5): the voxel (3, 3, 6) at x = 3.
    assert_eq!(
        c.trace([0.5, 3.5, 6.5], [1.0, 0.0, 0.0], f64::INFINITY),
        Trace::Hit(2.5)
    );
}

#[test]
fn escape_conventions_round_trip() {
    let c = volume(dims(8, 8, 6), |i, j, k| (i + j + k) % 5 == 0 && k > 1);
    let mut g = bake(&c, DirectionGrid::new(8, 8).unwrap(), Method::Exact);
    let raw = g.clone();
    g.set_escape_convention(EscapeConvention::Boundary);
    assert!(g.data().iter().all(|v| v.is_finite()));
    each(&raw, |i, j, k, a, b, v| {
        assert_eq!(g.is_escape(i, j, k, a, b), v.is_infinite());
        if v.is_infinite() {
            assert_eq!(g.get(i, j, k, a, b), g.boundary_distance(k, a));
        }
    });
    g.set_escape_convention(EscapeConvention::Infinite);
    assert_eq!(g, raw);
}

/// Fast with a stride past the last layer traces every ray to the end: identical to exact,
/// with rows that templates walk (12 wide) and rows they cannot (96: neither ≤ 64 nor a
/// multiple of 64, traced per ray).
#[test]
fn fast_with_full_stride_is_exact() {
    for d in [dims(12, 12, 6), dims(96, 3, 6)] {
        let c = volume(d, |i, j, k| (i * 7 + j * 3 + k * 5) % 11 == 0);
        let dirs = DirectionGrid::new(8, 16).unwrap();
        let exact = bake(&c, dirs, Method::Exact);
        let params = gdm::fast::FastParams {
            stride: 6,
            max_spread: f32::INFINITY,
        };
        let fast = gdm::fast::bake(&c, dirs, params, &Limits::default(), &()).unwrap();
        assert_eq!(fast, exact, "{d}");
    }
}

fn random_volume(bits: &[bool], d: Dims) -> VolumeCaster {
    volume(d, |i, j, k| bits[d.index(i, j, k)])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Along a ray, d(p + t·v) = d(p) − t for 0 ≤ t < d, escapes stay escapes, and the start
    /// point of a ray inside solid gives 0. Tolerance 1e-9 voxel (f64 traversal).
    #[test]
    fn distance_decreases_along_the_ray(
        bits in proptest::collection::vec(proptest::bool::weighted(0.08), 8 * 8 * 6),
        o in (0.0f64..8.0, 0.0f64..8.0, 0.0f64..6.0),
        theta in 0.0f64..std::f64::consts::PI,
        phi in 0.0f64..std::f64::consts::TAU,
        frac in 0.0f64..1.0,
    ) {
        let d = dims(8, 8, 6);
        let c = random_volume(&bits, d);
        let v = mesobake_package::grid::spherical_to_vector(theta, phi);
        prop_assume!(v[2].abs() > 1e-3);
        let o = [o.0, o.1, o.2];
        let cell = [o[0] as u32, o[1] as u32, o[2] as u32];
        match c.trace(o, v, f64::INFINITY) {
            Trace::Inside => prop_assert!(bits[d.index(cell[0], cell[1], cell[2])] || [o[0], o[1], o[2]].iter().any(|x| x.fract() == 0.0)),
            Trace::Hit(t) => {
                let s = frac * t;
                let p = [o[0] + s * v[0], o[1] + s * v[1], o[2] + s * v[2]];
                match c.trace(p, v, f64::INFINITY) {
                    Trace::Hit(t2) => prop_assert!((t2 - (t - s)).abs() < 1e-9 * (1.0 + t), "{t2} vs {}", t - s),
                    Trace::Inside => prop_assert!(t - s < 1e-9),
                    other => prop_assert!(false, "{other:?} after moving {s} of {t}"),
                }
            }
            Trace::Escape(t) => {
                let s = frac * t;
                let p = [o[0] + s * v[0], o[1] + s * v[1], o[2] + s * v[2]];
                let escaped = matches!(c.trace(p, v, f64::INFINITY), Trace::Escape(_));
                prop_assert!(escaped);
            }
            Trace::Limit => prop_assert!(false, "no limit was set"),
        }
        if !bits[d.index(cell[0], cell[1], cell[2])] {
            prop_assert!(c.trace(o, v, f64::INFINITY) != Trace::Inside || [o[0], o[1], o[2]].iter().any(|x| x.fract() == 0.0));
        } else {
            prop_assert_eq!(c.trace(o, v, f64::INFINITY), Trace::Inside);
        }
    }

    /// Empty-space skipping never changes a result: the skipping traversal equals the plain
    /// one-voxel-at-a-time DDA exactly.
    #[test]
    fn skipping_equals_plain_dda(
        bits in proptest::collection::vec(proptest::bool::weighted(0.03), 16 * 8 * 8),
        o in (0.0f64..16.0, 0.0f64..8.0, 0.0f64..8.0),
        theta in 0.0f64..std::f64::consts::PI,
        phi in 0.0f64..std::f64::consts::TAU,
    ) {
        let d = dims(16, 8, 8);
        let vol = Volume::from_fn(d, &Limits::default(), |i, j, k| bits[d.index(i, j, k)]).unwrap();
        let fast = VolumeCaster::new(&vol);
        let plain = VolumeCaster::from_occupancy(vol.occupancy(), false);
        let v = mesobake_package::grid::spherical_to_vector(theta, phi);
        let o = [o.0, o.1, o.2];
        let (a, b) = (fast.trace(o, v, 1e4), plain.trace(o, v, 1e4));
        match (a, b) {
            (Trace::Hit(x), Trace::Hit(y)) => prop_assert!((x - y).abs() <= 1e-12 * (1.0 + y), "{x} vs {y}"),
            (Trace::Escape(x), Trace::Escape(y)) => prop_assert!(x == y || (x - y).abs() <= 1e-12 * (1.0 + y)),
            _ => prop_assert_eq!(a, b),
        }
    }
}

/// Ray templates (64 samples per word) give bit-identical results to one traversal per ray,
/// for row widths below, at and above one word, including the slab and tie-prone directions of
/// a fine direction grid.
#[test]
fn templates_equal_per_ray_traversal() {
    for (d, density) in [
        (dims(12, 7, 5), 0.2),
        (dims(64, 4, 6), 0.05),
        (dims(128, 3, 4), 0.1),
    ] {
        let c = volume(d, |i, j, k| {
            let h = (d.index(i, j, k) as u64 + 1)
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left(29);
            ((h >> 11) as f64 / (1u64 << 53) as f64) < density
        });
        for dirs in [
            DirectionGrid::new(16, 32).unwrap(),
            DirectionGrid::new(2, 4).unwrap(),
            DirectionGrid::new(6, 8).unwrap(),
        ] {
            let fast = gdm::exact::bake(&c, dirs, &Limits::default(), &()).unwrap();
            let slow = gdm::exact::bake_per_ray(&c, dirs, &Limits::default(), &()).unwrap();
            assert_eq!(fast, slow, "{d} {dirs}");
        }
    }
}

/// The mesh path's per-direction route (ray templates over voxel-binned triangles) against one
/// BVH traversal per ray, on the `chain` tile with a row narrower than a word and one of a
/// full word. Both run the same f32 ray–triangle test, but a triangle can be met in the frame
/// of a neighbouring tile cell (a hit on a cell wall), which moves it by f32 rounding: all
/// hit/escape classifications must agree and distances within 1e-4 voxel.
#[test]
fn mesh_templates_equal_per_ray_bvh() {
    for d in [dims(24, 24, 12), dims(64, 64, 8)] {
        let tile = MeshTile::new(samples::mesh(SampleKind::Chain, d).unwrap(), false).unwrap();
        let m = MeshCaster::new(&tile, d, &Limits::default()).unwrap();
        let dirs = DirectionGrid::new(6, 12).unwrap();
        let fast = gdm::exact::bake(&m, dirs, &Limits::default(), &()).unwrap();
        let slow = gdm::exact::bake_per_ray(&m, dirs, &Limits::default(), &()).unwrap();
        let mut hits = 0;
        for (n, (&a, &b)) in fast.data().iter().zip(slow.data()).enumerate() {
            assert_eq!(a.is_finite(), b.is_finite(), "{d} value {n}: {a} vs {b}");
            if a.is_finite() {
                hits += 1;
                assert!((a - b).abs() <= 1e-4, "{d} value {n}: {a} vs {b}");
            }
        }
        assert!(hits > fast.data().len() / 4, "{d}: only {hits} hits");
    }
}
