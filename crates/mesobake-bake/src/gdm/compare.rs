//! Error of an approximate GDM against a reference on the same grids.

use super::Gdm;
use mesobake_core::error::{Error, Result};

/// How far an approximate GDM is from a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GdmError {
    /// Samples compared (all samples, inside ones included).
    pub samples: u64,
    /// Samples where both GDMs report a hit (the distances compared below).
    pub both_hit: u64,
    /// Mean |d − d_ref| over samples where both hit, in voxels.
    pub mean_abs_error: f64,
    /// Largest |d − d_ref| over samples where both hit, in voxels.
    pub max_abs_error: f64,
    /// Fraction of all samples whose hit/escape/inside classification differs.
    pub classification_mismatch: f64,
}

/// Compares `approx` against `reference` (same grids; any escape conventions).
pub fn compare(approx: &Gdm, reference: &Gdm) -> Result<GdmError> {
    if approx.dims() != reference.dims() || approx.dirs() != reference.dirs() {
        return Err(Error::InvalidParameter(format!(
            "cannot compare a {} GDM with {} directions against a {} one with {}",
            approx.dims(),
            approx.dirs(),
            reference.dims(),
            reference.dirs()
        )));
    }
    let mut a = approx.clone();
    let mut r = reference.clone();
    a.set_escape_convention(super::EscapeConvention::Infinite);
    r.set_escape_convention(super::EscapeConvention::Infinite);
    let mut out = GdmError::default();
    let mut sum = 0.0f64;
    let mut mismatched = 0u64;
    for (&x, &y) in a.data().iter().zip(r.data()) {
        out.samples += 1;
        let class = |v: f32| {
            if v == 0.0 {
                0
            } else if v.is_infinite() {
                2
            } else {
                1
            }
        };
        if class(x) != class(y) {
            mismatched += 1;
        } else if class(x) == 1 {
            let e = (x as f64 - y as f64).abs();
            out.both_hit += 1;
            sum += e;
            out.max_abs_error = out.max_abs_error.max(e);
        }
    }
    out.mean_abs_error = if out.both_hit > 0 {
        sum / out.both_hit as f64
    } else {
        0.0
    };
    out.classification_mismatch = mismatched as f64 / out.samples.max(1) as f64;
    Ok(out)
}
