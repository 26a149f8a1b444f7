//! Resource limits, checked before any allocation whose size comes from input.

use crate::error::{Error, Result};

/// Default memory limit for a bake's peak and for any allocation decided by input: 4 GiB.
pub const DEFAULT_MEMORY_LIMIT: u64 = 4 << 30;

/// Default limit on the pixels of an input image: 2²⁸ (16384 × 16384).
pub const DEFAULT_IMAGE_PIXELS: u64 = 1 << 28;

/// Largest accepted image side in pixels.
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// Limits that protect the process from input that asks for absurd sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Most bytes a single input-sized buffer, or a bake's whole peak, may take.
    pub memory_bytes: u64,
    /// Most pixels an input image (PNG height field, EXR environment) may have, checked
    /// from its header before it is decoded.
    pub image_pixels: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            memory_bytes: DEFAULT_MEMORY_LIMIT,
            image_pixels: DEFAULT_IMAGE_PIXELS,
        }
    }
}

impl Limits {
    /// Limits from the `MESOBAKE_MEMORY_LIMIT` environment variable (see [`parse_bytes`]),
    /// or the defaults when it is unset.
    pub fn from_env() -> Result<Self> {
        match std::env::var("MESOBAKE_MEMORY_LIMIT") {
            Ok(text) => Ok(Limits {
                memory_bytes: parse_bytes(&text)?,
                ..Limits::default()
            }),
            Err(_) => Ok(Limits::default()),
        }
    }

    /// Refuses `count` elements of `elem_bytes` each when their total (computed without
    /// overflow) exceeds the limit. Returns the total in bytes.
    pub fn check(&self, what: &str, count: u64, elem_bytes: u64) -> Result<u64> {
        let needed = count.saturating_mul(elem_bytes);
        if needed > self.memory_bytes {
            return Err(Error::MemoryLimit {
                what: what.to_string(),
                needed,
                limit: self.memory_bytes,
            });
        }
        Ok(needed)
    }

    /// Refuses a `width` × `height` image of `what` with more than [`Limits::image_pixels`]
    /// pixels: called with the header's size, before anything is decoded.
    pub fn check_image(&self, what: &str, width: u64, height: u64) -> Result<()> {
        let pixels = width.saturating_mul(height);
        if pixels > self.image_pixels {
            return Err(Error::InvalidParameter(format!(
                "{what} is {width}×{height} = {pixels} pixels, over the limit of {} pixels",
                self.image_pixels
            )));
        }
        Ok(())
    }
}

/// Parses a byte count such as `4096`, `512MiB`, `4GiB`, `2G` (binary units throughout).
pub fn parse_bytes(text: &str) -> Result<u64> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (digits, unit) = t.split_at(split);
    let value: u64 = digits
        .parse()
        .map_err(|_| Error::InvalidParameter(format!("byte count {text:?} is not a number")))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kib" | "kb" => 10,
        "m" | "mib" | "mb" => 20,
        "g" | "gib" | "gb" => 30,
        "t" | "tib" | "tb" => 40,
        other => {
            return Err(Error::InvalidParameter(format!(
                "byte count {text:?} has unknown unit {other:?}"
            )));
        }
    };
    value
        .checked_mul(1u64 << shift)
        .ok_or_else(|| Error::InvalidParameter(format!("byte count {text:?} overflows")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units() {
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        assert_eq!(parse_bytes("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("2G").unwrap(), 2 << 30);
        assert!(parse_bytes("12 parsecs").is_err());
        assert!(parse_bytes("99999999999999T").is_err());
    }

    #[test]
    fn refuses_overflowing_sizes() {
        let limits = Limits {
            memory_bytes: 1000,
            ..Limits::default()
        };
        assert_eq!(limits.check("x", 250, 4).unwrap(), 1000);
        assert!(limits.check("x", 251, 4).is_err());
        assert!(limits.check("x", u64::MAX, 4).is_err());
    }

    #[test]
    fn refuses_images_over_the_pixel_limit() {
        let limits = Limits {
            image_pixels: 100,
            ..Limits::default()
        };
        assert!(limits.check_image("a PNG", 10, 10).is_ok());
        let e = limits.check_image("a PNG", 16000, 16000).unwrap_err();
        assert!(e.to_string().contains("16000×16000"), "{e}");
        assert!(limits.check_image("a PNG", u64::MAX, 2).is_err());
    }
}
