//! The CI commands end to end: bake → package → unpack (.npy, EXR, KTX2), and report accuracy.

use mesobake_bake::package::Package;
use mesobake_core::limits::Limits;
use std::path::Path;

use crate::common::{each_fails_with, small_scene, succeeds};

/// `mesobake bake --input VOL --out PKG` with `options`, returning its JSON summary.
fn bake(vol: &str, pkg: &Path, options: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "bake",
        "--input",
        vol,
        "--out",
        pkg.to_str().unwrap(),
        "--json",
    ];
    args.extend_from_slice(options);
    serde_json::from_slice(&succeeds(&args).stdout).unwrap()
}

fn sample(dir: &Path) -> String {
    let vol = dir.join("weave.mbvol");
    let vol = vol.to_str().unwrap().to_string();
    succeeds(&["sample", "weave", "--res", "16x16x8", "--out", &vol]);
    vol
}

#[test]
fn bake_then_unpack_gives_the_documented_npy_and_exr() {
    let dir = tempfile::tempdir().unwrap();
    let vol = sample(dir.path());
    let pkg = dir.path().join("weave.mbpkg");
    let summary = bake(
        &vol,
        &pkg,
        &[
            "--dirs",
            "4x8",
            "--gdm-codec",
            "paper-svd",
            "--rank",
            "5",
            "--quant",
            "u8",
        ],
    );
    let bytes = std::fs::read(&pkg).unwrap();
    assert_eq!(summary["bytes"], bytes.len());
    assert_eq!(summary["gdm"]["codec"], "paper-svd");
    assert_eq!(summary["gdm"]["rank"], 5);
    assert_eq!(summary["gdm"]["quantization"], "u8");
    for stage in ["load", "bake", "svd", "quantize", "encode", "write"] {
        assert!(
            summary["seconds"][stage].as_f64().unwrap() >= 0.0,
            "{stage}"
        );
    }
    let package = Package::parse(bytes).unwrap();
    assert_eq!(
        summary["gdm"]["accuracy"]["flips"],
        package.manifest().gdm.as_ref().unwrap().accuracy.flips
    );

    let npy = dir.path().join("recon.npy");
    let exr = dir.path().join("maps.exr");
    succeeds(&[
        "unpack",
        pkg.to_str().unwrap(),
        "--out",
        npy.to_str().unwrap(),
        "--exr",
        exr.to_str().unwrap(),
    ]);
    // The .npy holds exactly the package's reconstruction, in `mesobake gdm`'s layout.
    let file = std::fs::read(&npy).unwrap();
    let array = npyz::NpyFile::new(&file[..]).unwrap();
    assert_eq!(array.shape(), &[16, 16, 8, 4, 8]);
    let values = array.into_vec::<f32>().unwrap();
    let recon = package.reconstruct(&Limits::default()).unwrap();
    for (x, y, z, a, b) in [(0, 0, 0, 0, 0), (3, 7, 5, 2, 6), (15, 15, 7, 3, 7)] {
        let v = values[(((x * 16 + y) * 8 + z) * 4 + a) * 8 + b];
        let r = recon.get(x as u32, y as u32, z as u32, a as u32, b as u32);
        assert!(v == r || (v.is_infinite() && r.is_infinite()), "{v} vs {r}");
    }
    assert!(values.iter().any(|v| v.is_infinite()), "escapes are +inf");
    assert!(values.iter().all(|v| *v >= 0.0 && !v.is_nan()));

    // The EXR holds W0..W4 (16 × 16·8) and E0..E4 (8 × 4) with the dequantized values.
    let image = exr::prelude::read_all_flat_layers_from_file(&exr).unwrap();
    let (w, e) = package.factors().unwrap();
    let (w, e) = (w.dequantize(), e.dequantize());
    assert_eq!(image.layer_data.len(), 10);
    for layer in &image.layer_data {
        let name = layer.attributes.layer_name.as_ref().unwrap().to_string();
        let (factor, width, height) = if name.starts_with('W') {
            (&w, 16, 16 * 8)
        } else {
            (&e, 8, 4)
        };
        let c: usize = name[1..].parse().unwrap();
        assert_eq!((layer.size.0, layer.size.1), (width, height), "{name}");
        let exr::prelude::FlatSamples::F32(samples) = &layer.channel_data.list[0].sample_data
        else {
            panic!("{name} is not f32");
        };
        for (r, s) in samples.iter().enumerate() {
            assert_eq!(*s, factor[r * 5 + c], "{name} texel {r}");
        }
    }

    // --ktx2 alone: one KTX 2.0 file per texture section (rank 5: two groups per factor), each
    // holding the section's bytes as its only level.
    let textures = dir.path().join("textures");
    succeeds(&[
        "unpack",
        pkg.to_str().unwrap(),
        "--ktx2",
        textures.to_str().unwrap(),
    ]);
    let sections = &package.manifest().sections;
    assert_eq!(sections.len(), 4);
    assert_eq!(std::fs::read_dir(&textures).unwrap().count(), 4);
    for section in sections {
        let file = std::fs::read(textures.join(format!("{}.ktx2", section.name))).unwrap();
        let reader = ktx2::Reader::new(&file[..]).unwrap();
        let h = reader.header();
        assert_eq!(
            (h.pixel_width, h.pixel_height),
            (section.texture.width, section.texture.height)
        );
        let level = reader.levels().next().unwrap();
        assert_eq!(
            level.data,
            package.section(&section.name).unwrap(),
            "{}",
            section.name
        );
    }
}

