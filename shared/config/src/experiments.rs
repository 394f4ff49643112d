//! Table I: the experiments of the protocol and their timing.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{read_toml, Check, Range, Ranges, Result, MAX_EXPERIMENT, MAX_PERIOD};

/// The documented range of every numeric key of an experiment table (the
/// doc comment of each key says the same). Durations are at most an hour
/// each; a run's whole protocol at most a day ([`crate::MAX_DURATION_S`]).
pub const EXPERIMENT_RANGES: Ranges = &[
    ("periods", Range::closed(1.0, MAX_PERIOD as f64)),
    (
        "amplitude_boost_from_period",
        Range::closed(1.0, MAX_PERIOD as f64 + 1.0),
    ),
    ("amplitude_boost", Range::above(0.0, 10.0)),
    ("frequency_step", Range::closed(0.1, 10.0)),
    ("timing.ramp_in_s", Range::closed(0.0, 3600.0)),
    ("timing.settling_s", Range::closed(0.0, 3600.0)),
    ("timing.analysis_s", Range::closed(0.01, 3600.0)),
    ("timing.ramp_out_s", Range::closed(0.0, 3600.0)),
    ("timing.rest_s", Range::closed(0.0, 3600.0)),
    (
        "experiment[*].number",
        Range::closed(1.0, MAX_EXPERIMENT as f64),
    ),
    ("experiment[*].alpha", Range::above(0.0, 10.0)),
    ("experiment[*].load_kg", Range::closed(0.0, 50.0)),
    ("experiment[*].grip_kg", Range::closed(0.0, 100.0)),
    ("experiment[*].bias_nm", Range::closed(-100.0, 100.0)),
    ("experiment[*].amplitude_nm", Range::closed(0.0, 100.0)),
    (
        "experiment[*].start_omega_rad_s",
        Range::above(0.0, 10_000.0),
    ),
];

/// Timing of one period (section "Experimental Protocol for Modeling").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolTiming {
    /// Bias ramp-in (s); the paper: 5. Range [0, 3600].
    pub ramp_in_s: f64,
    /// First part of the sine, left for settling (s); the paper: 5. Range [0, 3600].
    pub settling_s: f64,
    /// Second part of the sine, the analysis window (s); the paper: 5.
    /// Range [0.01, 3600].
    pub analysis_s: f64,
    /// Bias ramp-out (s); the paper: 5. Range [0, 3600].
    pub ramp_out_s: f64,
    /// Rest (s); the paper: 40. Range [0, 3600].
    pub rest_s: f64,
}

impl ProtocolTiming {
    /// Length of one period (s).
    pub fn period_s(&self) -> f64 {
        self.ramp_in_s + self.settling_s + self.analysis_s + self.ramp_out_s + self.rest_s
    }
}

/// One row of Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentSpec {
    /// Experiment number, 1 to 9 (the paper's; the protocol channel carries
    /// no other), each at most once.
    pub number: u32,
    /// Constant amplification α during identification. Range (0, 10]; the
    /// paper: 1, 2, 4.
    pub alpha: f64,
    /// Load on the exoskeleton arm (kg), at the rig's load lever arm. Range [0, 50].
    pub load_kg: f64,
    /// Hand-grip force the subject holds (kg), which sets co-contraction.
    /// Range [0, 100].
    pub grip_kg: f64,
    /// Bias torque applied by the actuator (Nm). Range [−100, 100].
    pub bias_nm: f64,
    /// Sine amplitude of the first periods (Nm). Range [0, 100].
    pub amplitude_nm: f64,
    /// Sine frequency of the first period (rad/s). Range (0, 10 000]; a run
    /// also needs every period's frequency (this × `frequency_step`^(p−1))
    /// below the Nyquist frequency π·`run.rate_hz` of its run file.
    pub start_omega_rad_s: f64,
}

