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
