//! mesobake's package format (`.mbpkg`) on its own, for game builds and engine tooling: read
//! and validate a package, reach its textures, reconstruct its GDM, and write one. It has no
//! server, GPU or async dependencies. The byte-exact format is specified in mesobake's
//! `docs/package-format.md`.
//!
//! ```no_run
//! # fn main() -> mesobake_package::Result<()> {
//! let package = mesobake_package::Package::read("chain.mbpkg".as_ref(), 1 << 30)?;
//! for section in &package.manifest().sections {
//!     let bytes = package.section(&section.name).expect("listed");
//!     println!("{}: {:?}, {} bytes", section.name, section.texture, bytes.len());
//! }
//! # Ok(())
//! # }
//! ```

pub mod container;
pub mod error;
pub mod gi;
pub mod grid;
pub mod ktx2;
pub mod manifest;
pub mod medium;
pub mod occupancy;
pub mod quantize;
pub mod supercompression;
pub mod svd;
pub mod texture;
pub mod vdm;

pub use error::{Error, Result};

use container::Contents;
use gi::RadianceTransfer;
use grid::{Dims, DirectionGrid};
use manifest::{
    BakeInfo, FORMAT_NAME, FactorInfo, GdmCodec, GiInfo, InputInfo, Manifest, Method,
    OccupancyInfo, Section, TexelFormat, Texture, TextureDimension,
};
use occupancy::OccupancyField;
use quantize::QuantizedFactor;
use std::io::Read;
use std::path::Path;
use svd::{SvdFactors, SvdGdm};

/// The memory limit of `parse` (every kind's): 4 GiB, mesobake's default `--memory-limit`;
/// `parse_within` takes the caller's.
pub const DEFAULT_MAX_MEMORY: u64 = 4 << 30;

/// A validated package in memory.
#[derive(Debug)]
pub struct Package {
    manifest: Manifest,
    contents: Contents,
    dims: Dims,
    dirs: DirectionGrid,
}

