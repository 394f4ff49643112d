//! The workspace-level integration tests in one test binary (issue 31
//! item 2: the dependencies are linked once, not once per file). Each
//! module, in `tests/it/`, was a test binary of its own; one of them
//! alone: `cargo test -p exo-tests --test it pipeline::`.

#[path = "it/amplification.rs"]
mod amplification;
#[path = "it/ankle.rs"]
mod ankle;
#[path = "it/bad_input.rs"]
mod bad_input;
#[path = "it/cli_design.rs"]
mod cli_design;
#[path = "it/determinism.rs"]
mod determinism;
#[path = "it/diagnose.rs"]
mod diagnose;
#[path = "it/diagnose_outside_catalogue.rs"]
mod diagnose_outside_catalogue;
#[path = "it/import.rs"]
mod import;
#[path = "it/import_csv.rs"]
mod import_csv;
#[path = "it/independent.rs"]
mod independent;
#[path = "it/multisine.rs"]
mod multisine;
#[path = "it/operator.rs"]
mod operator;
#[path = "it/pipeline.rs"]
mod pipeline;
#[path = "it/recordings.rs"]
mod recordings;
#[path = "it/reproduce.rs"]
mod reproduce;
#[path = "it/stability.rs"]
mod stability;
#[path = "it/tunnel_run.rs"]
mod tunnel_run;
#[path = "it/workspace.rs"]
mod workspace;
