//! The integration tests of exo-live in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-live --test it layout::`.

mod layout;
mod live;
