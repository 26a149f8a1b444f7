//! Export of a package's texture sections as KTX 2.0 files (Khronos KTX File Format 2.0), so
//! that engines' texture tooling can read them: one file per section, 3D textures (weight
//! maps, occupancy) with `pixelDepth` = depth, 2D textures (eigenmaps) with `pixelDepth` = 0;
//! one mip level, no supercompression, linear transfer, a basic data format descriptor and a
//! `KTXwriter` key. Buffers (the radiance-transfer sections) are not textures and have no KTX2
//! form.

use crate::error::{Error, Result};
use crate::manifest::{TexelFormat, Texture, TextureDimension};

/// The twelve bytes that open every KTX 2.0 file.
pub const IDENTIFIER: [u8; 12] = [
    0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A,
];

/// Bytes before the level index: identifier, header (9 × u32) and index (4 × u32, 2 × u64).
const LEVEL_INDEX_OFFSET: usize = 12 + 36 + 32;

/// The Vulkan format of a texel format (VkFormat values).
pub fn vk_format(format: TexelFormat) -> u32 {
    use TexelFormat::*;
    match format {
        R8unorm => 9,
        R8uint => 13,
        Rg8unorm => 16,
        Rgba8unorm => 37,
        R16float => 76,
        Rg16float => 83,
        Rgba16float => 97,
        R32uint => 98,
        R32float => 100,
        Rg32float => 103,
        Rgba32float => 109,
    }
}

/// Bytes per channel of a texel format.
fn channel_bytes(format: TexelFormat) -> u32 {
    format.texel_bytes() / format.channels()
}

/// The basic data format descriptor block (Khronos Data Format 1.3, version 2) of an
/// uncompressed RGBA-ordered format: colour model RGBSDA, BT.709 primaries, linear transfer,
/// one sample per channel.
fn basic_descriptor(format: TexelFormat) -> Vec<u8> {
    use TexelFormat::*;
    let channels = format.channels();
    let bits = 8 * channel_bytes(format);
    let (qualifiers, lower, upper): (u8, u32, u32) = match format {
        R8unorm | Rg8unorm | Rgba8unorm => (0, 0, 255),
        R8uint | R32uint => (0, 0, 1),
        // Float and signed, with −1.0 and 1.0 as the sample's bounds.
        _ => (0x80 | 0x40, (-1.0f32).to_bits(), 1.0f32.to_bits()),
    };
    let size = 24 + 16 * channels;
    let mut block = Vec::with_capacity(size as usize);
    block.extend(0u32.to_le_bytes()); // vendor 0 (Khronos), descriptor type 0 (basic)
    block.extend((2u32 | size << 16).to_le_bytes()); // version 2, block size
    block.extend([1, 1, 1, 0]); // RGBSDA, BT.709, linear, straight alpha
    block.extend([0; 4]); // a 1×1×1×1 texel block (dimensions minus one)
    block.extend([format.texel_bytes() as u8, 0, 0, 0, 0, 0, 0, 0]); // bytes in plane 0
    for c in 0..channels {
        let channel: u8 = [0, 1, 2, 15][c as usize]; // R, G, B, A
        block.extend(((c * bits) as u16).to_le_bytes());
        block.push((bits - 1) as u8);
        block.push(channel | qualifiers);
        block.extend([0; 4]); // sample position
        block.extend(lower.to_le_bytes());
        block.extend(upper.to_le_bytes());
    }
    block
}

/// The key/value data: `KTXwriter` naming this crate, padded to four bytes.
fn key_value_data() -> Vec<u8> {
    let entry = format!(
        "KTXwriter\0mesobake-package {}\0",
        env!("CARGO_PKG_VERSION")
    );
    let mut kvd = (entry.len() as u32).to_le_bytes().to_vec();
    kvd.extend(entry.as_bytes());
    kvd.resize(kvd.len().next_multiple_of(4), 0);
    kvd
}

/// The KTX 2.0 file of a texture section: `texture` as the manifest describes it, `data` its
/// bytes. An error for buffers and for data of the wrong length.
pub fn write(texture: &Texture, data: &[u8]) -> Result<Vec<u8>> {
    let depth = match texture.dimension {
        TextureDimension::D2 => 0,
        TextureDimension::D3 => texture.depth,
        TextureDimension::Buffer => {
            return Err(Error::InvalidParameter(
                "a buffer section has no KTX2 form (only 2D and 3D textures do)".into(),
            ));
        }
    };
    if texture.byte_len() != Some(data.len() as u64) {
        return Err(Error::InvalidParameter(format!(
            "{} bytes do not fill a {texture:?}",
            data.len()
        )));
    }
    let dfd_offset = LEVEL_INDEX_OFFSET + 24;
    let mut dfd = Vec::new();
    let block = basic_descriptor(texture.format);
    dfd.extend((4 + block.len() as u32).to_le_bytes());
    dfd.extend(block);
    let kvd = key_value_data();
    let kvd_offset = dfd_offset + dfd.len();
    // Level data is aligned to lcm(texel size, 4): the texel sizes are 1, 2, 4, 8 or 16.
    let alignment = (texture.format.texel_bytes() as usize).max(4);
    let level_offset = (kvd_offset + kvd.len()).next_multiple_of(alignment);

    let mut file = Vec::with_capacity(level_offset + data.len());
    file.extend(IDENTIFIER);
    for word in [
        vk_format(texture.format),
        channel_bytes(texture.format), // typeSize
        texture.width,
        texture.height,
        depth,
        0, // layerCount: not an array
        1, // faceCount
        1, // levelCount
        0, // supercompressionScheme: none
        dfd_offset as u32,
        dfd.len() as u32,
        kvd_offset as u32,
        kvd.len() as u32,
    ] {
        file.extend(word.to_le_bytes());
    }
    file.extend(0u64.to_le_bytes()); // sgdByteOffset
    file.extend(0u64.to_le_bytes()); // sgdByteLength
    for value in [level_offset as u64, data.len() as u64, data.len() as u64] {
        file.extend(value.to_le_bytes());
    }
    file.extend(dfd);
    file.extend(kvd);
    file.resize(level_offset, 0);
    file.extend(data);
    Ok(file)
}
