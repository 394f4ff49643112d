//! The diagnosis: locate the mismatch, refit the nominal model's own
//! parameters, then add candidate physics one term at a time while it is
//! significant, and score every model before and after.
//!
//! Selection (each step, every candidate not yet in the model):
//! - nested-model F-test of the model with the candidate against the model
//!   without it, as the paper compares M1 and M2 with M3 (eq. ft):
//!   `F = ((RSS₀ − RSS₁)/Δp) / (RSS₁/(n − p₁))`;
//! - Holm's correction over the candidates tried at the step (the chosen one
//!   is the smallest p-value, so its adjusted p is `m·p`);
//! - Akaike's criterion must fall and the held-out error must fall:
//!   two-fold validation over periods (odd periods fit, even predicted, and
//!   the reverse; within a single broadband window, alternate bands);
//! - the lack-of-fit χ² against the noise measured in each window is
//!   reported before and after: it says whether structure remains.
//!
//! The search runs only while the lack-of-fit test rejects (structure
//! beyond the noise remains); the most significant candidate that the
//! Holm-corrected F-test, Akaike's criterion and the held-out error all
//! accept, and whose parameters are determined (one differs from the
//! term's absence by more than two standard errors), is added; the search stops when none qualifies or nothing is left
//! to explain.
//!
//! ## Where it lives
//!
//! - this file: [`Settings`], [`DiagnoseError`], the whole result
//!   ([`Diagnosis`]) and the constants [`MARGINAL_P`] and [`MIN_WINDOWS`];
//! - `run.rs`: [`diagnose`] itself, the refit, the search loop and the
//!   verdict ([`ParamChange`]);
//! - `search.rs`: one step of the search, its candidates judged and the one
//!   taken ([`Candidate`], [`Step`], [`Found`], [`nominal_free`]);
//! - `checks.rs`: the checks beyond the F-test ([`TfCheck`],
//!   [`WindowCheck`], [`AmplitudeCheck`], a delay within one tick);
//! - `timing.rs`: a delay within one tick taken into the nominal model
//!   before the search, when only the noise, not the accuracy, sees it;
//! - `score.rs`: a model's scores and held-out error ([`Score`], [`TfScore`]);
//! - `locate.rs`: where the data and the nominal model differ ([`Location`],
//!   [`Cell`], [`Scaling`], [`TimeRow`]);
//! - `tests.rs`: the unit tests.
//!
//! Within the engine the files depend downwards only: `run` → `timing`,
//! `search`, `checks`, `score`, `locate`; `timing` → `search`, `checks`,
//! `score`; `search` → `checks`, `score`; `checks`,
//! `score` and `locate` import no other file of the engine. This file
//! holds the settings, the result and the constants they share, no logic.
//!
//! ## Dependencies
//!
//! The engine is the top of the crate but for [`crate::bench`]: it imports
//! [`crate::remains`] (what remains), [`crate::posture`],
//! [`crate::equilibrium`], [`crate::signatures`], [`crate::terms`],
//! [`crate::fit`], [`crate::model`] and [`crate::data`], and none of them
//! imports the engine. What both the engine and `remains` (or
//! `equilibrium`) need sits below them in `band.rs` (the frequency bands)
//! and `stats.rs` (the χ² and normal distribution functions), so the
//! dependency goes one way: engine → remains, never back.

mod checks;
mod locate;
mod run;
mod score;
mod search;
#[cfg(test)]
mod tests;
mod timing;

pub use checks::{AmplitudeCheck, TfCheck, WindowCheck};
pub use locate::{Cell, Location, Scaling, TimeRow};
pub use run::{diagnose, ParamChange};
pub use score::{Score, TfScore};
pub use search::{nominal_free, Candidate, Found, Step};

use std::collections::BTreeMap;

use exo_plant_model::PlantModel;
use serde::Serialize;

use crate::data::Tf;
use crate::model::Physics;
use crate::terms::Term;

/// Settings of a diagnosis.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Family-wise false-alarm probability of the tests.
    pub level: f64,
    /// Most terms added.
    pub max_terms: usize,
    /// Nominal `K_h`, `H_h` per experiment (a subject file), if known.
    pub nominal_subject: Option<BTreeMap<u32, (f64, f64)>>,
    /// Candidate terms allowed (default: the whole catalogue).
    pub candidates: Vec<Term>,
    /// Generic forms tried when no catalogue term is accepted (default:
    /// the whole library, [`Term::FORMS`]).
    pub forms: Vec<Term>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            level: 0.05,
            max_terms: 4,
            nominal_subject: None,
            candidates: Term::ALL.to_vec(),
            forms: Term::FORMS.to_vec(),
        }
    }
}

/// Error of a diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// Nothing to compare.
    #[error("no usable observations: {0}")]
    NoData(String),
    /// Settings out of range.
    #[error("{0}")]
    Settings(String),
}

/// The Holm-adjusted p-value at and above which an accepted term is
/// reported as marginal ([`Found::marginal`]): significant at the usual
/// 0.05, not at 0.001. (The real ankle record's hysteresis step, F = 8.6
/// against a critical 7.0, is one; every concealed effect of
/// `exo diagnose-bench` is far below it.)
pub const MARGINAL_P: f64 = 1e-3;

/// The fewest analysis windows (a broadband window counts once per band
/// it gives) from which the diagnosis tells structure from noise. Each
/// window's noise comes from its own residual, but with
/// one or two windows the model's own parameters (`K_h`, `H_h`, `M_h`, the
/// SEA's) take up nearly every value, so a lack-of-fit there measures the
/// few degrees of freedom left, not the physics: nothing is named and the
/// verdict says why.
pub const MIN_WINDOWS: usize = 3;

/// The whole result.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Recordings read.
    pub sources: Vec<String>,
    /// Transfer functions compared.
    pub supported: Vec<Tf>,
    /// What could not be used.
    pub notes: Vec<String>,
    /// The located mismatch.
    pub location: Location,
    /// Nominal model as given.
    pub nominal: Score,
    /// Nominal model with its own parameters refitted.
    pub refit: Score,
    /// Parameters of the nominal model that moved.
    pub parameter_changes: Vec<ParamChange>,
    /// The search.
    pub steps: Vec<Step>,
    /// Terms found, in the order added.
    pub found: Vec<Found>,
    /// Delays shorter than one sample period that the search took into the
    /// model as the rig's timing within a tick, not as missing physics
    /// (docs/diagnose.md, "The judgement by the measured noise").
    pub within_tick: Vec<String>,
    /// The family-wise false-alarm probability the tests were run at
    /// ([`Settings::level`]).
    pub level: f64,
    /// The final model's score.
    pub final_score: Score,
    /// The verdict in plain words.
    pub verdict: Vec<String>,
    /// Nominal coefficients.
    pub nominal_physics: Physics,
    /// Refitted nominal coefficients.
    pub refit_physics: Physics,
    /// Final coefficients.
    pub final_physics: Physics,
    /// What remains of the final model's misfit, per transfer function.
    pub remains: Vec<crate::remains::Remains>,
    /// The posture-dependent stiffness's fit in the 2nd harmonic of `τ_c`
    /// (taken or not, with why), when the windows have the harmonics.
    pub posture: Option<crate::posture::PostureFit>,
    /// Each experiment's posture against the model's static equilibrium
    /// ([`crate::equilibrium`]).
    pub equilibrium: Option<crate::equilibrium::Equilibrium>,
}

impl Diagnosis {
    /// The updated plant model.
    pub fn updated_plant(&self, base: &PlantModel) -> PlantModel {
        self.final_physics.write_plant(base)
    }
}
