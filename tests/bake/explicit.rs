//! `mesobake explicit`: the tile mapped through the shell follows the exact mapping within the
//! tolerance, closed tiles on closed bases give closed outward meshes, and the CLI end to end.

use crate::common::{each_fails_with, succeeds};
use glam::DVec3;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::surface::base_mesh::{BaseMesh, BuiltinMesh};
use mesobake_bake::surface::explicit::{Explicit, ExplicitParams, export};
use mesobake_bake::surface::shell::{PrismPoint, Shell, ShellParams};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use std::collections::HashMap;

fn base(mesh: BuiltinMesh) -> BaseMesh {
    mesh.build().unwrap().0
}

fn cylinder() -> BaseMesh {
    base(BuiltinMesh::Cylinder {
        radius: 0.5,
        height: 1.0,
        segments: [6, 3],
    })
}

fn torus() -> BaseMesh {
    base(BuiltinMesh::Torus {
        major_radius: 1.0,
        minor_radius: 0.4,
        segments: [12, 8],
    })
}

fn tile(kind: SampleKind) -> TriMesh {
    samples::mesh(kind, Dims::new(32, 32, 16).unwrap()).unwrap()
}

fn run(base: &BaseMesh, shell: ShellParams, tile: &TriMesh, tolerance: f64) -> (Shell, Explicit) {
    let shell = Shell::new(base, shell).unwrap();
    let params = ExplicitParams {
        tile_height: 0.5,
        tolerance,
        record_texture: true,
    };
    let out = export(&shell, tile, &params, &Limits::default(), &()).unwrap();
    (shell, out)
}

/// The exact mapping of a texture point through a prism, with barycentric coordinates solved
/// here from the prism's UV triangle (independently of the exporter's arithmetic).
fn exact(shell: &Shell, prism: u32, tex: DVec3) -> DVec3 {
    let p = &shell.prisms[prism as usize];
    let (e1, e2, r) = (
        p.uv[1] - p.uv[0],
        p.uv[2] - p.uv[0],
        tex.truncate() - p.uv[0],
    );
    let det = e1.perp_dot(e2);
    let b1 = r.perp_dot(e2) / det;
    let b2 = e1.perp_dot(r) / det;
    p.point(PrismPoint {
        bary: [1.0 - b1 - b2, b1, b2],
        w: tex.z,
    })
}

/// Largest distance between an output edge's midpoint and the exact image of its texture
/// midpoint; also checks that every vertex is the exact image of its texture point.
fn measured_deviation(shell: &Shell, out: &Explicit) -> f64 {
    let sources = out.sources.as_ref().unwrap();
    assert_eq!(sources.len(), out.mesh.triangles.len());
    let mut worst = 0.0f64;
    for (t, s) in out.mesh.triangles.iter().zip(sources) {
        let p = t.map(|v| DVec3::from(out.mesh.positions[v as usize]));
        for k in 0..3 {
            let image = exact(shell, s.prism, s.texture[k]);
            // Two evaluations of the same mapping in f64 (objects of size ~1), plus the
            // collapse of sliver edges (vertices move by at most 1e-9 × thickness): 1e-9.
            assert!((image - p[k]).length() < 1e-9, "{image} vs {}", p[k]);
            let mid_tex = (s.texture[k] + s.texture[(k + 1) % 3]) * 0.5;
            let chord = (p[k] + p[(k + 1) % 3]) * 0.5;
            worst = worst.max((exact(shell, s.prism, mid_tex) - chord).length());
        }
    }
    worst
}

#[test]
fn curved_base_edges_follow_the_mapping_within_tolerance() {
    // A six-sided cylinder: neighbouring extrusion directions differ by 60°, so the mapping
    // is strongly trilinear. The `grid` tile's bars are made of long triangles (1/8 tile).
    let shell_params = ShellParams {
        thickness: 0.1,
        tiles_per_uv: [2.0, 1.0],
        smoothing: 0,
    };
    let tile = tile(SampleKind::Grid);
    let tolerance = 1e-4;
    let (shell, out) = run(&cylinder(), shell_params, &tile, tolerance);
    let measured = measured_deviation(&shell, &out);
    // The bound holds for every edge, up to round-off and sliver collapse (1e-9, as above):
    // 1e-9 against a tolerance of 1e-4.
    assert!(measured <= tolerance + 1e-9, "{measured} > {tolerance}");
    assert!(out.stats.max_deviation <= tolerance, "{:?}", out.stats);
    // The reported deviation is the one measured here, up to the same 1e-9.
    assert!(
        (out.stats.max_deviation - measured).abs() < 1e-9,
        "{} vs {measured}",
        out.stats.max_deviation
    );
    assert_eq!(out.stats.depth_limited, 0);
    // Without subdivision the same check fails: it would catch a coarse export.
    let (shell, coarse) = run(&cylinder(), shell_params, &tile, 1e9);
    assert!(coarse.stats.triangles_out < out.stats.triangles_out);
    let coarse_deviation = measured_deviation(&shell, &coarse);
    assert!(coarse_deviation > 10.0 * tolerance, "{coarse_deviation}");
    assert!((coarse.stats.max_deviation - coarse_deviation).abs() < 1e-9);
}

