//! Physical plausibility of a fitted human joint: what a fit may return
//! that no passive joint of that kind can have, said in words instead of
//! printed silently.
//!
//! - `H < 0` or `B < 0`: a joint that *makes* energy over a cycle. A passive
//!   model cannot; a stretch reflex's delayed torque, or a sensor delay,
//!   shows up as negative damping in a model that lacks it.
//! - `M_h` outside the range plausible for the joint ([`Joint`]), e.g. an
//!   inertia of the exoskeleton counted as the human's.
//! - A residual far beyond the measured noise (weighted fits only): the
//!   model leaves out something the data show.

use serde::Serialize;

use crate::fit::ModelFit;

/// Which joint the data are of: sets the plausible human inertia.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Joint {
    /// Forearm and hand about the elbow.
    Elbow,
    /// Foot about the ankle.
    Ankle,
    /// Shank and foot about the knee.
    Knee,
    /// Hand about the wrist.
    Wrist,
    /// Not said: only a negative inertia is flagged.
    #[default]
    Unspecified,
}

impl Joint {
    /// Plausible human inertia about the joint (kg·m²), `[min, max]`.
    ///
    /// Segment inertias from anthropometric tables (Winter, *Biomechanics and
    /// Motor Control of Human Movement*, 4th ed., table 4.1: segment mass
    /// fraction and radius of gyration about the proximal joint) for body
    /// masses of 45–120 kg, widened by half on each side for hand-held
    /// grips, shoes and cuffs that move with the segment:
    /// forearm + hand 0.04–0.13, foot 0.01–0.04, shank + foot 0.25–0.7,
    /// hand 0.001–0.004 kg·m².
    pub fn inertia_range_kg_m2(self) -> [f64; 2] {
        match self {
            Joint::Elbow => [0.02, 0.4],
            Joint::Ankle => [0.003, 0.12],
            Joint::Knee => [0.1, 1.5],
            Joint::Wrist => [0.0003, 0.02],
            Joint::Unspecified => [0.0, f64::INFINITY],
        }
    }

    /// Parses `elbow`, `ankle`, `knee`, `wrist` or `unspecified`.
    pub fn parse(s: &str) -> Option<Joint> {
        Some(match s.trim().to_ascii_lowercase().as_str() {
            "elbow" => Joint::Elbow,
            "ankle" => Joint::Ankle,
            "knee" => Joint::Knee,
            "wrist" => Joint::Wrist,
            "unspecified" | "" => Joint::Unspecified,
            _ => return None,
        })
    }

    /// The name as [`Joint::parse`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            Joint::Elbow => "elbow",
            Joint::Ankle => "ankle",
            Joint::Knee => "knee",
            Joint::Wrist => "wrist",
            Joint::Unspecified => "unspecified",
        }
    }
}

/// Below this probability of the residual under noise alone a fit is
/// reported as leaving structure (one in a thousand).
pub const MISFIT_P_VALUE: f64 = 1e-3;

/// One finding about a fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Implausibility {
    /// `H < 0` (Nm/rad), with its 95 % half-width when known.
    NegativeHystereticDamping {
        /// The estimate.
        h_nm_per_rad: f64,
        /// Its 95 % half-width (0 when unknown).
        ci95: f64,
    },
    /// `B < 0` (Nm·s/rad).
    NegativeViscousDamping {
        /// The estimate.
        b_nm_s_per_rad: f64,
        /// Its 95 % half-width (0 when unknown).
        ci95: f64,
    },
    /// `M_h` outside the joint's plausible range (kg·m²).
    InertiaOutOfRange {
        /// The estimate.
        m_kg_m2: f64,
        /// Its 95 % half-width (0 when unknown).
        ci95: f64,
        /// The joint.
        joint: Joint,
    },
    /// A weighted fit's residual far beyond the measured noise.
    MisfitBeyondNoise {
        /// `χ²/dof`.
        reduced_chi2: f64,
        /// `P(χ²_dof > χ²)`.
        p_value: f64,
    },
}

impl Implausibility {
    /// Whether the estimate is beyond its 95 % interval of the plausible set
    /// (for the misfit, always: it is a test).
    pub fn significant(&self) -> bool {
        match *self {
            Implausibility::NegativeHystereticDamping { h_nm_per_rad, ci95 } => {
                h_nm_per_rad + ci95 < 0.0
            }
            Implausibility::NegativeViscousDamping {
                b_nm_s_per_rad,
                ci95,
            } => b_nm_s_per_rad + ci95 < 0.0,
            Implausibility::InertiaOutOfRange {
                m_kg_m2,
                ci95,
                joint,
            } => {
                let [lo, hi] = joint.inertia_range_kg_m2();
                m_kg_m2 + ci95 < lo || m_kg_m2 - ci95 > hi
            }
            Implausibility::MisfitBeyondNoise { .. } => true,
        }
    }
}

