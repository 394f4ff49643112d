//! A simulated subject: the human impedance per experiment (Table III).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{read_toml, Check, Result};

/// The impedance of a subject during one experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubjectExperiment {
    /// Experiment number.
    pub number: u32,
    /// Real stiffness K_h (Nm/rad).
    pub stiffness_nm_per_rad: f64,
    /// Hysteretic damping H_h (Nm/rad).
    pub hysteretic_damping_nm_per_rad: f64,
}

/// The power law a publication reported for the subject, kept beside the
/// simulated inputs so a reproduction can compare against it. Never used to
/// simulate: the per-experiment K and H are the inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportedPowerLaw {
    /// Intercept β0 of `log10 H = β0 + β1 log10 K` as printed.
    pub beta0: f64,
    /// Slope β1 as printed.
    pub beta1: f64,
    /// R² as printed.
    pub r2: f64,
    /// Where it was printed (e.g. "He et al. 2020, Table III").
    pub source: String,
}

/// A subject file (`configs/subjects/*.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Subject {
    /// Name (A–J for the paper's subjects).
    pub name: String,
    /// Forearm inertia M_h (kg·m²).
    pub inertia_kg_m2: f64,
    /// Impedance per experiment.
    pub experiment: Vec<SubjectExperiment>,
    /// The power law the source publication reported, for comparison only.
    #[serde(default)]
    pub reported_power_law: Option<ReportedPowerLaw>,
}

impl Subject {
    /// Reads and validates a subject file.
    pub fn from_file(file: &Path) -> Result<Self> {
        let s: Subject = read_toml(file)?;
        let c = Check::new(file);
        c.positive("inertia_kg_m2", s.inertia_kg_m2)?;
        for (i, e) in s.experiment.iter().enumerate() {
            c.positive(
                &format!("experiment[{i}].stiffness_nm_per_rad"),
                e.stiffness_nm_per_rad,
            )?;
            c.non_negative(
                &format!("experiment[{i}].hysteretic_damping_nm_per_rad"),
                e.hysteretic_damping_nm_per_rad,
            )?;
        }
        Ok(s)
    }

    /// The impedance during experiment `number`.
    pub fn get(&self, number: u32) -> Option<&SubjectExperiment> {
        self.experiment.iter().find(|e| e.number == number)
    }
}
