//! Global illumination end to end: scene bakes run exactly the stages the effects call for,
//! packages carry the compressed RTV and the PRT deterministically, and shading from a package
//! agrees with shading from the bake.

use crate::common::{each_fails_with, succeeds};
use glam::DVec3;
use mesobake_bake::gi::compressed_rtv::CompressedRtv;
use mesobake_bake::gi::rtv::NO_SAMPLE;
use mesobake_bake::package::Package;
use mesobake_core::limits::Limits;
use mesobake_scene::gi;
use mesobake_scene::package::{ScenePackageParams, bake_scene_package};
use mesobake_scene::render::load_scene;
use std::path::{Path, PathBuf};

/// A small GI scene (wavy plane, weave 32×32×16, 16×32 directions, overcast sky, glossy
/// material) with `effects`, written into `dir`.
fn write_scene(dir: &Path, effects: &[&str], segments: u32) -> PathBuf {
    let scene = serde_json::json!({
        "base_mesh": { "builtin": { "plane": {
            "size": 2.0, "amplitude": 0.1, "waves": 1.0, "segments": segments } } },
        "mesostructure": { "sample": "weave" },
        "resolution": [32, 32, 16],
        "directions": [16, 32],
        "shell": { "thickness": 0.125, "tiles_per_uv": [4, 4] },
        "material": { "albedo": [0.7, 0.6, 0.5], "specular": [0.25, 0.25, 0.25], "shininess": 24 },
        "camera": { "eye": [0.3, 1.6, 2.4], "target": [0, 0, 0], "fov_y_degrees": 50,
                    "width": 48, "height": 32 },
        "environment": { "sky": { "overcast": {
            "zenith": [1.0, 1.0, 1.1], "ground": [0.2, 0.2, 0.2] } } },
        "effects": effects,
    });
    let path = dir.join(format!("scene-{segments}.json"));
    std::fs::write(&path, scene.to_string()).unwrap();
    path
}

const GI: &[&str] = &[
    "silhouettes",
    "environment_lighting",
    "macro_shadows",
    "environment_gloss",
];

