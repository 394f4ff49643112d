//! What a recording says about the plant: one complex observation per
//! transfer function and analysis window (single-sine periods) or per band
//! (broadband windows), each with the noise measured from the data itself.
//!
//! Transfer functions, as the identifier defines them
//! (`docs/recording-format.md`):
//! - `S_h = τ_c/θ_e` (Nm/rad), the human's dynamic stiffness seen by the cuff;
//! - `S_{h-e} = (τ_s − τ_gravity)/θ_e` (Nm/rad), the coupled human–exoskeleton
//!   stiffness with the controller's gravity compensation removed;
//! - `τ_s/τ_d` (dimensionless), the SEA's torque tracking.
//!
//! The controller's own gravity compensation is measured too
//! (`τ_gravity/θ_e` at ω): it is an input of the comparison, not a term of
//! the plant, so a gravity-compensation error shows as the difference between
//! the plant's gravity and what the controller removed.
//!
//! ## Where it lives
//!
//! - this file: the transfer functions ([`Tf`]) and the reduction's
//!   settings ([`Reduction`]), which every file below shares;
//! - `condition.rs`: one analysis window's conditions ([`Condition`]), the
//!   measured angle's gravity fundamentals ([`GravityFundamentals`]) and
//!   the motor command as a torque limit sees it ([`CommandPeaks`]);
//! - `dataset.rs`: what the reduction gives ([`Dataset`], [`Observation`],
//!   [`TransientFree`], [`LocalNoise`], [`WindowSignals`]);
//! - `reduction.rs`: [`reduce`] itself and the analysis windows it finds
//!   in the protocol topic;
//! - `sine.rs`: a single-sine window's lines;
//! - `balance.rs`: a single-sine window's static balance;
//! - `broadband.rs`: a broadband window's bands;
//! - `transient.rs`: a window's transient, where the local polynomials can
//!   tell it ([`smooth_transient`]), and its variance pooled over an
//!   experiment's lines (`pool_transients`).
//!
//! The files depend downwards only: `reduction` → `sine`, `broadband`,
//! `transient`, `dataset`, `condition`; `sine` → `balance`, `transient`,
//! `dataset`, `condition`; `balance` and `broadband` → `dataset`,
//! `condition`; `transient` → `dataset`; `dataset` → `condition`;
//! `condition` imports no other file of it. They take [`Tf`] and
//! [`Reduction`] from this file, which holds no logic.

mod balance;
mod broadband;
mod condition;
mod dataset;
mod reduction;
mod sine;
mod transient;
mod within;

pub use condition::{CommandPeaks, Condition, GravityFundamentals};
pub use dataset::{Dataset, LocalNoise, Observation, TransientFree, WindowSignals};
pub(crate) use dataset::{SeaHarmonics, ShHarmonics};
pub use reduction::reduce;
pub use transient::smooth_transient;
pub use within::{within_window_rates, WindowRate};

use serde::Serialize;

/// A transfer function a recording can support.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Tf {
    /// `S_h = τ_c/θ_e` (Nm/rad).
    #[serde(rename = "S_h")]
    Sh,
    /// `S_{h-e} = (τ_s − τ_gravity)/θ_e` (Nm/rad).
    #[serde(rename = "S_h-e")]
    She,
    /// `τ_s/τ_d` (dimensionless).
    #[serde(rename = "tau_s/tau_d")]
    Sea,
    /// The exoskeleton's static balance `mean(τ_s − τ_gravity − τ_c)` over
    /// whole cycles (Nm, real; ω = 0): what the controller's gravity
    /// compensation left to the plant's gravity, plus the torque sensors'
    /// offsets. It needs no knowledge of the human's posture.
    #[serde(rename = "static_balance")]
    Balance,
}

impl Tf {
    /// Every transfer function, in report order.
    pub const ALL: [Tf; 4] = [Tf::Sh, Tf::She, Tf::Sea, Tf::Balance];

    /// Whether it is a frequency response (has a Bode plot).
    pub fn is_dynamic(self) -> bool {
        self != Tf::Balance
    }

    /// The name used in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Tf::Sh => "S_h",
            Tf::She => "S_h-e",
            Tf::Sea => "tau_s/tau_d",
            Tf::Balance => "static_balance",
        }
    }

    /// Which signals it is made of, for messages.
    pub fn signals(self) -> &'static str {
        match self {
            Tf::Sh => "τ_c/θ_e",
            Tf::She => "(τ_s − τ_gravity)/θ_e",
            Tf::Sea => "τ_s/τ_d",
            Tf::Balance => "mean(τ_s − τ_gravity − τ_c)",
        }
    }
}

/// Settings of the data reduction.
#[derive(Debug, Clone, Copy)]
pub struct Reduction {
    /// Smallest coherence (fraction of variance at ω) of θ_e and the output kept.
    pub min_coherence: f64,
    /// Welch segment for broadband windows (samples, at least 16).
    pub welch_segment: usize,
    /// Bands a broadband window is summarised into.
    pub broadband_points: usize,
    /// Band (rad/s) of broadband estimates.
    pub broadband_band_rad_s: [f64; 2],
}

impl Default for Reduction {
    fn default() -> Self {
        Self {
            min_coherence: 0.5,
            // As the identifier's defaults, so `exo fit` and `exo diagnose`
            // see the same broadband points.
            welch_segment: 4096,
            broadband_points: 20,
            broadband_band_rad_s: [1.0, 100.0],
        }
    }
}
