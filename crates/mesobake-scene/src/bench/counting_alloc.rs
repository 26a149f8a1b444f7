//! A global allocator that counts live heap bytes and their peak, for the benchmarks' memory
//! figures. Every call goes straight to the system allocator, zeroed allocations and
//! reallocations included: a large zeroed buffer keeps calloc's lazily zeroed pages instead
//! of being cleared up front, and a growing vector may still grow in place.
//!
//! It counts only once [`CountingAlloc::start_counting`] was called (the `bench` commands):
//! two threads updating one counter on every allocation made the ground truth's renders
//! spend three quarters of their time in these atomics (perf, torus-fur at 128², 16 samples
//! per pixel). Bytes allocated before counting started and freed after it leave the count
//! that much below the live bytes; the benchmarks measure growth, which that does not move.

use crate::bench::bakes::MemoryProbe;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering::Relaxed};

/// The system allocator, counting once asked to.
#[derive(Debug, Default)]
pub struct CountingAlloc {
    counting: AtomicBool,
    current: AtomicIsize,
    peak: AtomicIsize,
}

impl CountingAlloc {
    /// A counter at zero, not counting yet (for a `static`).
    pub const fn new() -> Self {
        CountingAlloc {
            counting: AtomicBool::new(false),
            current: AtomicIsize::new(0),
            peak: AtomicIsize::new(0),
        }
    }

    /// Counts every allocation from now on.
    pub fn start_counting(&self) {
        self.counting.store(true, Relaxed);
    }

    fn grew(&self, bytes: usize) {
        if self.counting.load(Relaxed) {
            let bytes = bytes as isize;
            let now = self.current.fetch_add(bytes, Relaxed) + bytes;
            self.peak.fetch_max(now, Relaxed);
        }
    }

    fn shrank(&self, bytes: usize) {
        if self.counting.load(Relaxed) {
            self.current.fetch_sub(bytes as isize, Relaxed);
        }
    }
}

impl MemoryProbe for CountingAlloc {
    fn reset_peak(&self) {
        self.peak.store(self.current.load(Relaxed), Relaxed);
    }
    fn peak_bytes(&self) -> u64 {
        self.peak.load(Relaxed).max(0) as u64
    }
    fn current_bytes(&self) -> u64 {
        self.current.load(Relaxed).max(0) as u64
    }
}

// SAFETY: every method forwards to `System` with the caller's arguments and only adds
// counting; the counters never affect what is returned.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded from the caller.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            self.grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded from the caller.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            self.grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded from the caller.
        unsafe { System.dealloc(ptr, layout) };
        self.shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: forwarded from the caller.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                self.grew(new_size - layout.size());
            } else {
                self.shrank(layout.size() - new_size);
            }
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts follow allocations, zeroed ones and reallocations both ways, and the peak
    /// resets to the live count.
    #[test]
    fn counts_live_bytes_and_peak() {
        let a = CountingAlloc::new();
        let layout = Layout::from_size_align(4096, 8).unwrap();
        // SAFETY: freed at once with its own layout.
        unsafe { a.dealloc(a.alloc(layout), layout) };
        assert_eq!(a.peak_bytes(), 0, "nothing counted before counting starts");
        a.start_counting();
        // SAFETY: each pointer is freed once with the layout it has at that moment.
        unsafe {
            let p = a.alloc_zeroed(layout);
            assert!(!p.is_null() && *p == 0 && *p.add(4095) == 0);
            assert_eq!(a.current_bytes(), 4096);
            let p = a.realloc(p, layout, 10_000);
            assert_eq!((a.current_bytes(), a.peak_bytes()), (10_000, 10_000));
            let p = a.realloc(p, Layout::from_size_align(10_000, 8).unwrap(), 100);
            assert_eq!((a.current_bytes(), a.peak_bytes()), (100, 10_000));
            a.reset_peak();
            assert_eq!(a.peak_bytes(), 100);
            let q = a.alloc(layout);
            assert_eq!(a.peak_bytes(), 4196);
            a.dealloc(q, layout);
            a.dealloc(p, Layout::from_size_align(100, 8).unwrap());
        }
        assert_eq!((a.current_bytes(), a.peak_bytes()), (0, 4196));
    }
}
