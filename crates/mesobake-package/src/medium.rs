//! Medium packages (`format` `"mesobake-medium-package"`): a translucent medium as the
//! semi-transparent 3D texture renderers read it, ready for GPU upload. Per level of its
//! opacity-aware mip-map (level 0 the medium itself, the coarser levels only where the scene
//! filters): a 3D texture of (linear colour, opacity) per voxel and a 3D texture of the
//! unnormalized outward normal (−∇ opacity) per voxel. Nothing in it depends on the base
//! mesh, so an animated surface renders from the same package. The same container as GDM
//! packages ([`crate::container`]); the byte-exact format is specified in mesobake's
//! `docs/package-format.md`.
//!
//! Opacity is per voxel length in texture space (a path of ℓ voxels through voxel v transmits
//! (1 − α_v)^ℓ); level l + 1 halves every side of level l and its opacity is per voxel
//! length of its own, coarser, voxels.

use crate::container::{self, ContainerManifest, Contents};
use crate::error::{Error, Result};
use crate::grid::Dims;
use crate::manifest::{FactorInfo, InputInfo, Section, TexelFormat, Texture, TextureDimension};
use crate::quantize::{Quantization, QuantizedFactor};
use std::path::Path;

/// The value of [`MediumManifest::format`].
pub const MEDIUM_FORMAT_NAME: &str = "mesobake-medium-package";

/// Most mip levels a medium package holds.
pub const MAX_LEVELS: usize = 16;

/// Stored values per voxel of the voxel texture: linear colour r, g, b and opacity.
const VOXEL_COMPONENTS: usize = 4;

/// Stored values per voxel of the normal texture: x, y, z (the texel's fourth channel is 0).
const NORMAL_COMPONENTS: usize = 3;

/// The manifest of a medium package.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumManifest {
    /// Always [`MEDIUM_FORMAT_NAME`].
    pub format: String,
    /// The container version, equal to the header's.
    pub version: u32,
    /// The tool that wrote the package, `mesobake <version>`.
    pub generator: String,
    /// Unit of opacity: `"voxel"` (opacity per voxel length of its level).
    pub units: String,
    /// The mesostructure the medium was made from.
    pub input: InputInfo,
    /// The levels, their decode parameters and the quantization's error.
    pub medium: MediumInfo,
    /// The binary sections, in file order.
    pub sections: Vec<Section>,
}

impl ContainerManifest for MediumManifest {
    const FORMAT: &'static str = MEDIUM_FORMAT_NAME;
    fn sections(&self) -> &[Section] {
        &self.sections
    }
    fn sections_mut(&mut self) -> &mut [Section] {
        &mut self.sections
    }
}

/// What a medium package holds.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumInfo {
    /// The number format of every texture.
    pub quantization: Quantization,
    /// Level 0 (the medium) and the coarser levels of its mip-map, if baked.
    pub levels: Vec<LevelInfo>,
    /// The stored values' error against the values they quantize.
    pub accuracy: MediumAccuracy,
}

/// One level of the mip-map.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LevelInfo {
    /// Voxels [X, Y, Z].
    pub res: [u32; 3],
    /// Section `medium.voxels.L`: components colour r, g, b, opacity.
    pub voxels: FactorInfo,
    /// Section `medium.normals.L`: components normal x, y, z.
    pub normals: FactorInfo,
}

/// The largest error quantization made, over every voxel of every level.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumAccuracy {
    /// Largest opacity error.
    pub opacity_max_abs: f64,
    /// Largest colour channel error.
    pub colour_max_abs: f64,
    /// Largest normal component error (normals are unnormalized opacity gradients).
    pub normal_max_abs: f64,
}

/// One level as the writer takes it and the reader returns it.
#[derive(Clone, Debug, PartialEq)]
pub struct MediumLevel {
    /// The level's grid.
    pub dims: Dims,
    /// Per voxel (x fastest, then y, then z): linear colour r, g, b and opacity in [0, 1].
    pub voxels: Vec<[f32; 4]>,
    /// Per voxel, same order: the unnormalized outward normal.
    pub normals: Vec<[f32; 3]>,
}

/// The number format of the normals of a package quantized to `q`: `q`, but f16 for u8: an
/// 8-bit code of a component's range cannot hold zero exactly, and the zero gradient inside
/// uniform medium (which has no normal) must decode to zero.
pub fn normal_quantization(q: Quantization) -> Quantization {
    match q {
        Quantization::U8 => Quantization::F16,
        q => q,
    }
}

/// The 3D texture of a level's section in `q`.
fn level_texture(res: [u32; 3], q: Quantization) -> Texture {
    Texture {
        dimension: TextureDimension::D3,
        format: TexelFormat::of(q, VOXEL_COMPONENTS),
        width: res[0],
        height: res[1],
        depth: res[2],
    }
}

