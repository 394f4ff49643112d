//! The whole loop-shaping recipe of the paper in one call: what `exo design`
//! prints. Gains from eqs. kp and kf, the fractional order from eq. f (or
//! given), the lag-filter cascade of eq. Fs and its real-time form, the loop's
//! crossovers and margins at both ends of the stiffness range, and the
//! predicted amplification.

use serde::Serialize;

use crate::error::{finite, positive, Result, ScienceError};
use crate::lag_filter::{DiscreteLagFilter, LagFilter};
use crate::loop_shaping::{
    fractional_gain, fractional_order, nominal_crossover, predicted_amplification,
    proportional_gain, AmplificationLoop, AmplificationPlant, LoopAnalysis, SeaModel,
    StiffnessRange,
};
use crate::power_law::PowerLaw;

/// Everything a design needs. Optional fields fall back to the paper's rules.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignInputs {
    /// Exoskeleton inertia `M_e` (kg·m²), load included.
    pub m_e_kg_m2: f64,
    /// Human inertia `M_h` (kg·m²).
    pub m_h_kg_m2: f64,
    /// Stiffness range the controller must cover.
    pub range: StiffnessRange,
    /// The subject's power law; gives `c(K)` and, with a phase margin, `f` by eq. f.
    pub power_law: Option<PowerLaw>,
    /// A constant loss factor `c`, used for the margins when no power law is given.
    pub loss_factor: Option<f64>,
    /// Guaranteed phase margin `φ` (degrees) for eq. f.
    pub phase_margin_deg: Option<f64>,
    /// Explicit fractional order (overrides eq. f).
    pub f: Option<f64>,
    /// Explicit proportional gain (overrides eq. kp).
    pub kp: Option<f64>,
    /// Number of lag filters `n`.
    pub n_filters: usize,
    /// First pole `p_1` (rad/s).
    pub p1_rad_s: f64,
    /// Pole spacing `r_pp`.
    pub r_pp: f64,
    /// Controller sample rate (Hz).
    pub rate_hz: f64,
    /// SEA model for the loop.
    pub sea: SeaModel,
    /// Frequencies (rad/s) at which to predict the amplification.
    pub prediction_omegas_rad_s: Vec<f64>,
}

impl DesignInputs {
    /// The paper's setup (section "Experimental Protocol for Loop Shaping"):
    /// `M_e = 1.01`, `M_h = 0.11` kg·m², `K` from 10.03 to 108.33 Nm/rad, five
    /// lag filters from `p_1 = 1` rad/s spaced by `10^0.5`, 1 kHz, a 10 Hz SEA,
    /// predictions at 1 and 10 rad/s. No power law, margin or `f` is set.
    pub fn paper_defaults() -> Self {
        DesignInputs {
            m_e_kg_m2: 1.01,
            m_h_kg_m2: 0.11,
            range: StiffnessRange {
                k_min: 10.03,
                k_max: 108.33,
            },
            power_law: None,
            loss_factor: None,
            phase_margin_deg: None,
            f: None,
            kp: None,
            n_filters: 5,
            p1_rad_s: 1.0,
            r_pp: 10f64.powf(0.5),
            rate_hz: 1000.0,
            sea: SeaModel::default(),
            prediction_omegas_rad_s: vec![1.0, 10.0],
        }
    }
}

/// Where the fractional order came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FractionalOrderSource {
    /// Given by the user.
    Explicit,
    /// Eq. f from the power law, the stiffness range and the phase margin.
    EqF,
}

/// The loop at one end of the stiffness range.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StiffnessCase {
    /// Stiffness `K` (Nm/rad).
    pub k_nm_per_rad: f64,
    /// Loss factor `c(K)`.
    pub loss_factor: f64,
    /// The paper's bound `atan(c)/90` on `f` for a positive margin.
    pub f_bound: f64,
    /// Crossovers and margins.
    pub analysis: LoopAnalysis,
}

/// Predicted `τ̃_s/τ̃_c` at one frequency.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Prediction {
    /// Frequency (rad/s).
    pub omega: f64,
    /// `|k_p F(jω)|` (the paper's `|τ̃_s/τ̃_c|`, ideal actuator).
    pub magnitude: f64,
    /// `∠k_p F(jω)` (degrees).
    pub phase_deg: f64,
    /// `|k_p F(jω) G_SEA(jω)|`: the same through the SEA's torque dynamics.
    pub magnitude_with_sea: f64,
    /// `∠k_p F(jω) G_SEA(jω)` (degrees).
    pub phase_deg_with_sea: f64,
}