/// Directed edge counts of a mesh.
fn directed_edges(mesh: &TriMesh) -> HashMap<(u32, u32), u32> {
    let mut edges = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    edges
}

fn signed_volume(mesh: &TriMesh) -> f64 {
    (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t).map(DVec3::from);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

fn torus_shell() -> ShellParams {
    // Whole tiles around both seams of the torus's UVs, so the tiling closes up.
    ShellParams {
        thickness: 0.08,
        tiles_per_uv: [3.0, 2.0],
        smoothing: 0,
    }
}

#[test]
fn closed_tiles_on_a_torus_give_closed_meshes() {
    // `weave` closes only modulo the lattice (threads leave one tile and enter the next);
    // `chain` is closed tori crossing the tile borders. On a closed torus (UV seams at whole
    // tiles) the output must be closed and consistently oriented: every directed edge once,
    // its reverse once, i.e. every edge shared by exactly two triangles.
    for kind in [SampleKind::Weave, SampleKind::Chain] {
        let (shell, out) = run(&torus(), torus_shell(), &tile(kind), 8e-5);
        assert_eq!(shell.report.folded, 0);
        assert!(out.stats.tile_closed && out.stats.triangles_clipped > 0);
        let edges = directed_edges(&out.mesh);
        let bad: Vec<_> = edges
            .iter()
            .filter(|&(&(a, b), &n)| n != 1 || edges.get(&(b, a)) != Some(&1))
            .take(5)
            .collect();
        assert!(
            bad.is_empty(),
            "{kind:?}: {} of {} directed edges unmatched, e.g. {bad:?}",
            edges
                .iter()
                .filter(|&(&(a, b), &n)| n != 1 || edges.get(&(b, a)) != Some(&1))
                .count(),
            edges.len()
        );
    }
}

#[test]
fn closed_output_is_outward() {
    // Outward tile faces stay outward: the enclosed volume is positive, and below the volume
    // of the shell (surface area × thickness, to within the torus's curvature: 10 %).
    let (shell, out) = run(&torus(), torus_shell(), &tile(SampleKind::Chain), 8e-5);
    let volume = signed_volume(&out.mesh);
    let area: f64 = shell
        .prisms
        .iter()
        .map(|p| {
            0.5 * (p.bottom[1] - p.bottom[0])
                .cross(p.bottom[2] - p.bottom[0])
                .length()
        })
        .sum();
    assert!(
        volume > 0.0 && volume < 1.1 * area * 0.08,
        "volume {volume}, shell {}",
        area * 0.08
    );
    // A mirrored UV mapping (u reversed) mirrors the mesostructure; windings are swapped so
    // the volume stays positive and equal.
    let mut mirrored = torus();
    for uv in &mut mirrored.uvs {
        uv.x = 1.0 - uv.x;
    }
    let (_, out) = run(&mirrored, torus_shell(), &tile(SampleKind::Chain), 8e-5);
    assert_eq!(out.stats.mirrored_prisms, out.stats.prisms);
    let v = signed_volume(&out.mesh);
    // Same solid, mirrored per tile: equal volume up to tessellation (1 %).
    assert!((v - volume).abs() < 0.01 * volume, "{v} vs {volume}");
}

#[test]
fn cli_writes_loadable_obj_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    std::fs::write(path("base.obj"), cylinder().to_obj("cylinder")).unwrap();
    std::fs::write(path("tile.obj"), tile(SampleKind::Grid).to_obj("grid")).unwrap();
    std::fs::write(path("bad.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let o = succeeds(&[
        "explicit",
        "--mesh",
        &path("base.obj"),
        "--tile",
        &path("tile.obj"),
        "--out",
        &path("out.obj"),
        "--thickness",
        "0.1",
        "--tiles",
        "2x1",
        "--tile-height",
        "0.5",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let written = TriMesh::read_obj(std::path::Path::new(&path("out.obj")), 1 << 30).unwrap();
    let stats = &json["stats"];
    assert_eq!(
        stats["triangles_out"].as_u64(),
        Some(written.triangles.len() as u64)
    );
    assert_eq!(
        stats["vertices_out"].as_u64(),
        Some(written.positions.len() as u64)
    );
    assert!((stats["tolerance"].as_f64().unwrap() - 1e-4).abs() < 1e-12);
    assert!(String::from_utf8_lossy(&o.stderr).contains("wrote"));

    // The same through a scene file, with a built-in sample as the tile.
    let scene = r#"{
      "base_mesh": { "builtin": { "cylinder": { "radius": 0.5, "height": 1.0, "segments": [6, 3] } } },
      "mesostructure": { "sample": "grid" },
      "resolution": [16, 16, 8],
      "shell": { "thickness": 0.1, "tiles_per_uv": [2, 1] },
      "camera": { "eye": [0, 0, 3], "target": [0, 0, 0], "fov_y_degrees": 45,
                  "width": 8, "height": 8 }
    }"#;
    std::fs::write(path("scene.json"), scene).unwrap();
    succeeds(&[
        "explicit",
        "--scene",
        &path("scene.json"),
        "--out",
        &path("scene.obj"),
    ]);
    let from_scene = TriMesh::read_obj(std::path::Path::new(&path("scene.obj")), 1 << 30).unwrap();
    // The same export as binary glTF, read back by the gltf crate: the OBJ's triangles and its
    // positions to f32 precision.
    succeeds(&[
        "explicit",
        "--scene",
        &path("scene.json"),
        "--out",
        &path("scene.glb"),
    ]);
    let glb = std::fs::read(path("scene.glb")).unwrap();
    let gltf = gltf::Gltf::from_slice(&glb).unwrap();
    let blob = gltf.blob.as_deref().unwrap();
    let mesh = gltf.meshes().next().unwrap();
    let primitive = mesh.primitives().next().unwrap();
    assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles);
    let reader = primitive.reader(|_| Some(blob));
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
    assert_eq!(positions.len(), from_scene.positions.len());
    assert_eq!(
        indices,
        from_scene
            .triangles
            .iter()
            .flatten()
            .copied()
            .collect::<Vec<_>>()
    );
    for (g, o) in positions.iter().zip(&from_scene.positions) {
        for axis in 0..3 {
            let (g, o) = (g[axis] as f64, o[axis]);
            assert!((g - o).abs() <= 1e-6 * (1.0 + o.abs()), "{g} vs {o}");
        }
    }
    // The same geometry, up to the OBJ round trip of the base mesh (9 decimals), which moves
    // clipping and subdivision decisions at a few places: counts within 1 %.
    let (a, b) = (from_scene.triangles.len(), written.triangles.len());
    assert!(a.abs_diff(b) * 100 <= b, "{a} vs {b}");
    std::fs::write(
        path("volume.json"),
        scene.replace(r#"{ "sample": "grid" }"#, r#"{ "volume": "x.mbvol" }"#),
    )
    .unwrap();

    let out = path("never.obj");
    let base_args = |tile: String| {
        vec![
            "explicit".to_string(),
            "--mesh".into(),
            path("base.obj"),
            "--tile".into(),
            tile,
            "--out".into(),
            out.clone(),
        ]
    };
    let missing = base_args(path("missing.obj"));
    let malformed = base_args(path("bad.obj"));
    let both = [
        base_args(path("tile.obj")),
        vec!["--scene".into(), path("scene.json")],
    ]
    .concat();
    let volume = ["explicit", "--scene", &path("volume.json"), "--out", &out];
    let no_tile = ["explicit", "--mesh", &path("base.obj"), "--out", &out];
    let bad_tiles = [
        base_args(path("tile.obj")),
        vec!["--tiles".into(), "0x2".into()],
    ]
    .concat();
    each_fails_with(&[
        (as_strs(&missing), "missing.obj"),
        (as_strs(&malformed), "OBJ"),
        (as_strs(&both), "cannot be used with"),
        (volume.to_vec(), "needs triangles"),
        (no_tile.to_vec(), "--tile"),
        (as_strs(&bad_tiles), "24x10"),
    ]);
    assert!(!dir.path().join("never.obj").exists());
}

fn as_strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}
