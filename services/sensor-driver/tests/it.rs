//! The integration tests of exo-sensor-driver in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-sensor-driver --test it alloc::`.

/// Counts the per-frame work's allocations (`alloc`) and the EtherCAT
/// cycle's (`ethercat`), per thread: the binary's other tests run in
/// parallel threads.
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

#[path = "it/alloc.rs"]
mod alloc;
#[path = "it/ethercat.rs"]
mod ethercat;
#[path = "it/ethercat_faults.rs"]
mod ethercat_faults;
#[path = "it/ethercat_refusal.rs"]
mod ethercat_refusal;
