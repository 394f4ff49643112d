//! Table I: the experiments of the protocol and their timing.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{read_toml, Check, Result};

/// Timing of one period (section "Experimental Protocol for Modeling").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolTiming {
    /// Bias ramp-in (s); the paper: 5.
    pub ramp_in_s: f64,
    /// First part of the sine, left for settling (s); the paper: 5.
    pub settling_s: f64,
    /// Second part of the sine, the analysis window (s); the paper: 5.
    pub analysis_s: f64,
    /// Bias ramp-out (s); the paper: 5.
    pub ramp_out_s: f64,
    /// Rest (s); the paper: 40.
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
    /// Experiment number (1–9 in the paper).
    pub number: u32,
    /// Constant amplification α during identification.
    pub alpha: f64,
    /// Load on the exoskeleton arm (kg), at the rig's load lever arm.
    pub load_kg: f64,
    /// Hand-grip force the subject holds (kg), which sets co-contraction.
    pub grip_kg: f64,
    /// Bias torque applied by the actuator (Nm).
    pub bias_nm: f64,
    /// Sine amplitude of the first periods (Nm).
    pub amplitude_nm: f64,
    /// Sine frequency of the first period (rad/s).
    pub start_omega_rad_s: f64,
}

/// The experiment table file (`configs/experiments.toml`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentTable {
    /// Periods per experiment (the paper: 10).
    pub periods: u32,
    /// From this period on (1-based) the amplitude is multiplied by `amplitude_boost`.
    pub amplitude_boost_from_period: u32,
    /// Amplitude factor (the paper: 10^0.2).
    pub amplitude_boost: f64,
    /// Frequency ratio between periods (the paper: 10^0.1).
    pub frequency_step: f64,
    /// Period timing.
    pub timing: ProtocolTiming,
    /// The experiments.
    pub experiment: Vec<ExperimentSpec>,
}

impl ExperimentTable {
    /// Reads and validates an experiment table.
    pub fn from_file(file: &Path) -> Result<Self> {
        let t: ExperimentTable = read_toml(file)?;
        t.validate(file)?;
        Ok(t)
    }

    /// Validates the values, naming the key at fault.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let c = Check::new(file);
        if self.periods == 0 {
            return Err(c.fail("periods", "must be at least 1"));
        }
        c.positive("amplitude_boost", self.amplitude_boost)?;
        c.positive("frequency_step", self.frequency_step)?;
        c.non_negative("timing.ramp_in_s", self.timing.ramp_in_s)?;
        c.non_negative("timing.settling_s", self.timing.settling_s)?;
        c.positive("timing.analysis_s", self.timing.analysis_s)?;
        c.non_negative("timing.ramp_out_s", self.timing.ramp_out_s)?;
        c.non_negative("timing.rest_s", self.timing.rest_s)?;
        if self.experiment.is_empty() {
            return Err(c.fail("experiment", "at least one [[experiment]] is needed"));
        }
        for (i, e) in self.experiment.iter().enumerate() {
            let k = |f: &str| format!("experiment[{i}].{f}");
            c.positive(&k("alpha"), e.alpha)?;
            c.non_negative(&k("load_kg"), e.load_kg)?;
            c.non_negative(&k("grip_kg"), e.grip_kg)?;
            c.finite(&k("bias_nm"), e.bias_nm)?;
            c.non_negative(&k("amplitude_nm"), e.amplitude_nm)?;
            c.positive(&k("start_omega_rad_s"), e.start_omega_rad_s)?;
            if self.experiment[..i].iter().any(|o| o.number == e.number) {
                return Err(c.fail(
                    &k("number"),
                    format!("experiment {} appears twice", e.number),
                ));
            }
        }
        Ok(())
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
