//! Builds `tests/reader.c` against the static library and the generated header, runs it on
//! packages of both codecs, and compares what it prints with the Rust reader's answers.

use mesobake_package::Package;
use mesobake_package::quantize::Quantization;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../mesobake-package/tests/support/mod.rs"]
mod support;

/// Three packages: pillars on a floor (occupancy), pseudo-random u8 factors (paper-svd), and
/// the pillars with a synthetic radiance transfer.
fn packages() -> Vec<Vec<u8>> {
    let (info, transfer) = support::radiance_transfer(3);
    vec![
        support::pillars(),
        support::random_svd(3, Quantization::U8),
        support::pillars_with_gi(info, &transfer),
    ]
}

/// Values as reader.c prints them: six decimals, space-separated, one line.
fn line(values: &[f32]) -> String {
    let values: Vec<String> = values.iter().map(|v| format!("{v:.6}")).collect();
    values.join(" ") + "\n"
}

/// What reader.c must print for `bytes`, from the Rust reader.
fn expected(bytes: &[u8]) -> String {
    let pkg = Package::parse(bytes.to_vec()).unwrap();
    let (dims, dirs) = (pkg.dims(), pkg.dirs());
    let m = pkg.manifest();
    let mut out = format!(
        "codec {}\ngrid {}x{}x{} dirs {}x{}\nmanifest ok\n",
        u32::from(m.codec == mesobake_package::manifest::GdmCodec::PaperSvd),
        dims.x,
        dims.y,
        dims.z,
        dirs.n_theta,
        dirs.n_phi
    );
    for s in &m.sections {
        let data = pkg.section(&s.name).unwrap();
        let sum = data
            .iter()
            .fold(0u32, |h, &b| h.wrapping_mul(31).wrapping_add(b as u32));
        let t = s.texture;
        let dimension = serde_json::to_value(t.dimension).unwrap();
        let dimension = ["2d", "3d", "buffer"]
            .iter()
            .position(|d| dimension == *d)
            .unwrap();
        let format = serde_json::to_value(t.format).unwrap();
        let format = [
            "r32float",
            "rg32float",
            "rgba32float",
            "r16float",
            "rg16float",
            "rgba16float",
            "r8unorm",
            "rg8unorm",
            "rgba8unorm",
            "r8uint",
            "r32uint",
        ]
        .iter()
        .position(|f| format == *f)
        .unwrap();
        out += &format!(
            "section {} dimension {dimension} format {format} {}x{}x{} bytes {} sum {sum:08x}\n",
            s.name,
            t.width,
            t.height,
            t.depth,
            data.len()
        );
    }
    let query = pkg.query().unwrap();
    let k = dims.z / 2;
    for a in 0..dirs.n_theta {
        for b in 0..dirs.n_phi {
            for j in 0..dims.y {
                for i in 0..dims.x {
                    out += &match query.distance(i, j, k, a, b) {
                        Some(d) => format!("{d:.6}\n"),
                        None => "escape\n".into(),
                    };
                }
            }
        }
    }
    match pkg.radiance_transfer() {
        None => out += "no radiance transfer\n",
        Some(transfer) => {
            let transfer = transfer.unwrap();
            let view = [dirs.n_theta - 1, dirs.n_phi - 1];
            for j in 0..dims.y {
                for i in 0..dims.x {
                    out += &match transfer.transfer_at_bin([i, j, k], view) {
                        Some(t) => line(t.as_flattened()),
                        None => "not a sample\n".into(),
                    };
                }
            }
            let mut v = 0;
            while let Some(matrix) = transfer.prt_matrix(v) {
                out += &line(matrix);
                v += 1;
            }
            out += &format!("{v} vertices\n");
        }
    }
    out
}

/// Builds the static library (`cargo test` builds only the rlib) in its own target
/// directory beside this test's, so that the two cargo runs never wait on each other.
fn static_library() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let target = exe.ancestors().nth(3).unwrap().join("c-abi");
    let status = Command::new(env!("CARGO"))
        .args(["build", "--release", "--lib", "-p", "mesobake-package-c"])
        .env("CARGO_TARGET_DIR", &target)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .unwrap();
    assert!(status.success(), "building the static library failed");
    target.join("release/libmesobake_package_c.a")
}

#[test]
fn a_c_program_reads_packages_like_the_rust_reader() {
    let dir = tempfile::tempdir().unwrap();
    let library = static_library();
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let program = dir.path().join("reader");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(crate_dir.join("include"))
        .arg(crate_dir.join("tests/reader.c"))
        .arg(&library)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&program)
        .status()
        .unwrap_or_else(|e| panic!("{cc}: {e}"));
    assert!(status.success(), "compiling reader.c failed");
    let mut hits = 0;
    for (n, bytes) in packages().iter().enumerate() {
        let path = dir.path().join(format!("p{n}.mbpkg"));
        std::fs::write(&path, bytes).unwrap();
        let out = Command::new(&program).arg(&path).output().unwrap();
        assert!(out.status.success(), "reader exited with {}", out.status);
        let printed = String::from_utf8(out.stdout).unwrap();
        let want = expected(bytes);
        for (line, (got, want)) in printed.lines().zip(want.lines()).enumerate() {
            assert_eq!(got, want, "package {n}, line {line}");
        }
        assert_eq!(printed.lines().count(), want.lines().count(), "package {n}");
        hits += printed
            .lines()
            .filter(|l| l.starts_with(char::is_numeric))
            .count();
        // A corrupted copy is refused with the reader's message.
        let mut bad = bytes.clone();
        let last = bad.len() - 1;
        bad[last] ^= 1;
        std::fs::write(&path, bad).unwrap();
        let out = Command::new(&program).arg(&path).output().unwrap();
        let printed = String::from_utf8(out.stdout).unwrap();
        assert_eq!(out.status.code(), Some(1));
        assert!(printed.starts_with("error: package: "), "{printed}");
    }
    assert!(hits > 500, "both codecs report hits ({hits})");

    // A small file that reads into far more memory (an empty 256³ occupancy field, stored
    // supercompressed): refused by its memory needs, under a limit the file itself is far below.
    let bytes = support::empty_occupancy(256);
    assert!(bytes.len() < 1 << 20, "{} bytes", bytes.len());
    let path = dir.path().join("bomb.mbpkg");
    std::fs::write(&path, &bytes).unwrap();
    let out = Command::new(&program)
        .args([path.as_os_str(), "67108864".as_ref()])
        .output()
        .unwrap();
    let printed = String::from_utf8(out.stdout).unwrap();
    assert_eq!(out.status.code(), Some(1), "{printed}");
    assert!(
        printed.contains("over the memory limit of 67108864 bytes"),
        "{printed}"
    );
    let out = Command::new(&program).arg(&path).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}
