//! The integration tests of exo-recording in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-recording --test it cdr::`.

#[path = "it/cdr.rs"]
mod cdr;
/// Every message with every field set, a full recording of them, temporary
/// directories.
#[path = "it/common.rs"]
mod common;
#[path = "it/files.rs"]
mod files;
#[path = "it/full_disk.rs"]
mod full_disk;
#[path = "it/inplace.rs"]
mod inplace;
#[path = "it/killed.rs"]
mod killed;
#[path = "it/python.rs"]
mod python;
