//! The default package against the uncompressed GDM on every sample scene (the packages
//! issue's target): rendered by the CPU GDM renderer, both are compared with the ground truth,
//! and the default package must come within 0.5 dB PSNR of the uncompressed GDM's image (or
//! closer to the truth) with at most 0.3 points more mask disagreement, in at most 2.2 MB. The
//! images are scaled down to 128 pixels per side to keep the suite fast; the grids are the
//! scenes' own. Scenes lit by an environment only are left out: their truth is the path
//! tracer, and their GDM part is the one of the same mesostructure under point lights.

use mesobake::report::codecs::{CodecSweep, codec_report};
use mesobake::scene::Effect;
use mesobake::scene::render::load_scene;
use mesobake::util::limits::Limits;
use std::path::Path;

mod common;
use common::{each_fails_with, succeeds};

#[test]
fn the_default_package_renders_like_the_uncompressed_gdm_on_every_sample_scene() {
    let limits = Limits::default();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let mut loaded = load_scene(&path, &limits).unwrap();
        if loaded.scene.wants(Effect::EnvironmentLighting) {
            continue;
        }
        let camera = &mut loaded.scene.camera;
        let scale = 128.0 / camera.width.max(camera.height) as f64;
        camera.width = (camera.width as f64 * scale).round() as u32;
        camera.height = (camera.height as f64 * scale).round() as u32;
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        scenes.push((name, loaded, dir.as_path()));
    }
    scenes.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(scenes.len() >= 5, "{} sample scenes", scenes.len());
    let sweep = CodecSweep {
        ranks: vec![],
        quantization: Default::default(),
        tiles: vec![],
        frames: 0,
    };
    let report = codec_report(&scenes, &sweep, &limits, &()).unwrap();
    eprintln!("{}", mesobake::report::codecs::markdown(&report));
    for pair in report.rows.chunks(2) {
        let [uncompressed, default] = pair else {
            panic!("rows come in pairs: {pair:?}")
        };
        assert_eq!(
            (uncompressed.codec.as_str(), default.codec.as_str()),
            ("uncompressed", "occupancy")
        );
        let scene = &default.scene;
        assert!(
            default.bytes <= 2_200_000,
            "{scene}: {} bytes",
            default.bytes
        );
        assert!(
            default.psnr_db >= uncompressed.psnr_db - 0.5,
            "{scene}: {:.2} dB against {:.2} dB uncompressed",
            default.psnr_db,
            uncompressed.psnr_db
        );
        assert!(
            default.mask_disagreement <= uncompressed.mask_disagreement + 0.003,
            "{scene}: mask {} against {}",
            default.mask_disagreement,
            uncompressed.mask_disagreement
        );
        // On volumes the march answers the exact GDM at every sample.
        assert_eq!(default.flip_rate, 0.0, "{scene}");
        assert!(default.hit_rmse < 1e-4, "{scene}: {}", default.hit_rmse);
    }
}

#[test]
fn report_codecs_writes_the_table_json_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/plane-weave.json"),
        )
        .unwrap(),
    )
    .unwrap();
    scene["resolution"] = serde_json::json!([16, 16, 8]);
    scene["directions"] = serde_json::json!([4, 8]);
    scene["camera"]["width"] = 48.into();
    scene["camera"]["height"] = 32.into();
    let path = dir.path().join("small.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    let out = dir.path().join("report");
    let o = succeeds(&[
        "report",
        "codecs",
        "--scenes",
        path.to_str().unwrap(),
        "--ranks",
        "2,4",
        "--tiles",
        "8",
        "--frames",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    let table = String::from_utf8(o.stdout).unwrap();
    assert_eq!(
        table,
        std::fs::read_to_string(out.join("codecs.md")).unwrap()
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("codecs.json")).unwrap()).unwrap();
    let rows = report["rows"].as_array().unwrap();
    let codecs: Vec<&str> = rows.iter().map(|r| r["codec"].as_str().unwrap()).collect();
    assert_eq!(
        codecs,
        [
            "uncompressed",
            "occupancy",
            "paper-svd",
            "paper-svd",
            "tiled-svd",
            "tiled-svd"
        ]
    );
    assert_eq!(rows[2]["setting"], "rank 2 f16");
    assert_eq!(rows[4]["setting"], "8×8 tiles, rank 2 f16");
    // Tiles fit better than one basis at the same rank (the weight maps' bytes are equal).
    assert!(rows[4]["flip_rate"].as_f64() <= rows[2]["flip_rate"].as_f64());
    // The uncompressed GDM is 4 bytes per sample; the SVD flips samples, the march none.
    assert_eq!(rows[0]["bytes"], 16 * 16 * 8 * 4 * 8 * 4);
    assert!(rows[2]["flip_rate"].as_f64().unwrap() > 0.0);
    assert_eq!(rows[1]["flip_rate"], 0.0);
    let svg = std::fs::read_to_string(out.join("codecs.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("paper-svd"),
        "{svg:.200}"
    );
    let (scene, out) = (path.to_str().unwrap(), out.to_str().unwrap());
    let missing = dir.path().join("missing.json");
    each_fails_with(&[
        (
            vec![
                "report", "codecs", "--scenes", scene, "--ranks", "0", "--out", out,
            ],
            "rank must be in 1..=64, got 0",
        ),
        (
            vec![
                "report",
                "codecs",
                "--scenes",
                missing.to_str().unwrap(),
                "--out",
                out,
            ],
            "missing.json",
        ),
    ]);
}
