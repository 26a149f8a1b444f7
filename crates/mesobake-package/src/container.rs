//! The `.mbpkg` container: a fixed header, 256-byte-aligned binary sections (each its
//! texture's texels, or those supercompressed), and the JSON manifest last. Every byte is
//! covered by a checksum or must be zero, so any corruption is detected. The byte-exact layout
//! is specified in `docs/package-format.md`.

use crate::error::{Error, Result};
use crate::supercompression::Supercompression;
use crate::texture::{Texture, TextureDimension};
use rayon::prelude::*;

/// The first eight bytes of every package.
pub const MAGIC: [u8; 8] = *b"\x89MBPKG\r\n";

/// The container version this build writes and reads.
pub const VERSION: u32 = 2;

/// Bytes in the fixed header.
pub const HEADER_BYTES: usize = 64;

/// Alignment of every section and of the manifest.
pub const ALIGNMENT: u64 = 256;

/// Largest manifest accepted.
pub const MAX_MANIFEST_BYTES: u64 = 16 << 20;

/// Most sections accepted.
pub const MAX_SECTIONS: usize = 4096;

/// Most bytes a package's supercompressed sections may inflate to, in all (checked against
/// their textures before inflating, so a small file cannot claim more memory than this).
pub const MAX_INFLATED_BYTES: u64 = 4 << 30;

/// One binary section.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Section {
    /// Unique name.
    pub name: String,
    /// Byte offset from the start of the file, a multiple of 256.
    pub offset: u64,
    /// Length in bytes, as stored.
    pub bytes: u64,
    /// CRC-32 (IEEE 802.3, as zlib's `crc32`) of the section's stored bytes.
    pub crc32: u32,
    /// The texture the bytes upload to.
    pub texture: Texture,
    /// How the stored bytes encode the texels; `None` (omitted): they are the texels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub supercompression: Option<Supercompression>,
}

impl Section {
    /// A section named `name` holding `texture`, placed by [`crate::container::assemble`],
    /// which stores it supercompressed where that is smaller.
    pub fn new(name: &str, texture: Texture) -> Section {
        Section {
            name: name.into(),
            offset: 0,
            bytes: 0,
            crc32: 0,
            texture,
            supercompression: Some(Supercompression::PaethZlib),
        }
    }
}

fn invalid(message: impl Into<String>) -> Error {
    Error::Package(message.into())
}

/// A manifest the container holds: a JSON object whose `format` and `version` fields say what
/// it is, listing the binary sections.
pub trait ContainerManifest: serde::Serialize + serde::de::DeserializeOwned {
    /// The value of the manifest's `format` field.
    const FORMAT: &'static str;
    /// The binary sections, in file order.
    fn sections(&self) -> &[Section];
    /// The binary sections, for [`assemble`] to place.
    fn sections_mut(&mut self) -> &mut [Section];
}

/// The fields every manifest starts with.
#[derive(serde::Deserialize)]
struct Head {
    format: String,
    version: u32,
}

