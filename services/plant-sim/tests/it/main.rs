//! The integration tests of exo-plant-sim in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module was a test binary of its own; one of them alone:
//! `cargo test -p exo-plant-sim --test it drive_defaults::`.

mod drive_defaults;
mod physics;
