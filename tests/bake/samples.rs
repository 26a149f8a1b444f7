//! Built-in samples: deterministic, closed on the tiling, and the volume and OBJ forms agree.

use mesobake_bake::gdm::caster::Caster;
use mesobake_bake::gdm::mesh_caster::MeshCaster;
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_bake::mesostructure::volume_format;
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;

/// The OBJ tile's inside classification of voxel centres agrees with the volume's solid voxels
/// for at least 97 % of voxels (they differ only within about half a voxel of the surface,
/// where supersampled voxelization and tessellation round differently); both forms are
/// byte-for-byte deterministic; the mesh is closed on the tiling.
#[test]
fn every_sample_is_closed_deterministic_and_consistent() {
    let d = Dims::new(32, 32, 16).unwrap();
    let limits = Limits::default();
    for kind in SampleKind::ALL {
        let vol = samples::volume(kind, d, &limits).unwrap();
        let bytes = volume_format::encode(&vol);
        assert_eq!(
            bytes,
            volume_format::encode(&samples::volume(kind, d, &limits).unwrap())
        );
        let occ = vol.occupancy();
        let solid = occ.solid_count();
        assert!(
            solid > 0 && solid < d.voxel_count(),
            "{kind:?}: {solid} solid voxels"
        );
        let mesh = samples::mesh(kind, d).unwrap();
        assert_eq!(mesh.to_obj(""), samples::mesh(kind, d).unwrap().to_obj(""));
        // Every part faces outward: the signed volume of the mesh (parts may overlap, so it
        // can exceed the union's) is at least 0.9 of the voxelized solid's volume and at most
        // 1.5 of it. A part turned inside out subtracts its volume twice. Threads and bars
        // close only modulo the tiling, so the volume is the flux of the field (0, 0, z),
        // periodic in x and y: ∑ (N_z / 2)·z̄ per triangle, N the edge cross product.
        let signed: f64 = (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                let n = mesobake_bake::mesostructure::trimesh::cross(
                    mesobake_bake::mesostructure::trimesh::sub(b, a),
                    mesobake_bake::mesostructure::trimesh::sub(c, a),
                );
                n[2] / 2.0 * (a[2] + b[2] + c[2]) / 3.0
            })
            .sum();
        let voxelized = solid as f64 / d.voxel_count() as f64 * d.z as f64 / d.x as f64;
        let ratio = signed / voxelized;
        assert!(
            (0.9..1.5).contains(&ratio),
            "{kind:?}: mesh/voxel volume {ratio:.3}"
        );
        let tile = MeshTile::new(mesh, false).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert!(tile.report.is_closed(), "{kind:?}: {:?}", tile.report);
        let caster = MeshCaster::new(&tile, d, &limits).unwrap();
        let inside = caster.centres_inside();
        let mut agree = 0u64;
        for k in 0..d.z {
            for j in 0..d.y {
                for i in 0..d.x {
                    agree += (inside.get(i, j, k) == occ.get(i, j, k)) as u64;
                }
            }
        }
        let frac = agree as f64 / d.voxel_count() as f64;
        assert!(frac >= 0.97, "{kind:?}: only {:.2} % agree", frac * 100.0);
    }
}
