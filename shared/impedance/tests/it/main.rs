//! The integration tests of exo-impedance in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-impedance --test it band_average::`.

/// Counts the allocations of `frf`'s streaming estimator (per thread: the
/// other tests run in parallel threads).
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

mod band_average;
mod frf;
mod ftest_inputs;
mod ftest_scipy;
mod lag_filter_closed_form;
mod paper;
mod power_law_numpy;
mod properties;
/// The seeded generator `paper` and `weighted` draw their noise from.
mod rng;
mod se_coverage;
/// Table III of the paper, for `paper`.
mod table3;
mod weighted;
