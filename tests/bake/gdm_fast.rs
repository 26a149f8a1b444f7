//! The fast (sweep) bake against the exact bake, with the error bounds it must hold.

use mesobake_bake::gdm::compare::compare;
use mesobake_bake::gdm::exact;
use mesobake_bake::gdm::fast::{self, FastParams};
use mesobake_bake::gdm::mesh_caster::MeshCaster;
use mesobake_bake::gdm::volume_caster::VolumeCaster;
use mesobake_bake::mesostructure::mesh_tile::MeshTile;
use mesobake_bake::mesostructure::samples::{self, SampleKind};
use mesobake_core::limits::Limits;
use mesobake_package::grid::{Dims, DirectionGrid};

/// On every sample at 32×32×16 with 8×16 directions, the default fast bake stays within the
/// targets of the W1 benchmark: mean absolute error ≤ 0.25 voxel over samples both bakes hit,
/// and at most 1 % of samples classified differently (hit / escape / inside).
#[test]
fn default_fast_bake_error_is_bounded() {
    let d = Dims::new(32, 32, 16).unwrap();
    let dirs = DirectionGrid::new(8, 16).unwrap();
    let limits = Limits::default();
    for kind in SampleKind::ALL {
        let c = VolumeCaster::new(&samples::volume(kind, d, &limits).unwrap());
        let reference = exact::bake(&c, dirs, &limits, &()).unwrap();
        let approx = fast::bake(&c, dirs, FastParams::default(), &limits, &()).unwrap();
        let e = compare(&approx, &reference).unwrap();
        assert!(e.mean_abs_error <= 0.25, "{kind:?}: {e:?}");
        assert!(e.classification_mismatch <= 0.01, "{kind:?}: {e:?}");
    }
}

/// The same bound on a mesh tile, where the sweep casts BVH rays instead of walking templates.
#[test]
fn fast_bake_of_a_mesh_tile_is_bounded() {
    let d = Dims::new(32, 32, 16).unwrap();
    let dirs = DirectionGrid::new(8, 16).unwrap();
    let limits = Limits::default();
    let tile = MeshTile::new(samples::mesh(SampleKind::Chain, d).unwrap(), false).unwrap();
    let c = MeshCaster::new(&tile, d, &limits).unwrap();
    let reference = exact::bake(&c, dirs, &limits, &()).unwrap();
    let approx = fast::bake(&c, dirs, FastParams::default(), &limits, &()).unwrap();
    let e = compare(&approx, &reference).unwrap();
    assert!(
        e.mean_abs_error <= 0.25 && e.classification_mismatch <= 0.01,
        "{e:?}"
    );
}

/// Interpolating everywhere (spread +∞) is the knob's fast end: measurably worse than the
/// default on the chain, which shows the knob does something.
#[test]
fn spread_knob_trades_error() {
    let d = Dims::new(32, 32, 16).unwrap();
    let dirs = DirectionGrid::new(8, 16).unwrap();
    let limits = Limits::default();
    let c = VolumeCaster::new(&samples::volume(SampleKind::Chain, d, &limits).unwrap());
    let reference = exact::bake(&c, dirs, &limits, &()).unwrap();
    let tight = compare(
        &fast::bake(&c, dirs, FastParams::default(), &limits, &()).unwrap(),
        &reference,
    )
    .unwrap();
    let loose_params = FastParams {
        max_spread: f32::INFINITY,
        ..FastParams::default()
    };
    let loose = compare(
        &fast::bake(&c, dirs, loose_params, &limits, &()).unwrap(),
        &reference,
    )
    .unwrap();
    assert!(
        loose.classification_mismatch > tight.classification_mismatch,
        "{loose:?} vs {tight:?}"
    );
    assert!(
        loose.mean_abs_error > tight.mean_abs_error,
        "{loose:?} vs {tight:?}"
    );
}