/// Lays out `payloads` (one per entry of the manifest's sections, in order: each its texture's
/// texels) and the manifest, filling in each section's offset, length and checksum. A section
/// marked for supercompression (as [`Section::new`] marks it) is stored compressed where that
/// is smaller, and unmarked where it is not.
pub fn assemble<M: ContainerManifest>(manifest: &mut M, payloads: &[Vec<u8>]) -> Vec<u8> {
    assert_eq!(
        manifest.sections().len(),
        payloads.len(),
        "one payload per section"
    );
    let stored: Vec<Option<Vec<u8>>> = (manifest.sections().par_iter().zip(payloads))
        .map(|(section, texels)| {
            let scheme = section.supercompression?;
            Some(scheme.compress(&section.texture, texels)).filter(|s| s.len() < texels.len())
        })
        .collect();
    let mut file = vec![0u8; HEADER_BYTES];
    for ((section, texels), stored) in manifest
        .sections_mut()
        .iter_mut()
        .zip(payloads)
        .zip(&stored)
    {
        if stored.is_none() {
            section.supercompression = None;
        }
        let payload = stored.as_deref().unwrap_or(texels);
        file.resize(file.len().next_multiple_of(ALIGNMENT as usize), 0);
        section.offset = file.len() as u64;
        section.bytes = payload.len() as u64;
        section.crc32 = crc32fast::hash(payload);
        file.extend_from_slice(payload);
    }
    file.resize(file.len().next_multiple_of(ALIGNMENT as usize), 0);
    let json = serde_json::to_vec(manifest).expect("manifests hold only finite numbers");
    let manifest_offset = file.len() as u64;
    file.extend_from_slice(&json);
    let total = file.len() as u64;
    let header = &mut file[..HEADER_BYTES];
    header[0..8].copy_from_slice(&MAGIC);
    header[8..12].copy_from_slice(&VERSION.to_le_bytes());
    header[12..16].copy_from_slice(&(HEADER_BYTES as u32).to_le_bytes());
    header[16..24].copy_from_slice(&manifest_offset.to_le_bytes());
    header[24..32].copy_from_slice(&(json.len() as u64).to_le_bytes());
    header[32..36].copy_from_slice(&crc32fast::hash(&json).to_le_bytes());
    header[40..48].copy_from_slice(&total.to_le_bytes());
    let crc = crc32fast::hash(&header[..60]);
    header[60..64].copy_from_slice(&crc.to_le_bytes());
    file
}

/// The `format` field of the package in `bytes` (`"mesobake-package"` for a GDM package,
/// `"mesobake-vdm-package"` for a VDM package), after checking the header and the manifest's
/// checksum; the sections are not checked.
pub fn format(bytes: &[u8]) -> Result<String> {
    let (json, _) = manifest_json(bytes)?;
    Ok(head(json)?.format)
}

fn head(json: &[u8]) -> Result<Head> {
    serde_json::from_slice(json).map_err(|e| invalid(format!("the manifest is not valid: {e}")))
}

/// Validates the container structure of `bytes` and returns its manifest, which must be an
/// `M`: header, checksums, the manifest's format and version, section bounds, alignment,
/// texture sizes and zero padding. What the sections mean is checked by the caller.
pub fn parse<M: ContainerManifest>(bytes: &[u8]) -> Result<M> {
    let (json, manifest_offset) = manifest_json(bytes)?;
    let head = head(json)?;
    if head.format != M::FORMAT || head.version != VERSION {
        return Err(invalid(format!(
            "the manifest describes {:?} version {}, not {:?} version {VERSION}",
            head.format,
            head.version,
            M::FORMAT
        )));
    }
    let manifest: M = serde_json::from_slice(json)
        .map_err(|e| invalid(format!("the manifest is not valid: {e}")))?;
    check_sections(bytes, manifest.sections(), manifest_offset)?;
    Ok(manifest)
}

