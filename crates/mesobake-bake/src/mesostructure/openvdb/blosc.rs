//! Decoding of Blosc 1 buffers, the codec OpenVDB compresses node values with by default
//! (`COMPRESS_BLOSC`): a 16-byte header, the start of every block, and each block as
//! `typesize` byte streams (or one) compressed with LZ4 or zlib, byte-shuffled. Written from
//! c-blosc 1.21's `blosc_d` and `blosc_run_decompression_with_context`, with every offset and
//! length checked against the buffer: a malformed buffer is an error, never a read outside
//! it. BloscLZ, Snappy, Zstd and bit-shuffled buffers are refused by name (OpenVDB writes
//! LZ4, byte-shuffled).

use std::io::Read;

/// Header flag: the blocks are byte-shuffled.
const DOSHUFFLE: u8 = 0x1;
/// Header flag: the data follows the header uncompressed.
const MEMCPYED: u8 = 0x2;
/// Header flag: the blocks are bit-shuffled.
const DOBITSHUFFLE: u8 = 0x4;
/// Header flag: each block is one stream, not split by byte.
const DONT_SPLIT: u8 = 0x10;
/// Blocks are split into `typesize` streams only for types up to this size…
const MAX_SPLITS: usize = 16;
/// …and blocks of at least this many elements.
const MIN_BUFFERSIZE: usize = 128;
/// Bytes of the header.
const HEADER: usize = 16;

/// Decodes the Blosc buffer `src` into exactly `expected` bytes.
pub fn decompress(src: &[u8], expected: usize) -> Result<Vec<u8>, String> {
    if src.len() < HEADER {
        return Err(format!(
            "a Blosc buffer of {} bytes is shorter than its header",
            src.len()
        ));
    }
    let word = |at: usize| u32::from_le_bytes([src[at], src[at + 1], src[at + 2], src[at + 3]]);
    let (version, flags, typesize) = (src[0], src[2], usize::from(src[3]));
    let (nbytes, blocksize, cbytes) = (word(4) as usize, word(8) as usize, word(12) as usize);
    if version != 2 && version != 1 {
        return Err(format!(
            "Blosc format version {version} (this reads 1 and 2)"
        ));
    }
    if cbytes != src.len() {
        return Err(format!(
            "the Blosc header says {cbytes} compressed bytes; the buffer holds {}",
            src.len()
        ));
    }
    if nbytes != expected {
        return Err(format!(
            "the Blosc buffer holds {nbytes} bytes; {expected} were expected"
        ));
    }
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    if flags & MEMCPYED != 0 {
        if nbytes + HEADER != cbytes {
            return Err("a stored Blosc buffer's sizes disagree".into());
        }
        return Ok(src[HEADER..].to_vec());
    }
    if flags & DOBITSHUFFLE != 0 {
        return Err("the Blosc buffer is bit-shuffled, which mesobake does not read".into());
    }
    if blocksize == 0 || typesize == 0 || blocksize > nbytes {
        return Err(format!(
            "Blosc block size {blocksize}, type size {typesize} for {nbytes} bytes"
        ));
    }
    let codec = match flags >> 5 {
        1 => Codec::Lz4,
        3 => Codec::Zlib,
        other => {
            let name = ["BloscLZ", "LZ4", "Snappy", "zlib", "Zstd"]
                .get(usize::from(other))
                .unwrap_or(&"an unknown codec");
            return Err(format!(
                "the Blosc buffer is compressed with {name}; mesobake reads LZ4 (OpenVDB's \
                 default) and zlib"
            ));
        }
    };
    let nblocks = nbytes.div_ceil(blocksize);
    if nblocks > (cbytes - HEADER) / 4 {
        return Err("the Blosc buffer is too short for its block starts".into());
    }
    let mut out = vec![0u8; nbytes];
    let mut block = vec![0u8; blocksize];
    for (b, dest) in out.chunks_mut(blocksize).enumerate() {
        let leftover = dest.len() < blocksize;
        let size = dest.len();
        let split = flags & DONT_SPLIT == 0
            && typesize <= MAX_SPLITS
            && blocksize / typesize >= MIN_BUFFERSIZE
            && !leftover;
        let nsplits = if split { typesize } else { 1 };
        if size % nsplits != 0 {
            return Err(format!(
                "a Blosc block of {size} bytes is not {nsplits} whole streams"
            ));
        }
        let stream = size / nsplits;
        let mut at = word(HEADER + 4 * b) as usize;
        let streams = &mut block[..size];
        for part in streams.chunks_exact_mut(stream) {
            let length = src
                .get(at..at + 4)
                .map(|w| i32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .ok_or("a Blosc stream starts past the buffer's end")?;
            at += 4;
            let data = usize::try_from(length)
                .ok()
                .and_then(|n| src.get(at..at + n))
                .ok_or("a Blosc stream runs past the buffer's end")?;
            at += data.len();
            if data.len() == stream {
                part.copy_from_slice(data);
            } else {
                codec.decompress(data, part)?;
            }
        }
        let do_shuffle = flags & DOSHUFFLE != 0 && typesize > 1;
        if do_shuffle {
            unshuffle(typesize, streams, dest);
        } else {
            dest.copy_from_slice(streams);
        }
    }
    Ok(out)
}

/// The codec of a Blosc buffer's streams.
#[derive(Clone, Copy)]
enum Codec {
    Lz4,
    Zlib,
}

impl Codec {
    /// Decodes `data` into exactly `part.len()` bytes.
    fn decompress(self, data: &[u8], part: &mut [u8]) -> Result<(), String> {
        let bad = |why: String| format!("a Blosc stream does not decode: {why}");
        let written = match self {
            Codec::Lz4 => {
                lz4_flex::block::decompress_into(data, part).map_err(|e| bad(e.to_string()))?
            }
            Codec::Zlib => {
                let mut decoder = flate2::read::ZlibDecoder::new(data);
                let mut n = 0;
                while n < part.len() {
                    match decoder
                        .read(&mut part[n..])
                        .map_err(|e| bad(e.to_string()))?
                    {
                        0 => break,
                        k => n += k,
                    }
                }
                n
            }
        };
        if written != part.len() {
            return Err(bad(format!("{written} bytes, {} expected", part.len())));
        }
        Ok(())
    }
}

/// Undoes Blosc's byte shuffle of one block: element i's byte j is at `j·n + i` of
/// `shuffled` (n elements); the bytes past the last whole element are as they were.
fn unshuffle(typesize: usize, shuffled: &[u8], dest: &mut [u8]) {
    let n = shuffled.len() / typesize;
    for i in 0..n {
        for j in 0..typesize {
            dest[i * typesize + j] = shuffled[j * n + i];
        }
    }
    let whole = n * typesize;
    dest[whole..].copy_from_slice(&shuffled[whole..]);
}
