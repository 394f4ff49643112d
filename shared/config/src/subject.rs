//! A simulated subject: the human impedance per experiment (Table III).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{check_name, read_toml, Check, Range, Ranges, Result, MAX_EXPERIMENT};

/// The documented range of every numeric key of a subject file (the doc
/// comment of each key says the same).
pub const SUBJECT_RANGES: Ranges = &[
    ("inertia_kg_m2", Range::closed(0.001, 10.0)),
    (
        "experiment[*].number",
        Range::closed(1.0, MAX_EXPERIMENT as f64),
    ),
    (
        "experiment[*].stiffness_nm_per_rad",
        Range::above(0.0, 5000.0),
    ),
    (
        "experiment[*].hysteretic_damping_nm_per_rad",
        Range::closed(0.0, 5000.0),
    ),
    ("reported_power_law.beta0", Range::closed(-10.0, 10.0)),
    ("reported_power_law.beta1", Range::closed(-10.0, 10.0)),
    ("reported_power_law.r2", Range::closed(0.0, 1.0)),
];

/// The impedance of a subject during one experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubjectExperiment {
    /// Experiment number, 1 to 9, each at most once.
    pub number: u32,
    /// Real stiffness K_h (Nm/rad). Range (0, 5000].
    pub stiffness_nm_per_rad: f64,
    /// Hysteretic damping H_h (Nm/rad). Range [0, 5000].
    pub hysteretic_damping_nm_per_rad: f64,
}

/// The power law a publication reported for the subject, kept beside the
/// simulated inputs so a reproduction can compare against it. Never used to
/// simulate: the per-experiment K and H are the inputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportedPowerLaw {
    /// Intercept β0 of `log10 H = β0 + β1 log10 K` as printed. Range [−10, 10].
    pub beta0: f64,
    /// Slope β1 as printed. Range [−10, 10].
    pub beta1: f64,
    /// R² as printed. Range [0, 1].
    pub r2: f64,
    /// Where it was printed (e.g. "He et al. 2020, Table III").
    pub source: String,
}

/// A subject file (`configs/subjects/*.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Subject {
    /// Name (A–J for the paper's subjects); it becomes part of recording
    /// file names, so: 1 to 64 characters, no path separator (`/`, `\`),
    /// no `..`, no control character, not starting with `.` or `-`.
    pub name: String,
    /// Forearm inertia M_h (kg·m²). Range [0.001, 10].
    pub inertia_kg_m2: f64,
    /// Impedance per experiment: at least one.
    pub experiment: Vec<SubjectExperiment>,
    /// The power law the source publication reported, for comparison only.
    #[serde(default)]
    pub reported_power_law: Option<ReportedPowerLaw>,
}

impl Subject {
    /// Reads and validates a subject file, naming every key at fault.
    pub fn from_file(file: &Path) -> Result<Self> {
        let s: Subject = read_toml(file)?;
        s.validate(file)?;
        Ok(s)
    }

    /// Validates the values, naming every key at fault.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let c = Check::with_ranges(file, SUBJECT_RANGES);
        if let Err(why) = check_name(&self.name) {
            c.note("name", why);
        }
        c.key("inertia_kg_m2", self.inertia_kg_m2);
        if self.experiment.is_empty() {
            c.note("experiment", "at least one [[experiment]] is needed");
        }
        for (i, e) in self.experiment.iter().enumerate() {
            let k = |f: &str| format!("experiment[{i}].{f}");
            c.key(&k("number"), f64::from(e.number));
            c.key(&k("stiffness_nm_per_rad"), e.stiffness_nm_per_rad);
            c.key(
                &k("hysteretic_damping_nm_per_rad"),
                e.hysteretic_damping_nm_per_rad,
            );
            if self.experiment[..i].iter().any(|o| o.number == e.number) {
                c.note(
                    &k("number"),
                    format!("experiment {} appears twice", e.number),
                );
            }
        }
        if let Some(law) = &self.reported_power_law {
            c.key("reported_power_law.beta0", law.beta0);
            c.key("reported_power_law.beta1", law.beta1);
            c.key("reported_power_law.r2", law.r2);
        }
        c.finish()
    }

    /// The impedance during experiment `number`.
    pub fn get(&self, number: u32) -> Option<&SubjectExperiment> {
        self.experiment.iter().find(|e| e.number == number)
    }
}
