//! What each setting costs and buys, measured against exact references: `mesobake report
//! accuracy` ([`accuracy`]: GDM compression), `report codecs` ([`codecs`]: every GDM codec
//! and size on scenes, samples and images), `report render` ([`render`]: the GDM renderer
//! against the truth, and its error budget), `report quality` ([`quality`]: the per-pixel
//! algorithm's accuracy knobs against the truth, and their time), `report gi` ([`gi`]:
//! radiance transfer), `report vdm` ([`vdm`]: the VDM's knobs, and the GDM beside it) and
//! `report transparency` ([`transparency`]: the translucent media's real-time algorithm
//! against their truth) and `report conformance` ([`conformance`]: every scene, technique
//! and preset against the supersampled truth, CPU and WGSL).

pub mod accuracy;
pub mod codecs;
pub mod conformance;
pub mod gi;
pub mod plot;
pub mod quality;
pub mod render;
pub mod transparency;
pub mod vdm;

use mesobake_core::error::{Error, Result};
use mesobake_core::observer::BakeObserver;

/// A report's progress: counts its finished steps out of a total for an observer, and stops
/// the report at a cancellation.
pub struct Steps<'o> {
    observer: &'o dyn BakeObserver,
    done: u64,
    total: u64,
}

impl<'o> Steps<'o> {
    /// Progress over `total` steps, told to `observer`.
    pub fn new(observer: &'o dyn BakeObserver, total: u64) -> Steps<'o> {
        Steps {
            observer,
            done: 0,
            total,
        }
    }

    /// One more step done; an error if a cancellation was asked for.
    pub fn step(&mut self) -> Result<()> {
        if self.observer.cancelled() {
            return Err(Error::Cancelled);
        }
        self.done += 1;
        self.observer.progress(self.done, self.total);
        Ok(())
    }
}
