//! The integration tests of exo-config in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-config --test it bad_values::`.

mod bad_values;
/// Scratch copies of `configs/` with one file edited, for
/// `safety_defaults` and `validation_edges`.
mod common;
mod configs;
mod safety_defaults;
mod subjects_table3;
mod validation_edges;
