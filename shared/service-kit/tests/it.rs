//! The integration tests of exo-service-kit in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-service-kit --test it alloc::`.

/// Counts the allocations of the IPC calls (`alloc`, run alone).
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

#[path = "it/alloc.rs"]
mod alloc;
#[path = "it/ipc.rs"]
mod ipc;
