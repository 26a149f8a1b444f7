//! Error of an approximate VDM (the paper's bake, a reconstruction) against a reference on
//! the same texels and grid.

use super::{NO_HIT, Vdm};
use mesobake_core::error::{Error, Result};

/// How far an approximate VDM is from a reference.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct VdmError {
    /// Samples compared.
    pub samples: u64,
    /// Samples where one VDM hits and the other does not.
    pub hit_disagreements: u64,
    /// Root-mean-square difference where both hit (tile units).
    pub rmse: f64,
    /// Largest absolute difference where both hit.
    pub max_abs: f64,
    /// Per curvature: hit disagreements and RMSE.
    pub per_curvature: Vec<(f64, u64, f64)>,
}

/// Compares `approx` against `reference`, which must share their texels and grid.
pub fn compare(approx: &Vdm, reference: &Vdm) -> Result<VdmError> {
    if approx.size != reference.size || approx.grid != reference.grid {
        return Err(Error::InvalidParameter(
            "cannot compare VDMs of different texels or grids".into(),
        ));
    }
    let texels = (reference.size.0 * reference.size.1) as usize;
    let per_k = texels * (reference.grid.n_theta * reference.grid.n_phi) as usize;
    let mut total = VdmError::default();
    let (mut sum_sq, mut hit_pairs) = (0.0, 0u64);
    for (k, (p, e)) in approx
        .values
        .chunks(per_k)
        .zip(reference.values.chunks(per_k))
        .enumerate()
    {
        let (mut flips, mut sq, mut both) = (0u64, 0.0f64, 0u64);
        for (&p, &e) in p.iter().zip(e) {
            if (p == NO_HIT) != (e == NO_HIT) {
                flips += 1;
            } else if e != NO_HIT {
                let d = f64::from(p) - f64::from(e);
                sq += d * d;
                both += 1;
                total.max_abs = total.max_abs.max(d.abs());
            }
        }
        total.samples += p.len() as u64;
        total.hit_disagreements += flips;
        (sum_sq, hit_pairs) = (sum_sq + sq, hit_pairs + both);
        let rmse = (sq / both.max(1) as f64).sqrt();
        total
            .per_curvature
            .push((reference.grid.curvature(k as u32), flips, rmse));
    }
    total.rmse = (sum_sq / hit_pairs.max(1) as f64).sqrt();
    Ok(total)
}