#[test]
fn a_scene_bake_runs_exactly_the_stages_its_effects_call_for() {
    let dir = tempfile::tempdir().unwrap();
    let stages_with = |effects: &[&str], options: &[&str]| {
        let scene = write_scene(dir.path(), effects, 8);
        let out = dir.path().join("p.mbpkg");
        let args = [
            "bake",
            "--scene",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        let stdout = succeeds(&[&args[..], &["--json"], options].concat()).stdout;
        let summary: serde_json::Value = serde_json::from_slice(&stdout).unwrap();
        let manifest = Package::read(&out, &Limits::default())
            .unwrap()
            .manifest()
            .clone();
        (summary, manifest)
    };
    let stages = |effects: &[&str]| stages_with(effects, &[]);
    let names = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap().to_owned())
            .collect()
    };

    let (summary, manifest) = stages(GI);
    assert_eq!(
        names(&summary["plan"]["stages"]),
        [
            "load",
            "bake_gdm",
            "occupancy",
            "bake_prt",
            "bake_rtv",
            "compress_rtv",
            "encode"
        ]
    );
    let no_compress = serde_json::json!({
        "stage": "compress", "reason": "the codec is occupancy: no GDM is stored"
    });
    assert_eq!(summary["plan"]["skipped"], serde_json::json!([no_compress]));
    for stage in ["bake_prt", "bake_rtv", "compress_rtv"] {
        assert!(
            summary["seconds"][stage].as_f64().unwrap() >= 0.0,
            "{stage}"
        );
    }
    let gi = manifest
        .gi
        .expect("the package holds the radiance transfer");
    assert!(gi.glossy.is_some() && gi.macro_shadows);
    assert_eq!(summary["gi"]["rtv"]["samples"], gi.samples);

    // Lambertian, unshadowed: the same stages, with the parts not called for skipped.
    let (summary, manifest) = stages(&["silhouettes", "environment_lighting"]);
    let skipped = &summary["plan"]["skipped"];
    assert_eq!(
        skipped,
        &serde_json::json!([
            no_compress,
            { "stage": "prt_visibility",
              "reason": "the scene calls for no macro_shadows: the PRT is a pure rotation" },
            { "stage": "rtv_gloss",
              "reason": "the scene calls for no environment_gloss: the RTV is Lambertian" },
        ])
    );
    let gi = manifest.gi.unwrap();
    assert!(gi.glossy.is_none() && !gi.macro_shadows);
    assert_eq!(
        gi.compression.rank, 1,
        "a Lambertian RTV is view-independent"
    );

    // No environment lighting: no radiance-transfer stage runs and the package has none;
    // the occupancy codec needs no GDM at all, the paper's codec bakes and compresses one.
    for (options, stages_run, skipped_first, prefix) in [
        (
            &[][..],
            &["load", "occupancy", "encode"][..],
            &["bake_gdm", "compress"][..],
            "occupancy.",
        ),
        (
            &["--gdm-codec", "paper-svd", "--rank", "4"][..],
            &["load", "bake_gdm", "compress", "encode"][..],
            &["occupancy"][..],
            "gdm.",
        ),
    ] {
        let (summary, manifest) = stages_with(&["silhouettes", "shadows"], options);
        assert_eq!(names(&summary["plan"]["stages"]), stages_run);
        let skipped = summary["plan"]["skipped"].as_array().unwrap();
        let gi_stages = ["bake_prt", "bake_rtv", "compress_rtv"];
        assert_eq!(
            skipped
                .iter()
                .map(|s| s["stage"].as_str().unwrap())
                .collect::<Vec<_>>(),
            [skipped_first, &gi_stages[..]].concat()
        );
        for s in &skipped[skipped_first.len()..] {
            assert_eq!(s["reason"], "the scene calls for no environment_lighting");
        }
        for stage in skipped.iter().map(|s| s["stage"].as_str().unwrap()) {
            assert!(summary["seconds"].get(stage).is_none(), "{stage}");
        }
        assert!(manifest.gi.is_none());
        assert!(manifest.sections.iter().all(|s| s.name.starts_with(prefix)));
        assert!(summary["gi"].is_null());
    }
}