#[test]
fn bake_chooses_the_rank_from_a_target_rmse() {
    let dir = tempfile::tempdir().unwrap();
    let vol = sample(dir.path());
    let pkg = dir.path().join("weave.mbpkg");
    let summary = bake(
        &vol,
        &pkg,
        &[
            "--dirs",
            "4x8",
            "--gdm-codec",
            "paper-svd",
            "--max-rmse",
            "0.5",
            "--quant",
            "f32",
        ],
    );
    let package = Package::read(&pkg, &Limits::default()).unwrap();
    let g = package.manifest().gdm.as_ref().unwrap();
    let rank = g.rank as usize;
    assert_eq!(summary["gdm"]["rank"], rank);
    // The fewest components whose optimal error meets the target.
    let optimal = |k: usize| {
        let tail: f64 = g.spectrum[k..].iter().map(|s| s * s).sum();
        (tail / (16.0 * 16.0 * 8.0 * 8.0 * 4.0)).sqrt()
    };
    assert!(optimal(rank) <= 0.5 && optimal(rank - 1) > 0.5);
    assert!(g.accuracy.rmse <= 0.5 * 1.01);
}

#[test]
fn report_accuracy_writes_table_csv_and_plot() {
    let dir = tempfile::tempdir().unwrap();
    let vol = sample(dir.path());
    let report = dir.path().join("report");
    let out = succeeds(&[
        "report",
        "accuracy",
        "--input",
        &vol,
        "--dirs",
        "2x4,4x8",
        "--ranks",
        "1,4",
        "--quants",
        "f32,f16",
        "--scenes",
        small_scene(dir.path()).to_str().unwrap(),
        "--out",
        report.to_str().unwrap(),
    ]);
    let table = String::from_utf8(out.stdout).unwrap();
    let (gdm_table, codec_section) = table.split_once("\n## Codecs\n\n").unwrap();
    assert_eq!(gdm_table.lines().count(), 2 + 2 * 2 * 2, "{table}");
    // The codec section is the codecs report at its defaults: uncompressed, occupancy,
    // paper-svd at 3 ranks, tiled-svd (one tile side) at 3, split-svd (two visibility grids,
    // two bases) at 3.
    let codecs: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("codecs.json")).unwrap())
            .unwrap();
    let rows = codecs["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2 + 3 + 3 + 12, "{codec_section}");
    for codec in ["occupancy", "paper-svd", "tiled-svd", "split-svd"] {
        assert!(
            codec_section.contains(&format!("| {codec} |")),
            "{codec_section}"
        );
    }
    assert!(report.join("codecs.svg").exists());
    let csv = std::fs::read_to_string(report.join("accuracy.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 8);
    // More components never increase the error at the same resolution and format.
    for pair in rows.chunks(4) {
        let rmse = |r: &Vec<&str>| r[6].parse::<f64>().unwrap();
        assert!(rmse(&pair[2]) <= rmse(&pair[0]) + 1e-6, "{csv}");
        // f16 halves the factor bytes (the manifest is the same size to within a few).
        let bytes = |r: &Vec<&str>| r[5].parse::<f64>().unwrap();
        assert!(bytes(&pair[1]) < bytes(&pair[0]), "{csv}");
    }
    let svg = std::fs::read_to_string(report.join("accuracy.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("RMSE against"));
    assert_eq!(
        std::fs::read_to_string(report.join("accuracy.md")).unwrap(),
        table
    );
}

#[test]
fn bad_packages_and_options_exit_non_zero_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let vol = sample(dir.path());
    let pkg = dir.path().join("p.mbpkg");
    let p = pkg.to_str().unwrap();
    bake(&vol, &pkg, &["--dirs", "2x4"]);
    let good = std::fs::read(&pkg).unwrap();
    let mut corrupt = good.clone();
    corrupt[300] ^= 0x10;
    let bad = dir.path().join("bad.mbpkg");
    std::fs::write(&bad, &corrupt).unwrap();
    let npy = dir.path().join("never.npy");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "unpack",
                bad.to_str().unwrap(),
                "--out",
                npy.to_str().unwrap(),
            ],
            "checksum mismatch",
        ),
        (
            vec!["unpack", &vol, "--out", npy.to_str().unwrap()],
            "bad magic",
        ),
        (
            vec![
                "bake",
                "--input",
                &vol,
                "--out",
                p,
                "--rank",
                "2",
                "--max-rmse",
                "1",
            ],
            "cannot be used with",
        ),
        (
            vec![
                "bake",
                "--input",
                &vol,
                "--out",
                p,
                "--gdm-codec",
                "paper-svd",
                "--max-rmse",
                "NaN",
            ],
            "target RMSE",
        ),
        // SVD sizes only with the SVD codec, and ranks within what the server accepts too.
        (
            vec!["bake", "--input", &vol, "--out", p, "--rank", "3"],
            "rank sizes the paper-svd codec's SVD, but the codec is occupancy",
        ),
        (
            vec!["bake", "--input", &vol, "--out", p, "--max-rmse", "1"],
            "--max-rmse sizes the paper-svd codec's SVD",
        ),
        (
            vec![
                "bake",
                "--input",
                &vol,
                "--out",
                p,
                "--gdm-codec",
                "paper-svd",
                "--rank",
                "0",
            ],
            "rank must be in 1..=64, got 0",
        ),
        (
            vec![
                "bake",
                "--input",
                &vol,
                "--out",
                p,
                "--gdm-codec",
                "paper-svd",
                "--rank",
                "100000",
            ],
            "rank must be in 1..=64, got 100000",
        ),
        (
            vec!["bake", "--input", &vol, "--out", p, "--gdm-codec", "jpeg"],
            "GDM codec \"jpeg\": expected occupancy or paper-svd",
        ),
        (
            vec!["bake", "--input", &vol, "--out", p, "--quant", "f8"],
            "quantization",
        ),
    ];
    each_fails_with(&cases);
    assert!(!npy.exists(), "nothing is written on failure");
    assert_eq!(
        std::fs::read(&pkg).unwrap(),
        good,
        "a failed bake keeps the old package"
    );
}

