//! The integration tests of exo-plant-sim in one test binary
//! (issue 31 item 2: the dependencies are linked once, not once per
//! file). Each module, in `tests/it/`, was a test binary of its own; one
//! of them alone:
//! `cargo test -p exo-plant-sim --test it drive_defaults::`.

#[path = "it/drive_defaults.rs"]
mod drive_defaults;
#[path = "it/physics.rs"]
mod physics;
