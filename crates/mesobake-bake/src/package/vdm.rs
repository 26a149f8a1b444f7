//! VDM packages: a compressed VDM with its provenance, in the format of the crate's
//! [`mesobake_package::vdm`] (see `docs/package-format.md`).

use crate::compress::vdm::CompressedVdm;
use crate::mesostructure::height_field::HeightField;
use crate::vdm::{Vdm, VdmParams};
use mesobake_core::error::{Error, Result};
use mesobake_core::fs::read_bounded;
use mesobake_core::limits::Limits;
use mesobake_package::manifest::InputInfo;
pub use mesobake_package::vdm::VdmPackage;
use mesobake_package::vdm::{ReliefInfo, VdmBakeInfo, VdmContent};
use std::path::Path;

/// The package bytes of `compressed`, made from `vdm` baked as `params` say from `field`,
/// identified by `input` (deterministic).
pub fn encode(
    input: InputInfo,
    field: &HeightField,
    vdm: &Vdm,
    params: VdmParams,
    compressed: &CompressedVdm,
) -> Vec<u8> {
    let content = VdmContent {
        relief: ReliefInfo {
            size: [vdm.size.0, vdm.size.1],
            depth: vdm.depth,
        },
        bake: VdmBakeInfo {
            grid: vdm.grid,
            method: params.method,
            oversampling: params.oversampling,
        },
        mvm_rank: compressed.mvm_rank,
        spectrum: &compressed.spectrum,
        weights: &compressed.weights,
        eigen: &compressed.eigen,
        accuracy: compressed.accuracy,
        heights: field.heights(),
    };
    VdmPackage::encode(input, content)
}

/// The identity of a height field's file: its kind (`"height_field"` for a PNG file,
/// `"relief"` for a built-in relief's 16-bit PNG as `mesobake relief` writes it), size and
/// BLAKE3 hash.
pub fn input_info(kind: &str, bytes: &[u8]) -> InputInfo {
    InputInfo {
        kind: kind.into(),
        bytes: bytes.len() as u64,
        blake3: blake3::hash(bytes).to_hex().to_string(),
    }
}

/// The height field a VDM package holds (what its renderers read the relief from).
pub fn height_field(package: &VdmPackage) -> Result<HeightField> {
    let [w, h] = package.manifest().relief.size;
    HeightField::new(w, h, package.heights())
}

/// Reads and validates the VDM package at `path` within the memory limit.
pub fn read(path: &Path, limits: &Limits) -> Result<VdmPackage> {
    let bytes = read_bounded(path, "package", limits.memory_bytes)?;
    VdmPackage::parse_within(bytes, limits.memory_bytes)
        .map_err(|e| Error::from(e).context(path.display()))
}
