//! GDM packages: round trips, determinism, and rejection of every kind of corrupt file.

use crate::package_edit::{reseal_header, with_manifest};
use mesobake_bake::compress::gdm::{CompressedGdm, compress};
use mesobake_bake::compress::layout::GdmRows;
use mesobake_bake::compress::quantize::Quantization;
use mesobake_bake::compress::svd::{GramEigen, RankChoice};
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::gdm::{self, EscapeConvention, Gdm, Method};
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume::Occupancy;
use mesobake_bake::package::bake::{PackageParams, bake_info, bake_package};
use mesobake_bake::package::manifest::{GdmCodec, InputInfo, Manifest};
use mesobake_bake::package::{GdmPayload, OCCUPANCY_SECTION, Package, container};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};
use proptest::prelude::*;

fn params(rank: usize, quantization: Quantization) -> PackageParams {
    PackageParams {
        res: None,
        dirs: DirectionGrid::new(4, 8).unwrap(),
        codec: GdmCodec::PaperSvd,
        method: Method::Exact,
        fast: Default::default(),
        rank: RankChoice::Rank(rank),
        quantization,
        allow_open: false,
    }
}

/// The exact GDM of a small `chain` (boundary convention) and its compression.
fn compressed(res: Dims, rank: usize, q: Quantization) -> (Gdm, CompressedGdm) {
    let limits = Limits::default();
    let volume = samples::volume(SampleKind::Chain, res, &limits).unwrap();
    let p = params(rank, q);
    let mut g = gdm::exact::bake(&VolumeCaster::new(&volume), p.dirs, &limits, &()).unwrap();
    g.set_escape_convention(EscapeConvention::Boundary);
    let gram = GramEigen::new(&GdmRows::new(&g).unwrap(), &limits).unwrap();
    let c = compress(&g, &gram, p.rank, q, &limits).unwrap();
    (g, c)
}

fn input_info() -> InputInfo {
    InputInfo {
        kind: "volume".into(),
        bytes: 1,
        blake3: "00".into(),
    }
}

fn small_package() -> Vec<u8> {
    svd_package(Dims::new(8, 8, 4).unwrap(), 5, Quantization::F16)
}

fn svd_package(res: Dims, rank: usize, q: Quantization) -> Vec<u8> {
    let (g, c) = compressed(res, rank, q);
    Package::encode(
        input_info(),
        bake_info(&g, Method::Exact, Default::default(), false),
        &GdmPayload::PaperSvd(Box::new(c)),
    )
}

#[test]
fn round_trip_gives_back_the_measured_reconstruction() {
    let limits = Limits::default();
    for q in Quantization::ALL {
        let (g, c) = compressed(Dims::new(16, 16, 8).unwrap(), 6, q);
        let bytes = Package::encode(
            input_info(),
            bake_info(&g, Method::Exact, Default::default(), false),
            &GdmPayload::PaperSvd(Box::new(c.clone())),
        );
        let pkg = Package::parse(bytes).unwrap();
        // The unpacked codes are the quantized factors, bit for bit.
        let (w, e) = pkg.factors().unwrap();
        assert_eq!((&w, &e), (&c.weights, &c.eigen), "{q}");
        // Reconstruction through the package (a GEMM per direction) agrees with the
        // measurement (a GEMM per row block): same flips, same error on agreeing hits.
        let recon = pkg.reconstruct(&limits).unwrap();
        let (mut flips, mut sum_sq) = (0u64, 0.0f64);
        let mut exact = g.clone();
        exact.set_escape_convention(EscapeConvention::Infinite);
        for (&r, &x) in recon.data().iter().zip(exact.data()) {
            if r.is_infinite() != x.is_infinite() {
                flips += 1;
            } else if x.is_finite() {
                sum_sq += ((r - x) as f64).powi(2);
            }
        }
        assert_eq!(flips, c.accuracy.flips, "{q}");
        // Errors on hits are part of the total (which also counts escapes and flips).
        let rmse_hits_part = (sum_sq / c.accuracy.samples as f64).sqrt();
        assert!(rmse_hits_part <= c.accuracy.rmse * (1.0 + 1e-4), "{q}");
        let m = pkg.manifest().gdm.as_ref().unwrap();
        assert_eq!(m.rank, 6);
        assert_eq!(m.weights.sections.len(), 2);
        assert_eq!(m.spectrum.len(), 4 * 8);
    }
}

