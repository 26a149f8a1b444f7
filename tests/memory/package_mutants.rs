//! The seeded mutation fuzzer over packages of every kind, its readings measured by the
//! counting allocator.

use mesobake_core::Error;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;
use mesobake_scene::bench::bakes::MemoryProbe;

/// A package of every kind: GDM (occupancy; paper-svd in f16 and u8; with radiance transfer),
/// VDM (the CLI's, at 32² texels) and medium (two levels, u8); and a bomb: an empty 320³
/// occupancy field, under 1 MiB stored supercompressed, 131 MB decoded. Each with whether it
/// reads under `limit`.
fn one_package_of_every_kind(
    dir: &std::path::Path,
    limit: u64,
) -> Vec<(&'static str, Vec<u8>, bool)> {
    use crate::package_support as support;
    use mesobake_bake::compress::quantize::Quantization;
    let (info, transfer) = support::radiance_transfer(2);
    let vdm = dir.join("vdm.mbpkg");
    crate::common::succeeds(&[
        "vdm",
        "--relief",
        "bumps",
        "--size",
        "32",
        "--package",
        vdm.to_str().unwrap(),
    ]);
    let dims = Dims::new(8, 8, 4).unwrap();
    let voxels: Vec<[f32; 4]> = (0..256)
        .map(|v| [0.5, 0.4, 0.3, if v % 3 == 0 { 0.8 } else { 0.0 }])
        .collect();
    let medium = mesobake_bake::mesostructure::medium::Medium::from_parts(
        dims,
        &voxels,
        &vec![[0.0, 0.0, 1.0]; 256],
    );
    let input = mesobake_package::manifest::InputInfo {
        kind: "medium".into(),
        bytes: 0,
        blake3: "0".repeat(64),
    };
    let medium = mesobake_bake::package::medium::encode(
        input,
        &medium,
        &medium.coarser_levels(),
        Quantization::U8,
    );
    let bomb = support::empty_occupancy(320);
    assert!(bomb.len() < 1 << 20 && 320u64.pow(3) * 4 > limit);
    vec![
        ("occupancy", support::pillars(), true),
        (
            "paper-svd f16",
            support::random_svd(3, Quantization::F16),
            true,
        ),
        (
            "paper-svd u8",
            support::random_svd(2, Quantization::U8),
            true,
        ),
        (
            "gdm with gi",
            support::pillars_with_gi(info, &transfer),
            true,
        ),
        ("vdm", std::fs::read(&vdm).unwrap(), true),
        ("medium", medium, true),
        ("occupancy bomb", bomb, false),
    ]
}

/// A deterministic pseudo-random source (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Every number in `json` (a manifest), as pointers to edit.
fn number_paths(json: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match json {
        serde_json::Value::Number(_) => out.push(at),
        serde_json::Value::Array(a) => {
            for (i, v) in a.iter().enumerate().take(8) {
                number_paths(v, format!("{at}/{i}"), out);
            }
        }
        serde_json::Value::Object(o) => {
            for (k, v) in o {
                number_paths(v, format!("{at}/{k}"), out);
            }
        }
        _ => {}
    }
}

/// `bytes` (a valid GDM or VDM package) with one bit of one section's texels flipped and the
/// package assembled again, so that the change passes every checksum and any supercompression
/// and meets the validation of the content itself.
fn with_texel_flipped(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    use mesobake_package::container::assemble;
    let flipped = |texels: Vec<Vec<u8>>, rng: &mut Rng| {
        let mut texels = texels;
        let s = rng.below(texels.len());
        let at = rng.below(texels[s].len());
        if let Some(b) = texels[s].get_mut(at) {
            *b ^= 1 << rng.below(8);
        }
        texels
    };
    if let Ok(p) = mesobake_package::vdm::VdmPackage::parse(bytes.to_vec()) {
        let mut m = p.manifest().clone();
        let texels = (m.sections.iter()).map(|s| p.section(&s.name).unwrap().to_vec());
        let texels = flipped(texels.collect(), rng);
        return assemble(&mut m, &texels);
    }
    let p = mesobake_package::Package::parse(bytes.to_vec()).unwrap();
    let mut m = p.manifest().clone();
    let texels = (m.sections.iter()).map(|s| p.section(&s.name).unwrap().to_vec());
    let texels = flipped(texels.collect(), rng);
    assemble(&mut m, &texels)
}

