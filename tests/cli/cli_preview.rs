//! `mesobake preview` end to end: every sample scene renders; a package baked by `mesobake
//! bake` previews like `mesobake render --package` draws it; bad requests fail clearly.
//! Needs a GPU adapter (CI installs Mesa's software Vulkan driver); MESOBAKE_SKIP_GPU_TESTS=1
//! skips these tests loudly.

use crate::common::{each_fails_with, succeeds};
use std::path::Path;

fn skip() -> bool {
    let skip = std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1");
    if skip {
        eprintln!("SKIPPED: MESOBAKE_SKIP_GPU_TESTS=1");
    }
    skip
}

/// Scene `name` from `scenes/`, made small (grids and image) so that it bakes and renders
/// in about a second.
fn small_scene(name: &str) -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["resolution"] = serde_json::json!([16, 16, 8]);
    scene["directions"] = serde_json::json!([8, 16]);
    let (w, h) = (
        scene["camera"]["width"].as_u64().unwrap(),
        scene["camera"]["height"].as_u64().unwrap(),
    );
    scene["camera"]["width"] = (w / 4).into();
    scene["camera"]["height"] = (h / 4).into();
    scene
}

#[test]
fn every_sample_scene_previews() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut names: Vec<String> =
        std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".json"))
            .collect();
    names.sort();
    assert!(names.len() >= 5, "{names:?}");
    for name in &names {
        let scene = small_scene(name);
        let scene_path = dir.path().join(name);
        std::fs::write(&scene_path, scene.to_string()).unwrap();
        let out = dir.path().join(name.replace(".json", ".png"));
        let medium = scene["mesostructure"].get("medium").is_some();
        let environment = scene["effects"]
            .as_array()
            .unwrap()
            .contains(&"environment_lighting".into());
        if environment {
            // The CPU renders the same scene's GI from its own bake (the uncompressed GDM
            // and its RTV; without the option it renders the scene's package, as preview).
            let o = succeeds(&[
                "render",
                "--scene",
                scene_path.to_str().unwrap(),
                "--method",
                "gdm",
                "--gdm-codec",
                "uncompressed",
                "--out",
                out.to_str().unwrap(),
                "--json",
            ]);
            let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert!(json["gi"]["rtv"]["samples"].as_u64().unwrap() > 0, "{json}");
            assert!(json["hit_pixels"].as_u64().unwrap() > 0, "{json}");
        }
        let o = succeeds(&[
            "preview",
            "--scene",
            scene_path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--frames",
            "2",
            "--json",
        ]);
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        if medium {
            // Translucent samples render in WGSL, shadows from deep maps, within the software
            // driver's loop budget (tests/scene/medium_preview.rs).
            assert_eq!(json["renderer"], "gpu", "{name}: {json}");
            assert_eq!(json["technique"], "transparency", "{name}: {json}");
        }
        let pixels = json["width"].as_u64().unwrap() * json["height"].as_u64().unwrap();
        let hits = json["hit_pixels"].as_u64().unwrap();
        assert!(
            hits * 20 > pixels && hits < pixels,
            "{name}: {hits} of {pixels}"
        );
        let p = &json["preview"];
        assert!(
            p["mean_frame_seconds"].as_f64().unwrap() > 0.0,
            "{name}: {p}"
        );
        // A height field on a closed surface renders by VDM (auto), a translucent medium by
        // the media pipeline, every other scene by GDM.
        let relief_on_torus = scene["mesostructure"].get("relief").is_some()
            && scene["base_mesh"]["builtin"].get("torus").is_some();
        let technique = match (medium, relief_on_torus) {
            (true, _) => "transparency",
            (false, true) => "vdm",
            (false, false) => "gdm",
        };
        assert_eq!(json["technique"], technique, "{name}: {json}");
        assert_eq!(p["technique"], technique, "{name}: {p}");
        if medium {
            // No package: the medium itself is uploaded.
            assert_eq!(p["memory"]["package"], 0, "{name}: {p}");
            assert!(p["memory"]["material"].as_u64().unwrap() > 0, "{name}: {p}");
            continue;
        }
        if relief_on_torus {
            // One pipeline, no variant; the package is the factors and the heights.
            assert!(p["variant"].is_null(), "{name}: {p}");
            assert!(
                p["memory"]["package"].as_u64().unwrap() > 16 * 16 * 4,
                "{name}: {p}"
            );
            assert!(std::fs::metadata(&out).unwrap().len() > 0);
            continue;
        }
        // Shadows where a scene asks for them: the paper's local query, or traced through
        // the shell where its quality says so (torus-chain: `balanced`).
        let shadows = scene["effects"]
            .as_array()
            .unwrap()
            .contains(&"shadows".into());
        let shell = matches!(scene["quality"].as_str(), Some("balanced" | "high"));
        assert_eq!(
            p["variant"]["shadows"],
            match (shadows, shell) {
                (false, _) => serde_json::Value::Null,
                (true, false) => "local".into(),
                (true, true) => "shell".into(),
            },
            "{name}: {p}"
        );
        assert_eq!(p["variant"]["environment"], environment);
        assert_eq!(
            p["memory"]["environment"].as_u64().unwrap() > 0,
            environment,
            "{name}: {p}"
        );
        // The default codec over a 16×16×8 grid: one r8uint texel per voxel.
        assert_eq!(p["variant"]["codec"], "occupancy");
        assert_eq!(p["memory"]["package"].as_u64().unwrap(), 16 * 16 * 8);
        assert!(std::fs::metadata(&out).unwrap().len() > 0);
    }
}

