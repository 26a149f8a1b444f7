//! Quantization of SVD factors (weight maps and eigenmaps) to the texel formats a GPU samples.
//!
//! A factor is an m × k row-major matrix whose column i is one map (component i). Float
//! formats store values as they are (rounded to f16 for [`Quantization::F16`]); the 8-bit
//! format stores per map a `scale` and `bias` and codes q ∈ 0..=255 that decode as
//! `bias + scale · q / 255`, which is exactly what a GPU's `rgba8unorm` sampler returns
//! (q / 255) followed by one fused multiply–add.

pub use crate::texture::Quantization;
use crate::texture::{CHANNELS, TexelFormat, Texture};
use half::f16;
use std::ops::Range;

/// A quantized m × k factor: the stored codes and what decodes them.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantizedFactor {
    /// Rows m.
    pub rows: usize,
    /// Maps (columns) k.
    pub rank: usize,
    /// The number format.
    pub format: Quantization,
    /// Per map: decoded value = bias + scale · code (code = q / 255 for 8-bit; for floats
    /// scale is 1 and bias 0).
    pub scale: Vec<f32>,
    /// Per map: see `scale`.
    pub bias: Vec<f32>,
    /// Codes, m × k row-major, `format.bytes()` little-endian bytes each.
    pub codes: Vec<u8>,
}

impl QuantizedFactor {
    /// Quantizes the m × `rank` row-major `values` (finite) to `format`.
    pub fn new(values: &[f32], rank: usize, format: Quantization) -> Self {
        let rows = values.len().checked_div(rank).unwrap_or(0);
        let (mut scale, mut bias) = (vec![1.0f32; rank], vec![0.0f32; rank]);
        if format == Quantization::U8 {
            for c in 0..rank {
                let column = values.iter().skip(c).step_by(rank);
                let (lo, hi) = column.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                });
                (bias[c], scale[c]) = if lo <= hi { (lo, hi - lo) } else { (0.0, 0.0) };
            }
        }
        let mut codes = Vec::with_capacity(values.len() * format.bytes());
        for (x, &v) in values.iter().enumerate() {
            let c = x % rank;
            match format {
                Quantization::F32 => codes.extend_from_slice(&v.to_le_bytes()),
                Quantization::F16 => codes.extend_from_slice(&f16::from_f32(v).to_le_bytes()),
                Quantization::U8 => codes.push(if scale[c] > 0.0 {
                    ((v - bias[c]) / scale[c] * 255.0).round().clamp(0.0, 255.0) as u8
                } else {
                    0
                }),
            }
        }
        QuantizedFactor {
            rows,
            rank,
            format,
            scale,
            bias,
            codes,
        }
    }

    /// The code of entry (r, c), as stored.
    pub fn code(&self, r: usize, c: usize) -> &[u8] {
        let b = self.format.bytes();
        &self.codes[(r * self.rank + c) * b..][..b]
    }

    /// The bytes of `texture` holding components 4·`group` onwards (at most four, and below
    /// `components`) of the factor's rows `rows`: texel t is row `rows.start + t`; channels
    /// past the last component are zero.
    pub fn pack_group(
        &self,
        rows: Range<usize>,
        components: usize,
        group: usize,
        texture: &Texture,
    ) -> Vec<u8> {
        let len = texture.byte_len().expect("writer textures are small") as usize;
        let mut bytes = vec![0u8; len];
        let (elem, texel) = (self.format.bytes(), texture.format.texel_bytes() as usize);
        for (t, r) in rows.enumerate() {
            for ch in 0..CHANNELS.min(components - group * CHANNELS) {
                let code = self.code(r, group * CHANNELS + ch);
                bytes[t * texel + ch * elem..][..elem].copy_from_slice(code);
            }
        }
        bytes
    }

    /// The factor of `rows` rows and `scale.len()` components stored in `groups` (the bytes
    /// and texel format of each texture, in group order, as [`QuantizedFactor::pack_group`]
    /// writes them); the textures must hold `rows` texels of the right format.
    pub fn unpack(
        groups: &[(&[u8], TexelFormat)],
        rows: usize,
        format: Quantization,
        scale: Vec<f32>,
        bias: Vec<f32>,
    ) -> QuantizedFactor {
        let (rank, elem) = (scale.len(), format.bytes());
        let mut codes = vec![0u8; rows * rank * elem];
        for (group, (bytes, texel_format)) in groups.iter().enumerate() {
            let texel = texel_format.texel_bytes() as usize;
            for r in 0..rows {
                for ch in 0..CHANNELS.min(rank - group * CHANNELS) {
                    let c = group * CHANNELS + ch;
                    codes[(r * rank + c) * elem..][..elem]
                        .copy_from_slice(&bytes[r * texel + ch * elem..][..elem]);
                }
            }
        }
        QuantizedFactor {
            rows,
            rank,
            format,
            scale,
            bias,
            codes,
        }
    }

    /// The decoded m × k row-major values.
    pub fn dequantize(&self) -> Vec<f32> {
        let b = self.format.bytes();
        self.codes
            .chunks_exact(b)
            .enumerate()
            .map(|(x, code)| {
                let c = x % self.rank;
                decode(self.format, code, self.scale[c], self.bias[c])
            })
            .collect()
    }
}

/// Decodes one stored value.
fn decode(format: Quantization, code: &[u8], scale: f32, bias: f32) -> f32 {
    match format {
        Quantization::F32 => f32::from_le_bytes([code[0], code[1], code[2], code[3]]),
        Quantization::F16 => f16::from_le_bytes([code[0], code[1]]).to_f32(),
        Quantization::U8 => bias + scale * (code[0] as f32 / 255.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_formats_round_to_their_precision() {
        let values = [0.0f32, 1.0, -2.5, 1234.567, 1e-3, 3.0e4];
        let f32q = QuantizedFactor::new(&values, 2, Quantization::F32);
        assert_eq!(f32q.dequantize(), values);
        let f16q = QuantizedFactor::new(&values, 2, Quantization::F16);
        for (d, v) in f16q.dequantize().iter().zip(values) {
            // binary16 has an 11-bit significand: relative error ≤ 2⁻¹¹.
            assert!((d - v).abs() <= v.abs() * 2f32.powi(-11), "{d} vs {v}");
        }
    }

    #[test]
    fn u8_codes_span_each_map_and_err_at_most_half_a_step() {
        // Two maps with different ranges, one of them constant.
        let values: Vec<f32> = (0..100)
            .flat_map(|r| [r as f32 * 0.37 - 5.0, 7.0])
            .collect();
        let q = QuantizedFactor::new(&values, 2, Quantization::U8);
        assert_eq!((q.bias[0], q.scale[0]), (-5.0, 99.0 * 0.37));
        assert_eq!((q.bias[1], q.scale[1]), (7.0, 0.0));
        assert_eq!(q.code(0, 0), [0]);
        assert_eq!(q.code(99, 0), [255]);
        let step = q.scale[0] / 255.0;
        for (d, v) in q.dequantize().iter().zip(&values) {
            assert!((d - v).abs() <= 0.5 * step + 1e-5, "{d} vs {v}");
        }
    }

    #[test]
    fn names_round_trip() {
        for q in Quantization::ALL {
            assert_eq!(q.name().parse::<Quantization>().unwrap(), q);
        }
        assert!("f8".parse::<Quantization>().is_err());
    }
}
