//! The format crate on its own: packages it writes read back to the same content, queries
//! match closed forms, and corruption is refused.

use mesobake_package::grid::{Dims, DirectionGrid, boundary_distance};
use mesobake_package::manifest::{FastParams, GdmCodec, Method, RankChoice};
use mesobake_package::occupancy::OccupancyField;
use mesobake_package::quantize::{Quantization, QuantizedFactor};
use mesobake_package::svd::SvdFactors;
use mesobake_package::{GdmContent, GdmQuery, Package};

#[path = "support/mod.rs"]
mod support;
use support::{accuracy, encode};

/// A deterministic pseudo-random value in [-1, 1).
fn noise(n: usize) -> f32 {
    2.0 * support::noise(n) - 1.0
}

#[test]
fn svd_packages_reconstruct_w_times_e_with_the_escape_rule() {
    let (dims, dirs) = (
        Dims::new(6, 5, 4).unwrap(),
        DirectionGrid::new(4, 6).unwrap(),
    );
    let rank = 5; // two texture groups, the second one channel wide
    let (m, n) = ((6 * 5 * 6) as usize, (4 * 4) as usize);
    let w: Vec<f32> = (0..m * rank).map(|x| 3.0 * noise(x)).collect();
    let e: Vec<f32> = (0..n * rank).map(|x| noise(x + 7919)).collect();
    for q in Quantization::ALL {
        let (wq, eq) = (
            QuantizedFactor::new(&w, rank, q),
            QuantizedFactor::new(&e, rank, q),
        );
        let spectrum = vec![1.0; m.min(n)];
        let factors = SvdFactors {
            rank_choice: RankChoice::Rank(rank),
            spectrum: &spectrum,
            weights: &wq,
            eigen: &eq,
            accuracy: accuracy(0.25),
            svd_rmse: 0.0,
        };
        let bytes = encode(dims, dirs, GdmContent::PaperSvd(factors));
        let again = encode(dims, dirs, GdmContent::PaperSvd(factors));
        assert_eq!(bytes, again, "{q}: writing is deterministic");
        let pkg = Package::parse(bytes).unwrap();
        assert_eq!(pkg.manifest().codec, GdmCodec::PaperSvd);
        let (w2, e2) = pkg.factors().unwrap();
        assert_eq!(
            (w2, e2),
            (wq.clone(), eq.clone()),
            "{q}: the codes read back"
        );
        let (wd, ed) = (wq.dequantize(), eq.dequantize());
        let query = pkg.query().unwrap();
        let mut escapes = 0;
        for (a, b, k, j, i) in samples(dims, dirs) {
            let row = ((b * dims.y + j) * dims.x + i) as usize;
            let col = (a * dims.z + k) as usize;
            let v: f32 = (0..rank)
                .map(|c| wd[row * rank + c] * ed[col * rank + c])
                .sum();
            let boundary = boundary_distance(dims, &dirs, k, a);
            let expected = (v < 0.75 * boundary).then_some(v.max(0.0));
            let got = query.distance(i, j, k, a, b);
            match (got, expected) {
                (Some(g), Some(x)) => assert!((g - x).abs() <= 1e-5 * (1.0 + x.abs()), "{q}"),
                (None, None) => escapes += 1,
                _ => panic!("{q}: sample {i},{j},{k},{a},{b}: {got:?} vs {expected:?}"),
            }
        }
        assert!(escapes > 0, "the escape rule is exercised");
    }
}

/// Every sample (a, b, k, j, i) of the grids.
fn samples(dims: Dims, dirs: DirectionGrid) -> Vec<(u32, u32, u32, u32, u32)> {
    let mut out = Vec::new();
    for a in 0..dirs.n_theta {
        for b in 0..dirs.n_phi {
            for k in 0..dims.z {
                for j in 0..dims.y {
                    for i in 0..dims.x {
                        out.push((a, b, k, j, i));
                    }
                }
            }
        }
    }
    out
}

#[test]
fn occupancy_queries_match_the_closed_form_of_a_floor() {
    // Layer 0 solid: looking down from layer k the floor's top (z = 1) is
    // (k + ½ − 1)/|cos θ| away; looking up the ray escapes.
    let (dims, dirs) = (
        Dims::new(8, 8, 5).unwrap(),
        DirectionGrid::new(6, 8).unwrap(),
    );
    let field = OccupancyField::from_solid(dims, |_, _, k| k == 0);
    let bytes = encode(dims, dirs, GdmContent::Occupancy(&field));
    let pkg = Package::parse(bytes).unwrap();
    assert_eq!(pkg.occupancy().unwrap().unwrap(), field);
    let query = pkg.query().unwrap();
    assert!(matches!(query, GdmQuery::Occupancy(..)));
    for (a, b, k, j, i) in samples(dims, dirs) {
        let cos = dirs.theta(a).cos();
        let expected = match (k, cos > 0.0) {
            (0, _) => Some(0.0),
            (_, true) => None,
            (_, false) => Some((k as f64 - 0.5) / cos.abs()),
        };
        let got = query.distance(i, j, k, a, b).map(f64::from);
        match (got, expected) {
            (Some(g), Some(x)) => assert!((g - x).abs() < 1e-5, "{g} vs {x}"),
            (None, None) => {}
            _ => panic!("sample {i},{j},{k},{a},{b}: {got:?} vs {expected:?}"),
        }
    }
}

