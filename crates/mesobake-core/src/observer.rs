//! Progress and cancellation of long work: bakes and their pipelines.

/// Observes a bake: progress for progress bars and event streams, and cancellation.
pub trait BakeObserver: Sync {
    /// `done` of `total` work units are finished. Called from worker threads.
    fn progress(&self, _done: u64, _total: u64) {}
    /// Whether the bake should stop (it then returns [`crate::error::Error::Cancelled`]).
    fn cancelled(&self) -> bool {
        false
    }
    /// A pipeline of several bakes begins its stage `name`; [`BakeObserver::progress`] then
    /// counts that stage's work.
    fn stage(&self, _name: &str) {}
}

/// The observer that ignores everything.
impl BakeObserver for () {}

/// Another observer's cancellation alone: for work inside a stage whose progress that
/// observer counts in other units (a preview's frames, not the tiles of each).
pub struct CancellationOf<'a>(pub &'a dyn BakeObserver);

impl BakeObserver for CancellationOf<'_> {
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}

/// A flag as an observer: cancelled once it is set.
impl BakeObserver for std::sync::atomic::AtomicBool {
    fn cancelled(&self) -> bool {
        self.load(std::sync::atomic::Ordering::Relaxed)
    }
}
