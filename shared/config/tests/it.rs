//! The integration tests of exo-config in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-config --test it bad_values::`.

#[path = "it/bad_values.rs"]
mod bad_values;
/// Scratch copies of `configs/` with one file edited, for
/// `safety_defaults` and `validation_edges`.
#[path = "it/common.rs"]
mod common;
#[path = "it/configs.rs"]
mod configs;
#[path = "it/cross_checks.rs"]
mod cross_checks;
#[path = "it/multisine.rs"]
mod multisine;
#[path = "it/safety_defaults.rs"]
mod safety_defaults;
#[path = "it/subjects_table3.rs"]
mod subjects_table3;
#[path = "it/validation_edges.rs"]
mod validation_edges;