/// A complete controller design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Design {
    /// Proportional gain `k_p`.
    pub kp: f64,
    /// Whether `k_p` came from eq. kp (`false`) or was given.
    pub kp_explicit: bool,
    /// Nominal crossover `ω̂_gc` (rad/s, eq. kf).
    pub omega_gc: f64,
    /// Nominal stiffness `K̂ = (K̲ K̄)^(1/2)` (Nm/rad).
    pub k_nominal: f64,
    /// Fractional gain `k_f` (eq. kf).
    pub kf: f64,
    /// Fractional order `f`.
    pub f: f64,
    /// Where `f` came from.
    pub f_source: FractionalOrderSource,
    /// The continuous lag-filter cascade (eq. Fs).
    pub filter: LagFilter,
    /// The real-time cascade.
    pub discrete: DiscreteLagFilter,
    /// Controller sample rate (Hz).
    pub rate_hz: f64,
    /// The loop at `K̲` and `K̄`; `None` when no loss factor is known.
    pub margins: Option<[StiffnessCase; 2]>,
    /// Predicted amplification at the requested frequencies.
    pub predicted: Vec<Prediction>,
}

/// Runs the paper's loop-shaping recipe.
pub fn design(inputs: &DesignInputs) -> Result<Design> {
    positive("m_e_kg_m2", inputs.m_e_kg_m2)?;
    positive("m_h_kg_m2", inputs.m_h_kg_m2)?;
    let range = StiffnessRange::new(inputs.range.k_min, inputs.range.k_max)?;
    let sea = SeaModel::new(inputs.sea.natural_frequency_hz, inputs.sea.damping_ratio)?;
    let (kp, kp_explicit) = match inputs.kp {
        Some(kp) => (positive("kp", kp)?, true),
        None => (
            proportional_gain(inputs.m_e_kg_m2, inputs.m_h_kg_m2)?,
            false,
        ),
    };
    let omega_gc = nominal_crossover(range, inputs.m_e_kg_m2, inputs.m_h_kg_m2)?;
    let (f, f_source) = match (inputs.f, inputs.power_law, inputs.phase_margin_deg) {
        (Some(f), _, _) => {
            finite("f", f)?;
            if !(f > 0.0 && f < 1.0) {
                return Err(ScienceError::OutOfRange {
                    name: "f",
                    value: f,
                    allowed: "(0, 1)",
                });
            }
            (f, FractionalOrderSource::Explicit)
        }
        (None, Some(law), Some(phi)) => (fractional_order(law, range, phi)?, FractionalOrderSource::EqF),
        _ => {
            return Err(ScienceError::Infeasible(
                "the fractional order is undetermined: give f, or a power law (beta0, beta1) and a phase margin".into(),
            ))
        }
    };
    let kf = fractional_gain(omega_gc, f)?;
    let filter = LagFilter::new(inputs.n_filters, inputs.p1_rad_s, inputs.r_pp, f, kf)?;
    let discrete = filter.discretize(inputs.rate_hz)?;

    let loss_factor_at = |k: f64| -> Option<Result<f64>> {
        match (inputs.power_law, inputs.loss_factor) {
            (Some(law), _) => Some(law.loss_factor(k)),
            (None, Some(c)) => Some(finite("loss_factor", c)),
            (None, None) => None,
        }
    };
    let case = |k: f64| -> Option<Result<StiffnessCase>> {
        loss_factor_at(k).map(|c| {
            let c = c?;
            let plant = AmplificationPlant::new(inputs.m_e_kg_m2, inputs.m_h_kg_m2, k, c, sea)?;
            let l = AmplificationLoop { kp, filter, plant };
            // Search from well below the filter band and the coupled resonance
            // to well above the SEA.
            let lo = 1e-3 * filter.p1_rad_s().min(1.0);
            let hi = 1e3 * sea.omega_n_rad_s().max(filter.band_rad_s().1);
            Ok(StiffnessCase {
                k_nm_per_rad: k,
                loss_factor: c,
                f_bound: c.atan().to_degrees() / 90.0,
                analysis: l.analyze(lo, hi)?,
            })
        })
    };
    let margins = match (case(range.k_min), case(range.k_max)) {
        (Some(a), Some(b)) => Some([a?, b?]),
        _ => None,
    };

    let predicted = inputs
        .prediction_omegas_rad_s
        .iter()
        .map(|&w| {
            positive("prediction omega", w)?;
            let a = predicted_amplification(kp, &filter, w);
            let b = a * sea.response(w);
            Ok(Prediction {
                omega: w,
                magnitude: a.norm(),
                phase_deg: a.arg().to_degrees(),
                magnitude_with_sea: b.norm(),
                phase_deg_with_sea: b.arg().to_degrees(),
            })
        })
        .collect::<Result<Vec<_>>>()?;

    Ok(Design {
        kp,
        kp_explicit,
        omega_gc,
        k_nominal: range.nominal(),
        kf,
        f,
        f_source,
        filter,
        discrete,
        rate_hz: inputs.rate_hz,
        margins,
        predicted,
    })
}
