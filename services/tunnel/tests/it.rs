//! The integration tests of exo-tunnel in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-tunnel --test it import::`.

#[path = "it/import.rs"]
mod import;
#[path = "it/tunnel.rs"]
mod tunnel;
