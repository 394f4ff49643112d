//! The integration tests of exo-live in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-live --test it layout::`.

#[path = "it/layout.rs"]
mod layout;
#[path = "it/live.rs"]
mod live;
