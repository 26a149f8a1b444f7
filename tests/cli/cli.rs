//! The command line, end to end: sample → gdm → .npy, checked with an independent reader.

use std::path::Path;

use crate::common::{each_fails_with, succeeds};

fn read_npy(path: &Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    (shape, npy.into_vec::<f32>().unwrap())
}

#[test]
fn sample_then_gdm_writes_the_documented_npy() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("grid.mbvol");
    succeeds(&[
        "sample",
        "grid",
        "--res",
        "16x16x8",
        "--out",
        vol.to_str().unwrap(),
    ]);
    for method in ["exact", "fast"] {
        let npy = dir.path().join(format!("{method}.npy"));
        let out = succeeds(&[
            "gdm",
            "--input",
            vol.to_str().unwrap(),
            "--dirs",
            "4x8",
            "--method",
            method,
            "--out",
            npy.to_str().unwrap(),
            "--json",
        ]);
        let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(summary["samples"], 16 * 16 * 8 * 32);
        let (shape, data) = read_npy(&npy);
        assert_eq!(shape, vec![16, 16, 8, 4, 8]);
        // Layer 0 (z = 0.5) of the grid sample is empty below the bars; looking straight down
        // (θ bin 3 of 4, cos θ < 0) from there escapes through the bottom: +inf.
        let idx = |x: usize, y: usize, z: usize, a: usize, b: usize| {
            (((x * 16 + y) * 8 + z) * 4 + a) * 8 + b
        };
        assert!(data[idx(0, 0, 0, 3, 0)].is_infinite());
        // Inside a bar (x-bar across y ∈ [0.4, 0.6], z ∈ [0.08, 0.28] of the unit tile) → 0.
        assert_eq!(data[idx(3, 8, 2, 0, 0)], 0.0);
        // Looking up from below the x-bar hits its underside: a finite distance.
        let up = data[idx(3, 8, 0, 0, 0)];
        assert!(up.is_finite() && up > 0.0 && up < 3.0, "{up}");
    }
}

#[test]
fn obj_tile_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("weave.obj");
    succeeds(&[
        "sample",
        "weave",
        "--res",
        "16x16x8",
        "--format",
        "obj",
        "--out",
        obj.to_str().unwrap(),
    ]);
    let npy = dir.path().join("w.npy");
    succeeds(&[
        "gdm",
        "--input",
        obj.to_str().unwrap(),
        "--res",
        "16x16x8",
        "--dirs",
        "4x8",
        "--out",
        npy.to_str().unwrap(),
    ]);
    let (shape, data) = read_npy(&npy);
    assert_eq!(shape, vec![16, 16, 8, 4, 8]);
    assert!(data.contains(&0.0) && data.iter().any(|v| v.is_infinite()));
}

#[test]
fn a_png_height_field_bakes_as_its_exact_surface() {
    let dir = tempfile::tempdir().unwrap();
    // 16×16, 8 bits: heights 0.75 for x < 8 and 0.25 beyond (6 and 2 voxels of 8).
    let png_path = dir.path().join("step.png");
    let pixels: Vec<u8> = (0..256)
        .map(|p| if p % 16 < 8 { 191 } else { 64 })
        .collect();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 16, 16);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .unwrap()
        .write_image_data(&pixels)
        .unwrap();
    std::fs::write(&png_path, &bytes).unwrap();
    let npy = dir.path().join("h.npy");
    succeeds(&[
        "gdm",
        "--input",
        png_path.to_str().unwrap(),
        "--res",
        "16x16x8",
        "--dirs",
        "4x8",
        "--out",
        npy.to_str().unwrap(),
    ]);
    let (shape, data) = read_npy(&npy);
    assert_eq!(shape, vec![16, 16, 8, 4, 8]);
    // Distance 0 (inside) exactly in the 16·16·6/2 + 16·16·2/2 voxels under the steps.
    let solid = data.chunks(32).filter(|d| d[0] == 0.0).count();
    assert_eq!(solid, 16 * 8 * 6 + 16 * 8 * 2);
    // Above the surface, looking up escapes (+inf); on the low step, looking down from
    // z = 4.5 meets the surface at z = 8·64/255 (the pixel's exact height, cast exactly).
    let idx =
        |x: usize, y: usize, z: usize, a: usize, b: usize| (((x * 16 + y) * 8 + z) * 4 + a) * 8 + b;
    assert!(data[idx(3, 3, 7, 0, 0)].is_infinite());
    let down = data[idx(12, 5, 4, 3, 0)];
    let surface = 8.0 * 64.0 / 255.0;
    let expected = (4.5 - surface) / (7.0 * std::f32::consts::PI / 8.0).cos().abs();
    assert!((down - expected).abs() < 1e-3, "{down} vs {expected}");
}

#[test]
fn bad_input_exits_non_zero_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nf 1 2 3\n").unwrap();
    let out_path = dir.path().join("x.npy");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "gdm",
                "--input",
                bad.to_str().unwrap(),
                "--res",
                "8x8x4",
                "--out",
                out_path.to_str().unwrap(),
            ],
            "out of bounds",
        ),
        (
            vec![
                "gdm",
                "--input",
                bad.to_str().unwrap(),
                "--out",
                out_path.to_str().unwrap(),
            ],
            "needs --res",
        ),
        (
            vec![
                "gdm",
                "--input",
                "/nonexistent.mbvol",
                "--res",
                "8x8x4",
                "--out",
                out_path.to_str().unwrap(),
            ],
            "No such file",
        ),
        (
            vec![
                "sample",
                "chain",
                "--res",
                "8x4x4",
                "--out",
                out_path.to_str().unwrap(),
            ],
            "X = Y",
        ),
        (
            vec![
                "--memory-limit",
                "1KiB",
                "sample",
                "chain",
                "--res",
                "16x16x8",
                "--out",
                out_path.to_str().unwrap(),
            ],
            "memory limit",
        ),
    ];
    each_fails_with(&cases);
    assert!(!out_path.exists(), "nothing is written on failure");
}

