//! Lossless supercompression of a section (`docs/package-format.md`, "Supercompression"):
//! the texels' bytes are split into byte planes, each plane's images are predicted by PNG's
//! Paeth predictor, and the residuals are deflated into one zlib stream (RFC 1950). The byte
//! planes put like bytes of neighbouring texels side by side (the high bytes of f16 weights
//! vary slowly, the low bytes do not), and the predictor turns smooth images into runs of
//! small residuals that deflate compresses well.

use crate::texture::Texture;

/// How a section's stored bytes encode its texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Supercompression {
    /// Byte planes, Paeth prediction per image, zlib at deflate level 9.
    PaethZlib,
}

/// Deflate's level for [`Supercompression::PaethZlib`] (9, zlib's best).
const LEVEL: u8 = 9;

/// PNG's Paeth predictor of a byte from its left (`a`), upper (`b`) and upper-left (`c`)
/// neighbours.
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let p = i16::from(a) + i16::from(b) - i16::from(c);
    let (pa, pb, pc) = (
        (p - i16::from(a)).abs(),
        (p - i16::from(b)).abs(),
        (p - i16::from(c)).abs(),
    );
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// Visits every byte of `texture` in stored order — byte plane, then image, row, texel — with
/// its index in the texel-interleaved layout and the indices of its left, upper and upper-left
/// neighbours in the same plane and image (`None` outside the image).
fn for_each_byte(texture: &Texture, mut visit: impl FnMut(usize, [Option<usize>; 3])) {
    let t = texture.format.texel_bytes() as usize;
    let (w, h, d) = (
        texture.width as usize,
        texture.height as usize,
        texture.depth as usize,
    );
    for plane in 0..t {
        for z in 0..d {
            for y in 0..h {
                for x in 0..w {
                    let at = |x: usize, y: usize| ((z * h + y) * w + x) * t + plane;
                    let left = (x > 0).then(|| at(x - 1, y));
                    let up = (y > 0).then(|| at(x, y - 1));
                    let up_left = (x > 0 && y > 0).then(|| at(x - 1, y - 1));
                    visit(at(x, y), [left, up, up_left]);
                }
            }
        }
    }
}

/// The prediction of a byte from its neighbours' values (0 outside the image).
fn predict(texels: &[u8], neighbours: [Option<usize>; 3]) -> u8 {
    let [a, b, c] = neighbours.map(|n| n.map_or(0, |i| texels[i]));
    paeth(a, b, c)
}

impl Supercompression {
    /// The stored bytes of `texels`, the tightly packed bytes of `texture`.
    pub fn compress(self, texture: &Texture, texels: &[u8]) -> Vec<u8> {
        let mut residuals = Vec::with_capacity(texels.len());
        for_each_byte(texture, |i, neighbours| {
            residuals.push(texels[i].wrapping_sub(predict(texels, neighbours)));
        });
        miniz_oxide::deflate::compress_to_vec_zlib(&residuals, LEVEL)
    }

