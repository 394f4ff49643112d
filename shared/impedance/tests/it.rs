//! The integration tests of exo-impedance in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-impedance --test it band_average::`.

/// Counts the allocations of `frf`'s streaming estimator (per thread: the
/// other tests run in parallel threads).
#[global_allocator]
static GLOBAL: exo_test_support::CountingAllocator = exo_test_support::CountingAllocator;

#[path = "it/band_average.rs"]
mod band_average;
#[path = "it/frf.rs"]
mod frf;
#[path = "it/ftest_inputs.rs"]
mod ftest_inputs;
#[path = "it/ftest_scipy.rs"]
mod ftest_scipy;
#[path = "it/lag_filter_closed_form.rs"]
mod lag_filter_closed_form;
#[path = "it/low_bin_noise.rs"]
mod low_bin_noise;
#[path = "it/multisine.rs"]
mod multisine;
#[path = "it/paper.rs"]
mod paper;
#[path = "it/periodic.rs"]
mod periodic;
#[path = "it/power_law_numpy.rs"]
mod power_law_numpy;
#[path = "it/properties.rs"]
mod properties;
/// The seeded generator `paper` and `weighted` draw their noise from.
#[path = "it/rng.rs"]
mod rng;
#[path = "it/se_coverage.rs"]
mod se_coverage;
/// Table III of the paper, for `paper`.
#[path = "it/table3.rs"]
mod table3;
#[path = "it/weighted.rs"]
mod weighted;
