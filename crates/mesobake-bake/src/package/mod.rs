//! GDM packages (`.mbpkg`): the compressed GDM as textures ready for GPU upload, with a
//! manifest that says how it was made and how accurate it is. The format itself (reader,
//! writer, validation, reconstruction) is the crate `mesobake-package`; this module adds what
//! needs the rest of mesobake: encoding its compressed GDM and radiance transfer, memory
//! limits, and the exact reconstruction of an occupancy package (see
//! `docs/package-format.md`).

pub mod bake;
pub mod exr_export;
pub mod gi;
pub mod medium;
pub mod vdm;

pub use mesobake_package::{OCCUPANCY_SECTION, container, ktx2, manifest};

use crate::compress::accuracy::resolve_escapes;
use crate::compress::gdm::CompressedGdm;
use crate::compress::occupancy::OccupancyField;
use crate::gdm::volume_caster::VolumeCaster;
use crate::gdm::{EscapeConvention, Gdm, exact};
use crate::mesostructure::volume::Occupancy;
use manifest::{BakeInfo, GdmCodec, InputInfo};
use mesobake_core::error::{Error, Result};
use mesobake_core::fs::read_bounded;
use mesobake_core::limits::Limits;
use mesobake_package::GdmContent;
use mesobake_package::grid::Dims;
use mesobake_package::svd::SvdFactors;
use std::path::Path;

/// A validated package in memory: the format crate's [`mesobake_package::Package`], whose
/// reader methods it derefs to, with mesobake's own operations.
#[derive(Debug)]
pub struct Package(mesobake_package::Package);

impl std::ops::Deref for Package {
    type Target = mesobake_package::Package;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

/// A validated package of either kind, told apart by its manifest's `format`.
#[derive(Debug)]
pub enum AnyPackage {
    /// A GDM package (`mesobake-package`).
    Gdm(Package),
    /// A VDM package (`mesobake-vdm-package`).
    Vdm(vdm::VdmPackage),
    /// A translucent medium's package (`mesobake-medium-package`).
    Medium(medium::MediumPackage),
}

impl AnyPackage {
    /// Validates `bytes` as the kind of package its manifest names, within the default
    /// memory limit.
    pub fn parse(bytes: Vec<u8>) -> Result<AnyPackage> {
        AnyPackage::parse_within(bytes, &Limits::default())
    }

    /// Validates `bytes` as the kind of package its manifest names, refusing before
    /// allocating one whose reading would take more than the memory limit.
    pub fn parse_within(bytes: Vec<u8>, limits: &Limits) -> Result<AnyPackage> {
        let max = limits.memory_bytes;
        match container::format(&bytes)?.as_str() {
            mesobake_package::vdm::VDM_FORMAT_NAME => {
                Ok(AnyPackage::Vdm(vdm::VdmPackage::parse_within(bytes, max)?))
            }
            mesobake_package::medium::MEDIUM_FORMAT_NAME => Ok(AnyPackage::Medium(
                medium::MediumPackage::parse_within(bytes, max)?,
            )),
            _ => Ok(AnyPackage::Gdm(Package::parse_within(bytes, limits)?)),
        }
    }

    /// Reads and validates the package at `path` within the memory limit (the file, and
    /// everything reading it allocates).
    pub fn read(path: &Path, limits: &Limits) -> Result<AnyPackage> {
        let bytes = mesobake_core::fs::read_bounded(path, "package", limits.memory_bytes)?;
        AnyPackage::parse_within(bytes, limits).map_err(|e| e.context(path.display()))
    }

    /// The manifest as JSON.
    pub fn manifest_json(&self) -> serde_json::Value {
        match self {
            AnyPackage::Gdm(p) => serde_json::to_value(p.manifest()),
            AnyPackage::Vdm(p) => serde_json::to_value(p.manifest()),
            AnyPackage::Medium(p) => serde_json::to_value(p.manifest()),
        }
        .expect("manifests serialize")
    }