/// The names of level `l`'s two sections.
fn section_names(l: usize) -> [String; 2] {
    [format!("medium.voxels.{l}"), format!("medium.normals.{l}")]
}

/// The largest |a − b| over paired values.
fn max_abs(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| f64::from((x - y).abs()))
        .fold(0.0, f64::max)
}

/// The grid of the level after one of `res`: every side halved, or `None` where a side is
/// odd or the grid is one voxel thick (the mip-map ends there).
pub fn coarser_res(res: [u32; 3]) -> Option<[u32; 3]> {
    (res.iter().all(|n| n % 2 == 0) && res[2] >= 2).then(|| res.map(|n| n / 2))
}

/// A validated medium package in memory, its levels decoded.
#[derive(Debug)]
pub struct MediumPackage {
    manifest: MediumManifest,
    contents: Contents,
    levels: Vec<MediumLevel>,
}

impl MediumPackage {
    /// Encodes `levels` (level 0 first, each the [`coarser_res`] of the one before) quantized
    /// to `q`, made from `input`, into package bytes (deterministic). Panics if the levels
    /// are not such a chain: the caller builds them.
    pub fn encode(input: InputInfo, q: Quantization, levels: &[MediumLevel]) -> Vec<u8> {
        assert!(
            (1..=MAX_LEVELS).contains(&levels.len()),
            "1 to {MAX_LEVELS} levels"
        );
        let (mut sections, mut payloads, mut infos) = (Vec::new(), Vec::new(), Vec::new());
        let mut accuracy = MediumAccuracy::default();
        for (l, level) in levels.iter().enumerate() {
            let d = level.dims;
            let res = [d.x, d.y, d.z];
            if l > 0 {
                let previous: &LevelInfo = &infos[l - 1];
                assert_eq!(coarser_res(previous.res), Some(res), "a mip chain");
            }
            let n = d.voxel_count() as usize;
            assert!(level.voxels.len() == n && level.normals.len() == n);
            let [voxel_name, normal_name] = section_names(l);
            let mut factor = |values: Vec<f32>, components: usize, q, name: &str| {
                let texture = level_texture(res, q);
                let f = QuantizedFactor::new(&values, components, q);
                payloads.push(f.pack_group(0..n, components, 0, &texture));
                sections.push(Section::new(name, texture));
                let decoded = f.dequantize();
                let info = FactorInfo {
                    sections: vec![name.to_owned()],
                    scale: f.scale,
                    bias: f.bias,
                };
                (info, values, decoded)
            };
            let (voxels, values, decoded) =
                factor(level.voxels.concat(), VOXEL_COMPONENTS, q, &voxel_name);
            for c in 0..VOXEL_COMPONENTS {
                let column = |v: &[f32]| -> Vec<f32> {
                    v.iter()
                        .skip(c)
                        .step_by(VOXEL_COMPONENTS)
                        .copied()
                        .collect()
                };
                let e = max_abs(&column(&values), &column(&decoded));
                let slot = if c == 3 {
                    &mut accuracy.opacity_max_abs
                } else {
                    &mut accuracy.colour_max_abs
                };
                *slot = slot.max(e);
            }
            let (normals, values, decoded) = factor(
                level.normals.concat(),
                NORMAL_COMPONENTS,
                normal_quantization(q),
                &normal_name,
            );
            accuracy.normal_max_abs = accuracy.normal_max_abs.max(max_abs(&values, &decoded));
            infos.push(LevelInfo {
                res,
                voxels,
                normals,
            });
        }
        let mut manifest = MediumManifest {
            format: MEDIUM_FORMAT_NAME.into(),
            version: container::VERSION,
            generator: format!("mesobake {}", env!("CARGO_PKG_VERSION")),
            units: "voxel".into(),
            input,
            medium: MediumInfo {
                quantization: q,
                levels: infos,
                accuracy,
            },
            sections,
        };
        container::assemble(&mut manifest, &payloads)
    }

    /// Validates `bytes` as a medium package: the container, the level chain, every
    /// section's texture and decode parameters, and every decoded value (opacity in [0, 1],
    /// colour finite and ≥ 0, normals finite).
    pub fn parse(bytes: Vec<u8>) -> Result<MediumPackage> {
        MediumPackage::parse_within(bytes, crate::DEFAULT_MAX_MEMORY)
    }

