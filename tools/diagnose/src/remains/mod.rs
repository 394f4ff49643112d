//! What remains after the diagnosis, per transfer function, in words a
//! user can act on (issue 15, item 2): whether the residual depends on the
//! excitation amplitude and on the operating point (experiment: bias,
//! stiffness level), each with its size and confidence.
//!
//! Both are weighted least-squares regressions of the final model's
//! relative residual `(data − model)/model` (in-phase part: a magnitude or
//! stiffness error; quadrature part: a phase or damping error), weighted by
//! the measured noise, with standard errors scaled by the residual variance
//! (so structure the regression does not describe widens them):
//!
//! - **amplitude**: per experiment a smooth trend in frequency (intercept,
//!   `ln ω`, `(ln ω)²`) plus one step shared by all experiments for the
//!   windows above the lowest excitation amplitude (the protocol raises it
//!   at periods 8–10). The step is what changes with amplitude beyond a
//!   smooth frequency trend; in this protocol the higher amplitude is also
//!   the highest frequencies, which the trend can only partly separate.
//! - **operating point**: one smooth trend in frequency shared by all
//!   experiments plus an offset per experiment; the offsets' F-test says
//!   whether the residual differs between operating points. `K_h`, `H_h`
//!   are fitted per experiment, so an in-phase (stiffness) offset of `S_h`
//!   is absorbed by them: there it shows in the fitted `K_h` against the
//!   bias, not in the residual.
//!
//! - **frequency band** (< 4, 4–10, ≥ 10 rad/s): the χ² per component
//!   and the weighted mean residual in each band, so a user sees where
//!   the misfit sits;
//! - **time within a window**: each single-sine window with at least four
//!   whole cycles is split into two halves of equal whole cycles, the
//!   transfer function measured in each (the same correlation as the
//!   window's), and the change second − first relative to the window's
//!   value is divided by the time between the halves' centres: a weighted
//!   mean rate (% per second) with its standard error (fatigue, warm-up,
//!   a drifting sensor within seconds);
//! - **time within an experiment** (across periods): a regression on the
//!   window's start time with the same per-experiment trend in frequency
//!   as the amplitude test. The protocol's periods sweep ω upwards, so in
//!   a frequency response the start time is (nearly) a function of `ln ω`:
//!   when the part of the time column the trend does not explain is below
//!   5 % of its spread, the words say that drift and frequency cannot be
//!   told apart from the residual alone and what would tell them (a
//!   repeated frequency late in the experiment, or the drift form of the
//!   library, whose `K_h(t)` the model's `−M_h ω²` does not mimic). The
//!   static balance has no frequency dependence: its drift is a slope in
//!   Nm per minute beside an offset per experiment;
//! - **harmonics and non-harmonic content** against each window's own
//!   noise with the ringing kept out of it ([`crate::signatures`]).
//!
//! ## Where it lives
//!
//! - this file: the result's types ([`Remains`] and the dependences it
//!   holds);
//! - `characterisation.rs`: [`characterise`] itself and the bands'
//!   residuals;
//! - `time.rs`: the change within a window (its rates measured by
//!   [`crate::data::within_window_rates`]) and the drift across an
//!   experiment;
//! - `regress.rs`: the weighted regressions they all use;
//! - `words.rs`: the sentences.
//!
//! `characterisation` imports `time`, `regress` and `words`; `time`
//! imports `regress`; `regress` and `words` import no other file of it.
//! The module imports [`crate::data`], [`crate::fit`], [`crate::model`],
//! [`crate::signatures`] and the bands (`band.rs`), never the engine:
//! [`crate::engine`] imports it, not the reverse.

mod characterisation;
mod regress;
mod time;
mod words;

pub use characterisation::characterise;

use serde::Serialize;

use crate::data::Tf;
use crate::signatures::HarmonicContent;

/// One regression coefficient with its standard error and p-value.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Estimate {
    /// Value (% of the model's value for a frequency response; Nm for the static balance).
    pub value: f64,
    /// Standard error.
    pub std_error: f64,
    /// Two-sided p-value (Student's t).
    pub p_value: f64,
}

/// The residual's dependence on the excitation amplitude.
#[derive(Debug, Clone, Serialize)]
pub struct AmplitudeDependence {
    /// Mean excitation amplitude of the low and the high windows (Nm).
    pub amplitudes_nm: [f64; 2],
    /// Mean angle amplitude of the low and the high windows (rad).
    pub theta_amp_rad: [f64; 2],
    /// Step of the in-phase part at the higher amplitude.
    pub in_phase: Estimate,
    /// Step of the quadrature part (`None` for the static balance).
    pub quadrature: Option<Estimate>,
    /// Significant (level Bonferroni-divided over transfer functions and parts).
    pub significant: bool,
}

