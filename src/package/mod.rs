//! GDM packages (`.mbpkg`): the compressed GDM as textures ready for GPU upload, with a
//! manifest that says how it was made and how accurate it is. Writing is deterministic;
//! reading validates everything (see `docs/package-format.md`).

pub mod bake;
pub mod container;
pub mod exr_export;
pub mod gi;
pub mod manifest;

use crate::bake::gdm::volume_caster::VolumeCaster;
use crate::bake::gdm::{EscapeConvention, Gdm, exact};
use crate::compress::accuracy::{MAX_MARGIN, resolve_escapes};
use crate::compress::gdm::CompressedGdm;
use crate::compress::occupancy::OccupancyField;
use crate::compress::quantize::{Quantization, QuantizedFactor};
use crate::compress::svd::gemm;
use crate::error::{Error, Result};
use crate::grid::{Dims, DirectionGrid};
use crate::util::limits::Limits;
use manifest::{
    BakeInfo, FORMAT_NAME, FactorInfo, GdmCodec, GdmInfo, InputInfo, Manifest, OccupancyInfo,
    Section, TexelFormat, Texture, TextureDimension,
};
use rayon::prelude::*;
use std::path::Path;

/// Components per texture (RGBA).
const CHANNELS: usize = 4;

/// A validated package in memory.
#[derive(Debug)]
pub struct Package {
    manifest: Manifest,
    bytes: Vec<u8>,
    dims: Dims,
    dirs: DirectionGrid,
}

/// The texture holding components 4g..4g+3 of a rank-`rank` factor quantized with `q`:
/// weight maps as 3D textures W(x, y, φ), eigenmaps as 2D textures E(z, θ); the last group
/// in the narrowest format that holds what is left (r, rg or rgba).
fn factor_texture(
    weights: bool,
    q: Quantization,
    rank: usize,
    group: usize,
    dims: Dims,
    dirs: DirectionGrid,
) -> Texture {
    let format = TexelFormat::of(q, rank - group * CHANNELS);
    let (dimension, width, height, depth) = if weights {
        (TextureDimension::D3, dims.x, dims.y, dirs.n_phi)
    } else {
        (TextureDimension::D2, dims.z, dirs.n_theta, 1)
    };
    Texture {
        dimension,
        format,
        width,
        height,
        depth,
    }
}

/// Packs the components of `factor` that `group` holds into `texture`'s bytes (texel r is
/// factor row r); channels past the rank are zero.
fn pack(factor: &QuantizedFactor, group: usize, texture: &Texture) -> Vec<u8> {
    let len = texture.byte_len().expect("writer textures are small") as usize;
    let mut bytes = vec![0u8; len];
    let elem = factor.format.bytes();
    for r in 0..factor.rows {
        let texel = r * texture.format.texel_bytes() as usize;
        for ch in 0..CHANNELS.min(factor.rank - group * CHANNELS) {
            let code = factor.code(r, group * CHANNELS + ch);
            bytes[texel + ch * elem..][..elem].copy_from_slice(code);
        }
    }
    bytes
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
}

/// The name of the occupancy codec's section.
pub const OCCUPANCY_SECTION: &str = "occupancy.distance";

/// The texture of the occupancy codec's section on the grid `dims`.
fn occupancy_texture(dims: Dims) -> Texture {
    Texture {
        dimension: TextureDimension::D3,
        format: TexelFormat::R8uint,
        width: dims.x,
        height: dims.y,
        depth: dims.z,
    }
}

