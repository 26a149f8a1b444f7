//! VDM packages with the format crate alone: what is written reads back and reconstructs as
//! the shared-weights SVD says, writing is deterministic, and corrupt or inconsistent
//! packages are refused by name.

use mesobake_package::Package;
use mesobake_package::container;
use mesobake_package::manifest::{FORMAT_NAME, InputInfo, TexelFormat, TextureDimension};
use mesobake_package::quantize::{Quantization, QuantizedFactor};
use mesobake_package::supercompression::Supercompression;
use mesobake_package::vdm::{
    ReliefInfo, VDM_FORMAT_NAME, VdmAccuracy, VdmBakeInfo, VdmContent, VdmGrid, VdmManifest,
    VdmMethod, VdmPackage,
};

#[path = "support/mod.rs"]
mod support;

const SIZE: [u32; 2] = [5, 3];
const GRID: VdmGrid = VdmGrid {
    n_theta: 3,
    n_phi: 4,
    n_curvature: 2,
    c_min: -1.0,
    c_max: 2.0,
};
const RANK: usize = 5; // two texture groups, the second one channel wide
const MVM_RANK: usize = 3;

/// SplitMix64's finalizer of `n`, in [0, 1): noise with no structure a predictor finds
/// (`support::noise` is a Weyl sequence, whose differences are constant).
fn hashed(n: usize) -> f32 {
    let mut z = (n as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// W (rows (φ, y, x)) in [0, 1) and E (rows (c, θ), then (c)) in [0, 1.2): a mix of
/// silhouettes and hits. Hashed weights do not compress in u8; `repeating` weights, whose rows
/// repeat with period 2, do.
fn factors_of(q: Quantization, repeating: bool) -> (QuantizedFactor, QuantizedFactor) {
    let rows = (SIZE[0] * SIZE[1] * GRID.n_phi) as usize;
    let cols = (GRID.n_curvature * (GRID.n_theta + 1)) as usize;
    let w: Vec<f32> = (0..rows * RANK)
        .map(|x| match repeating {
            true => support::noise(x % (2 * RANK)),
            false => hashed(x),
        })
        .collect();
    let e: Vec<f32> = (0..cols * RANK)
        .map(|x| 1.2 * support::noise(x + 7919))
        .collect();
    (
        QuantizedFactor::new(&w, RANK, q),
        QuantizedFactor::new(&e, RANK, q),
    )
}

fn factors(q: Quantization) -> (QuantizedFactor, QuantizedFactor) {
    factors_of(q, false)
}

fn encode(weights: &QuantizedFactor, eigen: &QuantizedFactor) -> Vec<u8> {
    let input = InputInfo {
        kind: "relief".into(),
        bytes: 0,
        blake3: "0".repeat(64),
    };
    let spectrum = vec![1.0; (GRID.n_curvature * (GRID.n_theta + 1)) as usize];
    let heights: Vec<f32> = (0..SIZE[0] * SIZE[1])
        .map(|t| support::noise(t as usize))
        .collect();
    VdmPackage::encode(
        input,
        VdmContent {
            relief: ReliefInfo {
                size: SIZE,
                depth: 0.125,
            },
            bake: VdmBakeInfo {
                grid: GRID,
                method: VdmMethod::Exact,
                oversampling: 1,
            },
            mvm_rank: MVM_RANK,
            spectrum: &spectrum,
            weights,
            eigen,
            accuracy: VdmAccuracy::default(),
            heights: &heights,
        },
    )
}

/// Both with sections stored as texels and supercompressed: the writer compresses the
/// repeating weights and stores u8 noise as it is.
#[test]
fn vdm_packages_reconstruct_the_shared_weights_svd() {
    for (q, repeating) in Quantization::ALL
        .into_iter()
        .flat_map(|q| [(q, false), (q, true)])
    {
        let (w, e) = factors_of(q, repeating);
        let bytes = encode(&w, &e);
        assert_eq!(bytes, encode(&w, &e), "{q}: writing is deterministic");
        let pkg = VdmPackage::parse(bytes).unwrap();
        let m = pkg.manifest();
        let weights = m
            .sections
            .iter()
            .find(|s| s.name == "vdm.weights.0")
            .unwrap();
        let compressed = weights.supercompression == Some(Supercompression::PaethZlib);
        assert_eq!(
            compressed,
            weights.bytes < weights.texture.byte_len().unwrap(),
            "{q}: stored compressed exactly where smaller"
        );
        if repeating || q == Quantization::U8 {
            assert_eq!(compressed, repeating, "{q}: u8 noise does not compress");
        }
        assert_eq!((m.vdm.vdm_rank, m.vdm.mvm_rank), (5, 3));
        let texture = |name: &str| {
            let s = m.sections.iter().find(|s| s.name == name).unwrap();
            (
                s.texture.dimension,
                s.texture.width,
                s.texture.height,
                s.texture.depth,
            )
        };
        assert_eq!(texture("vdm.weights.1"), (TextureDimension::D3, 5, 3, 4));
        assert_eq!(texture("vdm.height"), (TextureDimension::D2, 5, 3, 1));
        let heights: Vec<f32> = (0..15).map(support::noise).collect();
        assert_eq!(pkg.heights(), heights);
        assert_eq!(texture("vdm.eigen.0"), (TextureDimension::D2, 3, 2, 1));
        assert_eq!(texture("vdm.mvm.0"), (TextureDimension::D2, 2, 1, 1));
        assert!(!m.sections.iter().any(|s| s.name == "vdm.mvm.1"));
        let mvm_format = m.sections.iter().find(|s| s.name == "vdm.mvm.0").unwrap();
        assert_eq!(mvm_format.texture.format, TexelFormat::of(q, MVM_RANK));

        let (wd, ed) = (w.dequantize(), e.dequantize());
        let dot = |row: usize, col: usize, n: usize| -> f32 {
            (0..n)
                .map(|l| wd[row * RANK + l] * ed[col * RANK + l])
                .sum()
        };
        let query = pkg.query();
        let (mut hits, mut silhouettes) = (0, 0);
        for k in 0..GRID.n_curvature {
            for a in 0..GRID.n_theta {
                for b in 0..GRID.n_phi {
                    for j in 0..SIZE[1] {
                        for i in 0..SIZE[0] {
                            let row = ((b * SIZE[1] + j) * SIZE[0] + i) as usize;
                            let mvm_col = (GRID.n_curvature * GRID.n_theta + k) as usize;
                            let max_theta = dot(row, mvm_col, MVM_RANK);
                            let got_max = query.max_theta(i, j, b, k);
                            // Same products, same order: equal to rounding.
                            assert!((got_max - max_theta).abs() <= 1e-6, "{q}");
                            let expected = (GRID.theta(a) as f32 <= got_max)
                                .then(|| dot(row, (k * GRID.n_theta + a) as usize, RANK));
                            match (query.distance(i, j, a, b, k), expected) {
                                (Some(d), Some(x)) => {
                                    assert!((d - x).abs() <= 1e-6, "{q}: {d} vs {x}");
                                    hits += 1;
                                }
                                (None, None) => silhouettes += 1,
                                (got, x) => panic!("{q}: {i},{j},{a},{b},{k}: {got:?} vs {x:?}"),
                            }
                        }
                    }
                }
            }
        }
        assert!(
            hits > 0 && silhouettes > 0,
            "{q}: {hits} hits, {silhouettes} silhouettes"
        );
    }
}

#[test]
fn every_corrupted_byte_of_a_vdm_package_is_refused() {
    let (w, e) = factors(Quantization::U8);
    let bytes = encode(&w, &e);
    for at in 0..bytes.len() {
        let mut bad = bytes.clone();
        bad[at] ^= 0x04;
        assert!(
            VdmPackage::parse(bad).is_err(),
            "byte {at} of {}",
            bytes.len()
        );
    }
}

#[test]
fn the_two_package_kinds_tell_themselves_apart() {
    let (w, e) = factors(Quantization::F16);
    let vdm = encode(&w, &e);
    let gdm = support::pillars();
    assert_eq!(container::format(&vdm).unwrap(), VDM_FORMAT_NAME);
    assert_eq!(container::format(&gdm).unwrap(), FORMAT_NAME);
    let e = Package::parse(vdm).unwrap_err().to_string();
    assert!(e.contains("mesobake-vdm-package"), "{e}");
    let e = VdmPackage::parse(gdm).unwrap_err().to_string();
    assert!(e.contains("\"mesobake-package\""), "{e}");
}

/// The package with its manifest changed by `edit`, checksums and offsets redone.
fn reassembled(edit: impl Fn(&mut VdmManifest)) -> Result<VdmPackage, String> {
    let (w, e) = factors(Quantization::U8);
    let pkg = VdmPackage::parse(encode(&w, &e)).unwrap();
    let mut manifest = pkg.manifest().clone();
    edit(&mut manifest);
    let payloads: Vec<Vec<u8>> = manifest
        .sections
        .iter()
        .map(|s| pkg.section(&s.name).unwrap().to_vec())
        .collect();
    VdmPackage::parse(container::assemble(&mut manifest, &payloads)).map_err(|e| e.to_string())
}

#[test]
fn inconsistent_vdm_manifests_are_refused_by_name() {
    assert!(
        reassembled(|_| {}).is_ok(),
        "the unchanged manifest is valid"
    );
    type Edit = Box<dyn Fn(&mut VdmManifest)>;
    let cases: [(&str, Edit); 9] = [
        ("ranks", Box::new(|m| m.vdm.mvm_rank = 6)),
        (
            "vdm.height",
            Box::new(|m| m.sections.retain(|s| s.name != "vdm.height")),
        ),
        ("ranks", Box::new(|m| m.vdm.vdm_rank = 0)),
        ("oversampling", Box::new(|m| m.bake.oversampling = 2)),
        ("past the centre", Box::new(|m| m.bake.grid.c_max = 9.0)),
        ("relief depth", Box::new(|m| m.relief.depth = -0.1)),
        (
            "spectrum",
            Box::new(|m| {
                m.vdm.spectrum.pop();
            }),
        ),
        ("mvm factor", Box::new(|m| m.vdm.mvm.scale.push(1.0))),
        (
            "vdm.eigen.0",
            Box::new(|m| {
                let s = m
                    .sections
                    .iter_mut()
                    .find(|s| s.name == "vdm.eigen.0")
                    .unwrap();
                // As many bytes as before: only the layout check can refuse it.
                s.texture.dimension = TextureDimension::D3;
            }),
        ),
    ];
    for (what, edit) in cases {
        match reassembled(edit) {
            Ok(_) => panic!("{what}: accepted"),
            Err(e) => assert!(e.contains(what), "{what}: {e}"),
        }
    }
}

/// `bytes` with its manifest's section `name` changed by `edit` and the manifest's and
/// header's fields and checksums redone; `edit` also gets the section's stored bytes.
fn with_section_edited(
    bytes: &[u8],
    name: &str,
    edit: impl FnOnce(&mut serde_json::Value, &mut [u8]),
) -> Vec<u8> {
    let offset = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    let mut json: serde_json::Value = serde_json::from_slice(&bytes[offset..]).unwrap();
    let mut out = bytes[..offset].to_vec();
    let section = (json["sections"].as_array_mut().unwrap().iter_mut())
        .find(|s| s["name"] == name)
        .unwrap();
    let (at, len) = (
        section["offset"].as_u64().unwrap() as usize,
        section["bytes"].as_u64().unwrap() as usize,
    );
    edit(section, &mut out[at..][..len]);
    section["crc32"] = crc32fast::hash(&out[at..][..len]).into();
    let text = serde_json::to_vec(&json).unwrap();
    out.extend_from_slice(&text);
    let total = out.len() as u64;
    out[24..32].copy_from_slice(&(text.len() as u64).to_le_bytes());
    out[32..36].copy_from_slice(&crc32fast::hash(&text).to_le_bytes());
    out[40..48].copy_from_slice(&total.to_le_bytes());
    let header_crc = crc32fast::hash(&out[..60]);
    out[60..64].copy_from_slice(&header_crc.to_le_bytes());
    out
}

/// A supercompressed section whose stream is damaged, with every checksum redone, is refused
/// naming the section: the stream's own Adler-32 or its length catches what the CRC no longer
/// can. One that claims a texture larger than a reader inflates is refused before inflating:
/// by the caller's memory limit, and past it by the format's cap on inflated sections.
#[test]
fn damaged_or_oversized_supercompressed_sections_are_refused_by_name() {
    let (w, e) = factors_of(Quantization::U8, true);
    let bytes = encode(&w, &e);
    assert!(VdmPackage::parse(with_section_edited(&bytes, "vdm.weights.0", |_, _| {})).is_ok());
    for at in [0.0, 0.5, 1.0] {
        let bad = with_section_edited(&bytes, "vdm.weights.0", |s, stored| {
            assert_eq!(s["supercompression"], "paeth-zlib");
            let i = ((stored.len() - 1) as f64 * at) as usize;
            stored[i] ^= 0x10;
        });
        let e = VdmPackage::parse(bad).unwrap_err().to_string();
        assert!(
            e.contains("section \"vdm.weights.0\": its stream"),
            "byte at {at} of the stream: {e}"
        );
    }
    let bad = with_section_edited(&bytes, "vdm.weights.0", |s, _| {
        s["texture"]["depth"] = (1u64 << 28).into();
    });
    let e = VdmPackage::parse(bad.clone()).unwrap_err().to_string();
    assert!(e.contains("over the memory limit of 4294967296"), "{e}");
    // Past any caller's limit, the format's own cap on inflated sections still holds.
    let e = VdmPackage::parse_within(bad, u64::MAX)
        .unwrap_err()
        .to_string();
    assert!(e.contains("over the limit of 4294967296"), "{e}");
}
