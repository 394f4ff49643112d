//! The integration tests of exo-identifier in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-identifier --test it alloc::`.

/// Counts the per-sample calls' allocations (`alloc`), per thread: the
/// binary's other tests run in parallel threads.
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

#[path = "it/alloc.rs"]
mod alloc;
#[path = "it/identifier.rs"]
mod identifier;
#[path = "it/identifier_inputs.rs"]
mod identifier_inputs;
#[path = "it/multisine.rs"]
mod multisine;
#[path = "it/settings.rs"]
mod settings;
