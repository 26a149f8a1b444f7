//! Running the `mesobake` binary from integration tests.
#![allow(dead_code)] // each test file uses part of it

use std::process::{Command, Output};

/// Runs `mesobake` with `args`.
pub fn mesobake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mesobake"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs `mesobake` with `args` and asserts success, showing stderr otherwise.
pub fn succeeds(args: &[&str]) -> Output {
    let out = mesobake(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Asserts that each command fails with a message containing its expected text, and never
/// with a panic.
pub fn each_fails_with(cases: &[(Vec<&str>, &str)]) {
    for (args, want) in cases {
        let out = mesobake(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// Writes `plane-weave` shrunk to a 16×16×8 grid, 4×8 directions and a 48×32 image into
/// `dir` as `small.json`: a scene every report can sweep in seconds.
pub fn small_scene(dir: &std::path::Path) -> std::path::PathBuf {
    let sample = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/plane-weave.json");
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sample).unwrap()).unwrap();
    scene["resolution"] = serde_json::json!([16, 16, 8]);
    scene["directions"] = serde_json::json!([4, 8]);
    scene["camera"]["width"] = 48.into();
    scene["camera"]["height"] = 32.into();
    let path = dir.join("small.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    path
}
