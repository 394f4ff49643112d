//! # exo-analysis
//!
//! The analysis exo's identifier and tools share, each concept once:
//!
//! - [`refit`]: which measured FRF the parameters come from and the M1–M3
//!   refit of an experiment's points (the online identifier and `exo fit`);
//! - [`windows`]: the analysis windows of a protocol stream;
//! - [`merge`]: a recording's protocol states and commands played in time
//!   beside its samples;
//! - [`study`]: the paper's "Modeling Results" per subject — fits, F-tests,
//!   phase and M2 tables, power laws, the recommended f;
//! - [`stability`]: the spring-release test's verdict (`exo tune`);
//! - [`preflight`]: the amplification controller's loop margins at a
//!   run's operating points, checked before it starts (`exo run`);
//! - [`reproduce`]: the recovered impedance against the simulated subjects
//!   and the paper's printed rows, with the acceptance criteria
//!   (`exo reproduce`);
//! - [`trials`]: what one imported trial of another rig is (subject,
//!   experiment, condition, α, load, CSV columns) and a study file of them;
//! - [`import`]: another rig's CSV as a contract recording (gaps and time
//!   units refused, a single sine detected), `exo import` and `exo fit`.
//!
//! `M_e` is `exo_impedance::exo_inertia_kg_m2`, the one formula the rig
//! configuration, the plant model and the identifier all call.

pub mod error;
pub mod import;
pub mod merge;
pub mod preflight;
pub mod refit;
pub mod reproduce;
pub mod stability;
pub mod study;
pub mod trials;
pub mod windows;

pub use error::{Error, Result};
pub use merge::{Merge, Played};
pub use refit::{effective_alpha, fit_models, FitSource, ModelFitError};
pub use windows::{analysis_windows, AnalysisWindow};
