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