impl std::fmt::Display for Implausibility {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let beyond = match (self.significant(), self) {
            (true, _) => "beyond its 95 % interval",
            (false, Implausibility::InertiaOutOfRange { .. }) => "within its 95 % interval",
            (false, _) => "though within its 95 % interval of zero",
        };
        match *self {
            Implausibility::NegativeHystereticDamping { h_nm_per_rad, ci95 } => write!(
                f,
                "H = {h_nm_per_rad:.3} ± {ci95:.3} Nm/rad is negative ({beyond}): an active joint that makes energy each cycle; likely a phase lag the model lacks (a stretch reflex or a sensor delay; see `exo diagnose`), or use --nonneg-damping"
            ),
            Implausibility::NegativeViscousDamping {
                b_nm_s_per_rad,
                ci95,
            } => write!(
                f,
                "B = {b_nm_s_per_rad:.4} ± {ci95:.4} Nm·s/rad is negative ({beyond}): an active joint; likely a delay or reflex the model lacks (see `exo diagnose`), or use --nonneg-damping"
            ),
            Implausibility::InertiaOutOfRange {
                m_kg_m2,
                ci95,
                joint,
            } => {
                let [lo, hi] = joint.inertia_range_kg_m2();
                if joint == Joint::Unspecified {
                    write!(
                        f,
                        "M_h = {m_kg_m2:.4} ± {ci95:.4} kg·m² is negative ({beyond}): no body segment has that; an inertia counted twice (α or M_e wrong?) or a resonance the model lacks"
                    )
                } else {
                    write!(
                        f,
                        "M_h = {m_kg_m2:.4} ± {ci95:.4} kg·m² is outside {lo}–{hi} kg·m², plausible for a human {} ({beyond}): the exoskeleton's inertia counted as the human's (α, load or M_e wrong?), or a cuff/strap compliance the model lacks",
                        joint.name()
                    )
                }
            }
            Implausibility::MisfitBeyondNoise {
                reduced_chi2,
                p_value,
            } => write!(
                f,
                "the residual is {:.1}× the measured noise (χ²/dof = {reduced_chi2:.2}, p = {p_value:.1e}): the model leaves out something the data show (see `exo diagnose`)",
                reduced_chi2.sqrt()
            ),
        }
    }
}

