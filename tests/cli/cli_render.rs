//! `mesobake render` and `mesobake compare` end to end, and bad scenes.

use crate::common::{each_fails_with, mesobake, small_scene, succeeds};

const SCENE: &str = r#"{
  "base_mesh": { "builtin": { "torus": { "segments": [24, 12] } } },
  "mesostructure": { "sample": "grid" },
  "resolution": [16, 16, 8],
  "directions": [8, 16],
  "shell": { "thickness": 0.2, "tiles_per_uv": [8, 3] },
  "camera": { "eye": [0, 2.3, 2.9], "target": [0, 0, 0], "fov_y_degrees": 45,
              "width": 40, "height": 32 },
  "lights": [ { "point": { "position": [2, 4, 3], "intensity": [90, 90, 90] } },
              { "ambient": { "radiance": [0.05, 0.05, 0.05] } } ],
  "effects": ["shadows"]
}"#;

#[test]
fn render_both_methods_and_compare() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let scene = scene.to_str().unwrap();
    for (method, out) in [("truth", "truth.png"), ("gdm", "gdm.exr")] {
        let o = succeeds(&[
            "render",
            "--scene",
            scene,
            "--method",
            method,
            "--out",
            &path(out),
            "--json",
        ]);
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let hits = json["hit_pixels"].as_u64().unwrap();
        assert!(hits > 100 && hits < 40 * 32, "{method}: {hits} hits");
        assert_eq!(json["shell"]["prisms"], 24 * 12 * 2);
    }
    // An image against itself: identical (PSNR +inf is printed as null in JSON).
    let o = succeeds(&["compare", &path("truth.png"), &path("truth.png"), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(c["mean_abs_error"], 0.0);
    assert_eq!(c["mask_disagreement"], 0.0);
    // PNG against EXR: same size, so comparable; the difference picture is written.
    let o = succeeds(&[
        "compare",
        &path("truth.png"),
        &path("gdm.exr"),
        "--json",
        "--diff",
        &path("diff.png"),
    ]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let psnr = c["psnr_db"].as_f64().unwrap();
    assert!(psnr > 5.0 && psnr < 100.0, "{c}");
    assert!(std::fs::metadata(path("diff.png")).unwrap().len() > 0);
}

/// Blender's GLB and OBJ exports of one mesh (`tests/data/blender`) render the same image as
/// base meshes: the truth and the GDM renderer, chain mail on the torus (the glTF's node
/// transform applied, its v flipped back, its two primitives' seam welded; the OBJ carries
/// none of these).
#[test]
fn a_gltf_and_an_obj_export_of_one_mesh_render_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let blender = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender");
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let scene = |base: serde_json::Value| {
        serde_json::json!({
            "base_mesh": base,
            "mesostructure": { "sample": "chain" },
            "resolution": [32, 32, 16],
            "shell": { "thickness": 0.06, "tiles_per_uv": [8, 4] },
            "camera": { "eye": [0.3, 3.2, 2.4], "target": [0.25, 0.5, 0], "fov_y_degrees": 45, "width": 64, "height": 64 },
            "lights": [{ "point": { "position": [2, 4, 3], "intensity": [40, 40, 40] } }],
            "effects": ["shadows"]
        })
        .to_string()
    };
    let glb = blender.join("knight.glb");
    let obj = blender.join("knight.obj");
    std::fs::write(path("glb.json"), scene(serde_json::json!({ "gltf": glb }))).unwrap();
    std::fs::write(path("obj.json"), scene(serde_json::json!({ "obj": obj }))).unwrap();
    for method in ["truth", "gdm"] {
        for base in ["glb", "obj"] {
            succeeds(&[
                "render",
                "--scene",
                &path(&format!("{base}.json")),
                "--method",
                method,
                "--out",
                &path(&format!("{base}-{method}.png")),
            ]);
        }
        let o = succeeds(&[
            "compare",
            &path(&format!("obj-{method}.png")),
            &path(&format!("glb-{method}.png")),
            "--json",
        ]);
        let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        // The same but for the OBJ's rounding (six decimals for positions, four for normals;
        // the GLB holds f32), which moves a few edge pixels of the chain: at least 35 dB, at
        // most one pixel in a thousand on the mask.
        let psnr = c["psnr_db"].as_f64().unwrap_or(f64::INFINITY);
        assert!(psnr >= 35.0, "{method}: {c}");
        assert!(
            c["mask_disagreement"].as_f64().unwrap() <= 1e-3,
            "{method}: {c}"
        );
    }
}

/// OpenVDB files OpenVDB wrote (`tests/data/openvdb`) import with the real binary and render
/// as mesostructure: the level-set sphere's truth image has the hit mask of a volume the test
/// voxelizes from the analytic sphere (what differs is the shading: the import's normals follow
/// the distance field), and the GDM renders it as it renders those voxels; the fog volume
/// renders as a medium, as the same medium written from the formula that filled the file
/// renders.
#[test]
fn openvdb_level_sets_and_fog_volumes_import_and_render() {
    use mesobake_bake::mesostructure::{volume::Volume, volume_format};
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/openvdb");
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let o = succeeds(&[
        "import",
        data.join("sphere.vdb").to_str().unwrap(),
        "--out",
        &path("sphere.mbvol"),
    ]);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        said.contains("as an opaque volume of 30x30x31 voxels from index [2, 1, -3]"),
        "{said}"
    );
    // The sphere of make_vdbs.py, voxel (i, j, k) at index (2 + i, 1 + j, −3 + k).
    let dims = mesobake_package::grid::Dims::new(30, 30, 31).unwrap();
    let limits = mesobake_core::limits::Limits::default();
    let analytic = Volume::from_fn(dims, &limits, |i, j, k| {
        let p = [2 + i as i32, 1 + j as i32, k as i32 - 3].map(|c| f64::from(c) * 0.25);
        let c = [4.1, 3.9, 3.05];
        (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>().sqrt() < 3.1
    })
    .unwrap();
    volume_format::write(&analytic, std::path::Path::new(&path("analytic.mbvol"))).unwrap();
    let scene = |volume: &str, method: &str| {
        let resolution = if volume == "fog.mbvol" || volume == "formula.mbvol" {
            [15, 15, 7]
        } else {
            [30, 30, 31]
        };
        let json = serde_json::json!({
            "base_mesh": { "builtin": { "plane": { "amplitude": 0.1, "segments": 8 } } },
            "mesostructure": { "volume": volume },
            "resolution": resolution,
            "shell": { "thickness": 0.25, "tiles_per_uv": [4, 4] },
            "camera": { "eye": [0.2, 1.6, 1.5], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 64, "height": 64 },
            "lights": [{ "directional": { "direction": [0.3, -1, 0.2], "irradiance": [3, 3, 3] } },
                       { "ambient": { "radiance": [0.1, 0.1, 0.1] } }],
            "effects": ["shadows"]
        });
        let mut json = json;
        if resolution[2] == 7 {
            // The real-time algorithm with shadow rays (its reference, not the deep map).
            json["transparency"] = serde_json::json!({ "shadows": "rays" });
        }
        let name = format!("{volume}-{method}");
        std::fs::write(path(&format!("{name}.json")), json.to_string()).unwrap();
        succeeds(&[
            "render",
            "--scene",
            &path(&format!("{name}.json")),
            "--method",
            method,
            "--out",
            &path(&format!("{name}.png")),
        ]);
        path(&format!("{name}.png"))
    };
    let compare = |a: &str, b: &str| -> serde_json::Value {
        serde_json::from_slice(&succeeds(&["compare", a, b, "--json"]).stdout).unwrap()
    };
    let imported = scene("sphere.mbvol", "truth");
    let analytic_truth = scene("analytic.mbvol", "truth");
    let c = compare(&analytic_truth, &imported);
    assert!(c["mask_disagreement"].as_f64().unwrap() <= 2e-3, "{c}");
    // The GDM renders the import as it renders the analytic voxels: the same hit mask
    // against the truth (the GDM's own error at 16×32 directions, 3 % here) and a PSNR within
    // 1 dB (about 19 dB at 64² on this grazing view of spheres).
    let imported_gdm = compare(&imported, &scene("sphere.mbvol", "gdm"));
    let analytic_gdm = compare(&analytic_truth, &scene("analytic.mbvol", "gdm"));
    // (Identical images have an infinite PSNR, written as null.)
    let figure = |c: &serde_json::Value, key: &str| c[key].as_f64().unwrap_or(f64::INFINITY);
    assert!(
        (figure(&imported_gdm, "mask_disagreement") - figure(&analytic_gdm, "mask_disagreement"))
            .abs()
            <= 2e-3
            && figure(&imported_gdm, "psnr_db") >= figure(&analytic_gdm, "psnr_db") - 1.0,
        "{imported_gdm} against {analytic_gdm}"
    );

    succeeds(&[
        "import",
        data.join("fog.vdb").to_str().unwrap(),
        "--density-scale",
        "8",
        "--out",
        &path("fog.mbvol"),
    ]);
    // The same medium written by the test from make_vdbs.py's formula as raw RGBA (sRGB
    // colour, α = 1 − exp(−8·ρ·0.125)) over the import's box, index (6, −2, 3) on.
    let s = |t: f64| (std::f64::consts::PI * t).sin().powi(2);
    let mut raw = Vec::new();
    for k in 0..7 {
        for j in 0..15 {
            for i in 0..15 {
                let [x, y, z] = [i + 1, j + 1, k + 1].map(f64::from);
                let rho = 4.0 * s(x / 15.0) * s(y / 15.0) * s(z / 7.0);
                let srgb = |c: f64| f64::from(mesobake_core::color::linear_to_srgb(c as f32));
                let rgba = [
                    srgb(x / 15.0),
                    srgb(y / 15.0),
                    srgb(0.5),
                    1.0 - (-rho).exp(),
                ];
                raw.extend(rgba.iter().flat_map(|c| (*c as f32).to_le_bytes()));
            }
        }
    }
    std::fs::write(path("fog.raw"), raw).unwrap();
    succeeds(&[
        "import",
        &path("fog.raw"),
        "--format",
        "rgba32f",
        "--res",
        "15x15x7",
        "--out",
        &path("formula.mbvol"),
    ]);
    // The truth and the real-time algorithm (cells, shadow rays) each render the import as
    // they render the formula: ≥ 50 dB, the same hit mask.
    for method in ["truth", "cells"] {
        let c = compare(&scene("formula.mbvol", method), &scene("fog.mbvol", method));
        assert!(
            figure(&c, "psnr_db") >= 50.0 && figure(&c, "mask_disagreement") == 0.0,
            "{method}: {c}"
        );
    }
}

/// A scene of several objects from the command line: the Blender knight's two materials as
/// two objects, rendered together (truth and gdm, the image's hits those of the objects),
/// baked as one package per object (each the package of its object alone, byte for byte),
/// previewed (the WGSL ≥ 35 dB from `render --method gdm`; with a relief on the leather, a
/// VDM object beside the GDM chain, ≥ 35 dB from `render`'s composed GDM and VDM), and
/// refused by name where one object's package is given.
#[test]
fn a_scene_of_two_objects_renders_and_bakes_a_package_per_object() {
    let dir = tempfile::tempdir().unwrap();
    let glb =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blender/knight.glb");
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let shared = serde_json::json!({
        "camera": { "eye": [0.3, 3.2, 2.4], "target": [0.25, 0.5, 0], "fov_y_degrees": 45, "width": 48, "height": 48 },
        "lights": [{ "point": { "position": [2, 4, 3], "intensity": [40, 40, 40] } }],
        "effects": ["shadows"],
        "resolution": [16, 16, 8],
        "shell": { "thickness": 0.06, "tiles_per_uv": [8, 4] }
    });
    let mut scene = shared.clone();
    scene["objects"] = serde_json::json!([{
        "base_mesh": { "gltf": glb },
        "materials": {
            "Chain": { "mesostructure": { "sample": "chain" } },
            "Leather": { "mesostructure": { "sample": "weave" } }
        }
    }]);
    std::fs::write(path("knight.json"), scene.to_string()).unwrap();
    for method in ["truth", "gdm"] {
        let o = succeeds(&[
            "render",
            "--scene",
            &path("knight.json"),
            "--method",
            method,
            "--out",
            &path(&format!("{method}.png")),
            "--json",
        ]);
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(json["objects"][1]["name"], "Leather", "{json}");
        assert!(json["hit_pixels"].as_u64().unwrap() > 200, "{json}");
    }
    succeeds(&[
        "bake",
        "--scene",
        &path("knight.json"),
        "--out",
        &path("packages"),
    ]);
    // The chain's object alone, as a scene of one object: the same package.
    let mut chain = shared.clone();
    chain["base_mesh"] = serde_json::json!({ "gltf": { "file": glb, "material": "Chain" } });
    chain["mesostructure"] = serde_json::json!({ "sample": "chain" });
    std::fs::write(path("chain.json"), chain.to_string()).unwrap();
    succeeds(&[
        "bake",
        "--scene",
        &path("chain.json"),
        "--out",
        &path("chain.mbpkg"),
    ]);
    assert_eq!(
        std::fs::read(path("packages/Chain.mbpkg")).unwrap(),
        std::fs::read(path("chain.mbpkg")).unwrap()
    );
    assert!(
        std::fs::metadata(path("packages/Leather.mbpkg"))
            .unwrap()
            .len()
            > 0
    );
    // The README's example scene: the knight on a woven ground, three objects.
    let example =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/examples/knight-objects.json");
    let o = succeeds(&[
        "render",
        "--scene",
        example.to_str().unwrap(),
        "--method",
        "truth",
        "--out",
        &path("example.png"),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["objects"].as_array().unwrap().len(), 3, "{json}");
    each_fails_with(&[
        (
            vec![
                "render",
                "--scene",
                &path("knight.json"),
                "--package",
                &path("chain.mbpkg"),
                "--out",
                &path("x.png"),
            ],
            "this scene has several",
        ),
        (
            vec![
                "preview",
                "--scene",
                &path("knight.json"),
                "--package",
                &path("chain.mbpkg"),
                "--out",
                &path("x.png"),
            ],
            "a scene of several objects is previewed from a package baked for each",
        ),
    ]);
    // The preview draws both objects with the real-time pipeline, as `render --method gdm`
    // (its CPU specification, from the same packages) draws them.
    let o = succeeds(&[
        "preview",
        "--scene",
        &path("knight.json"),
        "--out",
        &path("preview.png"),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        json["objects"],
        serde_json::json!(["Chain", "Leather"]),
        "{json}"
    );
    if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() != Ok("1") {
        assert_eq!(json["renderer"], "gpu", "{json}");
    }
    let read = |name: &str| mesobake_render::image::Image::read(std::path::Path::new(&path(name)));
    let c =
        mesobake_render::image::compare(&read("preview.png").unwrap(), &read("gdm.png").unwrap())
            .unwrap();
    assert!(c.psnr_db >= 35.0 && c.mask_disagreement <= 0.005, "{c:?}");
    // An object list that leaves one object (the leather not drawn) previews as that object.
    scene["objects"][0]["materials"]["Leather"] = serde_json::Value::Null;
    std::fs::write(path("chain-only.json"), scene.to_string()).unwrap();
    let o = succeeds(&[
        "preview",
        "--scene",
        &path("chain-only.json"),
        "--out",
        &path("chain-only.png"),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json["hit_pixels"].as_u64().unwrap() > 100, "{json}");
    // A relief on the leather: a VDM package for it beside the chain's GDM, drawn together.
    scene["objects"][0]["materials"]["Leather"] =
        serde_json::json!({ "mesostructure": { "relief": "bumps" }, "technique": "vdm" });
    std::fs::write(path("mixed.json"), scene.to_string()).unwrap();
    let o = succeeds(&[
        "preview",
        "--scene",
        &path("mixed.json"),
        "--out",
        &path("mixed.png"),
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["technique"], "mixed", "{json}");
    // `render` without a method composes each object's real-time specification: GDM, VDM.
    succeeds(&[
        "render",
        "--scene",
        &path("mixed.json"),
        "--out",
        &path("mixed-cpu.png"),
    ]);
    let c = mesobake_render::image::compare(
        &read("mixed.png").unwrap(),
        &read("mixed-cpu.png").unwrap(),
    )
    .unwrap();
    assert!(c.psnr_db >= 35.0 && c.mask_disagreement <= 0.005, "{c:?}");
}

#[test]
fn the_render_report_ends_with_the_error_budget() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let out = dir.path().join("report");
    let o = succeeds(&[
        "report",
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--dirs",
        "8x16",
        "--ranks",
        "4",
        "--refinements",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("Error budget"));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("render-accuracy.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 2, "{json}");
    let budget = json["budget"].as_array().unwrap();
    let labels: Vec<&str> = budget
        .iter()
        .map(|r| r["substituted"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["none", "query", "shadows", "query+shadows"]);
    // The budget's first row is the sweep's exact row: the same deterministic image.
    assert_eq!(budget[0]["psnr_db"], json["rows"][0]["psnr_db"], "{json}");
    // Exact parts bring the image closer to the truth, not further (on this coarse torus the
    // straight segments per prism still leave most of the error).
    let psnr = |r: &serde_json::Value| r["psnr_db"].as_f64().unwrap();
    assert!(psnr(&budget[3]) > psnr(&budget[0]), "{json}");
}

#[test]
fn substituted_gdm_renders_come_closer_to_the_truth_and_bad_ones_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let scene = scene.to_str().unwrap();
    let args = |method: &'static str, substitute: &'static str, out: &str| -> Vec<String> {
        [
            "render",
            "--scene",
            scene,
            "--method",
            method,
            "--substitute",
            substitute,
            "--out",
            &path(out),
        ]
        .map(String::from)
        .to_vec()
    };
    for (method, substitute, out) in [
        ("truth", "none", "truth.exr"),
        ("gdm", "none", "gdm.exr"),
        ("gdm", "query,shadows", "exact.exr"),
    ] {
        let a = args(method, substitute, out);
        succeeds(&a.iter().map(String::as_str).collect::<Vec<_>>());
    }
    let psnr = |image: &str| {
        let o = succeeds(&["compare", &path("truth.exr"), &path(image), "--json"]);
        let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        c["psnr_db"].as_f64().unwrap()
    };
    // As in the report's budget on this scene: closer, not identical (straight segments).
    let (paper, exact) = (psnr("gdm.exr"), psnr("exact.exr"));
    assert!(exact > paper, "{exact} dB against {paper} dB");
    let bad_args = [
        args("gdm", "query,shade", "x.png"),
        args("gdm", "shadows,shell-shadows", "x.png"),
        args("truth", "query", "x.png"),
    ];
    let bad = |i: usize| bad_args[i].iter().map(String::as_str).collect::<Vec<_>>();
    each_fails_with(&[
        (bad(0), "substitution \"shade\""),
        (bad(1), "quality settings: --quality"),
        (bad(2), "GDM renderer"),
    ]);
}

#[test]
fn bad_scenes_and_images_fail_with_clear_messages() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let out = dir.path().join("x.png").to_str().unwrap().to_string();
    let count = std::cell::Cell::new(0);
    let bad = |from: &str, to: &str| {
        count.set(count.get() + 1);
        assert!(SCENE.contains(from), "{from}");
        write(
            &format!("bad{}.json", count.get()),
            &SCENE.replace(from, to),
        )
    };
    let cases = [
        (write("garbage.json", "{ not json"), "scene"),
        (
            bad(
                r#""effects": ["shadows"]"#,
                r#""effects": ["shadows", "subsurface"]"#,
            ),
            "unknown variant",
        ),
        (
            bad(r#""fov_y_degrees": 45"#, r#""fov_y_degrees": 0"#),
            "fov_y_degrees",
        ),
        (bad(r#""width": 40"#, r#""width": 100000"#), "width"),
        (
            bad(r#""thickness": 0.2"#, r#""thickness": -1"#),
            "thickness",
        ),
        (
            bad(r#""target": [0, 0, 0]"#, r#""target": [0, 2.3, 2.9]"#),
            "coincide",
        ),
        (
            bad(
                r#""resolution": [16, 16, 8]"#,
                r#""resolution": [16, 16, 0]"#,
            ),
            "resolution",
        ),
        (
            bad(r#""segments": [24, 12]"#, r#""segments": [2, 12]"#),
            "segments",
        ),
        (
            bad(r#""sample": "grid""#, r#""volume": "missing.mbvol""#),
            "missing.mbvol",
        ),
        (
            bad(r#""shell": {"#, r#""shell": { "colour": 1,"#),
            "unknown field",
        ),
    ];
    let owned: Vec<(Vec<String>, &str)> = cases
        .iter()
        .map(|(scene, want)| {
            (
                vec![
                    "render".into(),
                    "--scene".into(),
                    scene.clone(),
                    "--out".into(),
                    out.clone(),
                ],
                *want,
            )
        })
        .collect();
    let args: Vec<(Vec<&str>, &str)> = owned
        .iter()
        .map(|(a, w)| (a.iter().map(String::as_str).collect(), *w))
        .collect();
    each_fails_with(&args);
    // Images: wrong extension, not an image, different sizes.
    let not_png = write("fake.png", "hello");
    each_fails_with(&[
        (vec!["compare", &not_png, &not_png], "not a readable PNG"),
        (vec!["compare", "a.bmp", "b.bmp"], "unknown image extension"),
    ]);
    assert!(
        !mesobake(&["render", "--scene", "/nonexistent.json", "--out", &out])
            .status
            .success()
    );
}

#[test]
fn render_and_preview_agree_by_default_and_spp_supersamples_both() {
    // Without --package, render draws the scene's package as preview does (before, render
    // queried the uncompressed GDM: torus-chain 20.6 dB away from the preview); --gdm-codec
    // uncompressed keeps that reference at hand. The bar is the CPU-vs-WGSL tests' 35 dB.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let scene = scene.to_str().unwrap();
    let json = |o: std::process::Output| -> serde_json::Value {
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let psnr = |a: &str, b: &str| -> f64 {
        let o = succeeds(&["compare", &path(a), &path(b), "--json"]);
        // Identical images compare at +∞, which JSON writes as null.
        json(o)["psnr_db"].as_f64().unwrap_or(f64::INFINITY)
    };
    for spp in ["1", "4"] {
        let r = format!("render-{spp}.png");
        let p = format!("preview-{spp}.png");
        let rj = json(succeeds(&[
            "render",
            "--scene",
            scene,
            "--spp",
            spp,
            "--out",
            &path(&r),
            "--json",
        ]));
        let pj = json(succeeds(&[
            "preview",
            "--scene",
            scene,
            "--spp",
            spp,
            "--out",
            &path(&p),
            "--json",
        ]));
        assert_eq!(rj["samples_per_pixel"], spp.parse::<u32>().unwrap(), "{rj}");
        assert_eq!(pj["samples_per_pixel"], rj["samples_per_pixel"], "{pj}");
        let agreement = psnr(&r, &p);
        assert!(
            agreement >= 35.0,
            "{spp} spp: render vs preview {agreement} dB"
        );
    }
    // Supersampling changes the image (the grid's edges are antialiased).
    assert!(psnr("render-1.png", "render-4.png") < 35.0);
    succeeds(&[
        "render",
        "--scene",
        scene,
        "--gdm-codec",
        "uncompressed",
        "--out",
        &path("raw.png"),
    ]);
    assert!(
        psnr("render-1.png", "raw.png") < 60.0,
        "the raw GDM renders otherwise"
    );
}

#[test]
fn bad_sample_counts_and_codec_choices_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, SCENE).unwrap();
    let scene = scene.to_str().unwrap();
    let out = dir.path().join("x.png");
    let out = out.to_str().unwrap();
    let mut cases = Vec::new();
    for command in ["render", "preview"] {
        for (spp, want) in [
            ("0", "1..=1024"),
            ("1025", "1..=1024"),
            ("2.5", "whole number"),
            ("many", "whole number"),
        ] {
            cases.push((
                vec![command, "--scene", scene, "--spp", spp, "--out", out],
                want,
            ));
        }
    }
    cases.push((
        vec![
            "render",
            "--scene",
            scene,
            "--gdm-codec",
            "lossy",
            "--out",
            out,
        ],
        "expected occupancy, paper-svd or uncompressed",
    ));
    cases.push((
        vec![
            "render",
            "--scene",
            scene,
            "--method",
            "truth",
            "--gdm-codec",
            "uncompressed",
            "--out",
            out,
        ],
        "without --package",
    ));
    each_fails_with(&cases);
    // A scene whose camera asks for more rays than allowed, in the file.
    let big = SCENE.replace(
        r#""width": 40, "height": 32 }"#,
        r#""width": 8192, "height": 8192, "samples_per_pixel": 2 }"#,
    );
    let big_scene = dir.path().join("big.json");
    std::fs::write(&big_scene, big).unwrap();
    each_fails_with(&[(
        vec![
            "render",
            "--scene",
            big_scene.to_str().unwrap(),
            "--out",
            out,
        ],
        "134217728 camera rays",
    )]);
}

/// Runs `report conformance` on `scenes` (comma-separated) at 4 samples per pixel, 32 px,
/// one WGSL frame, into `out`: its printed table and its JSON.
fn conformance(scenes: &str, out: &std::path::Path) -> (String, serde_json::Value) {
    let o = succeeds(&[
        "report",
        "conformance",
        "--scenes",
        scenes,
        "--spp",
        "4",
        "--side",
        "32",
        "--frames",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    let json = std::fs::read(out.join("conformance.json")).unwrap();
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        serde_json::from_slice(&json).unwrap(),
    )
}

#[test]
fn the_conformance_report_measures_every_technique_and_preset_of_a_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.json");
    // A scene whose quality is not the paper's: its default row is its own preset.
    let mut json: serde_json::Value = serde_json::from_str(SCENE).unwrap();
    json["quality"] = "balanced".into();
    std::fs::write(&scene, json.to_string()).unwrap();
    let out = dir.path().join("report");
    let (table, json) = conformance(scene.to_str().unwrap(), &out);
    assert!(table.contains("| scene | technique |"), "{table}");
    assert_eq!(json["samples_per_pixel"], 4);
    let rows = json["rows"].as_array().unwrap();
    let presets: Vec<&str> = rows.iter().map(|r| r["preset"].as_str().unwrap()).collect();
    assert_eq!(presets, ["paper", "balanced", "high"], "{json}");
    let defaults: Vec<&serde_json::Value> =
        rows.iter().filter(|r| r["is_default"] == true).collect();
    assert_eq!(defaults.len(), 1);
    assert_eq!(defaults[0]["preset"], "balanced");
    // The verdict's default figure is that row's (the WGSL's where measured).
    let default_db = (defaults[0]["gpu"]["psnr_db"].as_f64())
        .unwrap_or_else(|| defaults[0]["cpu"]["psnr_db"].as_f64().unwrap());
    let md = std::fs::read_to_string(out.join("conformance.md")).unwrap();
    let verdict = md.lines().find(|l| l.starts_with("| scene |")).unwrap();
    let first = md.lines().skip_while(|l| *l != verdict).nth(2).unwrap();
    let cells: Vec<&str> = first.split('|').map(str::trim).collect();
    assert_eq!(cells[3], format!("{default_db:.2}"), "{md}");
    for r in rows {
        let db = r["cpu"]["psnr_db"].as_f64().unwrap();
        assert!(db > 10.0 && db.is_finite(), "{r}");
        // Where an adapter exists the WGSL agrees with its CPU twin.
        if let Some(a) = r["agreement"]["psnr_db"].as_f64() {
            assert!(a >= 35.0, "{r}");
        }
    }
    // The contact sheet: truth | real-time | difference, for the default row.
    let sheet = mesobake_render::image::Image::read(&out.join("conformance.png")).unwrap();
    assert_eq!((sheet.width, sheet.height), (3 * 32, 26));
}

#[test]
fn the_conformance_report_measures_the_vdm_and_the_media_at_their_accurate_settings_too() {
    // A VDM scene with the refinement measures the paper's VDM beside it; a translucent
    // scene shadowed by deep maps measures the maps' reference, shadow rays, beside it (the
    // WGSL refused where the adapter's loop budget is too small, the CPU's figure standing).
    let dir = tempfile::tempdir().unwrap();
    let light = r#"[ { "point": { "position": [2, 4, 3], "intensity": [90, 90, 90] } },
                     { "ambient": { "radiance": [0.05, 0.05, 0.05] } } ]"#;
    let camera = r#"{ "eye": [0, 2.3, 2.9], "target": [0, 0, 0], "fov_y_degrees": 45,
                      "width": 32, "height": 32 }"#;
    let torus = r#"{ "builtin": { "torus": { "segments": [24, 12] } } }"#;
    let scenes = [
        (
            "bumps.json",
            format!(
                r#"{{ "base_mesh": {torus}, "mesostructure": {{ "relief": "bumps" }},
                  "resolution": [32, 32, 8], "shell": {{ "thickness": 0.05, "tiles_per_uv": [8, 3] }},
                  "camera": {camera}, "lights": {light}, "effects": ["silhouettes", "shadows"],
                  "vdm": {{ "directions": [4, 8], "curvatures": 4, "refine_texels": 4 }} }}"#
            ),
        ),
        (
            "fur.json",
            format!(
                r#"{{ "base_mesh": {torus}, "mesostructure": {{ "medium": "fur" }},
                  "resolution": [16, 16, 8], "shell": {{ "thickness": 0.13, "tiles_per_uv": [8, 3] }},
                  "camera": {camera}, "lights": {light}, "effects": ["shadows"],
                  "transparency": {{ "shadow_map_size": 32, "shadow_levels": 4 }} }}"#
            ),
        ),
    ];
    let paths: Vec<String> = scenes
        .iter()
        .map(|(name, json)| {
            let path = dir.path().join(name);
            std::fs::write(&path, json).unwrap();
            path.to_str().unwrap().to_string()
        })
        .collect();
    let (_, json) = conformance(&paths.join(","), &dir.path().join("report"));
    let rows: Vec<(&str, &str, &str, bool)> = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["scene"].as_str().unwrap(),
                r["technique"].as_str().unwrap(),
                r["preset"].as_str().unwrap(),
                r["is_default"].as_bool().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        rows,
        [
            ("bumps", "vdm", "scene", true),
            ("bumps", "vdm", "paper", false),
            ("bumps", "gdm", "paper", false),
            ("bumps", "gdm", "balanced", false),
            ("bumps", "gdm", "high", false),
            ("fur", "transparency", "scene", true),
            ("fur", "transparency", "shadow rays", false),
        ],
        "{json}"
    );
    for r in json["rows"].as_array().unwrap() {
        let db = r["cpu"]["psnr_db"].as_f64().unwrap();
        assert!(db > 10.0 && db.is_finite(), "{r}");
        // The WGSL is measured, or refused with the reason, never both.
        assert!(r["gpu"].is_null() || r["refused"].is_null(), "{r}");
    }
}

#[test]
fn a_base_mesh_vertex_far_out_is_refused_naming_it() {
    // The probe's OBJ with one vertex at 1e308 panicked in the BVH build (render --method
    // gdm and truth); at 1e20 every triangle was dropped as "zero-area". A mesh_scale that
    // carries a sane mesh that far is refused likewise.
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let square = "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                  f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
    let mut cases = Vec::new();
    for (name, obj, scale) in [
        (
            "far.obj",
            square.replace("v 1 0 -1", "v 1e308 1e308 1e308"),
            1.0,
        ),
        ("far20.obj", square.replace("v 1 0 -1", "v 1e20 0 0"), 1.0),
        ("square.obj", square.to_string(), 1e12),
    ] {
        std::fs::write(path(name), obj).unwrap();
        let mut scene: serde_json::Value = serde_json::from_str(SCENE).unwrap();
        scene["base_mesh"] = serde_json::json!({ "obj": name });
        scene["mesh_scale"] = scale.into();
        let scene_path = path(&format!("{name}.json"));
        std::fs::write(&scene_path, scene.to_string()).unwrap();
        for method in ["gdm", "truth"] {
            cases.push((
                vec![
                    "render".to_string(),
                    "--scene".into(),
                    scene_path.clone(),
                    "--method".into(),
                    method.into(),
                    "--out".into(),
                    path("x.png"),
                ],
                "beyond ±1e9 are refused",
            ));
        }
    }
    let cases: Vec<(Vec<&str>, &str)> = cases
        .iter()
        .map(|(args, want)| (args.iter().map(String::as_str).collect(), *want))
        .collect();
    each_fails_with(&cases);
}

#[test]
fn a_scene_path_to_an_endless_device_fails_at_the_limit() {
    // /dev/zero reports no length: reading it whole took 2 GB before failing.
    if !std::path::Path::new("/dev/zero").exists() {
        return;
    }
    each_fails_with(&[(
        vec!["render", "--scene", "/dev/zero", "--out", "x.png"],
        "limit for scene files",
    )]);
}

/// Every file a command reads goes through the byte limit while reading, not only by the length
/// the file reports: /dev/zero (length 0, endless) as a scene, each kind of scene input, a
/// package and a raw medium is refused at once, naming the limit or what is wrong, never read
/// to the end (which would not come).
#[test]
fn endless_files_are_read_only_up_to_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let small = small_scene(dir.path());
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&small).unwrap()).unwrap();
    let out = dir.path().join("x.png");
    let mut cases: Vec<(Vec<String>, &str)> = Vec::new();
    for (key, value, expected) in [
        (
            "mesostructure",
            serde_json::json!({ "tile": "/dev/zero" }),
            "over the memory limit",
        ),
        (
            "mesostructure",
            serde_json::json!({ "height_field": "/dev/zero" }),
            "over the memory limit",
        ),
        (
            "mesostructure",
            serde_json::json!({ "volume": "/dev/zero" }),
            "shorter than the",
        ),
        (
            "base_mesh",
            serde_json::json!({ "obj": "/dev/zero" }),
            "over the memory limit",
        ),
    ] {
        let mut s = scene.clone();
        s[key] = value;
        let path = dir.path().join(format!("scene{}.json", cases.len()));
        std::fs::write(&path, s.to_string()).unwrap();
        let args = [
            "render",
            "--scene",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        cases.push((args.map(String::from).to_vec(), expected));
    }
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render".to_string(),
            "--out".into(),
            out.to_str().unwrap().into(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    cases.push((
        render(&["--scene", "/dev/zero"]),
        "over the 1048576-byte limit",
    ));
    let package = ["--scene", small.to_str().unwrap(), "--package", "/dev/zero"];
    cases.push((render(&package), "over the memory limit"));
    let unpack = ["unpack", "/dev/zero", "--out", "x.npy"];
    cases.push((unpack.map(String::from).to_vec(), "over the memory limit"));
    for (args, expected) in cases {
        let mut all = vec!["--memory-limit".to_string(), "16MiB".into()];
        all.extend(args);
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        let o = mesobake(&all);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{all:?}: {stderr}");
        assert!(stderr.contains(expected), "{all:?}: {stderr}");
    }
    assert!(!out.exists());
}