#[test]
fn inputs_are_recognized_by_content_not_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let volume = path("grid.mbvol");
    succeeds(&["sample", "grid", "--res", "8x8x4", "--out", &volume]);
    // A volume named like an OBJ bakes as the volume it is.
    let disguised = path("grid.obj");
    std::fs::copy(&volume, &disguised).unwrap();
    let npy = path("grid.npy");
    succeeds(&["gdm", "--input", &disguised, "--dirs", "2x4", "--out", &npy]);
    std::fs::write(path("fake.mbvol"), b"{\"resolution\": [8, 8, 4]}").unwrap();
    std::fs::write(path("notes.txt"), b"remember to bake the chain\n").unwrap();
    std::fs::write(path("tile.dat"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let out = path("x.npy");
    let gdm = |input: String| -> Vec<String> {
        ["gdm", "--input", &input, "--out", &out]
            .map(str::to_owned)
            .to_vec()
    };
    let cases = [
        (
            gdm(path("fake.mbvol")),
            "fake.mbvol is JSON text (though its name suggests a .mbvol volume), not a \
             mesostructure input",
        ),
        (gdm(path("notes.txt")), "notes.txt is text that is not OBJ"),
        (gdm(npy.clone()), "grid.npy is a NumPy .npy array"),
        (
            gdm(path("tile.dat")),
            "tile.dat is OBJ text; an OBJ tile needs --res",
        ),
    ];
    let cases: Vec<(Vec<&str>, &str)> = cases
        .iter()
        .map(|(args, want)| (args.iter().map(String::as_str).collect(), *want))
        .collect();
    each_fails_with(&cases);
    let out = crate::common::mesobake(
        &gdm(path("notes.txt"))
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.matches("invalid parameter").count(), 1, "{err}");
    // A scene file's error names the file once, and its kind once.
    std::fs::write(
        path("bad.json"),
        b"{\"resolution\": [8, 8, 4], \"bogus\": 1}",
    )
    .unwrap();
    let out = crate::common::mesobake(&[
        "render",
        "--scene",
        &path("bad.json"),
        "--out",
        &path("x.png"),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(err.matches("scene:").count(), 1, "{err}");
    assert_eq!(err.matches("bad.json").count(), 1, "{err}");
}

/// Runs `mesobake args` in `dir` under a pseudo-terminal (util-linux `script`) and returns
/// everything it wrote there.
fn on_a_terminal(dir: &Path, args: &[&str]) -> String {
    let quote = |s: &str| format!("'{}'", s.replace('\'', r"'\''"));
    let command: Vec<String> = std::iter::once(env!("CARGO_BIN_EXE_mesobake"))
        .chain(args.iter().copied())
        .map(quote)
        .collect();
    let out = std::process::Command::new("script")
        .args(["-qec", &command.join(" "), "/dev/null"])
        .current_dir(dir)
        .env("TERM", "xterm")
        .output()
        .expect("script (util-linux) runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{args:?}: {text}");
    text
}

/// Long work shows a labelled bar on a terminal (the bake, the truth render, the explicit
/// export; later stages' labels may go undrawn on work this small, bars redraw at most 20
/// times a second) and nothing of it when stderr is not one.
#[test]
fn long_work_shows_progress_on_a_terminal_only() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::common::small_scene(dir.path());
    let scene = scene.to_str().unwrap();
    let volume = dir.path().join("weave.mbvol");
    succeeds(&[
        "sample",
        "weave",
        "--res",
        "16x16x8",
        "--out",
        volume.to_str().unwrap(),
    ]);
    let cases: [(&[&str], &[&str]); 3] = [
        (
            &[
                "bake",
                "--input",
                "weave.mbvol",
                "--out",
                "w.mbpkg",
                "--gdm-codec",
                "paper-svd",
                "--dirs",
                "4x8",
            ],
            &["baking"],
        ),
        (
            &[
                "render", "--scene", scene, "--method", "truth", "--out", "t.png",
            ],
            &["rendering"],
        ),
        (
            &["explicit", "--scene", scene, "--out", "e.glb"],
            &["mapping prisms"],
        ),
    ];
    for (args, labels) in cases {
        let text = on_a_terminal(dir.path(), args);
        for label in labels {
            assert!(
                text.contains(&format!("{label} [")),
                "{args:?}: no {label:?} bar in {text:?}"
            );
        }
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_mesobake"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success() && !stderr.contains(" ["),
            "{args:?}: {stderr}"
        );
    }
}

/// `docs/cli.md` is the command line's reference as clap describes it (`mesobake
/// help-markdown`): it fails when an option or its help changed without the document.
/// `MESOBAKE_WRITE_DOCS=1` rewrites it instead.
#[test]
fn the_cli_reference_is_generated_from_the_parser() {
    let out = succeeds(&["help-markdown"]);
    let generated = String::from_utf8(out.stdout).unwrap();
    assert!(generated.contains("## `mesobake render`"), "{generated}");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/cli.md");
    if std::env::var_os("MESOBAKE_WRITE_DOCS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "docs/cli.md is stale: regenerate it with `mesobake help-markdown > docs/cli.md` \
         (or MESOBAKE_WRITE_DOCS=1 cargo test --release --test cli)"
    );
}