/// A VDM bake whose view-dependent map alone is exactly the memory limit (the issue's
/// 4096² height field at 4 GiB, here 64² texels at 16 MiB) passed the one-buffer check and
/// then allocated the map's copy, its MVM and the SVD's blocks beyond the limit: the bake's
/// whole peak is checked before anything is loaded, and named. Twice the limit is not
/// enough either (the copy alone takes it); at the bound the plan states, it bakes.
#[test]
fn a_bake_whose_largest_buffer_is_exactly_the_limit_is_refused_before_loading() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("relief.json");
    let text = r#"{
        "base_mesh": { "builtin": { "torus": { "major_radius": 1.0, "minor_radius": 0.4, "segments": [24, 12] } } },
        "mesostructure": { "relief": "bumps" },
        "technique": "vdm",
        "resolution": [64, 64, 16],
        "shell": { "thickness": 0.04, "tiles_per_uv": [6, 3] },
        "camera": { "eye": [0, 2, 2], "target": [0, 0, 0], "fov_y_degrees": 45, "width": 32, "height": 32 },
        "vdm": { "directions": [8, 16], "curvatures": 8 }
    }"#;
    std::fs::write(&scene, text).unwrap();
    // Texels × view directions × curvatures × 4 bytes: the VDM's one buffer.
    let vdm = 64 * 64 * 8 * 16 * 8 * 4;
    let out = dir.path().join("relief.mbpkg");
    let bake = |limit: u64| {
        let limit = limit.to_string();
        crate::common::mesobake(&[
            "--memory-limit",
            &limit,
            "bake",
            "--scene",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    for limit in [vdm, 2 * vdm] {
        let run = bake(limit);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{limit}: {stderr}");
        assert!(
            stderr.contains("the bake (largest parts: VDM")
                && stderr.contains(&format!("over the memory limit of {limit} bytes")),
            "{stderr}"
        );
        assert!(!out.exists());
    }
    let read = mesobake_scene::Scene::read(&scene).unwrap();
    let technique = mesobake_scene::technique::Technique::Vdm;
    let params = mesobake_scene::package::ScenePackageParams::default();
    let gdm = (params.codec, params.rank);
    let bound = mesobake_scene::memory::bake_memory(&read, dir.path(), technique, gdm)
        .unwrap()
        .total();
    let run = bake(bound);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

/// A small package that reads into far more memory than its size (an empty 256³ occupancy
/// field, stored supercompressed: 16 MiB of texels, 64 MiB decoded) is refused by every command
/// that reads packages under a 64 MiB limit, before it allocates, naming the limit; nothing is
/// written.
#[test]
fn a_package_that_reads_into_more_than_the_memory_limit_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let bomb = dir.path().join("bomb.mbpkg");
    let bytes = crate::package_support::empty_occupancy(256);
    assert!(bytes.len() < 1 << 20, "{} bytes", bytes.len());
    std::fs::write(&bomb, &bytes).unwrap();
    let (npy, png) = (dir.path().join("x.npy"), dir.path().join("x.png"));
    let scene = small_scene(dir.path());
    let limit = ["--memory-limit", "64MiB"];
    let unpack = [
        &limit[..],
        &[
            "unpack",
            bomb.to_str().unwrap(),
            "--out",
            npy.to_str().unwrap(),
        ],
    ];
    let render = [
        &limit[..],
        &[
            "render",
            "--scene",
            scene.to_str().unwrap(),
            "--package",
            bomb.to_str().unwrap(),
        ],
        &["--out", png.to_str().unwrap()],
    ];
    for args in [unpack.concat(), render.concat()] {
        let out = crate::common::mesobake(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("over the memory limit of 67108864 bytes"),
            "{args:?}: {stderr}"
        );
    }
    assert!(!npy.exists() && !png.exists());
    // Under the default limit it reads, and is then refused for what it is: another grid.
    let out = crate::common::mesobake(&render.concat()[2..]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("256x256x256 grid"), "{stderr}");
}
