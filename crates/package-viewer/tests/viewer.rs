//! The example renders packages of both codecs from their GPU textures exactly as the format
//! crate's CPU queries answer, and its binary writes the PNG it promises.

#[path = "../../mesobake-package/tests/support/mod.rs"]
mod support;

use mesobake_package::Package;
use mesobake_package::quantize::Quantization;
use mesobake_package_viewer::{Viewer, shade};

/// The GPU, or `None` when the GPU tests are skipped here (MESOBAKE_SKIP_GPU_TESTS=1).
fn viewer() -> Option<Viewer> {
    match Viewer::open(None) {
        Ok(v) => Some(v),
        Err(_) if std::env::var("MESOBAKE_SKIP_GPU_TESTS").as_deref() == Ok("1") => None,
        Err(e) => panic!("{e} (set MESOBAKE_SKIP_GPU_TESTS=1 to skip the GPU tests)"),
    }
}

fn packages() -> Vec<(&'static str, Vec<u8>)> {
    vec![
        ("occupancy", support::pillars()),
        (
            "paper-svd u8 rank 6",
            support::random_svd(6, Quantization::U8),
        ),
        (
            "paper-svd f16 rank 5",
            support::random_svd(5, Quantization::F16),
        ),
        (
            "paper-svd f32 rank 2",
            support::random_svd(2, Quantization::F32),
        ),
    ]
}

/// Every direction bin, every top-layer texel: the same hit or escape, distances within
/// 10⁻⁴ relative (the GPU sums in f32, the CPU queries in f32 and f64).
#[test]
fn gpu_depths_match_the_format_crates_queries() {
    let Some(viewer) = viewer() else { return };
    for (name, bytes) in packages() {
        let pkg = Package::parse(bytes).unwrap();
        let (dims, dirs) = (pkg.dims(), pkg.dirs());
        let query = pkg.query().unwrap();
        let (mut hits, mut escapes) = (0, 0);
        for a in 0..dirs.n_theta {
            for b in 0..dirs.n_phi {
                let gpu = viewer.top_layer(&pkg, a, b).unwrap();
                for j in 0..dims.y {
                    for i in 0..dims.x {
                        let cpu = query.distance(i, j, dims.z - 1, a, b);
                        let got = gpu[(j * dims.x + i) as usize];
                        match (got, cpu) {
                            (Some(g), Some(c)) if (g - c).abs() <= 1e-4 * (1.0 + c) => hits += 1,
                            (None, None) => escapes += 1,
                            _ => panic!(
                                "{name}: texel {i},{j} bin {a},{b}: GPU {got:?}, CPU {cpu:?}"
                            ),
                        }
                    }
                }
            }
        }
        assert!(
            hits > 100 && escapes > 100,
            "{name}: {hits} hits, {escapes} escapes"
        );
    }
}

#[test]
fn the_binary_writes_the_shaded_depth_view() {
    let Some(_) = viewer() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (path, out) = (dir.path().join("p.mbpkg"), dir.path().join("view.png"));
    std::fs::write(&path, support::pillars()).unwrap();
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_mesobake-package-viewer"))
        .arg(&path)
        .arg(&out)
        .args(["--view", "3,1", "--tiles", "3"])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(summary["codec"], "occupancy");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&out).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgb).unwrap();
    assert_eq!((reader.info().width, reader.info().height), (36, 30));
    // Each pixel is the shade of the CPU query at its texel, tiled.
    let pkg = Package::parse(support::pillars()).unwrap();
    let (dims, dirs, query) = (pkg.dims(), pkg.dirs(), pkg.query().unwrap());
    let cos = dirs.theta(3).cos().abs() as f32;
    for y in 0..30u32 {
        for x in 0..36u32 {
            let d = query.distance(x % dims.x, y % dims.y, dims.z - 1, 3, 1);
            let at = ((y * 36 + x) * 3) as usize;
            let want = shade(d, cos, dims.z);
            let got = &rgb[at..at + 3];
            assert!(
                got.iter().zip(want).all(|(g, w)| g.abs_diff(w) <= 1),
                "pixel {x},{y}"
            );
        }
    }
    // Bad input: a missing file and a bin off the grid are refused by name.
    for args in [
        vec!["missing.mbpkg", "x.png"],
        vec![path.to_str().unwrap(), "x.png", "--view", "9,0"],
    ] {
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_mesobake-package-viewer"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("missing.mbpkg") || stderr.contains("off the"),
            "{stderr}"
        );
    }
}
