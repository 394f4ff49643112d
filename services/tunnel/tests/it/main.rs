//! The integration tests of exo-tunnel in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-tunnel --test it import::`.

mod import;
mod tunnel;