/// Checks the header and the manifest's placement and checksum; returns the manifest's bytes
/// and offset.
fn manifest_json(bytes: &[u8]) -> Result<(&[u8], u64)> {
    if bytes.len() < HEADER_BYTES {
        return Err(invalid(format!(
            "truncated: {} bytes, shorter than the {HEADER_BYTES}-byte header",
            bytes.len()
        )));
    }
    let header = &bytes[..HEADER_BYTES];
    if header[..8] != MAGIC {
        return Err(invalid("not a mesobake package (bad magic number)"));
    }
    let u32_at = |o: usize| u32::from_le_bytes(header[o..o + 4].try_into().expect("4 bytes"));
    let u64_at = |o: usize| u64::from_le_bytes(header[o..o + 8].try_into().expect("8 bytes"));
    if crc32fast::hash(&header[..60]) != u32_at(60) {
        return Err(invalid("header checksum mismatch: the file is corrupt"));
    }
    let version = u32_at(8);
    if version != VERSION {
        return Err(invalid(format!(
            "package format version {version} is not supported (this build reads version {VERSION}; bake the package again)"
        )));
    }
    if u32_at(12) != HEADER_BYTES as u32
        || u32_at(36) != 0
        || header[48..60].iter().any(|&b| b != 0)
    {
        return Err(invalid(
            "malformed header: unexpected header size or reserved bytes",
        ));
    }
    let (manifest_offset, manifest_len, total) = (u64_at(16), u64_at(24), u64_at(40));
    if total != bytes.len() as u64 {
        return Err(invalid(format!(
            "the header declares {total} bytes but the file has {} (truncated or extended)",
            bytes.len()
        )));
    }
    if manifest_len > MAX_MANIFEST_BYTES {
        return Err(invalid(format!(
            "the manifest's declared size, {manifest_len} bytes, exceeds the limit of {MAX_MANIFEST_BYTES}"
        )));
    }
    if manifest_offset % ALIGNMENT != 0
        || manifest_offset < HEADER_BYTES as u64
        || manifest_offset.checked_add(manifest_len) != Some(total)
    {
        return Err(invalid(format!(
            "the manifest ({manifest_len} bytes at offset {manifest_offset}) must be aligned and end the file"
        )));
    }
    let json = &bytes[manifest_offset as usize..];
    if crc32fast::hash(json) != u32_at(32) {
        return Err(invalid("manifest checksum mismatch: the file is corrupt"));
    }
    Ok((json, manifest_offset))
}

/// Checks section bounds, order, alignment, sizes, checksums and the zero padding between.
fn check_sections(bytes: &[u8], sections: &[Section], manifest_offset: u64) -> Result<()> {
    if sections.len() > MAX_SECTIONS {
        return Err(invalid(format!(
            "{} sections, over the limit of {MAX_SECTIONS}",
            sections.len()
        )));
    }
    let mut names = std::collections::BTreeSet::new();
    let mut end = HEADER_BYTES as u64;
    for s in sections {
        let what = format!("section {:?}", s.name);
        if !names.insert(s.name.as_str()) {
            return Err(invalid(format!("{what} appears twice")));
        }
        let t = &s.texture;
        if t.width == 0
            || t.height == 0
            || t.depth == 0
            || (t.dimension == TextureDimension::D2 && t.depth != 1)
            || (t.dimension == TextureDimension::Buffer && (t.height, t.depth) != (1, 1))
        {
            return Err(invalid(format!(
                "{what} has an invalid texture shape {t:?}"
            )));
        }
        if t.byte_len().is_none() || (s.supercompression.is_none() && t.byte_len() != Some(s.bytes))
        {
            return Err(invalid(format!(
                "{what} holds {} bytes but its {}×{}×{} texture needs {:?}",
                s.bytes,
                t.width,
                t.height,
                t.depth,
                t.byte_len()
            )));
        }
        let section_end = s
            .offset
            .checked_add(s.bytes)
            .filter(|&e| e <= manifest_offset);
        let Some(section_end) =
            section_end.filter(|_| s.offset >= end && s.offset % ALIGNMENT == 0)
        else {
            return Err(invalid(format!(
                "{what} ({} bytes at offset {}) is misplaced: sections must be aligned, in order, \
                 and lie before the manifest",
                s.bytes, s.offset
            )));
        };
        zero_padding(bytes, end, s.offset)?;
        let payload = &bytes[s.offset as usize..section_end as usize];
        if crc32fast::hash(payload) != s.crc32 {
            return Err(invalid(format!(
                "{what}: checksum mismatch, the file is corrupt"
            )));
        }
        end = section_end;
    }
    zero_padding(bytes, end, manifest_offset)
}

fn zero_padding(bytes: &[u8], from: u64, to: u64) -> Result<()> {
    if bytes[from as usize..to as usize].iter().any(|&b| b != 0) {
        return Err(invalid(format!(
            "non-zero padding between bytes {from} and {to}: the file is corrupt"
        )));
    }
    Ok(())
}

