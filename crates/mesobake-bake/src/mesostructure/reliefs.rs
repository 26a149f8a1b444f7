//! Built-in height-field (relief) samples, in the spirit of the VDM paper's: `bumps`
//! (rounded domes), `bricks` (running bond with bevelled edges and mortar joints), and the
//! reliefs of the `weave` and `bark` samples (the top of each column of their volumes, so
//! that a GDM of the volume and a VDM of the relief see the same detail where the sample is a
//! height field). Each is also the volume under it ([`HeightField::to_volume`]).

use crate::mesostructure::height_field::HeightField;
use crate::mesostructure::samples::{self, SampleKind};
use mesobake_core::error::{Error, Result};
use mesobake_core::limits::Limits;
use mesobake_package::grid::Dims;

/// The built-in reliefs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ReliefKind {
    /// 4 × 4 rounded domes (spherical caps) on a flat ground.
    Bumps,
    /// Four courses of bricks in running bond, bevelled, with sunken mortar joints.
    Bricks,
    /// The top surface of the `weave` sample.
    Weave,
    /// The top surface of the `bark` sample (its overhangs filled in).
    Bark,
}

impl ReliefKind {
    /// Every relief, in documentation order.
    pub const ALL: [ReliefKind; 4] = [
        ReliefKind::Bumps,
        ReliefKind::Bricks,
        ReliefKind::Weave,
        ReliefKind::Bark,
    ];
}

/// The relief `kind` as a `size` × `size` height field (pixel centres at (i + ½)/size).
pub fn height_field(kind: ReliefKind, size: u32, limits: &Limits) -> Result<HeightField> {
    if !(4..=4096).contains(&size) {
        return Err(Error::InvalidParameter(format!(
            "a relief's size must be 4 to 4096 pixels, got {size}"
        )));
    }
    limits.check("relief heights", u64::from(size) * u64::from(size), 4)?;
    let centre = |n: u32| (f64::from(n) + 0.5) / f64::from(size);
    let analytic = |f: &dyn Fn(f64, f64) -> f64| {
        let heights = (0..size)
            .flat_map(|j| (0..size).map(move |i| (i, j)))
            .map(|(i, j)| f(centre(i), centre(j)).clamp(0.0, 1.0) as f32)
            .collect();
        HeightField::new(size, size, heights)
    };
    match kind {
        ReliefKind::Bumps => analytic(&bumps),
        ReliefKind::Bricks => analytic(&bricks),
        ReliefKind::Weave => column_tops(SampleKind::Weave, size, limits),
        ReliefKind::Bark => column_tops(SampleKind::Bark, size, limits),
    }
}

/// Domes of radius 0.11 on a 4 × 4 lattice: h = √(1 − (r/0.11)²), 0 between them.
fn bumps(u: f64, v: f64) -> f64 {
    let cell = |x: f64| (x * 4.0).fract() - 0.5;
    let r = cell(u).hypot(cell(v)) / 4.0;
    (1.0 - (r / 0.11).powi(2)).max(0.0).sqrt()
}

/// Bricks 1/2 × 1/4 of the tile, alternate courses offset by 1/4; mortar joints 0.03 wide
/// at height 0.2, brick faces at 1 with a bevel 0.03 wide.
fn bricks(u: f64, v: f64) -> f64 {
    let course = (v * 4.0).floor();
    let (along, across) = (
        (u * 2.0 + 0.5 * (course % 2.0)).fract() / 2.0,
        (v * 4.0).fract() / 4.0,
    );
    // Distance to the brick's nearest edge, in tile units.
    let edge = along.min(0.5 - along).min(across).min(0.25 - across);
    let (joint, bevel) = (0.015, 0.03);
    if edge < joint {
        0.2
    } else {
        0.2 + 0.8 * ((edge - joint) / bevel).min(1.0)
    }
}

/// The top of each column of a sample's volume: the highest voxel with material, plus the
/// fraction of it filled (so the relief is continuous where the volume's density is).
fn column_tops(kind: SampleKind, size: u32, limits: &Limits) -> Result<HeightField> {
    let z = (size / 2).max(2);
    let dims = Dims::new(size, size, z)?;
    let volume = samples::volume(kind, dims, limits)?;
    let density = volume.density();
    let heights = (0..size)
        .flat_map(|j| (0..size).map(move |i| (i, j)))
        .map(|(i, j)| {
            (0..z)
                .rev()
                .find_map(|k| {
                    let d = density[dims.index(i, j, k)];
                    (d > 0.0).then(|| (f64::from(k) + f64::from(d)) / f64::from(z))
                })
                .unwrap_or(0.0) as f32
        })
        .collect();
    HeightField::new(size, size, heights)
}