/// The sections and manifest entry of a compressed GDM.
fn svd_sections(
    gdm: &CompressedGdm,
    dims: Dims,
    dirs: DirectionGrid,
    sections: &mut Vec<Section>,
    payloads: &mut Vec<Vec<u8>>,
) -> GdmInfo {
    let (q, rank) = (gdm.weights.format, gdm.svd.rank);
    let groups = rank.div_ceil(CHANNELS);
    let mut factor_info = |name: &str, factor: &QuantizedFactor, weights: bool| {
        let names: Vec<String> = (0..groups).map(|g| format!("gdm.{name}.{g}")).collect();
        for (g, section) in names.iter().enumerate() {
            let texture = factor_texture(weights, q, rank, g, dims, dirs);
            payloads.push(pack(factor, g, &texture));
            sections.push(Section::new(section, texture));
        }
        FactorInfo {
            sections: names,
            scale: factor.scale.clone(),
            bias: factor.bias.clone(),
        }
    };
    let weights = factor_info("weights", &gdm.weights, true);
    let eigen = factor_info("eigen", &gdm.eigen, false);
    GdmInfo {
        rank_choice: gdm.rank_choice,
        rank: gdm.svd.rank as u32,
        spectrum: gdm.svd.spectrum.clone(),
        quantization: gdm.weights.format,
        weights,
        eigen,
        accuracy: gdm.accuracy,
        svd_rmse: gdm.svd.optimal_rmse(gdm.svd.rank),
    }
}

/// Checks the manifest entry of a compressed GDM against the grids and the sections.
fn validate_svd(
    g: &GdmInfo,
    sections: &[Section],
    dims: Dims,
    dirs: DirectionGrid,
    bad: impl Fn(String) -> Error,
) -> Result<()> {
    let (m, n) = (
        dims.x as u64 * dims.y as u64 * dirs.n_phi as u64,
        dims.z as u64 * dirs.n_theta as u64,
    );
    let rank = g.rank as usize;
    if g.rank as u64 > m.min(n) {
        return Err(bad(format!("rank {} exceeds the matrix's {m}×{n}", g.rank)));
    }
    if g.spectrum.len() as u64 != m.min(n)
        || g.spectrum.iter().any(|s| !(s.is_finite() && *s >= 0.0))
    {
        return Err(bad(
            "the spectrum must hold min(m, n) finite values ≥ 0".into()
        ));
    }
    let a = &g.accuracy;
    if !(0.0..=MAX_MARGIN).contains(&a.escape_margin) {
        return Err(bad(format!("escape margin {} is invalid", a.escape_margin)));
    }
    for (name, info, weights) in [("weights", &g.weights, true), ("eigen", &g.eigen, false)] {
        if info.sections.len() != rank.div_ceil(CHANNELS)
            || info.scale.len() != rank
            || info.bias.len() != rank
            || info.scale.iter().chain(&info.bias).any(|v| !v.is_finite())
        {
            return Err(bad(format!(
                "the {name} factor must list {} sections and {rank} finite scales and biases",
                rank.div_ceil(CHANNELS)
            )));
        }
        for (group, section) in info.sections.iter().enumerate() {
            let expected = factor_texture(weights, g.quantization, rank, group, dims, dirs);
            expect_section(sections, section, expected, &bad)?;
        }
    }
    Ok(())
}

