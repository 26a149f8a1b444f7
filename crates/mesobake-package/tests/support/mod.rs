//! Small packages written with the format crate alone, shared by its tests and by the tests of
//! the crates built on it (included with `#[path]`).
#![allow(dead_code)]

use mesobake_package::gi::{NO_SAMPLE, RTV_MATRICES, RadianceTransfer, SH_COEFFS};
use mesobake_package::grid::{Dims, DirectionGrid};
use mesobake_package::manifest::{
    Accuracy, BakeInfo, GiInfo, InputInfo, Method, RankChoice, RtvCompression,
};
use mesobake_package::occupancy::OccupancyField;
use mesobake_package::quantize::{Quantization, QuantizedFactor};
use mesobake_package::svd::SvdFactors;
use mesobake_package::{GdmContent, Package};

/// Encodes `content` on the grids `dims` × `dirs` with placeholder provenance.
pub fn encode(dims: Dims, dirs: DirectionGrid, content: GdmContent) -> Vec<u8> {
    let input = InputInfo {
        kind: "volume".into(),
        bytes: 0,
        blake3: "0".repeat(64),
    };
    let bake = BakeInfo {
        res: [dims.x, dims.y, dims.z],
        dirs: [dirs.n_theta, dirs.n_phi],
        method: Method::Exact,
        fast: None,
        allow_open: false,
    };
    Package::encode(input, bake, content, None)
}

/// A deterministic pseudo-random value in [0, 1).
pub fn noise(n: usize) -> f32 {
    let x = (n as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    (x >> 40) as f32 / (1u64 << 24) as f32
}

/// Accuracy statistics that only set the escape margin.
pub fn accuracy(escape_margin: f32) -> Accuracy {
    Accuracy {
        rmse: 0.0,
        max_abs: 0.0,
        escape_margin,
        flips: 0,
        flip_rate: 0.0,
        samples: 0,
    }
}

/// An occupancy package: a floor with pillars, 12×10×6 voxels, 4×8 directions.
pub fn pillars() -> Vec<u8> {
    let (dims, dirs) = (
        Dims::new(12, 10, 6).unwrap(),
        DirectionGrid::new(4, 8).unwrap(),
    );
    let field = OccupancyField::from_solid(dims, |i, j, k| k == 0 || (i % 4 == 1 && j % 3 == 0));
    encode(dims, dirs, GdmContent::Occupancy(&field))
}

/// An occupancy package of an empty `side`³ field: a small file (its section is stored
/// supercompressed) that reads into side³ bytes and decodes to four times that.
pub fn empty_occupancy(side: u32) -> Vec<u8> {
    let (dims, dirs) = (
        Dims::new(side, side, side).unwrap(),
        DirectionGrid::new(2, 4).unwrap(),
    );
    let field = OccupancyField::from_solid(dims, |_, _, _| false);
    encode(dims, dirs, GdmContent::Occupancy(&field))
}

/// A paper-svd package on 12×10×6 voxels and 4×8 directions whose factors (rank `rank`,
/// quantized with `q`) are pseudo-random, W in [0, 4) and E in [0, 1), escape margin 0.1.
pub fn random_svd(rank: usize, q: Quantization) -> Vec<u8> {
    random_svd_with(rank, q, |_, _| {})
}

/// [`random_svd`] with its factors' values edited by `edit` (weights, eigenmaps) before they
/// are quantized.
pub fn random_svd_with(
    rank: usize,
    q: Quantization,
    edit: impl FnOnce(&mut Vec<f32>, &mut Vec<f32>),
) -> Vec<u8> {
    let (dims, dirs) = (
        Dims::new(12, 10, 6).unwrap(),
        DirectionGrid::new(4, 8).unwrap(),
    );
    let rows = [(12 * 10 * 8) as usize, (6 * 4) as usize];
    let mut w: Vec<f32> = (0..rows[0] * rank).map(|n| 4.0 * noise(n)).collect();
    let mut e: Vec<f32> = (0..rows[1] * rank).map(|n| noise(n + 99)).collect();
    edit(&mut w, &mut e);
    let (w, e) = (
        QuantizedFactor::new(&w, rank, q),
        QuantizedFactor::new(&e, rank, q),
    );
    let spectrum = vec![1.0; rows[1]];
    let svd = SvdFactors {
        rank_choice: RankChoice::Rank(rank),
        spectrum: &spectrum,
        weights: &w,
        eigen: &e,
        accuracy: accuracy(0.1),
        svd_rmse: 0.0,
    };
    encode(dims, dirs, GdmContent::PaperSvd(svd))
}

/// A synthetic radiance transfer on `pillars`' grids (12×10×6 voxels, 4×8 directions) with
/// `rank` components: every third voxel a sample, pseudo-random weights, eigenfunctions and
/// PRT matrices for 5 vertices (all exactly representable in f16 except the PRT's f32).
pub fn radiance_transfer(rank: usize) -> (GiInfo, RadianceTransfer) {
    let (dims, dirs) = (
        Dims::new(12, 10, 6).unwrap(),
        DirectionGrid::new(4, 8).unwrap(),
    );
    let mut samples = 0;
    let sample_of = (0..dims.voxel_count())
        .map(|v| {
            if v % 3 == 0 {
                samples += 1;
                samples - 1
            } else {
                NO_SAMPLE
            }
        })
        .collect();
    let quarter = |n: usize| (noise(n) * 64.0).round() / 16.0 - 2.0;
    let transfer = RadianceTransfer {
        dims,
        dirs,
        rank,
        sample_of,
        weights: (0..samples as usize * RTV_MATRICES * rank)
            .map(quarter)
            .collect(),
        eigen: (0..RTV_MATRICES * 32 * rank)
            .map(|n| quarter(n + 7))
            .collect(),
        prt: (0..5 * SH_COEFFS * SH_COEFFS)
            .map(|n| noise(n + 3))
            .collect(),
    };
    let info = GiInfo {
        samples,
        bounces: 1,
        glossy: None,
        compression: RtvCompression {
            rank,
            rmse: 0.0,
            relative_rmse: 0.0,
            svd_rmse: 0.0,
            spectra: vec![vec![1.0; rank]; RTV_MATRICES],
        },
        vertices: 5,
        macro_shadows: false,
        base_mesh: "0".repeat(64),
    };
    (info, transfer)
}

/// `pillars` with the radiance transfer `transfer` (manifest entry `info`).
pub fn pillars_with_gi(info: GiInfo, transfer: &RadianceTransfer) -> Vec<u8> {
    let pkg = Package::parse(pillars()).unwrap();
    let field = pkg.occupancy().unwrap().unwrap();
    let m = pkg.manifest();
    let gi = transfer.encode(info);
    Package::encode(
        m.input.clone(),
        m.bake.clone(),
        GdmContent::Occupancy(&field),
        Some(gi),
    )
}
