//! The integration tests of exo-service-kit in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-service-kit --test it alloc::`.

/// Counts the allocations of the IPC calls (`alloc`, run alone).
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

mod alloc;
mod ipc;