    /// `parse`, refusing before allocating a package whose reading would take more than
    /// `max_memory` bytes ([`container::memory_needed`]).
    pub fn parse_within(bytes: Vec<u8>, max_memory: u64) -> Result<MediumPackage> {
        let manifest: MediumManifest = container::parse(&bytes)?;
        let contents = Contents::inflate(bytes, &manifest.sections, max_memory)?;
        let bad = |what: String| Error::Package(format!("manifest: {what}"));
        manifest.input.check().map_err(bad)?;
        let info = &manifest.medium;
        if manifest.units != "voxel" {
            return Err(bad(format!(
                "units {:?}: a medium package's opacity is per \"voxel\" length",
                manifest.units
            )));
        }
        if !(1..=MAX_LEVELS).contains(&info.levels.len()) {
            return Err(bad(format!(
                "{} levels: a medium package holds 1 to {MAX_LEVELS}",
                info.levels.len()
            )));
        }
        let a = info.accuracy;
        if ![a.opacity_max_abs, a.colour_max_abs, a.normal_max_abs]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
        {
            return Err(bad("the accuracy must hold finite values ≥ 0".into()));
        }
        let q = info.quantization;
        let mut levels = Vec::with_capacity(info.levels.len());
        for (l, level) in info.levels.iter().enumerate() {
            let [x, y, z] = level.res;
            let dims = Dims::new(x, y, z).map_err(|e| bad(format!("level {l}: {e}")))?;
            if l > 0 && coarser_res(info.levels[l - 1].res) != Some(level.res) {
                return Err(bad(format!(
                    "level {l} is {x}×{y}×{z}, not the previous level halved"
                )));
            }
            let n = dims.voxel_count() as usize;
            let names = section_names(l);
            let decode = |f: &FactorInfo, name: &String, components: usize, q| {
                let texture = level_texture(level.res, q);
                if f.sections != [name.clone()]
                    || f.scale.len() != components
                    || f.bias.len() != components
                    || f.scale.iter().chain(&f.bias).any(|v| !v.is_finite())
                {
                    return Err(bad(format!(
                        "level {l} must list section {name:?} and {components} finite scales \
                         and biases"
                    )));
                }
                crate::expect_section(&manifest.sections, name, texture, bad)?;
                let group = crate::groups(&manifest.sections, &contents, &f.sections);
                Ok(
                    QuantizedFactor::unpack(&group, n, q, f.scale.clone(), f.bias.clone())
                        .dequantize(),
                )
            };
            let voxels = decode(&level.voxels, &names[0], VOXEL_COMPONENTS, q)?;
            let normals = decode(
                &level.normals,
                &names[1],
                NORMAL_COMPONENTS,
                normal_quantization(q),
            )?;
            let voxels: Vec<[f32; 4]> = voxels
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            if let Some(v) = voxels.iter().position(|c| {
                !(0.0..=1.0).contains(&c[3]) || c[..3].iter().any(|x| !(x.is_finite() && *x >= 0.0))
            }) {
                return Err(bad(format!(
                    "level {l}, voxel {v}: colour {:?} and opacity {} are not finite colours ≥ 0 \
                     and an opacity in [0, 1]",
                    &voxels[v][..3],
                    voxels[v][3]
                )));
            }
            if let Some(v) = normals.iter().position(|x| !x.is_finite()) {
                return Err(bad(format!(
                    "level {l}, voxel {}: the normal is not finite",
                    v / 3
                )));
            }
            let normals = normals
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            levels.push(MediumLevel {
                dims,
                voxels,
                normals,
            });
        }
        Ok(MediumPackage {
            manifest,
            contents,
            levels,
        })
    }

    /// Reads and validates the medium package at `path`, refusing before reading a file over
    /// `max_bytes` and before decoding one whose reading would take more memory than that.
    pub fn read(path: &Path, max_bytes: u64) -> Result<MediumPackage> {
        MediumPackage::parse_within(crate::read_limited(path, max_bytes)?, max_bytes)
    }

    /// The manifest.
    pub fn manifest(&self) -> &MediumManifest {
        &self.manifest
    }

    /// The decoded levels, level 0 first.
    pub fn levels(&self) -> &[MediumLevel] {
        &self.levels
    }

