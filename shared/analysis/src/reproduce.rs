//! The comparison of `exo reproduce` (the paper's modelling study, simulated). Every subject of
//! Table III goes through the nine experiments of Table I in the real
//! processes (plant simulator, sensor driver, controller, recorder, in
//! lockstep); the recordings are fitted as `exo fit` fits them, and what the
//! fit recovers is compared with what was simulated:
//!
//! - M2's `K_h` and `H_h` per subject and experiment within 5 % of the inputs;
//! - the power law of the recovered (K, H) within 0.05 (β0 and β1) of the
//!   power law of the inputs, and that one within 0.08 and 0.06 of the row
//!   Table III prints (which is rounded to two decimals);
//! - `F_{M1−M3}` above its critical value for every subject (hysteretic
//!   damping needed);
//! - the phase-shift table within 3° of the phase of `S_h` the inputs imply
//!   at the same frequencies, `arg(K − M_h ω² + jH)`.
//!
//! The criteria are the issue's; the comparison is computed, never copied.

//! This module compares; the simulation is `exo_experiments::simulate`'s.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::error::{Error, Result};
use exo_config::{ReportedPowerLaw, Subject};
use exo_impedance::{fit_power_law, Complex64};
use serde::Serialize;

use crate::study::{group_of, FRow, FitReport};

/// The acceptance criteria of the reproduction.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Criteria {
    /// Largest relative error of M2's K_h and H_h.
    pub kh_rel: f64,
    /// Largest |Δβ0| and |Δβ1| between the recovered and the inputs' power law.
    pub beta_abs: f64,
    /// Largest |Δβ0| between the inputs' power law and the printed row.
    pub beta0_vs_reported: f64,
    /// Largest |Δβ1| between the inputs' power law and the printed row.
    pub beta1_vs_reported: f64,
    /// Largest phase-table difference (degrees).
    pub phase_deg: f64,
}

impl Default for Criteria {
    fn default() -> Self {
        Criteria {
            kh_rel: 0.05,
            beta_abs: 0.05,
            beta0_vs_reported: 0.08,
            beta1_vs_reported: 0.06,
            phase_deg: 3.0,
        }
    }
}

/// One subject-experiment: inputs against M2's fit.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentComparison {
    /// Experiment number.
    pub experiment: u32,
    /// Simulated K_h (Nm/rad).
    pub k_input: f64,
    /// Recovered K_h (Nm/rad).
    pub k_fit: f64,
    /// `(fit − input)/input`.
    pub k_rel_error: f64,
    /// Simulated H_h (Nm/rad).
    pub h_input: f64,
    /// Recovered H_h (Nm/rad).
    pub h_fit: f64,
    /// `(fit − input)/input`.
    pub h_rel_error: f64,
}

/// A power law `log10 H = β0 + β1 log10 K`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Law {
    /// Intercept.
    pub beta0: f64,
    /// Slope.
    pub beta1: f64,
    /// R² on the log scale.
    pub r2: f64,
}

/// One cell of the phase-shift table against the inputs' phase.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseComparison {
    /// Experiment group (`1-3`, `4-6`, `7-9`).
    pub experiments: String,
    /// Fitted mean phase of `S_h` (degrees).
    pub fitted_deg: f64,
    /// Its standard error (degrees).
    pub se_deg: f64,
    /// Mean of `arg(K − M_h ω² + jH)` over the same points (degrees).
    pub implied_deg: f64,
    /// `fitted − implied` (degrees).
    pub diff_deg: f64,
}

/// One subject's comparison.
#[derive(Debug, Clone, Serialize)]
pub struct SubjectComparison {
    /// Subject name.
    pub subject: String,
    /// Per experiment.
    pub experiments: Vec<ExperimentComparison>,
    /// Power law of the simulated (K, H).
    pub law_input: Law,
    /// Power law of the recovered (K, H).
    pub law_fit: Option<Law>,
    /// The row the publication printed, when the subject file has it.
    pub law_reported: Option<ReportedPowerLaw>,
    /// `F_{M1−M3}` over the subject's experiments (F^sub).
    pub f_m1_m3: Option<FRow>,
    /// The phase-shift table's row against the inputs.
    pub phase: Vec<PhaseComparison>,
}

/// The whole comparison.
#[derive(Debug, Clone, Serialize)]
pub struct Reproduction {
    /// Criteria applied.
    pub criteria: Criteria,
    /// Per subject.
    pub subjects: Vec<SubjectComparison>,
    /// Every criterion missed, in words (empty: all met).
    pub failures: Vec<String>,
    /// What the fitter could not use.
    pub warnings: Vec<String>,
    /// The recordings fitted.
    pub recordings: Vec<PathBuf>,
}

impl Reproduction {
    /// All criteria met.
    pub fn pass(&self) -> bool {
        self.failures.is_empty()
    }
}

/// `|x| ≤ limit`; false for NaN, so a missing number misses the criterion.
fn within(x: f64, limit: f64) -> bool {
    x.abs() <= limit
}

fn law(fit: exo_impedance::PowerLawFit) -> Law {
    Law {
        beta0: fit.law.beta0,
        beta1: fit.law.beta1,
        r2: fit.r2,
    }
}