#[test]
fn quantization_error_is_measured_and_ordered() {
    let (_, f32q) = compressed(Dims::new(16, 16, 8).unwrap(), 8, Quantization::F32);
    let (_, f16q) = compressed(Dims::new(16, 16, 8).unwrap(), 8, Quantization::F16);
    let (_, u8q) = compressed(Dims::new(16, 16, 8).unwrap(), 8, Quantization::U8);
    // f32 loses nothing beyond the SVD's own optimum (within the SVD test's 1 %).
    let optimal = f32q.svd.optimal_rmse(8);
    assert!(f32q.accuracy.rmse <= optimal * 1.01 + 1e-4);
    // f16 adds at most its half-ulp relative rounding; u8 adds more.
    assert!((f16q.accuracy.rmse - f32q.accuracy.rmse).abs() <= 0.01 * f32q.accuracy.rmse);
    assert!(u8q.accuracy.rmse > f16q.accuracy.rmse);
}

#[test]
fn packages_are_byte_identical_across_runs_and_thread_counts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chain.mbvol");
    let limits = Limits::default();
    let volume =
        samples::volume(SampleKind::Chain, Dims::new(16, 16, 8).unwrap(), &limits).unwrap();
    mesobake_bake::mesostructure::volume_format::write(&volume, &path).unwrap();
    let bake = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| bake_package(&path, &params(4, Quantization::F16), &limits, &()))
            .unwrap()
            .bytes
    };
    let one = bake(1);
    assert_eq!(one, bake(2));
    assert_eq!(one, bake(3));
    let m = Package::parse(one).unwrap().manifest().clone();
    let file = std::fs::read(&path).unwrap();
    assert_eq!(m.input.blake3, blake3::hash(&file).to_hex().to_string());
    assert_eq!(m.input.bytes, file.len() as u64);
}

/// The default codec's package of a small `chain` volume file.
fn occupancy_package(dir: &std::path::Path) -> Vec<u8> {
    let path = dir.join("chain.mbvol");
    let limits = Limits::default();
    let volume =
        samples::volume(SampleKind::Chain, Dims::new(16, 16, 8).unwrap(), &limits).unwrap();
    mesobake_bake::mesostructure::volume_format::write(&volume, &path).unwrap();
    let p = PackageParams {
        codec: GdmCodec::Occupancy,
        ..params(8, Quantization::F16)
    };
    bake_package(&path, &p, &limits, &()).unwrap().bytes
}

#[test]
fn an_occupancy_package_holds_the_voxels_and_reconstructs_the_exact_gdm() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = occupancy_package(dir.path());
    let limits = Limits::default();
    let pkg = Package::parse(bytes.clone()).unwrap();
    let m = pkg.manifest();
    assert_eq!(m.codec, GdmCodec::Occupancy);
    assert!(m.gdm.is_none() && pkg.factors().is_none());
    // One byte per voxel, nothing else: 16·16·8 texels in the only section, stored in fewer
    // bytes (supercompressed: the distances are smooth).
    assert_eq!(m.sections.len(), 1);
    assert_eq!(m.sections[0].texture.byte_len(), Some(16 * 16 * 8));
    assert_eq!(pkg.section(OCCUPANCY_SECTION).unwrap().len(), 16 * 16 * 8);
    assert!(m.sections[0].bytes < 16 * 16 * 8, "{}", m.sections[0].bytes);
    let volume =
        samples::volume(SampleKind::Chain, Dims::new(16, 16, 8).unwrap(), &limits).unwrap();
    let field = pkg.occupancy().unwrap().unwrap();
    assert_eq!(Occupancy::of_field(&field), volume.occupancy());
    assert_eq!(
        m.occupancy.as_ref().unwrap().solid_voxels,
        volume.occupancy().solid_count()
    );
    // Its GDM is the exact bake of the volume, sample for sample.
    let mut exact =
        gdm::exact::bake(&VolumeCaster::new(&volume), pkg.dirs(), &limits, &()).unwrap();
    exact.set_escape_convention(EscapeConvention::Infinite);
    assert_eq!(pkg.reconstruct(&limits).unwrap().data(), exact.data());
    // Deterministic: the same input gives the same bytes.
    assert_eq!(bytes, occupancy_package(dir.path()));
}