#[test]
fn a_baked_package_previews_as_the_cpu_renderer_draws_it() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    succeeds(&[
        "sample",
        "weave",
        "--res",
        "16x16x8",
        "--out",
        &path("weave.mbvol"),
    ]);
    succeeds(&[
        "bake",
        "--input",
        &path("weave.mbvol"),
        "--dirs",
        "8x16",
        "--gdm-codec",
        "paper-svd",
        "--rank",
        "5",
        "--quant",
        "u8",
        "--out",
        &path("weave.mbpkg"),
    ]);
    let mut scene = small_scene("plane-weave.json");
    scene["mesostructure"] = serde_json::json!({ "volume": "weave.mbvol" });
    std::fs::write(path("scene.json"), scene.to_string()).unwrap();
    succeeds(&[
        "preview",
        "--scene",
        &path("scene.json"),
        "--package",
        &path("weave.mbpkg"),
        "--out",
        &path("gpu.exr"),
    ]);
    succeeds(&[
        "render",
        "--scene",
        &path("scene.json"),
        "--method",
        "gdm",
        "--package",
        &path("weave.mbpkg"),
        "--out",
        &path("cpu.exr"),
    ]);
    let o = succeeds(&["compare", &path("gpu.exr"), &path("cpu.exr"), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let psnr = c["psnr_db"].as_f64().unwrap_or(f64::INFINITY);
    assert!(
        psnr >= 35.0 && c["mask_disagreement"].as_f64().unwrap() <= 0.005,
        "{c}"
    );
}

#[test]
fn bad_preview_requests_fail_clearly() {
    if skip() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    std::fs::write(
        path("scene.json"),
        small_scene("torus-chain.json").to_string(),
    )
    .unwrap();
    succeeds(&[
        "sample",
        "chain",
        "--res",
        "32x32x16",
        "--out",
        &path("chain.mbvol"),
    ]);
    succeeds(&[
        "bake",
        "--input",
        &path("chain.mbvol"),
        "--dirs",
        "8x16",
        "--out",
        &path("chain.mbpkg"),
    ]);
    std::fs::write(path("junk.mbpkg"), b"not a package").unwrap();
    let scene = path("scene.json");
    let out = path("out.png");
    // A package of another mesostructure on the scene's grid: refused unless --force.
    succeeds(&[
        "sample",
        "weave",
        "--res",
        "16x16x8",
        "--out",
        &path("weave.mbvol"),
    ]);
    succeeds(&[
        "bake",
        "--input",
        &path("weave.mbvol"),
        "--dirs",
        "8x16",
        "--out",
        &path("weave.mbpkg"),
    ]);
    let other = path("weave.mbpkg");
    let forced_out = path("forced.png");
    let forced = |command: &str| {
        let mut args = vec![
            command,
            "--scene",
            &scene,
            "--package",
            &other,
            "--out",
            &forced_out,
        ];
        if command == "render" {
            args.extend(["--method", "gdm"]);
        }
        succeeds(&[&args[..], &["--force"]].concat());
    };
    forced("preview");
    forced("render");
    assert!(Path::new(&forced_out).is_file());
    each_fails_with(&[
        (
            vec![
                "preview",
                "--scene",
                &scene,
                "--out",
                &out,
                "--package",
                &other,
            ],
            "weave.mbpkg: the package was baked from another mesostructure (volume input",
        ),
        (
            vec![
                "render",
                "--scene",
                &scene,
                "--out",
                &out,
                "--package",
                &other,
            ],
            "pass --force to render it anyway",
        ),
        (
            vec!["preview", "--scene", &scene, "--out", &out, "--force"],
            "--package",
        ),
        (
            vec![
                "preview",
                "--scene",
                &scene,
                "--out",
                &out,
                "--adapter",
                "no-such-gpu-anywhere",
            ],
            "no adapter's name contains \"no-such-gpu-anywhere\"",
        ),
        (
            vec![
                "preview",
                "--scene",
                &scene,
                "--out",
                &out,
                "--package",
                &path("chain.mbpkg"),
            ],
            "resolution",
        ),
        (
            vec![
                "preview",
                "--scene",
                &scene,
                "--out",
                &out,
                "--package",
                &path("junk.mbpkg"),
            ],
            "package",
        ),
        (
            vec!["preview", "--scene", &path("missing.json"), "--out", &out],
            "missing.json",
        ),
    ]);
    // No adapter at all (WGPU_BACKEND names a backend this build lacks): by default the CPU
    // twin renders and says so; with --fallback none, a clear error.
    let no_adapter = |extra: &[&str], image: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_mesobake"))
            .args(
                [
                    &["preview", "--scene", &scene, "--out", image, "--json"][..],
                    extra,
                ]
                .concat(),
            )
            .env("WGPU_BACKEND", "gl")
            .env_remove("MESOBAKE_ADAPTER")
            .output()
            .unwrap()
    };
    let o = no_adapter(&["--fallback", "none"], &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no GPU adapter available"),
        "{err}"
    );
    assert!(
        err.contains("mesa-vulkan-drivers") && !err.contains("panicked"),
        "{err}"
    );
    let cpu_out = path("cpu.png");
    let default_package = path("default.mbpkg");
    succeeds(&["bake", "--scene", &scene, "--out", &default_package]);
    let o = no_adapter(&["--package", &default_package], &cpu_out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["renderer"], "cpu", "{json}");
    assert!(
        json["fallback_reason"]
            .as_str()
            .unwrap()
            .contains("no GPU adapter available")
    );
    assert!(json["preview"].is_null() && json["hit_pixels"].as_u64().unwrap() > 0);
    // The CPU twin is the renderer the WGSL follows: the image `render --method gdm` draws
    // from the same package, pixel for pixel.
    succeeds(&[
        "render",
        "--scene",
        &scene,
        "--method",
        "gdm",
        "--package",
        &default_package,
        "--out",
        &path("gdm.png"),
    ]);
    let o = succeeds(&["compare", &cpu_out, &path("gdm.png"), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(c["mask_disagreement"], 0.0, "{c}");
    assert_eq!(c["mean_abs_error"], 0.0, "{c}");
    assert!(!Path::new(&out).exists(), "a failed preview wrote an image");
}