    /// The manifest's record of the input the package was baked from.
    pub fn input(&self) -> &InputInfo {
        match self {
            AnyPackage::Gdm(p) => &p.manifest().input,
            AnyPackage::Vdm(p) => &p.manifest().input,
            AnyPackage::Medium(p) => &p.manifest().input,
        }
    }
}

/// What a package holds to answer GDM queries, by codec.
#[derive(Clone, Debug)]
pub enum GdmPayload {
    /// [`GdmCodec::PaperSvd`]: the compressed GDM.
    PaperSvd(Box<CompressedGdm>),
    /// [`GdmCodec::Occupancy`]: the occupancy field.
    Occupancy(OccupancyField),
}

impl GdmPayload {
    /// The codec.
    pub fn codec(&self) -> GdmCodec {
        match self {
            GdmPayload::PaperSvd(_) => GdmCodec::PaperSvd,
            GdmPayload::Occupancy(_) => GdmCodec::Occupancy,
        }
    }

    /// The compressed GDM, for [`GdmCodec::PaperSvd`].
    pub fn compressed(&self) -> Option<&CompressedGdm> {
        match self {
            GdmPayload::PaperSvd(gdm) => Some(gdm),
            GdmPayload::Occupancy(_) => None,
        }
    }

    /// The payload as the format crate's writer takes it.
    fn content(&self) -> GdmContent<'_> {
        match self {
            GdmPayload::PaperSvd(gdm) => GdmContent::PaperSvd(SvdFactors {
                rank_choice: gdm.rank_choice,
                spectrum: &gdm.svd.spectrum,
                weights: &gdm.weights,
                eigen: &gdm.eigen,
                accuracy: gdm.accuracy,
                svd_rmse: gdm.svd.optimal_rmse(gdm.svd.rank),
            }),
            GdmPayload::Occupancy(field) => GdmContent::Occupancy(field),
        }
    }
}

impl Package {
    /// Encodes a GDM payload with its provenance into package bytes.
    pub fn encode(input: InputInfo, bake: BakeInfo, gdm: &GdmPayload) -> Vec<u8> {
        Package::encode_with(input, bake, gdm, None)
    }

    /// [`Package::encode`], with the radiance-transfer sections of `gi` when given.
    pub fn encode_with(
        input: InputInfo,
        bake: BakeInfo,
        payload: &GdmPayload,
        gi: Option<&gi::GiPayload>,
    ) -> Vec<u8> {
        mesobake_package::Package::encode(input, bake, payload.content(), gi.map(gi::content))
    }

    /// Validates `bytes` as a package ([`mesobake_package::Package::parse`]).
    pub fn parse(bytes: Vec<u8>) -> Result<Package> {
        Ok(Package(mesobake_package::Package::parse(bytes)?))
    }

    /// [`Package::parse`] within the memory limit (the file, and everything reading it
    /// allocates; [`mesobake_package::Package::parse_within`]).
    pub fn parse_within(bytes: Vec<u8>, limits: &Limits) -> Result<Package> {
        let package = mesobake_package::Package::parse_within(bytes, limits.memory_bytes)?;
        Ok(Package(package))
    }

    /// Reads and validates the package at `path` within the memory limit.
    pub fn read(path: &Path, limits: &Limits) -> Result<Package> {
        Package::parse_within(read_bounded(path, "package", limits.memory_bytes)?, limits)
    }

    /// Refuses a package whose voxel grid is not a scene's `resolution`.
    pub fn check_grid(&self, resolution: Dims) -> Result<()> {
        if self.dims() == resolution {
            return Ok(());
        }
        Err(Error::Scene(format!(
            "the package holds a {} grid but the scene's resolution is {resolution}",
            self.dims()
        )))
    }

    /// The dense GDM a renderer sees on the package's grids, escapes +∞ (the
    /// [`EscapeConvention::Infinite`] of `mesobake gdm`): for `paper-svd` W·Eᵀ with the escape
    /// rule applied; for `occupancy` the exact bake of its voxels.
    pub fn reconstruct(&self, limits: &Limits) -> Result<Gdm> {
        let (dims, dirs) = (self.dims(), self.dirs());
        limits.check(
            "the reconstructed GDM",
            dims.voxel_count() * dirs.count() as u64,
            4,
        )?;
        let Some(svd) = self.svd() else {
            let field = self.occupancy().expect("one codec entry")?;
            let caster = VolumeCaster::from_occupancy(Occupancy::of_field(&field), true);
            return exact::bake(&caster, dirs, limits, &());
        };
        let gdm = Gdm::from_values(dims, dirs, EscapeConvention::Boundary, svd.values())?;
        resolve_escapes(gdm, svd.escape_margin())
    }
}