#[test]
fn a_march_wraps_around_the_tile_and_refuses_flat_directions() {
    // One solid voxel at (0, 0, 0); from (3.5, 0.5, 0.5) along −x it is 3 voxels away
    // (through x = 1), along +x the ray wraps: 4 voxels of an 8-wide tile later (x = 8).
    let dims = Dims::new(8, 4, 2).unwrap();
    let field = OccupancyField::from_solid(dims, |i, j, k| (i, j, k) == (0, 0, 0));
    let tilt = 1e-9; // not quite flat, so the ray may leave eventually
    let d = field.march([3.5, 0.5, 0.5], [-1.0, 0.0, tilt]).unwrap();
    assert!((d - 2.5).abs() < 1e-6, "{d}");
    let d = field.march([3.5, 0.5, 0.5], [1.0, 0.0, tilt]).unwrap();
    assert!((d - 4.5).abs() < 1e-6, "{d}");
    assert_eq!(field.march([3.5, 0.5, 0.5], [1.0, 0.0, 0.0]), None);
    assert_eq!(field.march([0.5, 0.5, 0.5], [0.0, 0.0, 1.0]), Some(0.0));
    assert_eq!(field.march([3.5, 0.5, 1.5], [0.0, 0.0, 1.0]), None);
}

#[test]
fn every_corrupted_byte_is_refused() {
    let (dims, dirs) = (
        Dims::new(4, 4, 3).unwrap(),
        DirectionGrid::new(2, 4).unwrap(),
    );
    let field = OccupancyField::from_solid(dims, |i, _, k| k == 0 || i == 2);
    let bytes = encode(dims, dirs, GdmContent::Occupancy(&field));
    for at in 0..bytes.len() {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        assert!(Package::parse(bad).is_err(), "byte {at} of {}", bytes.len());
    }
    let e = Package::parse(bytes[..100].to_vec()).unwrap_err();
    assert!(e.to_string().starts_with("package: "), "{e}");
}

#[test]
fn radiance_transfer_reads_back_and_answers_the_documented_sum() {
    let (info, transfer) = support::radiance_transfer(3);
    let package = Package::parse(support::pillars_with_gi(info, &transfer)).unwrap();
    let read = package.radiance_transfer().unwrap().unwrap();
    // Every value was chosen exactly representable in f16: the round trip is exact.
    assert_eq!(read, transfer);
    // docs/package-format.md: t_c,i(s, (a, b)) = Σ_k W[(s·48 + m)·r + k]·E[(m·Nθ·Nφ + a·Nφ + b)·r + k],
    // m = 16·c + i, with the voxel's sample s from rtv.index (x fastest).
    let index: Vec<u32> = (package.section("rtv.index").unwrap().chunks_exact(4))
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    let half = |name: &str, at: usize| {
        let b = &package.section(name).unwrap()[2 * at..];
        half::f16::from_le_bytes([b[0], b[1]]).to_f32()
    };
    let (mut samples, mut others) = (0, 0);
    for (voxel, [i, j, k]) in [[0, 0, 0], [1, 0, 0], [5, 3, 2], [11, 9, 5], [6, 7, 4]]
        .into_iter()
        .map(|[i, j, k]| ((k * 10 + j) * 12 + i, [i, j, k]))
    {
        for (a, b) in [(0, 0), (3, 7), (1, 5)] {
            let got = read.transfer_at_bin([i, j, k], [a, b]);
            let s = index[voxel as usize];
            if s == u32::MAX {
                assert_eq!(got, None);
                others += 1;
                continue;
            }
            samples += 1;
            let got = got.unwrap();
            for m in 0..48usize {
                let expected: f32 = (0..3)
                    .map(|kk| {
                        half("rtv.weights", (s as usize * 48 + m) * 3 + kk)
                            * half("rtv.eigen", (m * 32 + (a * 8 + b) as usize) * 3 + kk)
                    })
                    .sum();
                assert!((got[m / 16][m % 16] - expected).abs() < 1e-5, "m {m}");
            }
        }
    }
    assert!(
        samples > 0 && others > 0,
        "{samples} samples, {others} others"
    );
    assert_eq!(read.prt_matrix(4).unwrap(), &transfer.prt[4 * 256..]);
    assert_eq!(read.prt_matrix(5), None);
}