/// Every finding about `fit` for a human `joint`.
pub fn check_fit(fit: &ModelFit, joint: Joint) -> Vec<Implausibility> {
    let ci = fit.ci95.unwrap_or_default();
    let p = fit.params;
    let mut out = Vec::new();
    if p.h_nm_per_rad < 0.0 {
        out.push(Implausibility::NegativeHystereticDamping {
            h_nm_per_rad: p.h_nm_per_rad,
            ci95: ci.h_nm_per_rad,
        });
    }
    if p.b_nm_s_per_rad < 0.0 {
        out.push(Implausibility::NegativeViscousDamping {
            b_nm_s_per_rad: p.b_nm_s_per_rad,
            ci95: ci.b_nm_s_per_rad,
        });
    }
    let [lo, hi] = joint.inertia_range_kg_m2();
    if !(lo..=hi).contains(&p.m_kg_m2) {
        out.push(Implausibility::InertiaOutOfRange {
            m_kg_m2: p.m_kg_m2,
            ci95: ci.m_kg_m2,
            joint,
        });
    }
    if let (Some(rc), Some(pv)) = (fit.reduced_chi2, fit.misfit_p_value) {
        if pv < MISFIT_P_VALUE {
            out.push(Implausibility::MisfitBeyondNoise {
                reduced_chi2: rc,
                p_value: pv,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{fit_model, FitTarget, FrfPoint};
    use crate::models::{DynamicStiffness, ImpedanceModel};

    fn fit_of(truth: DynamicStiffness, sigma: f64, wobble: f64) -> ModelFit {
        let pts: Vec<FrfPoint> = (0..10)
            .map(|i| {
                let w = 2.0 * 10f64.powf(0.1 * i as f64);
                // A deterministic ±wobble pattern standing in for noise.
                let d = wobble * if i % 2 == 0 { 1.0 } else { -1.0 };
                let v = truth.response(w);
                FrfPoint::new(w, v.re + d, v.im - d).with_std_dev(sigma)
            })
            .collect();
        fit_model(ImpedanceModel::M3, &pts, FitTarget::Human).unwrap()
    }

    #[test]
    fn a_passive_elbow_has_no_finding() {
        let f = fit_of(
            DynamicStiffness::from_array([0.12, 0.2, 30.0, 9.0]),
            0.3,
            0.2,
        );
        assert!(
            check_fit(&f, Joint::Elbow).is_empty(),
            "{:?}",
            check_fit(&f, Joint::Elbow)
        );
    }

    #[test]
    fn negative_damping_and_a_heavy_elbow_are_named() {
        let f = fit_of(
            DynamicStiffness::from_array([0.9, -0.5, 30.0, -6.0]),
            0.3,
            0.2,
        );
        let found = check_fit(&f, Joint::Elbow);
        let text: Vec<String> = found.iter().map(|x| x.to_string()).collect();
        assert!(found.iter().all(Implausibility::significant), "{text:?}");
        assert_eq!(found.len(), 3, "{text:?}");
        assert!(text[0].starts_with("H = -6.0"), "{}", text[0]);
        assert!(text[1].starts_with("B = -0.49"), "{}", text[1]);
        assert!(text[2].contains("outside 0.02–0.4"), "{}", text[2]);
        // Unspecified joint: 0.9 kg·m² is not flagged, a negative one is.
        assert_eq!(check_fit(&f, Joint::Unspecified).len(), 2);
    }

    #[test]
    fn a_residual_far_beyond_the_noise_is_a_misfit() {
        // Residuals of ±2 against a stated noise of 0.1.
        let f = fit_of(
            DynamicStiffness::from_array([0.12, 0.0, 30.0, 9.0]),
            0.1,
            2.0,
        );
        let found = check_fit(&f, Joint::Elbow);
        assert!(
            found
                .iter()
                .any(|x| matches!(x, Implausibility::MisfitBeyondNoise { reduced_chi2, .. } if *reduced_chi2 > 100.0)),
            "{found:?}"
        );
        // Same residuals with a noise that explains them: no misfit.
        let f = fit_of(
            DynamicStiffness::from_array([0.12, 0.0, 30.0, 9.0]),
            3.0,
            2.0,
        );
        assert!(!check_fit(&f, Joint::Elbow)
            .iter()
            .any(|x| matches!(x, Implausibility::MisfitBeyondNoise { .. })));
    }

    #[test]
    fn a_negative_estimate_within_its_interval_is_said_so() {
        let x = Implausibility::NegativeHystereticDamping {
            h_nm_per_rad: -0.5,
            ci95: 2.0,
        };
        assert!(!x.significant());
        assert!(x.to_string().contains("within its 95 % interval"), "{x}");
    }

    #[test]
    fn significance_is_beyond_the_interval_strictly() {
        let h =
            |h_nm_per_rad, ci95| Implausibility::NegativeHystereticDamping { h_nm_per_rad, ci95 };
        let b = |b_nm_s_per_rad, ci95| Implausibility::NegativeViscousDamping {
            b_nm_s_per_rad,
            ci95,
        };
        // −0.5 ± 0.5 reaches zero: not beyond; ± 0.4 is.
        assert!(!h(-0.5, 0.5).significant() && h(-0.5, 0.4).significant());
        assert!(!b(-0.5, 0.5).significant() && b(-0.5, 0.4).significant());
        assert!(!b(-0.5, 0.6).significant());
        let m = |m_kg_m2, ci95| Implausibility::InertiaOutOfRange {
            m_kg_m2,
            ci95,
            joint: Joint::Elbow,
        };
        // Elbow: 0.02–0.4 kg·m².
        assert!(m(0.01, 0.005).significant() && !m(0.01, 0.02).significant());
        assert!(!m(0.015, 0.005).significant(), "reaches 0.02 exactly");
        assert!(m(0.5, 0.05).significant() && !m(0.5, 0.2).significant());
        assert!(!m(0.5, 0.1).significant(), "reaches 0.4 exactly");
    }

    #[test]
    fn a_term_the_model_lacks_is_not_a_negative_one() {
        // M1 has H = 0 and M2 has B = 0 exactly: neither is "negative".
        let truth = DynamicStiffness::from_array([0.12, 0.0, 30.0, 9.0]);
        let pts: Vec<FrfPoint> = (0..10)
            .map(|i| {
                let w = 2.0 * 10f64.powf(0.1 * i as f64);
                let v = truth.response(w);
                FrfPoint::new(w, v.re, v.im + if i % 2 == 0 { 0.1 } else { -0.1 })
            })
            .collect();
        for model in [ImpedanceModel::M1, ImpedanceModel::M2] {
            let f = fit_model(model, &pts, FitTarget::Human).unwrap();
            let found = check_fit(&f, Joint::Elbow);
            assert!(
                !found.iter().any(|x| matches!(
                    x,
                    Implausibility::NegativeHystereticDamping { .. }
                        | Implausibility::NegativeViscousDamping { .. }
                )),
                "{model}: {found:?}"
            );
        }
        // An elbow at exactly the range's ends is plausible.
        for m in [0.02, 0.4] {
            let mut f = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap();
            f.params.m_kg_m2 = m;
            assert!(check_fit(&f, Joint::Elbow).is_empty(), "{m}");
        }
    }

    #[test]
    fn joints_parse_by_name() {
        for j in [
            Joint::Elbow,
            Joint::Ankle,
            Joint::Knee,
            Joint::Wrist,
            Joint::Unspecified,
        ] {
            assert_eq!(Joint::parse(j.name()), Some(j));
            let [lo, hi] = j.inertia_range_kg_m2();
            assert!(lo < hi);
        }
        assert_eq!(Joint::parse("hip?"), None);
    }
}