/// Compares what the fit recovered with the simulated subjects, which went
/// through `experiments` (each must have been fitted).
pub fn compare(
    subjects: &[Subject],
    experiments: &[u32],
    report: &FitReport,
    c: Criteria,
) -> Result<Reproduction> {
    let mut out = Vec::new();
    let mut failures = Vec::new();
    for subject in subjects {
        let name = &subject.name;
        let Some(fitted) = report.subjects.iter().find(|s| &s.subject == name) else {
            failures.push(format!("subject {name}: no fitted data"));
            continue;
        };
        for n in experiments {
            if !fitted.experiments.iter().any(|e| e.experiment == *n) {
                failures.push(format!(
                    "subject {name} experiment {n}: simulated but not fitted (no usable data)"
                ));
            }
        }
        let mut experiments = Vec::new();
        let (mut k_in, mut h_in) = (Vec::new(), Vec::new());
        // Phase of S_h the inputs imply, over the same points the table keeps.
        let mut implied: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
        for e in &fitted.experiments {
            let Some(input) = subject.get(e.experiment) else {
                failures.push(format!(
                    "subject {name} experiment {}: not in the subject file",
                    e.experiment
                ));
                continue;
            };
            let (k, h) = (
                input.stiffness_nm_per_rad,
                input.hysteretic_damping_nm_per_rad,
            );
            k_in.push(k);
            h_in.push(h);
            let keep = e.points.len().saturating_sub(3);
            implied
                .entry(group_of(e.experiment))
                .or_default()
                .extend(e.points[..keep].iter().map(|p| {
                    Complex64::new(k - subject.inertia_kg_m2 * p.omega * p.omega, h)
                        .arg()
                        .to_degrees()
                }));
            let Some(m2) = e.models.get("M2") else {
                failures.push(format!(
                    "subject {name} experiment {}: M2 not fitted",
                    e.experiment
                ));
                continue;
            };
            let row = ExperimentComparison {
                experiment: e.experiment,
                k_input: k,
                k_fit: m2.k,
                k_rel_error: (m2.k - k) / k,
                h_input: h,
                h_fit: m2.h,
                h_rel_error: (m2.h - h) / h,
            };
            for (what, err) in [("K_h", row.k_rel_error), ("H_h", row.h_rel_error)] {
                if !within(err, c.kh_rel) {
                    failures.push(format!(
                        "subject {name} experiment {}: {what} off by {:+.1} % (limit {:.0} %)",
                        e.experiment,
                        100.0 * err,
                        100.0 * c.kh_rel
                    ));
                }
            }
            experiments.push(row);
        }
        let law_input =
            law(
                fit_power_law(&k_in, &h_in).map_err(|source| Error::InputPowerLaw {
                    subject: name.clone(),
                    source,
                })?,
            );
        let law_fit = match (fitted.beta0, fitted.beta1, fitted.r2) {
            (Some(beta0), Some(beta1), Some(r2)) => Some(Law { beta0, beta1, r2 }),
            _ => None,
        };
        match law_fit {
            Some(f) => {
                for (what, d) in [
                    ("β0", f.beta0 - law_input.beta0),
                    ("β1", f.beta1 - law_input.beta1),
                ] {
                    if !within(d, c.beta_abs) {
                        failures.push(format!(
                            "subject {name}: recovered {what} off the inputs' by {d:+.3} (limit {})",
                            c.beta_abs
                        ));
                    }
                }
            }
            None => failures.push(format!("subject {name}: no power law fitted")),
        }
        if let Some(r) = &subject.reported_power_law {
            for (what, d, limit) in [
                ("β0", law_input.beta0 - r.beta0, c.beta0_vs_reported),
                ("β1", law_input.beta1 - r.beta1, c.beta1_vs_reported),
            ] {
                if !within(d, limit) {
                    failures.push(format!(
                        "subject {name}: the inputs' {what} is {d:+.3} off the printed row (limit {limit})"
                    ));
                }
            }
        }
        let f_m1_m3 = report
            .f_tests
            .per_subject
            .iter()
            .find(|p| &p.group == name)
            .map(|p| p.m1_m3);
        match f_m1_m3 {
            Some(f) if f.statistic > f.critical => {}
            Some(f) => failures.push(format!(
                "subject {name}: F_M1−M3 = {:.2} not above its critical {:.2}",
                f.statistic, f.critical
            )),
            None => failures.push(format!("subject {name}: no F^sub test")),
        }
        let mut phase = Vec::new();
        if let Some(row) = report.phase_table.iter().find(|r| &r.subject == name) {
            for cell in &row.groups {
                let Some(v) = implied.get(&cell.group).filter(|v| !v.is_empty()) else {
                    continue;
                };
                let implied_deg = v.iter().sum::<f64>() / v.len() as f64;
                let diff = cell.mean_deg - implied_deg;
                if !within(diff, c.phase_deg) {
                    failures.push(format!(
                        "subject {name} experiments {}: phase {:.1}° against the inputs' {:.1}° (limit {}°)",
                        cell.experiments, cell.mean_deg, implied_deg, c.phase_deg
                    ));
                }
                phase.push(PhaseComparison {
                    experiments: cell.experiments.clone(),
                    fitted_deg: cell.mean_deg,
                    se_deg: cell.se_deg,
                    implied_deg,
                    diff_deg: diff,
                });
            }
        }
        out.push(SubjectComparison {
            subject: name.clone(),
            experiments,
            law_input,
            law_fit,
            law_reported: subject.reported_power_law.clone(),
            f_m1_m3,
            phase,
        });
    }
    Ok(Reproduction {
        criteria: c,
        subjects: out,
        failures,
        warnings: report.warnings.clone(),
        recordings: Vec::new(),
    })
}