/// A package's bytes, checked by [`parse`], with its supercompressed sections inflated.
#[derive(Debug)]
pub struct Contents {
    file: Vec<u8>,
    /// Per section of the manifest, in order: its texels where they are stored compressed.
    inflated: Vec<Option<Vec<u8>>>,
}

/// The most memory reading a package of `file_len` bytes with `sections` takes, from its
/// manifest alone: the file, its supercompressed sections inflated, and every section's texels
/// decoded to f32 per channel (no reader of the format decodes a texel to more) — saturating,
/// so that a manifest claiming absurd sizes gives `u64::MAX`.
pub fn memory_needed(file_len: u64, sections: &[Section]) -> u64 {
    (sections.iter()).fold(file_len, |sum, s| sum.saturating_add(section_memory(s)))
}

/// What reading section `s` takes beyond the file: its texels inflated (when supercompressed)
/// and decoded to f32 per channel, saturating.
fn section_memory(s: &Section) -> u64 {
    let t = &s.texture;
    let texels = (t.width as u64)
        .saturating_mul(t.height as u64)
        .saturating_mul(t.depth as u64);
    let decoded = texels.saturating_mul(4 * t.format.channels() as u64);
    let inflated = match s.supercompression {
        Some(_) => texels.saturating_mul(t.format.texel_bytes() as u64),
        None => 0,
    };
    decoded.saturating_add(inflated)
}

impl Contents {
    /// Inflates the supercompressed ones among `sections` (the manifest's, as [`parse`]
    /// returned it from `file`), refusing a stream that is not valid or does not hold exactly
    /// its texture, and first refusing a package whose reading would take more than
    /// `max_memory` bytes ([`memory_needed`]).
    pub fn inflate(file: Vec<u8>, sections: &[Section], max_memory: u64) -> Result<Contents> {
        let needed = memory_needed(file.len() as u64, sections);
        if needed > max_memory {
            let largest = sections.iter().max_by_key(|s| section_memory(s));
            return Err(Error::MemoryLimit {
                what: format!(
                    "reading this package (its {} bytes, its sections inflated and decoded; \
                     the largest, section {:?}, {} bytes)",
                    file.len(),
                    largest.map_or("", |s| &s.name),
                    largest.map_or(0, section_memory)
                ),
                needed,
                limit: max_memory,
            });
        }
        let mut inflated_bytes = 0u64;
        for s in sections.iter().filter(|s| s.supercompression.is_some()) {
            let texels = s.texture.byte_len();
            inflated_bytes = match texels.and_then(|n| n.checked_add(inflated_bytes)) {
                Some(sum) if sum <= MAX_INFLATED_BYTES => sum,
                _ => {
                    return Err(invalid(format!(
                        "section {:?}: its texture ({} bytes) takes the supercompressed \
                         sections over the limit of {MAX_INFLATED_BYTES} bytes in all",
                        s.name,
                        texels.map_or("over 2^64".into(), |n| n.to_string())
                    )));
                }
            };
        }
        let inflated = sections
            .par_iter()
            .map(|s| {
                let Some(scheme) = s.supercompression else {
                    return Ok(None);
                };
                let stored = &file[s.offset as usize..][..s.bytes as usize];
                scheme
                    .decompress(&s.texture, stored)
                    .map(Some)
                    .map_err(|e| invalid(format!("section {:?}: {e}", s.name)))
            })
            .collect::<Result<_>>()?;
        Ok(Contents { file, inflated })
    }

    /// The whole file.
    pub fn file(&self) -> &[u8] {
        &self.file
    }

    /// The texels of section `name` among `sections` (the manifest's), if listed.
    pub fn section<'a>(&'a self, sections: &[Section], name: &str) -> Option<&'a [u8]> {
        let i = sections.iter().position(|s| s.name == name)?;
        let s = &sections[i];
        Some(
            self.inflated[i]
                .as_deref()
                .unwrap_or(&self.file[s.offset as usize..][..s.bytes as usize]),
        )
    }
}