/// The experiment table file (`configs/experiments.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentTable {
    /// Periods per experiment (the paper: 10). Range 1 to 10 (the protocol
    /// channel carries no other).
    pub periods: u32,
    /// From this period on (1-based) the amplitude is multiplied by
    /// `amplitude_boost`. Range 1 to `periods` + 1 (the latter: never).
    pub amplitude_boost_from_period: u32,
    /// Amplitude factor (the paper: 10^0.2). Range (0, 10].
    pub amplitude_boost: f64,
    /// Frequency ratio between periods (the paper: 10^0.1). Range [0.1, 10].
    pub frequency_step: f64,
    /// Period timing.
    pub timing: ProtocolTiming,
    /// The experiments: at least one.
    pub experiment: Vec<ExperimentSpec>,
}

impl ExperimentTable {
    /// Reads and validates an experiment table.
    pub fn from_file(file: &Path) -> Result<Self> {
        let t: ExperimentTable = read_toml(file)?;
        t.validate(file)?;
        Ok(t)
    }

    /// Validates the values, naming every key at fault.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let c = Check::with_ranges(file, EXPERIMENT_RANGES);
        self.check(&c);
        c.finish()
    }

    /// Records every value out of range in `c`.
    pub(crate) fn check(&self, c: &Check<'_>) {
        c.key("periods", f64::from(self.periods));
        if c.key(
            "amplitude_boost_from_period",
            f64::from(self.amplitude_boost_from_period),
        ) && self.amplitude_boost_from_period > self.periods.saturating_add(1)
        {
            c.note(
                "amplitude_boost_from_period",
                format!(
                    "must be at most periods + 1 = {} (never boosted), got {}",
                    self.periods.saturating_add(1),
                    self.amplitude_boost_from_period
                ),
            );
        }
        c.key("amplitude_boost", self.amplitude_boost);
        c.key("frequency_step", self.frequency_step);
        let t = &self.timing;
        c.key("timing.ramp_in_s", t.ramp_in_s);
        c.key("timing.settling_s", t.settling_s);
        c.key("timing.analysis_s", t.analysis_s);
        c.key("timing.ramp_out_s", t.ramp_out_s);
        c.key("timing.rest_s", t.rest_s);
        if self.experiment.is_empty() {
            c.note("experiment", "at least one [[experiment]] is needed");
        }
        for (i, e) in self.experiment.iter().enumerate() {
            let k = |f: &str| format!("experiment[{i}].{f}");
            c.key(&k("number"), f64::from(e.number));
            c.key(&k("alpha"), e.alpha);
            c.key(&k("load_kg"), e.load_kg);
            c.key(&k("grip_kg"), e.grip_kg);
            c.key(&k("bias_nm"), e.bias_nm);
            c.key(&k("amplitude_nm"), e.amplitude_nm);
            c.key(&k("start_omega_rad_s"), e.start_omega_rad_s);
            if self.experiment[..i].iter().any(|o| o.number == e.number) {
                c.note(
                    &k("number"),
                    format!("experiment {} appears twice", e.number),
                );
            }
        }
    }

    /// The index of experiment `number` in [`ExperimentTable::experiment`].
    pub fn index_of(&self, number: u32) -> Option<usize> {
        self.experiment.iter().position(|e| e.number == number)
    }

    /// The experiment numbered `number`.
    pub fn get(&self, number: u32) -> Option<&ExperimentSpec> {
        self.experiment.iter().find(|e| e.number == number)
    }

    /// Sine frequency (rad/s) of `period` (1-based) of `e`.
    pub fn omega_rad_s(&self, e: &ExperimentSpec, period: u32) -> f64 {
        e.start_omega_rad_s * self.frequency_step.powi(period.saturating_sub(1) as i32)
    }

    /// Sine amplitude (Nm) of `period` (1-based) of `e`.
    pub fn amplitude_nm(&self, e: &ExperimentSpec, period: u32) -> f64 {
        if period >= self.amplitude_boost_from_period {
            e.amplitude_nm * self.amplitude_boost
        } else {
            e.amplitude_nm
        }
    }
}