#[test]
fn gi_packages_are_deterministic_and_shade_like_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits::default();
    let path = write_scene(dir.path(), GI, 8);
    // Every RTV component (rank 16 is exact): what is left is f16 and the bilinear
    // interpolation of the eigenfunctions between view bins.
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    json["gi"] = serde_json::json!({ "rtv_rank": 16 });
    std::fs::write(&path, json.to_string()).unwrap();
    let loaded = load_scene(&path, &limits).unwrap();
    let params = ScenePackageParams::default();
    let bake = || {
        bake_scene_package(&loaded, dir.path(), params, &limits, &())
            .unwrap()
            .bytes
    };
    let bytes = bake();
    assert_eq!(bytes, bake(), "identical scenes give identical packages");
    let package = Package::parse(bytes).unwrap();
    let gi = package.manifest().gi.clone().unwrap();
    assert_eq!(gi.compression.rank, 16);

    // The format crate's reading at view-bin centres (what the C ABI answers) against the
    // renderers' (the compressed RTV with its bilinear view interpolation, in f64) on every
    // sample voxel and every fourth bin: the two differ by f32 round-off alone.
    let transfer = package.radiance_transfer().unwrap().unwrap();
    let (dims, dirs) = (package.dims(), package.dirs());
    let rtv = CompressedRtv::from_parts(
        dims,
        dirs,
        16,
        transfer.sample_of.clone(),
        transfer.weights.clone(),
        transfer.eigen.clone(),
    )
    .unwrap();
    let (mut worst, mut compared) = (0.0f64, 0);
    for (voxel, &s) in transfer.sample_of.iter().enumerate() {
        if s == NO_SAMPLE {
            continue;
        }
        let (i, j, k) = (
            voxel as u32 % dims.x,
            voxel as u32 / dims.x % dims.y,
            voxel as u32 / dims.x / dims.y,
        );
        for bin in (0..dirs.count()).step_by(4) {
            let [a, b] = [bin as u32 / dirs.n_phi, bin as u32 % dirs.n_phi];
            let ours = transfer.transfer_at_bin([i, j, k], [a, b]).unwrap();
            let theirs = rtv.transfer(s as usize, DVec3::from(dirs.vector(a, b)));
            for (x, y) in ours.as_flattened().iter().zip(theirs.as_flattened()) {
                worst = worst.max((f64::from(*x) - y).abs() / (1.0 + y.abs()));
            }
            compared += 1;
        }
    }
    assert!(compared > 10_000, "{compared}");
    assert!(worst < 1e-5, "{worst}");

    // Shading from the package against shading from the exact bake, at texture points all
    // over the tile and views above the surface.
    let exact = gi::bake_shading(
        &loaded,
        &loaded.bake_gdm(&limits, &()).unwrap(),
        &limits,
        &(),
    )
    .unwrap()
    .0;
    let packaged = gi::shading_from_package(&loaded, &package).unwrap();
    let (mut diff2, mut norm2, mut hits) = (0.0, 0.0, 0);
    for i in 0..32 {
        for j in 0..32 {
            for view in [
                DVec3::new(0.0, 0.0, -1.0),
                DVec3::new(0.5, 0.2, -0.8).normalize(),
                DVec3::new(-0.3, 0.6, -0.6).normalize(),
            ] {
                let t = DVec3::new(i as f64 + 0.5, j as f64 + 0.5, 8.3);
                let (a, b) = (exact.radiance(0, t, view), packaged.radiance(0, t, view));
                diff2 += (a - b).length_squared();
                norm2 += a.length_squared();
                hits += usize::from(a != DVec3::ZERO);
            }
        }
    }
    assert!(hits > 1000, "{hits} lit points");
    let relative = (diff2 / norm2).sqrt();
    // Measured 2.1e-2, nearly all of it the bilinear interpolation between view bins (the
    // f16 transfer error the manifest reports is 3e-4); 3e-2 is the bound.
    assert!(relative < 3e-2, "{relative}");
    assert!(gi.compression.relative_rmse < 1e-3, "{:?}", gi.compression);

    // The PRT belongs to its base mesh.
    let other = load_scene(&write_scene(dir.path(), GI, 9), &limits).unwrap();
    let err = gi::shading_from_package(&other, &package).err().unwrap();
    assert!(err.to_string().contains("another base mesh"), "{err}");
    // A package without radiance transfer says how to make one.
    let plain = write_scene(dir.path(), &["silhouettes"], 8);
    let plain = load_scene(&plain, &limits).unwrap();
    let bytes = bake_scene_package(&plain, dir.path(), params, &limits, &())
        .unwrap()
        .bytes;
    let err = gi::shading_from_package(&loaded, &Package::parse(bytes).unwrap())
        .err()
        .unwrap();
    assert!(err.to_string().contains("--scene"), "{err}");
}

#[test]
fn scene_bakes_refuse_bad_knobs_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), GI, 8);
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    json["gi"] = serde_json::json!({ "rtv_rank": 17 });
    let bad_rank = dir.path().join("bad-rank.json");
    std::fs::write(&bad_rank, json.to_string()).unwrap();
    json["gi"] = serde_json::json!({});
    json["effects"] = serde_json::json!(["environment_gloss"]);
    let gloss_alone = dir.path().join("gloss-alone.json");
    std::fs::write(&gloss_alone, json.to_string()).unwrap();
    let out = dir.path().join("p.mbpkg");
    let (scene, out) = (scene.to_str().unwrap(), out.to_str().unwrap());
    each_fails_with(&[
        (
            vec!["bake", "--scene", bad_rank.to_str().unwrap(), "--out", out],
            "rtv_rank 1–16",
        ),
        (
            vec![
                "bake",
                "--scene",
                gloss_alone.to_str().unwrap(),
                "--out",
                out,
            ],
            "environment_gloss and macro_shadows refine environment_lighting",
        ),
        (
            vec!["bake", "--scene", scene, "--out", out, "--max-rmse", "0.1"],
            "cannot be used with",
        ),
        (vec!["bake", "--out", out], "--input FILE is required"),
    ]);
    assert!(!Path::new(out).exists(), "nothing is written on failure");
}
