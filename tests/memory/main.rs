//! The memory the bakes and the package readers allocate, measured by a counting global
//! allocator: a bake's peak heap stays within the bound its plan checks against the memory
//! limit, and reading a mutated package never takes more than the limit. A binary of its
//! own, its tests one at a time, so that nothing else allocates while a peak is measured.

#[path = "../common/mod.rs"]
mod common;
#[path = "../common/package_edit.rs"]
mod package_edit;
#[path = "../../crates/mesobake-package/tests/support/mod.rs"]
mod package_support;

mod bakes;
mod package_mutants;

use mesobake_scene::bench::counting_alloc::CountingAlloc;
use std::sync::{Mutex, MutexGuard};

#[global_allocator]
static ALLOCATOR: CountingAlloc = CountingAlloc::new();

/// Held by each test while it measures: the allocator counting, no other test running.
fn measuring() -> MutexGuard<'static, ()> {
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    let guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    ALLOCATOR.start_counting();
    guard
}
