//! The integration tests of exo-recording in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-recording --test it cdr::`.

mod cdr;
/// Every message with every field set, a full recording of them, temporary
/// directories.
mod common;
mod files;
mod python;
