//! # exo-test-support
//!
//! What any exo crate's tests may share (a dev-dependency from any layer;
//! ARCHITECTURE.md, "Layers"), with no dependency of its own so that a
//! pure-math crate's tests do not pull in IPC.
//!
//! [`ScratchDir`] is a test's own directory under the system's temporary
//! directory, removed when the test passes and kept (its path printed) when
//! it fails.
//!
//! [`CountingAllocator`] proves a path allocation-free: a test binary
//! installs it as its global allocator and measures a closure with
//! [`allocations_on_this_thread`] (only the test's own thread is counted,
//! in a counter of that thread's own: the harness's threads allocate at
//! times of their own, a CI run once counted four of theirs, and the other
//! tests of the same binary run in parallel threads) or
//! [`allocations_anywhere`] (every thread, for a library that may allocate
//! off the calling thread: meaningful only in a process where nothing else
//! runs, which [`in_a_process_of_its_own`] gives a test).
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
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Allocations on any thread while at least one `allocations_anywhere`
/// measurement is running.
static EVERYWHERE: AtomicUsize = AtomicUsize::new(0);
/// How many `allocations_anywhere` measurements are running.
static EVERY_THREAD: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    /// Whether this thread's allocations are being counted.
    static ARMED: Cell<bool> = const { Cell::new(false) };
    /// This thread's allocations while armed (no other thread touches it).
    static HERE: Cell<usize> = const { Cell::new(0) };
}

/// The system allocator, counting the allocations made while armed.
pub struct CountingAllocator;

// SAFETY: every call is forwarded unchanged to the system allocator; the
// counting touches only atomics and const-initialised thread-locals without
// destructors (`try_with`, so a thread being torn down is not counted and
// never panics).
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.try_with(Cell::get).unwrap_or(false) {
            let _ = HERE.try_with(|n| n.set(n.get() + 1));
        }
        if EVERY_THREAD.load(Ordering::SeqCst) > 0 {
            EVERYWHERE.fetch_add(1, Ordering::SeqCst);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// `f`'s result and the heap allocations made on this thread while it ran
/// (0 unless the test binary installed [`CountingAllocator`]). Other
/// threads, measuring or not, never change it.
pub fn allocations_on_this_thread<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let count = ThreadCount::start();
    let r = f();
    (r, count.stop())
}

/// `f`'s result and the heap allocations made on any thread of the process
/// while it ran. Other tests of the same binary run in parallel threads and
/// would be counted too: call it from a test that runs
/// [`in_a_process_of_its_own`].
pub fn allocations_anywhere<R>(f: impl FnOnce() -> R) -> (R, usize) {
    EVERY_THREAD.fetch_add(1, Ordering::SeqCst);
    let before = EVERYWHERE.load(Ordering::SeqCst);
    let r = f();
    let n = EVERYWHERE.load(Ordering::SeqCst) - before;
    EVERY_THREAD.fetch_sub(1, Ordering::SeqCst);
    (r, n)
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
        let before = HERE.with(Cell::get);
        ARMED.with(|a| a.set(true));
        ThreadCount { before }
    }

    /// Disarms it; the allocations made on this thread since `start`.
    pub fn stop(self) -> usize {
        ARMED.with(|a| a.set(false));
        HERE.with(Cell::get) - self.before
    }
}

/// The variable that marks the process [`in_a_process_of_its_own`] starts.
const ALONE: &str = "EXO_TEST_SUPPORT_ALONE";

/// For a test that must be the only one in its process (e.g. it counts
/// [`allocations_anywhere`]), while the test binary holds other tests that
/// the harness runs in parallel threads. `test` is the test's path as
/// `concat!(module_path!(), "::", "name_of_the_test")` gives it.
///
/// In the test binary's own process: runs this binary again with only that
/// test (`--exact`, one test thread), asserts that it ran and passed
/// (its stderr is passed on), and returns `false`: the caller returns. In
/// that second process: returns `true`, and the caller measures.
pub fn in_a_process_of_its_own(test: &str) -> bool {
    // The harness names a test without its crate, the first segment.
    let name = test.split_once("::").map_or(test, |(_, rest)| rest);
    if std::env::var_os(ALONE).is_some_and(|v| v == name) {
        return true;
    }
    let exe = std::env::current_exe().expect("the test binary's path");
    let out = Command::new(&exe)
        .args(["--exact", name, "--test-threads=1", "--nocapture"])
        .env(ALONE, name)
        .output()
        .unwrap_or_else(|e| panic!("running {} again: {e}", exe.display()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprint!("{stderr}");
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "{name} in a process of its own ({}):\n{stdout}\n{stderr}",
        out.status
    );
    false
}

/// A test's own directory under the system's temporary directory,
/// `exo-{tag}-{pid}`: created empty, and removed when the test passes. A
/// failing (panicking) test leaves it in place and prints where it is, for
/// inspection. Without the removal, every test run left its recordings behind
/// (about 1 GB per `cargo test --workspace`).
pub struct ScratchDir(PathBuf);

impl ScratchDir {
    /// Creates `exo-{tag}-{pid}` afresh (anything already there is removed).
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("exo-{tag}-{}", std::process::id()));
        Self::at(dir)
    }

    /// Creates `dir` afresh, to be removed in the same way.
    pub fn at(dir: PathBuf) -> Self {
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)
            .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
        ScratchDir(dir)
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl std::ops::Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("test failed: its files are kept in {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}