/// The residual's dependence on the angle amplitude squared (the form of a
/// polynomial spring's describing function, `¾ K₃ A²`), beyond a smooth
/// trend in frequency per experiment; per (0.1 rad)² of `A²`.
#[derive(Debug, Clone, Serialize)]
pub struct AngleAmplitudeDependence {
    /// Smallest and largest angle amplitude of the windows (rad).
    pub theta_amp_rad: [f64; 2],
    /// In-phase slope (% or Nm per (0.1 rad)²).
    pub in_phase: Estimate,
    /// Quadrature slope (`None` for the static balance).
    pub quadrature: Option<Estimate>,
    /// Significant (level Bonferroni-divided over transfer functions and parts).
    pub significant: bool,
}

/// The residual's dependence on the operating point (experiment).
#[derive(Debug, Clone, Serialize)]
pub struct OperatingPointDependence {
    /// Per experiment: experiment, its bias (Nm), in-phase offset and quadrature offset.
    pub per_experiment: Vec<(u32, f64, Estimate, Option<Estimate>)>,
    /// F-test p-value of the offsets (in-phase, quadrature).
    pub p_value: [f64; 2],
    /// Significant (level Bonferroni-divided over transfer functions and parts).
    pub significant: bool,
}

/// What remains in one transfer function.
#[derive(Debug, Clone, Serialize)]
pub struct Remains {
    /// Transfer function.
    pub tf: Tf,
    /// Mean squared whitened residual per real component (1 = at the noise).
    pub chi2_per_component: f64,
    /// Dependence on amplitude, when the windows have two amplitudes or more.
    pub amplitude: Option<AmplitudeDependence>,
    /// Dependence on the angle amplitude squared (frequency responses).
    pub angle_amplitude: Option<AngleAmplitudeDependence>,
    /// Dependence on the operating point, with two experiments or more.
    pub operating_point: Option<OperatingPointDependence>,
    /// The residual per frequency band.
    pub bands: Vec<BandResidual>,
    /// Change within a window (second half against the first).
    pub within_window: Option<WithinWindow>,
    /// Dependence on the time within an experiment (across its periods).
    pub over_time: Option<TimeDependence>,
    /// Harmonics and non-harmonic content of its output channel.
    pub harmonics: Vec<HarmonicContent>,
    /// In words, every line.
    pub words: Vec<String>,
    /// The lines that say something remains (significant dependences, or
    /// that one amplitude cannot tell): what the verdict repeats.
    pub findings: Vec<String>,
}

/// The residual in one frequency band.
#[derive(Debug, Clone, Serialize)]
pub struct BandResidual {
    /// Band.
    pub band: &'static str,
    /// Points in it.
    pub points: usize,
    /// Mean squared whitened residual per real component (1 = at the noise).
    pub chi2_per_component: f64,
    /// Weighted mean in-phase residual (% or Nm).
    pub in_phase: Estimate,
    /// Weighted mean quadrature residual (`None` for the static balance).
    pub quadrature: Option<Estimate>,
}

/// The change of a transfer function within its windows.
#[derive(Debug, Clone, Serialize)]
pub struct WithinWindow {
    /// Windows split in halves.
    pub windows: usize,
    /// Rate of the in-phase change (% of the value per second).
    pub in_phase: Estimate,
    /// Rate of the quadrature change (% per second).
    pub quadrature: Estimate,
    /// Significant (level divided over transfer functions and parts).
    pub significant: bool,
}

/// The residual's dependence on the time within an experiment.
#[derive(Debug, Clone, Serialize)]
pub struct TimeDependence {
    /// The share of the start time's spread that the per-experiment trend
    /// in frequency does not explain (0: time is a function of frequency).
    pub independent_share: f64,
    /// Time and frequency cannot be told apart (share below 5 %).
    pub confounded_with_frequency: bool,
    /// Slope of the in-phase residual (% or Nm per minute), when not confounded.
    pub in_phase: Option<Estimate>,
    /// Slope of the quadrature residual (% per minute).
    pub quadrature: Option<Estimate>,
    /// Significant (level divided over transfer functions and parts).
    pub significant: bool,
}
