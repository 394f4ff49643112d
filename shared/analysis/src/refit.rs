//! The M1–M3 refit of an experiment's FRF points, one place for the online
//! identifier and `exo fit`: which measured FRF the parameters come from
//! ([`FitSource`]: `S_h = τ_c/θ_e` by default, as the paper does), and each
//! model fitted on its own ([`fit_models`]).

use exo_impedance::{
    fit_model_with, Complex64, DampingSign, FitTarget, FrfPoint as FitPoint, ImpedanceModel,
    ModelFit,
};
use exo_messages::FrfPoint;

/// α as the fit uses it: a protocol's α ≤ 0 (or not finite) means "not
/// set" and is taken as 1 (no amplification).
pub fn effective_alpha(alpha: f64) -> f64 {
    if alpha.is_finite() && alpha > 0.0 {
        alpha
    } else {
        1.0
    }
}

/// Why one model of [`fit_models`] was not fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelFitError {
    /// Fewer points than one residual degree of freedom needs (`2n − p ≥ 1`).
    #[error("needs {needed} FRF points for a residual degree of freedom")]
    TooFewPoints {
        /// Points needed.
        needed: usize,
    },
    /// The fit itself failed (singular design, bad data).
    #[error(transparent)]
    Science(#[from] exo_impedance::ScienceError),
}

/// M1, M2 and M3 fitted to the same points, each on its own: a model with
/// too few points for a residual degree of freedom (standard errors,
/// F-tests) is not fitted, and says how many it needs. Used by the online
/// refit and by `exo fit`, so both fit the same way.
pub fn fit_models(
    points: &[FitPoint],
    target: FitTarget,
    damping: DampingSign,
) -> [Result<ModelFit, ModelFitError>; 3] {
    ImpedanceModel::ALL.map(|model| {
        let needed = model.n_params() / 2 + 1;
        if points.len() < needed {
            return Err(ModelFitError::TooFewPoints { needed });
        }
        Ok(fit_model_with(model, points, target, damping)?)
    })
}

/// Which measured FRF the models' parameters are estimated from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum FitSource {
    /// `S_h = τ_c/θ_e` (eqs. Sh1–Sh3), as the paper does "to take advantage
    /// of the clean human cuff sensor signal": needs neither `M_e` nor α, and
    /// no exoskeleton dynamics enter the estimate.
    #[default]
    CuffTorque,
    /// The actuator side `(τ_s − τ_gravity)/θ_e = S_h + M_e s²`, with the
    /// whole `M_e` removed (`M_e` from the rig settings and the protocol's
    /// load). Its high-frequency points are dominated by `M_e ω²` and carry
    /// the SEA sensor's noise; kept for rigs whose cuff is not trusted.
    ActuatorTorque,
}

impl FitSource {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            FitSource::CuffTorque => "cuff",
            FitSource::ActuatorTorque => "actuator",
        }
    }

    /// The fit target of this source for an exoskeleton of inertia `m_e_kg_m2`.
    pub fn target(self, m_e_kg_m2: f64) -> FitTarget {
        match self {
            FitSource::CuffTorque => FitTarget::Human,
            FitSource::ActuatorTorque => FitTarget::ActuatorSide { m_e_kg_m2 },
        }
    }

    /// The points this source fits, each with its measured noise
    /// `σ = noise_rel · |S|` (0 when not measured: then the fit is unweighted).
    pub fn fit_points(self, points: &[FrfPoint]) -> Vec<FitPoint> {
        points
            .iter()
            .map(|p| {
                let (re, im, rel) = match self {
                    FitSource::CuffTorque => (p.s_h_re, p.s_h_im, p.noise_rel),
                    FitSource::ActuatorTorque => (p.s_he_re, p.s_he_im, p.s_he_noise_rel),
                };
                let sigma = rel * Complex64::new(re, im).norm();
                let sigma = if sigma.is_finite() && sigma > 0.0 {
                    sigma
                } else {
                    0.0
                };
                FitPoint::new(p.omega, re, im).with_std_dev(sigma)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unset_alpha_is_one() {
        assert_eq!(effective_alpha(2.0), 2.0);
        assert_eq!(effective_alpha(0.5), 0.5);
        for unset in [0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(effective_alpha(unset), 1.0, "{unset}");
        }
    }

    #[test]
    fn each_source_fits_its_own_transfer_function_weighted_by_its_own_noise() {
        let p = FrfPoint {
            omega: 5.0,
            s_h_re: 3.0,
            s_h_im: 4.0,
            noise_rel: 0.01,
            s_he_re: -6.0,
            s_he_im: 8.0,
            s_he_noise_rel: 0.02,
            ..Default::default()
        };
        let [cuff] = FitSource::CuffTorque.fit_points(&[p])[..] else {
            panic!("one point")
        };
        // σ = noise_rel · |S|: 0.01 · 5 and 0.02 · 10.
        assert_eq!(cuff.value, Complex64::new(3.0, 4.0));
        assert!((cuff.std_dev_nm_per_rad - 0.05).abs() < 1e-15);
        let [act] = FitSource::ActuatorTorque.fit_points(&[p])[..] else {
            panic!("one point")
        };
        assert_eq!(act.value, Complex64::new(-6.0, 8.0));
        assert!((act.std_dev_nm_per_rad - 0.2).abs() < 1e-15);
        assert_eq!(act.omega_rad_s, 5.0);
        // Noise not measured (0, NaN, inf): σ = 0, the fit goes unweighted.
        for rel in [0.0, f64::NAN, f64::INFINITY, -0.1] {
            let q = FrfPoint {
                noise_rel: rel,
                ..p
            };
            let pts = FitSource::CuffTorque.fit_points(&[q]);
            assert_eq!(pts[0].std_dev_nm_per_rad, 0.0, "{rel}");
        }
        assert_eq!(FitSource::CuffTorque.name(), "cuff");
        assert_eq!(FitSource::ActuatorTorque.name(), "actuator");
        assert_eq!(FitSource::CuffTorque.target(1.0), FitTarget::Human);
        assert_eq!(
            FitSource::ActuatorTorque.target(1.25),
            FitTarget::ActuatorSide { m_e_kg_m2: 1.25 }
        );
    }

    #[test]
    fn models_with_too_few_points_say_how_many_they_need() {
        let pts = [FitPoint::new(2.0, 20.0, 5.0)];
        let fits = fit_models(&pts, FitTarget::Human, DampingSign::Free);
        // M1, M2: 3 parameters → 2 points; M3: 4 → 3 points.
        assert_eq!(fits[0], Err(ModelFitError::TooFewPoints { needed: 2 }));
        assert_eq!(fits[1], Err(ModelFitError::TooFewPoints { needed: 2 }));
        assert_eq!(fits[2], Err(ModelFitError::TooFewPoints { needed: 3 }));
        let pts = [FitPoint::new(2.0, 20.0, 5.0), FitPoint::new(4.0, 18.0, 5.1)];
        let fits = fit_models(&pts, FitTarget::Human, DampingSign::Free);
        assert!(fits[0].is_ok() && fits[1].is_ok());
        assert_eq!(fits[2], Err(ModelFitError::TooFewPoints { needed: 3 }));
    }
}
