//! The per-pixel GDM algorithm's accuracy knobs (`render::quality`) against the exact ground
//! truth, through `mesobake report quality`'s own code: on torus-chain (curved, closed, point
//! light) the `high` preset must reach the real-time issue's target, 30 dB PSNR and at most
//! 0.5 % mask disagreement, where the paper's algorithm stays below 20 dB; each knob alone
//! must buy what it is for. Images at 256² (the targets hold at the scenes' 512²:
//! docs/BENCHMARKS.md); the package is the scene's default (the exact occupancy march).

use mesobake_core::limits::Limits;
use mesobake_core::quality::Preset;
use mesobake_scene::render::load_scene;
use mesobake_scene::report::quality::{QualityRow, default_settings, quality_report};
use std::path::Path;

use crate::common::{each_fails_with, small_scene, succeeds};

fn report(scene: &str) -> Vec<QualityRow> {
    let limits = Limits::default();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut loaded = load_scene(&dir.join(scene), &limits).unwrap();
    let own = loaded.scene.quality;
    loaded.scene.camera.width = 256;
    loaded.scene.camera.height = 256;
    let mut scenes = vec![(scene.to_owned(), loaded, dir.as_path())];
    let report = quality_report(&mut scenes, &default_settings(), 0, &limits, &()).unwrap();
    eprintln!("{}", mesobake_scene::report::quality::markdown(&report));
    // The scene's own quality is left as it was.
    assert_eq!(scenes[0].1.scene.quality, own);
    report.rows
}

fn row<'a>(rows: &'a [QualityRow], label: &str) -> &'a QualityRow {
    rows.iter()
        .find(|r| r.quality == label)
        .unwrap_or_else(|| panic!("no row {label}"))
}

#[test]
fn the_high_preset_reaches_the_truth_on_torus_chain_and_each_knob_buys_its_part() {
    let rows = report("torus-chain.json");
    let paper = row(&rows, "paper");
    let high = row(&rows, "high");
    // The target (measured 33.2 dB, 0.14 %).
    assert!(high.psnr_db >= 30.0, "{high:?}");
    assert!(high.mask_disagreement <= 0.005, "{high:?}");
    // The paper's algorithm is far from it (17.9 dB, 1.1 %), or the knobs measure nothing.
    assert!(paper.psnr_db < 20.0, "{paper:?}");
    assert!(paper.mask_disagreement > 0.008, "{paper:?}");
    // Shell shadows: the other side of the torus and the neighbouring links shadow
    // (+6 dB measured); the mask is the same hits.
    let shell = row(&rows, "shell+chords1+mean");
    assert!(shell.psnr_db >= paper.psnr_db + 3.0, "{shell:?}");
    assert_eq!(shell.mask_disagreement, paper.mask_disagreement);
    // Chords: the silhouettes follow the curved shell (mask 1.08 % → 0.14 % at 8 chords).
    let chords = [2, 4, 8].map(|n| row(&rows, &format!("local+chords{n}+mean")));
    assert!(chords[0].mask_disagreement < paper.mask_disagreement);
    assert!(chords[1].mask_disagreement < chords[0].mask_disagreement);
    assert!(chords[2].mask_disagreement <= paper.mask_disagreement / 4.0);
    // The Jacobian frame: the exact normal and light direction, a small gain (0.25 dB).
    let frame = row(&rows, "local+chords1+jacobian");
    assert!(frame.psnr_db > paper.psnr_db, "{frame:?}");
    assert!(frame.flip_mean < paper.flip_mean, "{frame:?}");
    // The presets order the curve: each higher one closer to the truth.
    let balanced = row(&rows, Preset::Balanced.name());
    assert!(paper.psnr_db < balanced.psnr_db && balanced.psnr_db < high.psnr_db);
}

#[test]
fn the_knobs_do_not_hurt_an_open_gently_curved_surface() {
    // plane-weave: directional light, little curvature; the paper already does well (33.5
    // dB), and the knobs must keep that (high 35 dB measured).
    let rows = report("plane-weave.json");
    let paper = row(&rows, "paper");
    let high = row(&rows, "high");
    assert!(paper.psnr_db >= 30.0, "{paper:?}");
    assert!(high.psnr_db >= paper.psnr_db, "{high:?}");
    assert!(
        high.mask_disagreement <= paper.mask_disagreement,
        "{high:?}"
    );
}

#[test]
fn scenes_and_the_command_line_choose_the_quality_and_refuse_bad_ones() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_scene(dir.path());
    let text = std::fs::read_to_string(&scene).unwrap();
    let with = |name: &str, quality: &str| {
        let path = dir.path().join(format!("{name}.json"));
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        v["quality"] = serde_json::from_str(quality).unwrap();
        std::fs::write(&path, v.to_string()).unwrap();
        path
    };
    let out = dir.path().join("out.png");
    let out = out.to_str().unwrap();
    let high = with("high", r#""high""#);
    succeeds(&["render", "--scene", high.to_str().unwrap(), "--out", out]);
    let custom = with("custom", r#"{"preset": "balanced", "chords": 3}"#);
    succeeds(&["render", "--scene", custom.to_str().unwrap(), "--out", out]);
    let scene = scene.to_str().unwrap();
    succeeds(&[
        "render",
        "--scene",
        scene,
        "--quality",
        "high",
        "--out",
        out,
    ]);
    let bad_preset = with("bad-preset", r#""ultra""#);
    let bad_chords = with("bad-chords", r#"{"chords": 0}"#);
    let bad_key = with("bad-key", r#"{"chord": 4}"#);
    each_fails_with(&[
        (
            vec![
                "render",
                "--scene",
                bad_preset.to_str().unwrap(),
                "--out",
                out,
            ],
            "ultra",
        ),
        (
            vec![
                "render",
                "--scene",
                bad_chords.to_str().unwrap(),
                "--out",
                out,
            ],
            "quality.chords must be between 1 and 16, got 0",
        ),
        (
            vec!["render", "--scene", bad_key.to_str().unwrap(), "--out", out],
            "chord",
        ),
        (
            vec![
                "render",
                "--scene",
                scene,
                "--quality",
                "fast",
                "--out",
                out,
            ],
            "fast",
        ),
    ]);
}
