//! NumPy `.npy` files (format version 1.0) of float32 arrays: little-endian, C order.

use crate::error::Result;
use std::io::Write;
use std::path::Path;

/// Writes `values`, a C-order float32 array of `shape`, to `path`.
pub fn write_array(path: &Path, shape: &[u64], values: &[f32]) -> Result<()> {
    debug_assert_eq!(shape.iter().product::<u64>(), values.len() as u64);
    crate::fs::write_atomic_with(path, |w| {
        w.write_all(&header(shape))?;
        for chunk in values.chunks(1 << 16) {
            let bytes: Vec<u8> = chunk.iter().flat_map(|v| v.to_le_bytes()).collect();
            w.write_all(&bytes)?;
        }
        Ok(())
    })
}

/// The `.npy` header for a little-endian float32 C-order array of `shape`.
pub fn header(shape: &[u64]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}), }}",
        dims.join(", ") + if shape.len() == 1 { "," } else { "" }
    );
    // magic (6) + version (2) + length (2) + dict + padding + '\n' is a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let padding = unpadded.next_multiple_of(64) - unpadded;
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend_from_slice(&((dict.len() + padding + 1) as u16).to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.extend(std::iter::repeat_n(b' ', padding));
    h.push(b'\n');
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_padded_to_64_bytes() {
        let h = header(&[64, 64, 32, 16, 32]);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(*h.last().unwrap(), b'\n');
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert!(text.contains("'shape': (64, 64, 32, 16, 32)"));
    }
}
