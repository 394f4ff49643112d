//! The integration tests of exo-diagnose in one test binary (issue 31
//! item 2: the dependencies are linked once, not once per file). Each
//! module, in `tests/it/`, was a test binary of its own; one of them alone:
//! `cargo test -p exo-diagnose --test it noise_model::`.

#[path = "it/bench_cases.rs"]
mod bench_cases;
#[path = "it/broadband.rs"]
mod broadband;
#[path = "it/common.rs"]
mod common;
#[path = "it/engine.rs"]
mod engine;
#[path = "it/forward.rs"]
mod forward;
#[path = "it/friction_scaling.rs"]
mod friction_scaling;
#[path = "it/noise_model.rs"]
mod noise_model;
#[path = "it/outside_catalogue.rs"]
mod outside_catalogue;
#[path = "it/remains_gate.rs"]
mod remains_gate;
#[path = "it/signatures.rs"]
mod signatures;
#[path = "it/statistics.rs"]
mod statistics;
#[path = "it/subject_file.rs"]
mod subject_file;
#[path = "it/undetermined.rs"]
mod undetermined;
#[path = "it/verdict.rs"]
mod verdict;
