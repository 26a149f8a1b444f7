//! Bad input gets a clear error naming the problem, never a panic.

use mesobake_bake::gdm::{self, Method};
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::trimesh::TriMesh;
use mesobake_bake::mesostructure::volume::Volume;
use mesobake_bake::mesostructure::volume_format::{self, HEADER_BYTES};
use mesobake_core::Error;
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};

fn sample_bytes() -> Vec<u8> {
    let d = Dims::new(4, 4, 2).unwrap();
    let v = Volume::from_fn(d, &Limits::default(), |i, j, k| (i + j + k) % 3 == 0).unwrap();
    volume_format::encode(&v)
}

fn decode_err(bytes: &[u8]) -> String {
    match volume_format::decode(bytes, &Limits::default()) {
        Ok(_) => panic!("accepted bad bytes"),
        Err(e) => e.to_string(),
    }
}

fn set_u32(bytes: &mut [u8], offset: usize, v: u32) {
    bytes[offset..offset + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn volume_round_trips_byte_identically() {
    let bytes = sample_bytes();
    let v = volume_format::decode(&bytes, &Limits::default()).unwrap();
    assert_eq!(volume_format::encode(&v), bytes);
}

#[test]
fn volume_header_errors_name_the_field() {
    let good = sample_bytes();
    let mut b = good.clone();
    b[0] = b'X';
    assert!(decode_err(&b).contains("magic"));
    let mut b = good.clone();
    set_u32(&mut b, 8, 7);
    assert!(decode_err(&b).contains("version 7"));
    let mut b = good.clone();
    set_u32(&mut b, 16, 0);
    assert!(decode_err(&b).contains("dimensions 4x0x2"));
    let mut b = good.clone();
    set_u32(&mut b, 24, 0x10);
    assert!(decode_err(&b).contains("channel"));
    let mut b = good.clone();
    b[28..32].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(decode_err(&b).contains("threshold"));
    let mut b = good.clone();
    b[32..36].copy_from_slice(&(-1.0f32).to_le_bytes());
    assert!(decode_err(&b).contains("voxel size"));
    let mut b = good.clone();
    b.push(0);
    assert!(decode_err(&b).contains("unexpected bytes"));
    let mut b = good.clone();
    let last = b.len() - 1;
    b[last] ^= 1;
    assert!(decode_err(&b).contains("checksum"));
}

/// Every truncation is refused with an error, never a panic.
#[test]
fn volume_truncated_at_every_offset() {
    let good = sample_bytes();
    for len in 0..good.len() {
        let e = decode_err(&good[..len]);
        assert!(
            e.contains("truncated") || e.contains("shorter than") || e.contains("magic"),
            "{len}: {e}"
        );
    }
}

/// A header asking for 65536³ voxels is refused by the memory limit before any allocation.
#[test]
fn huge_volume_refused_before_allocating() {
    let mut b = sample_bytes();
    for off in [12, 16, 20] {
        set_u32(&mut b, off, 65536);
    }
    assert!(decode_err(&b).contains("memory limit"));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.mbvol");
    std::fs::write(&path, &b[..HEADER_BYTES]).unwrap();
    let e = volume_format::read(&path, &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::MemoryLimit { .. }), "{e}");
}

#[test]
fn non_finite_density_is_named() {
    let d = Dims::new(2, 2, 2).unwrap();
    let mut density = vec![0.0f32; 8];
    density[5] = f32::INFINITY;
    let e = Volume::new(d, density, 0.5, None).unwrap_err().to_string();
    assert!(e.contains("voxel (1, 0, 1)") && e.contains("inf"), "{e}");
    let e = Volume::new(d, vec![0.0; 7], 0.5, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("7 densities"), "{e}");
}

#[test]
fn gdm_over_memory_limit_is_refused() {
    let d = Dims::new(4, 4, 2).unwrap();
    let v = Volume::from_fn(d, &Limits::default(), |_, _, _| false).unwrap();
    let c = mesobake_bake::gdm::volume_caster::VolumeCaster::new(&v);
    let limits = Limits {
        memory_bytes: 1000,
        ..Limits::default()
    };
    let e = gdm::bake(
        &c,
        DirectionGrid::PAPER,
        Method::Exact,
        Default::default(),
        &limits,
        &(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::MemoryLimit { needed: 65536, .. }), "{e}");
    assert!(
        "64x64x0"
            .parse::<Dims>()
            .unwrap_err()
            .to_string()
            .contains("z must be")
    );
    assert!("16x32x".parse::<DirectionGrid>().is_err());
}

fn obj_err(text: &str) -> String {
    match TriMesh::from_obj(text).and_then(|m| MeshTile::new(m, false)) {
        Ok(_) => panic!("accepted bad OBJ"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn obj_errors_name_the_problem() {
    assert!(obj_err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").contains("out of bounds"));
    assert!(obj_err("v 0 0 nan\nv 0.5 0 0\nv 0 0.5 0\nf 1 2 3\n").contains("non-finite"));
    assert!(obj_err("v 0 0 0\nv 1 0 0\n").contains("no faces"));
    assert!(obj_err("v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n").contains("spans"));
    assert!(obj_err("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n").contains("degenerate"));
    let open = "v 0.1 0.1 0.1\nv 0.5 0.1 0.1\nv 0.1 0.5 0.1\nf 1 2 3\n";
    let e = obj_err(open);
    assert!(
        e.contains("not a closed surface") && e.contains("3 boundary edges"),
        "{e}"
    );
    // With allow_open the sheet is accepted, and nothing is inside.
    let tile = MeshTile::new(TriMesh::from_obj(open).unwrap(), true).unwrap();
    assert!(!tile.closed);
    let c = mesobake_bake::gdm::mesh_caster::MeshCaster::new(
        &tile,
        Dims::new(8, 8, 4).unwrap(),
        &Limits::default(),
    )
    .unwrap();
    use mesobake_bake::gdm::caster::Caster;
    assert_eq!(c.centres_inside().solid_count(), 0);
    assert!(TriMesh::from_obj("v 0 0 0\nf 1 1 x\n").is_err());
    let e = MeshTile::new(
        TriMesh::from_obj("v 0 0 0\nv 0.5 0 0\nv 0 0.5 0\nf 1 2 3\n").unwrap(),
        false,
    )
    .unwrap_err();
    assert!(e.to_string().contains("boundary edges"));
}

#[test]
fn copies_of_one_triangle_are_dropped_as_duplicates() {
    // The probe's open tile: three vertices and N copies of one face (100,000 took over
    // 120 s in the BVH build); copies either way round count as one triangle.
    let mut obj = String::from("v 0.1 0.1 0.1\nv 0.5 0.1 0.1\nv 0.1 0.5 0.1\n");
    for _ in 0..50_000 {
        obj.push_str("f 1 2 3\nf 3 2 1\n");
    }
    let tile = MeshTile::new(TriMesh::from_obj(&obj).unwrap(), true).unwrap();
    assert_eq!(tile.mesh.triangles.len(), 1);
    assert_eq!(tile.report.duplicates, 99_999);
    assert_eq!(tile.report.triangles, 100_000);
    let caster = mesobake_bake::gdm::mesh_caster::MeshCaster::new(
        &tile,
        Dims::new(8, 8, 4).unwrap(),
        &Limits::default(),
    );
    assert!(caster.is_ok());
}

#[test]
fn mesh_grid_must_be_square() {
    let mesh = mesobake_bake::mesostructure::samples::mesh(
        mesobake_bake::mesostructure::samples::SampleKind::Chain,
        Dims::new(8, 8, 4).unwrap(),
    )
    .unwrap();
    let tile = MeshTile::new(mesh, false).unwrap();
    let e = mesobake_bake::gdm::mesh_caster::MeshCaster::new(
        &tile,
        Dims::new(8, 16, 4).unwrap(),
        &Limits::default(),
    );
    assert!(e.err().unwrap().to_string().contains("X = Y"));
}

fn translucent_bytes() -> Vec<u8> {
    let d = Dims::new(4, 4, 2).unwrap();
    let v = Volume::from_fn(d, &Limits::default(), |i, _, _| i == 0).unwrap();
    let opacity = (0..32).map(|n| n as f32 / 31.0).collect();
    volume_format::encode(&v.with_opacity(opacity).unwrap())
}

/// The opacity channel is version 2, round-trips byte for byte, and is refused in version 1
/// files; opacities outside [0, 1] or non-finite are named by voxel.
#[test]
fn opacity_channel_is_versioned_and_validated() {
    let bytes = translucent_bytes();
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 2);
    assert_eq!(
        u32::from_le_bytes(sample_bytes()[8..12].try_into().unwrap()),
        1
    );
    let v = volume_format::decode(&bytes, &Limits::default()).unwrap();
    assert_eq!(v.opacity().unwrap()[31], 1.0);
    assert_eq!(volume_format::encode(&v), bytes);
    let mut b = bytes.clone();
    set_u32(&mut b, 8, 1);
    let e = decode_err(&b);
    assert!(
        e.contains("channel set 0x5 is invalid for version 1"),
        "{e}"
    );
    for (value, shown) in [(1.5f32, "1.5"), (-0.25, "-0.25"), (f32::NAN, "NaN")] {
        let d = Dims::new(2, 2, 2).unwrap();
        let v = Volume::from_fn(d, &Limits::default(), |_, _, _| true).unwrap();
        let mut opacity = vec![0.5f32; 8];
        opacity[6] = value;
        let e = v.with_opacity(opacity).unwrap_err().to_string();
        assert!(e.contains("voxel (0, 1, 1)") && e.contains(shown), "{e}");
    }
    for len in [bytes.len() - 4, bytes.len() - 1] {
        let e = decode_err(&bytes[..len]);
        assert!(e.contains("truncated"), "{e}");
    }
}

/// A package of every kind: GDM (occupancy; paper-svd in f16 and u8; with radiance transfer),
/// VDM (the CLI's, at 32² texels) and medium (two levels, u8).
fn one_package_of_every_kind(dir: &std::path::Path) -> Vec<(&'static str, Vec<u8>)> {
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
    vec![
        ("occupancy", support::pillars()),
        ("paper-svd f16", support::random_svd(3, Quantization::F16)),
        ("paper-svd u8", support::random_svd(2, Quantization::U8)),
        ("gdm with gi", support::pillars_with_gi(info, &transfer)),
        ("vdm", std::fs::read(&vdm).unwrap()),
        ("medium", medium),
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
            crate::package::with_manifest(&out, |m| m["sections"][s]["crc32"] = crc.into())
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
            crate::package::with_manifest(&out, |m| *m.pointer_mut(&path).unwrap() = value)
        }
    }
}

/// The seeded mutation fuzzer over packages of every kind: 4,800 mutants (800 per kind),
/// each parsed under a 64 MiB memory limit and, where accepted, read the way renderers read
/// it (GDM queries, a reconstruction under the limit, the radiance transfer, VDM lookups,
/// medium levels). Nothing may panic or abort; an accepted mutant's reading stays within the
/// limit; every refusal names its problem.
#[test]
fn mutated_packages_of_every_kind_never_panic_and_are_refused_by_name() {
    use mesobake_bake::package::AnyPackage;
    let dir = tempfile::tempdir().unwrap();
    let limits = Limits {
        memory_bytes: 64 << 20,
        ..Limits::default()
    };
    let mut rng = Rng(0x5EED);
    let (mut accepted, mut refused) = (0, 0);
    for (kind, bytes) in one_package_of_every_kind(dir.path()) {
        assert!(
            AnyPackage::parse_within(bytes.clone(), &limits).is_ok(),
            "{kind}"
        );
        for case in 0..800 {
            let mutant = mutate(&bytes, &mut rng);
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
    // Most mutants are refused (checksums catch flips; re-forged ones meet validation).
    assert!(
        refused > 3 * accepted,
        "{refused} refused, {accepted} accepted"
    );
}