/// The format crate's queries (what a game build calls) against mesobake's reconstruction:
/// for occupancy an independent voxel march against the exact bake, for paper-svd the same
/// W·Eᵀ with the escape rule.
#[test]
fn the_format_crates_queries_agree_with_mesobakes_reconstruction() {
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits::default();
    let svd = svd_package(Dims::new(16, 16, 8).unwrap(), 6, Quantization::U8);
    let svd = Package::parse(svd).unwrap();
    let occupancy = Package::parse(occupancy_package(dir.path())).unwrap();
    for pkg in [svd, occupancy] {
        let (dims, dirs) = (pkg.dims(), pkg.dirs());
        let (gdm, query) = (pkg.reconstruct(&limits).unwrap(), pkg.query().unwrap());
        let mut hits = 0;
        for a in 0..dirs.n_theta {
            for b in 0..dirs.n_phi {
                for k in 0..dims.z {
                    for j in 0..dims.y {
                        for i in 0..dims.x {
                            let expected = gdm.get(i, j, k, a, b);
                            let got = query.distance(i, j, k, a, b).unwrap_or(f32::INFINITY);
                            hits += usize::from(got.is_finite());
                            assert!(
                                got == expected || (got - expected).abs() <= 1e-5 * expected,
                                "{}: sample {i},{j},{k},{a},{b}: {got} vs {expected}",
                                pkg.manifest().codec
                            );
                        }
                    }
                }
            }
        }
        assert!(hits > 1000, "{hits} hits");
    }
}

#[test]
fn corrupt_or_mismatched_occupancy_packages_are_refused_naming_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = occupancy_package(dir.path());
    // A distance larger than its solid voxels allow, with every checksum fixed up: a march
    // would skip solid voxels, so the package is refused.
    let pkg = Package::parse(bytes.clone()).unwrap();
    let mut manifest = pkg.manifest().clone();
    assert_eq!(manifest.sections[0].name, OCCUPANCY_SECTION);
    let mut distances = pkg.section(OCCUPANCY_SECTION).unwrap().to_vec();
    let at = distances.iter().position(|&d| d == 1).unwrap();
    distances[at] = 9;
    let e = error_of(container::assemble(&mut manifest, &[distances]));
    assert!(e.contains("occupancy field's distance"), "{e}");
    // The codec must come with its own entry.
    let e = error_of(with_manifest(&bytes, |m| {
        m["codec"] = serde_json::json!("paper-svd")
    }));
    assert!(
        e.contains("codec paper-svd needs exactly its own entry (gdm)"),
        "{e}"
    );
    let e = error_of(with_manifest(&bytes, |m| {
        m["codec"] = serde_json::json!("jpeg")
    }));
    assert!(e.contains("unknown variant"), "{e}");
    let e = error_of(with_manifest(&bytes, |m| {
        m["sections"][0]["texture"]["format"] = serde_json::json!("r8unorm")
    }));
    assert!(e.contains("occupancy.distance"), "{e}");
}

#[test]
fn every_flipped_byte_is_rejected() {
    let bytes = small_package();
    assert!(Package::parse(bytes.clone()).is_ok());
    for offset in 0..bytes.len() {
        for mask in [0x01u8, 0x80] {
            let mut bad = bytes.clone();
            bad[offset] ^= mask;
            assert!(
                Package::parse(bad).is_err(),
                "flipping {mask:#x} at byte {offset} of {} went unnoticed",
                bytes.len()
            );
        }
    }
}

