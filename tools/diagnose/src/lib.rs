//! # exo-diagnose: the mismatch finder
//!
//! When simulation and recordings differ, this crate says where, names the
//! physics the model left out, models it and shows the fit improve
//! (`exo diagnose`).
//!
//! 1. [`data::reduce`] turns recordings that follow `docs/recording-format.md`
//!    (whoever wrote them) into complex observations of every transfer
//!    function they support (`S_h`, `S_h-e`, `τ_s/τ_d`), one per
//!    single-sine analysis window or per band of a broadband window, each
//!    with the noise measured in that window.
//! 2. [`model::Physics`] is the plant TOML's every term as a frequency-domain
//!    forward model (checked against the simulator in the tests).
//! 3. [`engine::diagnose`] locates the mismatch (per transfer function,
//!    band and experiment, against the measured noise; residual scaling with
//!    amplitude, stiffness and frequency; time-domain residuals and
//!    harmonics), refits the nominal model's own parameters, then tries the
//!    [`terms::Term`] catalogue one term at a time with nested F-tests,
//!    Holm's correction, Akaike's criterion and two-fold held-out
//!    validation, then the library of generic forms with the same criteria
//!    (a posture-dependent stiffness in the 2nd harmonic: [`posture`]), and
//!    writes the updated plant model.
//!
//! [`bench`](mod@bench) holds the cases `exo diagnose-bench` proves it on: concealed
//! effects (and null cases) in a true plant behind a nominal model.

mod band;
pub mod bench;
pub mod data;
pub mod engine;
pub mod equilibrium;
pub mod fit;
pub mod model;
pub mod posture;
pub mod remains;
pub mod signatures;
mod stats;
pub mod synth;
pub mod terms;

pub use data::{reduce, Dataset, Observation, Reduction, Tf};
pub use engine::{diagnose, DiagnoseError, Diagnosis, Settings};
pub use model::{Param, Physics};
pub use terms::Term;