/// `bytes` mutated one of four ways: a flipped byte; a truncation; a flipped texel in a
/// section, the package assembled again (a medium's: a flipped stored byte with the checksums
/// re-forged); a number of the
/// manifest replaced by an awkward one (0, −1, huge, fractional, 2³²) with checksums re-forged.
fn mutate(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let manifest_at = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    let manifest: serde_json::Value = serde_json::from_slice(&bytes[manifest_at..]).unwrap();
    match rng.below(4) {
        0 => {
            let at = rng.below(out.len());
            out[at] ^= 1 << rng.below(8);
            out
        }
        1 => {
            out.truncate(rng.below(out.len()));
            out
        }
        2 if manifest["format"] != "mesobake-medium-package" => with_texel_flipped(bytes, rng),
        2 => {
            let sections = manifest["sections"].as_array().unwrap();
            let s = rng.below(sections.len());
            let (offset, len) = (
                sections[s]["offset"].as_u64().unwrap() as usize,
                sections[s]["bytes"].as_u64().unwrap() as usize,
            );
            if len == 0 {
                return out;
            }
            out[offset + rng.below(len)] ^= 1 << rng.below(8);
            let crc = crc32fast::hash(&out[offset..offset + len]);
            crate::package_edit::with_manifest(&out, |m| m["sections"][s]["crc32"] = crc.into())
        }
        _ => {
            let mut paths = Vec::new();
            number_paths(&manifest, String::new(), &mut paths);
            let path = paths[rng.below(paths.len())].clone();
            let awkward = [
                serde_json::json!(0),
                serde_json::json!(-1),
                serde_json::json!(1e300),
                serde_json::json!(0.5),
                serde_json::json!(1u64 << 32),
                serde_json::json!(u64::MAX),
            ];
            let value = awkward[rng.below(awkward.len())].clone();
            crate::package_edit::with_manifest(&out, |m| *m.pointer_mut(&path).unwrap() = value)
        }
    }
}

/// The seeded mutation fuzzer over packages of every kind: 4,808 mutants (800 per kind, 8 of the bomb),
/// each parsed under a 64 MiB memory limit and, where accepted, read the way renderers read
/// it (GDM queries, a reconstruction under the limit, the radiance transfer, VDM lookups,
/// medium levels). Nothing may panic or abort; every refusal names its problem; and whether
/// accepted or refused, a mutant's reading never holds more heap than the limit beyond the
/// mutant's own bytes (measured by the counting allocator: the peak of live bytes).
#[test]
fn mutated_packages_of_every_kind_never_panic_stay_within_the_limit_and_are_refused_by_name() {
    use mesobake_bake::package::AnyPackage;
    let _measuring = crate::measuring();
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits {
        memory_bytes: 64 << 20,
        ..Limits::default()
    };
    let mut rng = Rng(0x5EED);
    let (mut accepted, mut refused, mut largest) = (0, 0, 0);
    for (kind, bytes, reads) in one_package_of_every_kind(dir.path(), limits.memory_bytes) {
        let before = crate::ALLOCATOR.current_bytes();
        crate::ALLOCATOR.reset_peak();
        let parsed = AnyPackage::parse_within(bytes.clone(), &limits).is_ok();
        let held = crate::ALLOCATOR.peak_bytes().saturating_sub(before);
        assert!(held <= limits.memory_bytes, "{kind}: {held} bytes held");
        assert_eq!(parsed, reads, "{kind}");
        // The bomb's mutants re-assemble 131 MB of texels each: a few of them.
        let cases = if reads { 800 } else { 8 };
        for case in 0..cases {
            let mutant = mutate(&bytes, &mut rng);
            let before = crate::ALLOCATOR.current_bytes();
            crate::ALLOCATOR.reset_peak();
            let outcome = std::panic::catch_unwind(|| -> Result<(), Error> {
                let len = mutant.len() as u64;
                match AnyPackage::parse_within(mutant.clone(), &limits)? {
                    AnyPackage::Gdm(p) => {
                        let needed =
                            mesobake_package::container::memory_needed(len, &p.manifest().sections);
                        assert!(needed <= limits.memory_bytes, "{kind} {case}: {needed}");
                        let query = p.query()?;
                        let (d, g) = (p.dims(), p.dirs());
                        query.distance(d.x - 1, d.y / 2, 0, g.n_theta - 1, 0);
                        p.reconstruct(&limits)?;
                        p.radiance_transfer().transpose()?;
                    }
                    AnyPackage::Vdm(p) => {
                        let query = p.query();
                        let g = p.manifest().bake.grid;
                        let [w, h] = p.manifest().relief.size;
                        query.distance(w - 1, h - 1, g.n_theta - 1, g.n_phi - 1, 0);
                        query.sample(0.3, 0.7, 1.0, 2.0, 0.5);
                    }
                    AnyPackage::Medium(p) => {
                        mesobake_bake::package::medium::levels(&p, true)?;
                    }
                }
                Ok(())
            });
            let held = crate::ALLOCATOR.peak_bytes().saturating_sub(before);
            let allowed = limits.memory_bytes + 2 * mutant.len() as u64;
            assert!(held <= allowed, "{kind}, mutant {case}: {held} bytes held");
            largest = largest.max(held);
            match outcome {
                Err(_) => panic!("{kind}, mutant {case}: a panic"),
                Ok(Ok(())) => accepted += 1,
                Ok(Err(e)) => {
                    let message = e.to_string();
                    assert!(message.len() > 12, "{kind}, mutant {case}: {message:?}");
                    refused += 1;
                }
            }
        }
    }
    eprintln!(
        "{accepted} mutants accepted, {refused} refused; the most heap one held: {largest} bytes"
    );
    // Most mutants are refused (checksums catch flips; re-forged ones meet validation).
    assert!(
        refused > 3 * accepted,
        "{refused} refused, {accepted} accepted"
    );
}
