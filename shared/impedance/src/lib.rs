//! # exo-impedance
//!
//! The science of He, Huang, Thomas & Sentis, *A Complex Stiffness Human
//! Impedance Model with Customizable Exoskeleton Control*, IEEE TNSRE 2020,
//! as a library: pure math on `nalgebra` and `num-complex`, no IPC and no file
//! I/O, so every process of exo and every test can use it directly.
//!
//! | paper | here |
//! |---|---|
//! | models M1, M2, M3, eqs. Sh1–Sh3, Sh2-new | [`models`] |
//! | frequency-domain linear regression, RSS, R² | [`fit`] |
//! | F-statistics `F^sub`, `F^exp`, `F^all` (eq. ft) | [`ftest`] |
//! | power law `H = 10^β0 K^β1`, eqs. ch and zt-m2 | [`power_law`] |
//! | eqs. kp, kf, f; `P(s)`; crossovers and margins | [`loop_shaping`] |
//! | lag-filter approximation of `F(s)` (eq. Fs) | [`lag_filter`] |
//! | the whole recipe (what `exo design` prints) | [`design`] |
//! | a designed multisine excitation (not the paper's: issue 34) | [`multisine`] |
//!
//! Units: inertia kg·m², stiffness and hysteretic damping Nm/rad, viscous
//! damping Nm·s/rad, frequency rad/s unless a name says `_hz`, angles in
//! degrees only where a name says `_deg`.
//!
//! No function panics on user data or returns a silent NaN: bad input gives a
//! [`ScienceError`] naming the quantity or the data point.

#![warn(missing_docs)]

pub mod design;
pub mod error;
pub mod fit;
pub mod frf;
pub mod ftest;
pub mod lag_filter;
pub mod loop_shaping;
pub mod models;
pub mod multisine;
pub mod plausibility;
pub mod power_law;
pub mod quantiser;

pub use error::{Result, ScienceError};
pub use fit::{
    chi_squared_survival, fit_all, fit_all_with, fit_model, fit_model_with, students_t_quantile,
    DampingSign, FitTarget, FrfPoint, ModelComparison, ModelFit, CONFIDENCE_LEVEL,
};
pub use ftest::{f_critical, nested_f_test, paper_f_tests, FTest, NestedRss, PaperFTests};
pub use lag_filter::{DiscreteLagFilter, FirstOrderSection, LagFilter, MAX_SECTIONS};
pub use loop_shaping::{
    crossover_frequency, fractional_gain, fractional_order, nominal_crossover,
    predicted_amplification, proportional_gain, AmplificationLoop, AmplificationPlant, Crossover,
    LoopAnalysis, SeaModel, StiffnessRange,
};
pub use models::{
    exo_inertia_kg_m2, perceived_inertia, recreate_coupled, DynamicStiffness, ImpedanceModel,
    ReducedModel, Term,
};
pub use num_complex::Complex64;
pub use plausibility::{check_fit, Implausibility, Joint};
pub use power_law::{fit_power_law, geometric_mean, PowerLaw, PowerLawFit};