/// Checks that section `name` exists with texture `expected`.
fn expect_section(
    sections: &[Section],
    name: &str,
    expected: Texture,
    bad: impl Fn(String) -> Error,
) -> Result<()> {
    match sections.iter().find(|s| s.name == name) {
        Some(s) if s.texture == expected => Ok(()),
        Some(s) => Err(bad(format!(
            "section {name:?} has texture {:?}, expected {expected:?}",
            s.texture
        ))),
        None => Err(bad(format!("section {name:?} is missing"))),
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
        let (dims, dirs) = (
            Dims {
                x: bake.res[0],
                y: bake.res[1],
                z: bake.res[2],
            },
            DirectionGrid {
                n_theta: bake.dirs[0],
                n_phi: bake.dirs[1],
            },
        );
        let mut sections = Vec::new();
        let mut payloads = Vec::new();
        let (gdm, occupancy) = match payload {
            GdmPayload::PaperSvd(gdm) => (
                Some(svd_sections(gdm, dims, dirs, &mut sections, &mut payloads)),
                None,
            ),
            GdmPayload::Occupancy(field) => {
                sections.push(Section::new(OCCUPANCY_SECTION, occupancy_texture(dims)));
                payloads.push(field.bytes().to_vec());
                let info = OccupancyInfo {
                    section: OCCUPANCY_SECTION.into(),
                    solid_voxels: field.solid_voxels(),
                };
                (None, Some(info))
            }
        };
        if let Some(gi) = gi {
            for (section, bytes) in gi::sections(gi, dims, dirs) {
                sections.push(section);
                payloads.push(bytes);
            }
        }
        let mut manifest = Manifest {
            format: FORMAT_NAME.into(),
            version: container::VERSION,
            generator: format!("mesobake {}", env!("CARGO_PKG_VERSION")),
            units: "voxel".into(),
            input,
            bake,
            codec: payload.codec(),
            gdm,
            occupancy,
            gi: gi.map(|g| g.info.clone()),
            sections,
        };
        container::assemble(&mut manifest, &payloads)
    }

    /// Validates `bytes` as a package: the container (see [`container::parse`]) and the GDM
    /// it describes (grids, the codec's entry, ranks, decode parameters, every section's
    /// texture shape, and an occupancy field's distances).
    pub fn parse(bytes: Vec<u8>) -> Result<Package> {
        let manifest = container::parse(&bytes)?;
        let bad = |what: String| Error::Package(format!("manifest: {what}"));
        let [x, y, z] = manifest.bake.res;
        let dims = Dims::new(x, y, z).map_err(|e| bad(e.to_string()))?;
        let [n_theta, n_phi] = manifest.bake.dirs;
        let dirs = DirectionGrid::new(n_theta, n_phi).map_err(|e| bad(e.to_string()))?;
        match (manifest.codec, &manifest.gdm, &manifest.occupancy) {
            (GdmCodec::PaperSvd, Some(g), None) => {
                validate_svd(g, &manifest.sections, dims, dirs, bad)?
            }
            (GdmCodec::Occupancy, None, Some(o)) => {
                expect_section(&manifest.sections, &o.section, occupancy_texture(dims), bad)?
            }
            (codec, _, _) => {
                return Err(bad(format!(
                    "codec {codec} needs exactly its own entry ({})",
                    match codec {
                        GdmCodec::PaperSvd => "gdm",
                        GdmCodec::Occupancy => "occupancy",
                    }
                )));
            }
        }
        if let Some(info) = &manifest.gi {
            let rank = info.compression.rank;
            if !(1..=crate::bake::gi::compressed_rtv::MAX_RTV_RANK).contains(&rank) {
                return Err(bad(format!(
                    "the RTV rank {rank} is not 1 to {}",
                    crate::bake::gi::compressed_rtv::MAX_RTV_RANK
                )));
            }
            for (name, expected) in gi::textures(info, dims, dirs) {
                expect_section(&manifest.sections, name, expected, bad)?;
            }
        }
        let package = Package {
            manifest,
            bytes,
            dims,
            dirs,
        };
        package.occupancy().transpose()?;
        Ok(package)
    }

    /// Reads and validates the package at `path`, refusing files over the memory limit.
    pub fn read(path: &Path, limits: &Limits) -> Result<Package> {
        let len = std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len();
        limits.check(&format!("package {}", path.display()), len, 1)?;
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Package::parse(bytes)
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// Refuses a package whose voxel grid is not a scene's `resolution`.
    pub fn check_grid(&self, resolution: Dims) -> Result<()> {
        if self.dims == resolution {
            return Ok(());
        }
        Err(Error::Scene(format!(
            "the package holds a {} grid but the scene's resolution is {resolution}",
            self.dims
        )))
    }

    /// The direction grid.
    pub fn dirs(&self) -> DirectionGrid {
        self.dirs
    }

    /// The bytes of section `name`, if present.
    pub fn section(&self, name: &str) -> Option<&[u8]> {
        let s = self.manifest.sections.iter().find(|s| s.name == name)?;
        Some(&self.bytes[s.offset as usize..][..s.bytes as usize])
    }

    /// The quantized weight maps and eigenmaps, unpacked from their textures.
    pub fn factors(&self) -> Option<(QuantizedFactor, QuantizedFactor)> {
        let g = self.manifest.gdm.as_ref()?;
        let rows_w = self.dims.x as usize * self.dims.y as usize * self.dirs.n_phi as usize;
        let rows_e = self.dims.z as usize * self.dirs.n_theta as usize;
        let unpack = |info: &FactorInfo, rows: usize| {
            let (rank, format) = (g.rank as usize, g.quantization);
            let elem = format.bytes();
            let mut codes = vec![0u8; rows * rank * elem];
            for (group, name) in info.sections.iter().enumerate() {
                let t = self
                    .manifest
                    .sections
                    .iter()
                    .find(|s| &s.name == name)
                    .expect("validated")
                    .texture;
                let bytes = self.section(name).expect("validated");
                for r in 0..rows {
                    let texel = r * t.format.texel_bytes() as usize;
                    for ch in 0..CHANNELS.min(rank - group * CHANNELS) {
                        let c = group * CHANNELS + ch;
                        codes[(r * rank + c) * elem..][..elem]
                            .copy_from_slice(&bytes[texel + ch * elem..][..elem]);
                    }
                }
            }
            QuantizedFactor {
                rows,
                rank,
                format,
                scale: info.scale.clone(),
                bias: info.bias.clone(),
                codes,
            }
        };
        Some((unpack(&g.weights, rows_w), unpack(&g.eigen, rows_e)))
    }

    /// The occupancy field, for [`GdmCodec::Occupancy`] (validated: its distances are those
    /// its solid voxels imply).
    pub fn occupancy(&self) -> Option<Result<OccupancyField>> {
        let info = self.manifest.occupancy.as_ref()?;
        let bytes = self.section(&info.section).expect("validated");
        Some(OccupancyField::from_bytes(self.dims, bytes))
    }

    /// The dense GDM a renderer sees on the package's grids, escapes +∞ (the
    /// [`EscapeConvention::Infinite`] of `mesobake gdm`): for `paper-svd` W·Eᵀ with the escape
    /// rule applied; for `occupancy` the exact bake of its voxels.
    pub fn reconstruct(&self, limits: &Limits) -> Result<Gdm> {
        let (dims, dirs) = (self.dims, self.dirs);
        let count = dims.voxel_count() * dirs.count() as u64;
        limits.check("the reconstructed GDM", count, 4)?;
        let Some((w, e)) = self.factors() else {
            let field = self.occupancy().expect("one codec entry")?;
            let caster = VolumeCaster::from_occupancy(field.occupancy(), true);
            return exact::bake(&caster, dirs, limits, &());
        };
        let (w, e, k) = (w.dequantize(), e.dequantize(), w.rank);
        let layer = (dims.x * dims.y) as usize;
        let stride = dims.voxel_count() as usize;
        let mut values = vec![0.0f32; count as usize];
        if k > 0 {
            values
                .par_chunks_mut(stride)
                .enumerate()
                .for_each(|(d, volume)| {
                    let (a, b) = (d / dirs.n_phi as usize, d % dirs.n_phi as usize);
                    // volume[k·layer + t] = W[b·layer + t] · E[a·Z + k]
                    let w_b = &w[b * layer * k..][..layer * k];
                    let e_a = &e[a * dims.z as usize * k..][..dims.z as usize * k];
                    gemm(
                        layer,
                        k,
                        dims.z as usize,
                        (w_b, k, 1),
                        (e_a, 1, k),
                        (volume, 1, layer),
                    );
                });
        }
        let gdm = Gdm::from_values(dims, dirs, EscapeConvention::Boundary, values)?;
        let margin = self
            .manifest
            .gdm
            .as_ref()
            .expect("factors")
            .accuracy
            .escape_margin;
        resolve_escapes(gdm, margin)
    }
}
