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

/// The adapter, or `None` (loudly) where there is none and MESOBAKE_SKIP_GPU_TESTS=1.
pub fn gpu() -> Option<mesobake_gpu::gpu::Gpu> {
    match mesobake_gpu::gpu::Gpu::open(None) {
        Ok(gpu) => Some(gpu),
        Err(e) if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") => {
            eprintln!("SKIPPED: no GPU adapter ({e}) and MESOBAKE_SKIP_GPU_TESTS=1");
            None
        }
        Err(e) => panic!("{e} (set MESOBAKE_SKIP_GPU_TESTS=1 to skip the GPU tests)"),
    }
}

/// Validates WGSL `source` with naga (every validation, every capability) and returns its
/// entry points' names.
pub fn naga_entry_points(source: &str) -> Vec<String> {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{e:?}"));
    module.entry_points.iter().map(|e| e.name.clone()).collect()
}
