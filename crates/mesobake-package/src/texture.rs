//! What a section's bytes are on the GPU: textures, their texel formats, and the number
//! formats values are quantized to.

use crate::error::{Error, Result};

/// Components per texel of a factor texture (RGBA).
pub const CHANNELS: usize = 4;

/// The number format of quantized maps (f16 by default).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Quantization {
    /// 32-bit float (no quantization).
    F32,
    /// 16-bit float (IEEE binary16, round to nearest even).
    #[default]
    F16,
    /// 8-bit unsigned normalized code with a per-map scale and bias.
    U8,
}

impl Quantization {
    /// Every format, smallest last.
    pub const ALL: [Quantization; 3] = [Quantization::F32, Quantization::F16, Quantization::U8];

    /// Bytes per stored value.
    pub fn bytes(self) -> usize {
        match self {
            Quantization::F32 => 4,
            Quantization::F16 => 2,
            Quantization::U8 => 1,
        }
    }

    /// The name used on the command line and in package manifests.
    pub fn name(self) -> &'static str {
        match self {
            Quantization::F32 => "f32",
            Quantization::F16 => "f16",
            Quantization::U8 => "u8",
        }
    }
}

impl std::str::FromStr for Quantization {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Quantization::ALL
            .into_iter()
            .find(|q| q.name() == s)
            .ok_or_else(|| {
                Error::InvalidParameter(format!("quantization {s:?}: expected f32, f16 or u8"))
            })
    }
}

impl std::fmt::Display for Quantization {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A texture with tightly packed texels: `width` texels per row (x fastest), `height` rows
/// per image, `depth` images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Texture {
    /// `"2d"` or `"3d"`.
    pub dimension: TextureDimension,
    /// The texel format.
    pub format: TexelFormat,
    /// Texels per row.
    pub width: u32,
    /// Rows per image.
    pub height: u32,
    /// Images (1 for 2D textures).
    pub depth: u32,
}

/// Texture dimensionality.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum TextureDimension {
    /// A 2D texture.
    #[serde(rename = "2d")]
    D2,
    /// A 3D texture.
    #[serde(rename = "3d")]
    D3,
    /// A storage buffer of `width` texels (`height` and `depth` are 1).
    #[serde(rename = "buffer")]
    Buffer,
}

/// Texel formats, named as in WebGPU: one, two or four channels of little-endian f32,
/// IEEE binary16, or 8-bit codes read as code / 255.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[allow(missing_docs)]
pub enum TexelFormat {
    R32float,
    Rg32float,
    Rgba32float,
    R16float,
    Rg16float,
    Rgba16float,
    R8unorm,
    Rg8unorm,
    Rgba8unorm,
    R8uint,
    R32uint,
}

impl TexelFormat {
    /// The narrowest format that holds `components` (1 to 4) values quantized with `q`.
    pub fn of(q: Quantization, components: usize) -> Self {
        use TexelFormat::*;
        let [one, two, four] = match q {
            Quantization::F32 => [R32float, Rg32float, Rgba32float],
            Quantization::F16 => [R16float, Rg16float, Rgba16float],
            Quantization::U8 => [R8unorm, Rg8unorm, Rgba8unorm],
        };
        match components {
            0 | 1 => one,
            2 => two,
            _ => four,
        }
    }

    /// Channels per texel.
    pub fn channels(self) -> u32 {
        use TexelFormat::*;
        match self {
            R32float | R16float | R8unorm | R8uint | R32uint => 1,
            Rg32float | Rg16float | Rg8unorm => 2,
            Rgba32float | Rgba16float | Rgba8unorm => 4,
        }
    }

    /// Bytes per texel.
    pub fn texel_bytes(self) -> u32 {
        use TexelFormat::*;
        let per_channel = match self {
            R32float | Rg32float | Rgba32float | R32uint => 4,
            R16float | Rg16float | Rgba16float => 2,
            R8unorm | Rg8unorm | Rgba8unorm | R8uint => 1,
        };
        per_channel * self.channels()
    }
}

impl Texture {
    /// Total bytes, computed without overflow (None when it would overflow).
    pub fn byte_len(&self) -> Option<u64> {
        (self.width as u64 * self.format.texel_bytes() as u64)
            .checked_mul(self.height as u64)?
            .checked_mul(self.depth as u64)
    }
}