#[test]
fn every_truncation_and_extension_is_rejected() {
    let bytes = small_package();
    for len in 0..bytes.len() {
        let err = Package::parse(bytes[..len].to_vec())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("truncated") || err.contains("bytes"),
            "{len}: {err}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(Package::parse(longer).is_err());
}

fn error_of(bytes: Vec<u8>) -> String {
    Package::parse(bytes).unwrap_err().to_string()
}

#[test]
fn wrong_versions_and_absurd_sizes_get_clear_errors() {
    let bytes = small_package();
    // Sanity: resealing an unchanged manifest keeps the package valid.
    assert!(Package::parse(with_manifest(&bytes, |_| {})).is_ok());

    // Version 1 (before codecs) and any later version are refused by number.
    for version in [1u32, 3] {
        let mut other = bytes.clone();
        other[8..12].copy_from_slice(&version.to_le_bytes());
        reseal_header(&mut other);
        let e = error_of(other);
        assert!(
            e.contains(&format!("format version {version} is not supported")),
            "{e}"
        );
    }

    let mut huge = bytes.clone();
    huge[24..32].copy_from_slice(&(1u64 << 62).to_le_bytes());
    reseal_header(&mut huge);
    assert!(error_of(huge).contains("manifest's declared size"));

    let e = error_of(with_manifest(&bytes, |m| {
        m["sections"][0]["bytes"] = serde_json::json!(1u64 << 60);
    }));
    assert!(e.contains("section \"gdm.weights.0\""), "{e}");

    let e = error_of(with_manifest(&bytes, |m| {
        m["sections"][0]["texture"]["depth"] = serde_json::json!(1u32 << 31);
    }));
    assert!(e.contains("gdm.weights.0"), "{e}");

    let e = error_of(with_manifest(&bytes, |m| {
        m["gdm"]["rank"] = serde_json::json!(9)
    }));
    assert!(e.contains("sections"), "{e}");

    let e = error_of(with_manifest(&bytes, |m| {
        m["bake"]["res"] = serde_json::json!([8, 8, 0])
    }));
    assert!(e.contains("manifest"), "{e}");

    let e = error_of(with_manifest(&bytes, |m| {
        m["version"] = serde_json::json!(7)
    }));
    assert!(e.contains("version 7"), "{e}");

    let e = error_of(with_manifest(&bytes, |m| m["extra"] = serde_json::json!(1)));
    assert!(e.contains("unknown field"), "{e}");

    let e = error_of(with_manifest(&bytes, |m| {
        m["gdm"]["accuracy"]["escape_margin"] = serde_json::json!(3.0)
    }));
    assert!(e.contains("escape margin"), "{e}");
}

#[test]
fn every_manifest_field_a_reader_relies_on_is_validated() {
    // The probe's accepted mutations (CRCs recomputed), each refused naming the field.
    let bytes = small_package();
    type Edit = fn(&mut serde_json::Value);
    let cases: [(&str, Edit); 8] = [
        ("stride", |m| {
            m["bake"]["fast"] = serde_json::json!({ "stride": 0, "max_spread": 1.0 })
        }),
        ("descending", |m| {
            m["gdm"]["spectrum"].as_array_mut().unwrap().reverse()
        }),
        ("accuracy", |m| {
            m["gdm"]["accuracy"]["rmse"] = serde_json::json!(-1.0)
        }),
        ("accuracy", |m| {
            m["gdm"]["svd_rmse"] = serde_json::json!(-0.5)
        }),
        ("accuracy", |m| {
            m["gdm"]["accuracy"]["flips"] = serde_json::json!(u64::MAX)
        }),
        ("max_rmse", |m| {
            m["gdm"]["rank_choice"] = serde_json::json!({ "max_rmse": -2.0 })
        }),
        ("input kind", |m| {
            m["input"]["kind"] = serde_json::json!("v".repeat(10_000))
        }),
        ("input blake3", |m| {
            m["input"]["blake3"] = serde_json::json!("not hex")
        }),
    ];
    for (want, edit) in cases {
        let e = error_of(with_manifest(&bytes, edit));
        assert!(e.contains(want), "{want}: {e}");
    }
}

#[test]
fn a_huge_declared_grid_fails_on_the_memory_limit_not_on_allocation() {
    // A rank-0 package has no sections, so nothing in the file bounds its grid.
    let (g, c) = compressed(Dims::new(8, 8, 4).unwrap(), 0, Quantization::F16);
    let bytes = Package::encode(
        input_info(),
        bake_info(&g, Method::Exact, Default::default(), false),
        &GdmPayload::PaperSvd(Box::new(c)),
    );
    let bytes = with_manifest(&bytes, |m| {
        m["bake"]["res"] = serde_json::json!([65536, 65536, 65536]);
        m["gdm"]["spectrum"] = serde_json::json!(vec![0.0; 65536 * 4]);
    });
    let pkg = Package::parse(bytes).unwrap();
    let e = pkg.reconstruct(&Limits::default()).unwrap_err().to_string();
    assert!(e.contains("memory limit"), "{e}");
}

#[test]
fn reconstruction_refuses_grids_over_the_memory_limit() {
    let pkg = Package::parse(small_package()).unwrap();
    let tiny = Limits {
        memory_bytes: 1024,
        ..Limits::default()
    };
    let e = pkg.reconstruct(&tiny).unwrap_err().to_string();
    assert!(e.contains("memory limit"), "{e}");
}

#[test]
fn manifests_round_trip_through_json() {
    let pkg = Package::parse(small_package()).unwrap();
    let text = serde_json::to_string(pkg.manifest()).unwrap();
    let back: Manifest = serde_json::from_str(&text).unwrap();
    assert_eq!(&back, pkg.manifest());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        prop_assert!(Package::parse(bytes).is_err());
    }

    #[test]
    fn arbitrary_edits_of_a_valid_package_are_rejected_or_harmless(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)
    ) {
        let mut bytes = small_package_cached().clone();
        let original = bytes.clone();
        for (at, value) in edits {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        match Package::parse(bytes.clone()) {
            Ok(_) => prop_assert_eq!(bytes, original),
            Err(_) => prop_assert_ne!(bytes, original),
        }
    }
}

fn small_package_cached() -> &'static Vec<u8> {
    static PACKAGE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    PACKAGE.get_or_init(small_package)
}