    /// The texels of `texture` from its stored bytes; an error naming the problem when the
    /// stream is not valid zlib or does not inflate to exactly the texture's size (inflating
    /// stops at that size, so a hostile stream cannot exhaust memory).
    pub fn decompress(self, texture: &Texture, stored: &[u8]) -> Result<Vec<u8>, String> {
        let len = texture
            .byte_len()
            .and_then(|n| usize::try_from(n).ok())
            .ok_or("its texture is too large for this machine")?;
        let residuals = miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(stored, len)
            .map_err(|e| match e.status {
                miniz_oxide::inflate::TINFLStatus::HasMoreOutput => {
                    format!("its stream inflates to more than its texture's {len} bytes")
                }
                status => format!("its stream is not valid zlib ({status:?})"),
            })?;
        if residuals.len() != len {
            return Err(format!(
                "its stream inflates to {} bytes, not its texture's {len}",
                residuals.len()
            ));
        }
        let mut texels = vec![0u8; len];
        let mut residual = residuals.iter();
        for_each_byte(texture, |i, neighbours| {
            let r = *residual.next().expect("one residual per byte");
            texels[i] = r.wrapping_add(predict(&texels, neighbours));
        });
        Ok(texels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{TexelFormat, TextureDimension};

    fn texture(format: TexelFormat, width: u32, height: u32, depth: u32) -> Texture {
        Texture {
            dimension: if depth > 1 {
                TextureDimension::D3
            } else {
                TextureDimension::D2
            },
            format,
            width,
            height,
            depth,
        }
    }

    /// PNG's specification (ISO 15948, 9.4) spelled out: the nearest of a, b, c to a + b − c,
    /// ties in the order a, b, c.
    #[test]
    fn paeth_is_pngs_predictor() {
        for (a, b, c, expected) in [
            (10, 20, 10, 20), // p = 20: b exact
            (20, 10, 10, 20), // p = 20: a exact
            (10, 20, 30, 10), // p = 0: a nearest
            (100, 100, 100, 100),
            (0, 255, 0, 255),    // p = 255: b
            (255, 0, 255, 0),    // p = 0: b
            (10, 40, 30, 10),    // p = 20: a and c tie at 10, a first
            (200, 10, 100, 100), // p = 110: c at 10 nearest
        ] {
            assert_eq!(paeth(a, b, c), expected, "paeth({a}, {b}, {c})");
        }
    }

    /// The stored stream is standard zlib: an independent inflater (zune-inflate) reads it,
    /// and it holds the residuals worked out by hand for a 2×2 two-byte texture.
    #[test]
    fn the_stream_is_zlib_of_byte_planes_of_paeth_residuals() {
        let t = texture(TexelFormat::R16float, 2, 2, 1);
        // Texels (lo, hi): (1, 9), (4, 9) / (2, 8), (7, 8).
        let texels = [1, 9, 4, 9, 2, 8, 7, 8];
        let stored = Supercompression::PaethZlib.compress(&t, &texels);
        let residuals = zune_inflate::DeflateDecoder::new(&stored)
            .decode_zlib()
            .unwrap();
        // Low plane 1 4 / 2 7: 1−0, 4−1 (left), 2−1 (up), 7−paeth(2, 4, 1) = 7−4 (p = 5, b).
        // High plane 9 9 / 8 8: 9, 0, 8−9, 8−paeth(8, 9, 9) = 8−8 (p = 8, a).
        assert_eq!(residuals, [1, 3, 1, 3, 9, 0, 255, 0]);
    }

    #[test]
    fn every_texture_shape_and_format_round_trips() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for (format, w, h, d) in [
            (TexelFormat::R8unorm, 1, 1, 1),
            (TexelFormat::Rgba8unorm, 17, 5, 3),
            (TexelFormat::Rgba16float, 8, 8, 4),
            (TexelFormat::R32float, 33, 1, 1),
            (TexelFormat::Rg32float, 3, 7, 2),
        ] {
            let t = texture(format, w, h, d);
            let n = t.byte_len().unwrap() as usize;
            // Smooth data (what compresses) and noise (what does not) both round-trip.
            let smooth: Vec<u8> = (0..n).map(|i| (i / 7) as u8).collect();
            let noise: Vec<u8> = (0..n).map(|_| next() as u8).collect();
            for texels in [smooth, noise] {
                let stored = Supercompression::PaethZlib.compress(&t, &texels);
                let back = Supercompression::PaethZlib.decompress(&t, &stored);
                assert_eq!(back.as_deref(), Ok(&texels[..]), "{format:?} {w}×{h}×{d}");
            }
        }
    }

    #[test]
    fn streams_of_the_wrong_size_or_not_zlib_are_refused_by_name() {
        let small = texture(TexelFormat::Rgba8unorm, 4, 4, 1);
        let large = texture(TexelFormat::Rgba8unorm, 4, 8, 1);
        let stored = Supercompression::PaethZlib.compress(&large, &[7; 128]);
        let e = Supercompression::PaethZlib
            .decompress(&small, &stored)
            .unwrap_err();
        assert!(e.contains("more than its texture's 64 bytes"), "{e}");
        let short = Supercompression::PaethZlib.compress(&small, &[7; 64]);
        let e = Supercompression::PaethZlib
            .decompress(&large, &short)
            .unwrap_err();
        assert!(
            e.contains("inflates to 64 bytes, not its texture's 128"),
            "{e}"
        );
        let e = Supercompression::PaethZlib
            .decompress(&small, b"not zlib")
            .unwrap_err();
        assert!(e.contains("not valid zlib"), "{e}");
    }
}