#[test]
fn radiance_transfer_with_a_bad_value_or_sample_index_is_refused_by_name() {
    let (info, transfer) = support::radiance_transfer(2);
    let mut cases: Vec<(mesobake_package::gi::RadianceTransfer, String)> = Vec::new();
    let mut t = transfer.clone();
    t.weights[17] = f32::NAN;
    cases.push((t, "weight or eigenfunction value is not finite".into()));
    let mut t = transfer.clone();
    t.eigen[3] = f32::INFINITY;
    cases.push((t, "weight or eigenfunction value is not finite".into()));
    let mut t = transfer.clone();
    t.prt[100] = f32::NEG_INFINITY;
    cases.push((t, "a PRT value is not finite".into()));
    let mut t = transfer.clone();
    t.sample_of[9] = info.samples;
    let n = info.samples;
    cases.push((t, format!("the sample map names sample {n} of {n}")));
    for (bad, expected) in cases {
        let err = Package::parse(support::pillars_with_gi(info.clone(), &bad)).unwrap_err();
        assert!(err.to_string().contains(&expected), "{err}");
    }
}

#[test]
fn a_package_is_refused_before_allocating_more_than_the_callers_limit() {
    // An empty 128³ field: 2 MiB of texels stored supercompressed in a small file, decoded to
    // f32 at most: file + 2 MiB + 8 MiB.
    let bytes = support::empty_occupancy(128);
    let file = bytes.len() as u64;
    assert!(file < 64 << 10, "{file} bytes");
    let package = Package::parse(bytes.clone()).unwrap();
    let needed = mesobake_package::container::memory_needed(file, &package.manifest().sections);
    assert_eq!(needed, file + (2 << 20) + (8 << 20));
    let err = Package::parse_within(bytes.clone(), needed - 1).unwrap_err();
    assert!(
        matches!(err, mesobake_package::Error::MemoryLimit { needed: n, limit, .. }
            if n == needed && limit == needed - 1),
        "{err}"
    );
    assert!(err.to_string().contains("over the memory limit"), "{err}");
    assert!(Package::parse_within(bytes, needed).is_ok());
}

#[test]
fn non_finite_factors_are_refused_in_either_float_format() {
    for q in [Quantization::F16, Quantization::F32] {
        assert!(Package::parse(support::random_svd(3, q)).is_ok());
        type Edit = fn(&mut Vec<f32>, &mut Vec<f32>);
        let cases: [(Edit, &str); 3] = [
            (|w, _| w[7] = f32::NAN, "weights"),
            (|w, _| w[100] = f32::NEG_INFINITY, "weights"),
            (|_, e| e[5] = f32::INFINITY, "eigen"),
        ];
        for (edit, factor) in cases {
            let e = Package::parse(support::random_svd_with(3, q, edit)).unwrap_err();
            let e = e.to_string();
            assert!(
                e.contains(&format!(
                    "the {factor} factor holds a value that is not finite"
                )),
                "{q:?}: {e}"
            );
        }
    }
}

#[test]
fn an_occupancy_count_or_a_bake_method_that_disagrees_with_the_package_is_refused() {
    let package = Package::parse(support::pillars()).unwrap();
    let (m, field) = (package.manifest(), package.occupancy().unwrap().unwrap());
    let encode = |solid_voxels: u64, method: Method, fast: Option<FastParams>| {
        let mut manifest = m.clone();
        manifest.occupancy.as_mut().unwrap().solid_voxels = solid_voxels;
        manifest.bake.method = method;
        manifest.bake.fast = fast;
        let payloads = vec![field.bytes().to_vec()];
        mesobake_package::container::assemble(&mut manifest, &payloads)
    };
    let (solid, fast) = (
        field.solid_voxels(),
        Some(FastParams {
            stride: 2,
            max_spread: 1.0,
        }),
    );
    assert!(Package::parse(encode(solid, Method::Exact, None)).is_ok());
    assert!(Package::parse(encode(solid, Method::Fast, fast)).is_ok());
    let e = Package::parse(encode(solid + 1, Method::Exact, None)).unwrap_err();
    assert!(
        e.to_string().contains(&format!(
            "solid_voxels {} but the field holds {solid}",
            solid + 1
        )),
        "{e}"
    );
    for (method, fast) in [(Method::Fast, None), (Method::Exact, fast)] {
        let e = Package::parse(encode(solid, method, fast)).unwrap_err();
        assert!(
            e.to_string()
                .contains("the fast method has them, the exact one not"),
            "{e}"
        );
    }
}