    /// The whole package's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.contents.file()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input() -> InputInfo {
        InputInfo {
            kind: "medium".into(),
            bytes: 3,
            blake3: "00".repeat(32),
        }
    }

    /// A 4×4×2 medium with varied values and its one coarser level.
    fn levels() -> Vec<MediumLevel> {
        let level = |x: u32, y: u32, z: u32| {
            let dims = Dims::new(x, y, z).unwrap();
            let n = dims.voxel_count() as usize;
            MediumLevel {
                dims,
                voxels: (0..n)
                    .map(|v| {
                        let t = v as f32 / n as f32;
                        [t, 0.5 * t, 1.0 - t, if v % 3 == 0 { 1.0 } else { 0.1 * t }]
                    })
                    .collect(),
                normals: (0..n).map(|v| [v as f32 - 3.0, 0.25, -7.5]).collect(),
            }
        };
        vec![level(4, 4, 2), level(2, 2, 1)]
    }

    #[test]
    fn f32_round_trips_exactly_and_every_format_errs_within_its_step() {
        let levels = levels();
        let bytes = MediumPackage::encode(input(), Quantization::F32, &levels);
        let p = MediumPackage::parse(bytes.clone()).unwrap();
        assert_eq!(p.levels(), &levels[..]);
        assert_eq!(p.manifest().medium.accuracy, MediumAccuracy::default());
        // Deterministic.
        assert_eq!(
            MediumPackage::encode(input(), Quantization::F32, &levels),
            bytes
        );
        // f16: relative 2⁻¹¹; u8: half a step of each channel's range (≤ 1/510 of [0, 1]).
        let f16 = MediumPackage::parse(MediumPackage::encode(input(), Quantization::F16, &levels))
            .unwrap();
        let acc = f16.manifest().medium.accuracy;
        assert!(
            acc.opacity_max_abs <= 2f64.powi(-11) && acc.normal_max_abs <= 7.5 * 2f64.powi(-11)
        );
        let u8 = MediumPackage::parse(MediumPackage::encode(input(), Quantization::U8, &levels))
            .unwrap();
        let acc = u8.manifest().medium.accuracy;
        assert!(acc.opacity_max_abs <= 0.5 / 255.0 + 1e-6, "{acc:?}");
        assert!(acc.opacity_max_abs > 0.0 && acc.colour_max_abs <= 0.5 / 255.0 + 1e-6);
        // Opaque and empty voxels, and zero gradients, stay exactly so in every format.
        let mut zero = levels.clone();
        zero[0].normals[5] = [0.0; 3];
        for q in [Quantization::F16, Quantization::U8] {
            let p = MediumPackage::parse(MediumPackage::encode(input(), q, &zero)).unwrap();
            for (got, want) in p.levels()[0].voxels.iter().zip(&zero[0].voxels) {
                if want[3] == 1.0 || want[3] == 0.0 {
                    assert_eq!(got[3], want[3]);
                }
            }
            assert_eq!(p.levels()[0].normals[5], [0.0; 3], "{q}");
        }
    }

    #[test]
    fn corrupt_or_inconsistent_packages_are_refused_by_name() {
        let levels = levels();
        let bytes = MediumPackage::encode(input(), Quantization::F32, &levels);
        let manifest: MediumManifest = container::parse(&bytes).unwrap();
        let rewrite = |edit: &dyn Fn(&mut MediumManifest, &mut Vec<Vec<u8>>)| {
            let mut m = manifest.clone();
            let contents = Contents::inflate(bytes.clone(), &m.sections, u64::MAX).unwrap();
            let mut payloads: Vec<Vec<u8>> = m
                .sections
                .iter()
                .map(|s| contents.section(&m.sections, &s.name).unwrap().to_vec())
                .collect();
            edit(&mut m, &mut payloads);
            MediumPackage::parse(container::assemble(&mut m, &payloads))
                .unwrap_err()
                .to_string()
        };
        let e = rewrite(&|m, _| m.medium.levels[1].res = [2, 2, 2]);
        assert!(e.contains("not the previous level halved"), "{e}");
        let e = rewrite(&|_, p| p[0][12..16].copy_from_slice(&1.5f32.to_le_bytes()));
        assert!(
            e.contains("level 0, voxel 0") && e.contains("opacity 1.5"),
            "{e}"
        );
        let e = rewrite(&|_, p| p[1][0..4].copy_from_slice(&f32::NAN.to_le_bytes()));
        assert!(e.contains("the normal is not finite"), "{e}");
        let e = rewrite(&|m, _| {
            m.medium.levels[0].voxels.scale.pop();
        });
        assert!(e.contains("4 finite scales"), "{e}");
        let e = rewrite(&|m, _| m.units = "tile".into());
        assert!(e.contains("units"), "{e}");
        let mut flipped = bytes.clone();
        flipped[300] ^= 1;
        assert!(MediumPackage::parse(flipped).is_err());
        assert!(MediumPackage::parse(bytes).is_ok());
    }

    #[test]
    fn the_mip_chain_halves_until_a_side_is_odd_or_one_voxel_thick() {
        assert_eq!(coarser_res([8, 8, 4]), Some([4, 4, 2]));
        assert_eq!(coarser_res([4, 4, 2]), Some([2, 2, 1]));
        assert_eq!(coarser_res([2, 2, 1]), None);
        assert_eq!(coarser_res([6, 3, 4]), None);
    }
}
