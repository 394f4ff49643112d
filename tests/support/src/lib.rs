//! # exo-test-support
//!
//! What any exo crate's tests may share (a dev-dependency from any layer;
//! ARCHITECTURE.md, "Layers"), with no dependency of its own so that a
//! pure-math crate's tests do not pull in IPC.
//!
//! [`CountingAllocator`] proves a path allocation-free: a test binary
//! installs it as its global allocator and measures a closure with
//! [`allocations_on_this_thread`] (only the test's own thread is counted:
//! the harness's threads allocate at times of their own, and a CI run once
//! counted four of theirs) or [`allocations_anywhere`] (every thread, for a
//! library that may allocate off the calling thread).
//!
//! ```ignore
//! #[global_allocator]
//! static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;
//!
//! let (_, n) = exo_test_support::allocations_on_this_thread(|| tick());
//! assert_eq!(n, 0);
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
static EVERY_THREAD: AtomicBool = AtomicBool::new(false);
thread_local! {
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

/// The system allocator, counting the allocations made while armed.
pub struct CountingAllocator;

// SAFETY: every call is forwarded unchanged to the system allocator; the
// counting touches only an atomic and a thread-local flag (`try_with`, so a
// thread being torn down is not counted and never panics).
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if EVERY_THREAD.load(Ordering::Relaxed) || ARMED.try_with(Cell::get).unwrap_or(false) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// `f`'s result and the heap allocations made on this thread while it ran
/// (0 unless the test binary installed [`CountingAllocator`]).
pub fn allocations_on_this_thread<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    ARMED.with(|a| a.set(true));
    let r = f();
    ARMED.with(|a| a.set(false));
    (r, ALLOCATIONS.load(Ordering::SeqCst) - before)
}

/// `f`'s result and the heap allocations made on any thread while it ran.
pub fn allocations_anywhere<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    EVERY_THREAD.store(true, Ordering::SeqCst);
    let r = f();
    EVERY_THREAD.store(false, Ordering::SeqCst);
    (r, ALLOCATIONS.load(Ordering::SeqCst) - before)
}

/// The allocations on this thread between [`ThreadCount::start`] and
/// [`ThreadCount::stop`], for a measured stretch that is not one closure.
#[must_use = "stop it to read the count"]
pub struct ThreadCount {
    before: usize,
}

impl ThreadCount {
    /// Arms this thread's count.
    pub fn start() -> Self {
        let before = ALLOCATIONS.load(Ordering::SeqCst);
        ARMED.with(|a| a.set(true));
        ThreadCount { before }
    }

    /// Disarms it; the allocations made on this thread since `start`.
    pub fn stop(self) -> usize {
        ARMED.with(|a| a.set(false));
        ALLOCATIONS.load(Ordering::SeqCst) - self.before
    }
}