/// What a package holds to answer GDM queries, as the writer takes it.
#[derive(Clone, Copy, Debug)]
pub enum GdmContent<'a> {
    /// [`GdmCodec::PaperSvd`]: the quantized factors.
    PaperSvd(SvdFactors<'a>),
    /// [`GdmCodec::Occupancy`]: the occupancy field.
    Occupancy(&'a OccupancyField),
}

/// The radiance-transfer sections as the writer takes them ([`RadianceTransfer::encode`]):
/// the manifest entry and the bytes of the four sections in [`gi::textures`] order.
#[derive(Clone, Debug)]
pub struct GiContent {
    /// The manifest entry.
    pub info: GiInfo,
    /// The bytes of `rtv.index`, `rtv.weights`, `rtv.eigen` and `prt.transfer`.
    pub sections: [Vec<u8>; 4],
}

/// A package's GDM, ready for queries at the baked samples: voxel centres (i, j, k) and
/// direction bins (a, b) of the package's grids.
#[derive(Clone, Debug)]
pub enum GdmQuery {
    /// The decoded SVD, with the escape rule.
    PaperSvd(SvdGdm),
    /// The occupancy field, marched exactly along the bin's direction.
    Occupancy(OccupancyField, DirectionGrid),
}

impl GdmQuery {
    /// The distance from voxel centre (i, j, k) along direction bin (a, b) to the
    /// mesostructure, `None` for an escape (coordinates must lie on the package's grids).
    pub fn distance(&self, i: u32, j: u32, k: u32, a: u32, b: u32) -> Option<f32> {
        match self {
            GdmQuery::PaperSvd(svd) => svd.distance(i, j, k, a, b),
            GdmQuery::Occupancy(field, dirs) => {
                let p = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5];
                field.march(p, dirs.vector(a, b)).map(|d| d as f32)
            }
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

/// The bytes of the file at `path`, refused when over `max_bytes`: by its length before
/// reading, and by what it yields while reading (a device such as /dev/zero reports a length
/// that bounds nothing).
fn read_limited(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let io = |source| Error::Io {
        path: path.into(),
        source,
    };
    let too_large = |len| {
        Error::Package(format!(
            "{}: {len} bytes or more, over the limit of {max_bytes}",
            path.display()
        ))
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len > max_bytes {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// The texels and texel format of each named section of a validated package, for
/// [`QuantizedFactor::unpack`].
fn groups<'a>(
    sections: &[Section],
    contents: &'a Contents,
    names: &[String],
) -> Vec<(&'a [u8], TexelFormat)> {
    names
        .iter()
        .map(|name| {
            let s = sections
                .iter()
                .find(|s| &s.name == name)
                .expect("validated");
            (
                contents.section(sections, name).expect("validated"),
                s.texture.format,
            )
        })
        .collect()
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
    /// Encodes a GDM with its provenance, and the radiance transfer when given, into package
    /// bytes (deterministic: the same content gives the same bytes).
    pub fn encode(
        input: InputInfo,
        bake: BakeInfo,
        content: GdmContent,
        gi: Option<GiContent>,
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
        let (codec, gdm, occupancy, mut sections) = match content {
            GdmContent::PaperSvd(factors) => {
                let (info, sections) = svd::sections(&factors, dims, dirs);
                (GdmCodec::PaperSvd, Some(info), None, sections)
            }
            GdmContent::Occupancy(field) => {
                let section = Section::new(OCCUPANCY_SECTION, occupancy_texture(dims));
                let info = OccupancyInfo {
                    section: OCCUPANCY_SECTION.into(),
                    solid_voxels: field.solid_voxels(),
                };
                let sections = vec![(section, field.bytes().to_vec())];
                (GdmCodec::Occupancy, None, Some(info), sections)
            }
        };
        let gi_info = gi.map(|gi| {
            let textures = gi::textures(&gi.info, dims, dirs);
            for ((name, texture), bytes) in textures.into_iter().zip(gi.sections) {
                sections.push((Section::new(name, texture), bytes));
            }
            gi.info
        });
        let (sections, payloads): (Vec<Section>, Vec<Vec<u8>>) = sections.into_iter().unzip();
        let mut manifest = Manifest {
            format: FORMAT_NAME.into(),
            version: container::VERSION,
            generator: format!("mesobake {}", env!("CARGO_PKG_VERSION")),
            units: "voxel".into(),
            input,
            bake,
            codec,
            gdm,
            occupancy,
            gi: gi_info,
            sections,
        };
        container::assemble(&mut manifest, &payloads)
    }

    /// Validates `bytes` as a package: the container (see [`container::parse`]) and the GDM
    /// it describes (grids, the codec's entry, ranks, decode parameters, every section's
    /// texture shape, an occupancy field's distances, the radiance transfer's sections).
    pub fn parse(bytes: Vec<u8>) -> Result<Package> {
        Package::parse_within(bytes, DEFAULT_MAX_MEMORY)
    }

    /// [`Package::parse`], refusing before allocating a package whose reading would take more
    /// than `max_memory` bytes ([`container::memory_needed`]).
    pub fn parse_within(bytes: Vec<u8>, max_memory: u64) -> Result<Package> {
        let manifest: Manifest = container::parse(&bytes)?;
        let contents = Contents::inflate(bytes, &manifest.sections, max_memory)?;
        let bad = |what: String| Error::Package(format!("manifest: {what}"));
        let [x, y, z] = manifest.bake.res;
        let dims = Dims::new(x, y, z).map_err(|e| bad(e.to_string()))?;
        let [n_theta, n_phi] = manifest.bake.dirs;
        let dirs = DirectionGrid::new(n_theta, n_phi).map_err(|e| bad(e.to_string()))?;
        manifest.input.check().map_err(bad)?;
        if (manifest.bake.method == Method::Fast) != manifest.bake.fast.is_some() {
            return Err(bad(format!(
                "bake method {:?} with fast parameters {:?}: the fast method has them, the \
                 exact one not",
                manifest.bake.method, manifest.bake.fast
            )));
        }
        if let Some(f) = manifest.bake.fast
            && !(f.stride >= 1 && f.max_spread.is_finite() && f.max_spread >= 0.0)
        {
            return Err(bad(format!(
                "the fast bake's stride {} and spread {} must be ≥ 1 and finite ≥ 0",
                f.stride, f.max_spread
            )));
        }
        match (manifest.codec, &manifest.gdm, &manifest.occupancy) {
            (GdmCodec::PaperSvd, Some(g), None) => {
                svd::validate(g, &manifest.sections, dims, dirs, bad)?
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
            if !(1..=gi::MAX_RTV_RANK).contains(&rank) {
                return Err(bad(format!(
                    "the RTV rank {rank} is not 1 to {}",
                    gi::MAX_RTV_RANK
                )));
            }
            for (name, expected) in gi::textures(info, dims, dirs) {
                expect_section(&manifest.sections, name, expected, bad)?;
            }
        }
        let package = Package {
            manifest,
            contents,
            dims,
            dirs,
        };
        if let Some(field) = package.occupancy().transpose()? {
            let claimed = package.manifest.occupancy.as_ref().map(|o| o.solid_voxels);
            if claimed != Some(field.solid_voxels()) {
                return Err(bad(format!(
                    "occupancy solid_voxels {} but the field holds {} solid voxels",
                    claimed.unwrap_or(0),
                    field.solid_voxels()
                )));
            }
        }
        package.check_factors_finite()?;
        package.radiance_transfer().transpose()?;
        Ok(package)
    }

    /// Reads and validates the package at `path`, refusing before reading a file over
    /// `max_bytes` and before decoding one whose reading would take more memory than that.
    pub fn read(path: &Path, max_bytes: u64) -> Result<Package> {
        Package::parse_within(read_limited(path, max_bytes)?, max_bytes)
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The voxel grid.
    pub fn dims(&self) -> Dims {
        self.dims
    }

    /// The direction grid.
    pub fn dirs(&self) -> DirectionGrid {
        self.dirs
    }

    /// The texels of section `name`, if present.
    pub fn section(&self, name: &str) -> Option<&[u8]> {
        self.contents.section(&self.manifest.sections, name)
    }

    /// The whole package's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.contents.file()
    }

    /// The quantized weight maps and eigenmaps, unpacked from their textures (codec
    /// `paper-svd`).
    pub fn factors(&self) -> Option<(QuantizedFactor, QuantizedFactor)> {
        let g = self.manifest.gdm.as_ref()?;
        let rows_w = self.dims.x as usize * self.dims.y as usize * self.dirs.n_phi as usize;
        let rows_e = self.dims.z as usize * self.dirs.n_theta as usize;
        let unpack = |info: &FactorInfo, rows: usize| {
            let groups = groups(&self.manifest.sections, &self.contents, &info.sections);
            QuantizedFactor::unpack(
                &groups,
                rows,
                g.quantization,
                info.scale.clone(),
                info.bias.clone(),
            )
        };
        Some((unpack(&g.weights, rows_w), unpack(&g.eigen, rows_e)))
    }

    /// Refuses a `paper-svd` factor holding a value that is not finite (a NaN or ±Inf stored
    /// as f16 or f32; u8 codes are finite by construction).
    fn check_factors_finite(&self) -> Result<()> {
        let Some(g) = &self.manifest.gdm else {
            return Ok(());
        };
        for (factor, info) in [("weights", &g.weights), ("eigen", &g.eigen)] {
            for (bytes, format) in groups(&self.manifest.sections, &self.contents, &info.sections) {
                let finite = match format.texel_bytes() / format.channels() {
                    2 => (bytes.chunks_exact(2))
                        .all(|h| half::f16::from_le_bytes([h[0], h[1]]).is_finite()),
                    4 => (bytes.chunks_exact(4))
                        .all(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite()),
                    _ => true,
                };
                if !finite {
                    return Err(Error::Package(format!(
                        "the {factor} factor holds a value that is not finite (NaN or ±Inf)"
                    )));
                }
            }
        }
        Ok(())
    }

    /// The decoded `paper-svd` GDM, for queries or a whole reconstruction.
    pub fn svd(&self) -> Option<SvdGdm> {
        let (w, e) = self.factors()?;
        let margin = self.manifest.gdm.as_ref()?.accuracy.escape_margin;
        Some(SvdGdm::new(self.dims, self.dirs, &w, &e, margin))
    }

    /// What answers GDM queries d(i, j, k, a, b) for this package's codec.
    pub fn query(&self) -> Result<GdmQuery> {
        match self.svd() {
            Some(svd) => Ok(GdmQuery::PaperSvd(svd)),
            None => Ok(GdmQuery::Occupancy(
                self.occupancy().expect("one codec entry")?,
                self.dirs,
            )),
        }
    }

    /// The radiance transfer, where the package holds one (validated: see
    /// [`RadianceTransfer::decode`]).
    pub fn radiance_transfer(&self) -> Option<Result<RadianceTransfer>> {
        let info = self.manifest.gi.as_ref()?;
        let section = |name| self.section(name).expect("validated");
        let sections = [
            section(gi::RTV_INDEX),
            section(gi::RTV_WEIGHTS),
            section(gi::RTV_EIGEN),
            section(gi::PRT_TRANSFER),
        ];
        Some(RadianceTransfer::decode(
            info,
            (self.dims, self.dirs),
            sections,
        ))
    }

    /// The occupancy field, for [`GdmCodec::Occupancy`] (validated: its distances are those
    /// its solid voxels imply).
    pub fn occupancy(&self) -> Option<Result<OccupancyField>> {
        let info = self.manifest.occupancy.as_ref()?;
        let bytes = self.section(&info.section).expect("validated");
        Some(OccupancyField::from_bytes(self.dims, bytes))
    }
}
