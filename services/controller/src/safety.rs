//! Limits, sample validation and the latched fault state.

use exo_config::LimitSettings;

/// Why the controller is in its safe state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fault {
    /// A sample field was NaN or infinite.
    NonFiniteSample {
        /// The field.
        field: &'static str,
    },
    /// The joint angle left its allowed range.
    AngleOutOfRange {
        /// The angle (rad).
        theta_rad: f64,
    },
    /// |τ_c| exceeded the sensor's plausible range.
    InteractionTorqueOutOfRange {
        /// The torque (Nm).
        tau_c_nm: f64,
    },
    /// The sample carried a fault flag from the driver.
    SensorStatus {
        /// The flags.
        status: u32,
    },
    /// No sample arrived within the deadline.
    SampleTimeout,
    /// The sensor driver latched its safe state (the sample's `SAFE_STATE`
    /// bit): the controller follows it, so it never commands mode `Run`
    /// while the driver holds the actuator safe.
    DriverSafeState,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Fault::NonFiniteSample { field } => write!(f, "sample field {field} is not finite"),
            Fault::AngleOutOfRange { theta_rad } => {
                write!(f, "joint angle {theta_rad} rad is outside its limits")
            }
            Fault::InteractionTorqueOutOfRange { tau_c_nm } => {
                write!(
                    f,
                    "interaction torque {tau_c_nm} Nm is outside its plausible range"
                )
            }
            Fault::SensorStatus { status } => write!(f, "sensor reports fault flags {status:#x}"),
            Fault::SampleTimeout => write!(f, "no sensor sample within the deadline"),
            Fault::DriverSafeState => write!(f, "the sensor driver latched its safe state"),
        }
    }
}

/// A fault, once raised, stays until [`FaultLatch::reset`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FaultLatch {
    fault: Option<Fault>,
}

impl FaultLatch {
    /// Latches `fault` unless one is already latched (the first cause is kept).
    pub fn raise(&mut self, fault: Fault) {
        if self.fault.is_none() {
            self.fault = Some(fault);
        }
    }
    /// The latched fault.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }
    /// Whether a fault is latched.
    pub fn is_latched(&self) -> bool {
        self.fault.is_some()
    }
    /// Clears the latch (operator command).
    pub fn reset(&mut self) {
        self.fault = None;
    }
}

/// Torque and torque-rate limits applied to every command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// |τ_d| ≤ this (Nm).
    pub torque_nm: f64,
    /// |Δτ_d| ≤ this per tick (Nm).
    pub torque_step_nm: f64,
    /// Allowed θ_e (rad).
    pub theta_rad: [f64; 2],
    /// Plausible |τ_c| (Nm).
    pub tau_c_nm: f64,
}

impl Limits {
    /// Limits from the configuration at control rate `rate_hz`.
    pub fn new(s: &LimitSettings, rate_hz: f64) -> Self {
        Limits {
            torque_nm: s.torque_nm,
            torque_step_nm: s.torque_rate_nm_per_s / rate_hz,
            theta_rad: s.theta_rad,
            tau_c_nm: s.tau_c_nm,
        }
    }

    /// Clamps `tau_nm` to the torque limit and to the rate limit from `previous_nm`.
    /// A non-finite request yields the previous (finite) command.
    #[inline]
    pub fn clamp(&self, tau_nm: f64, previous_nm: f64) -> f64 {
        let tau = if tau_nm.is_finite() {
            tau_nm
        } else {
            previous_nm
        };
        let stepped = tau.clamp(
            previous_nm - self.torque_step_nm,
            previous_nm + self.torque_step_nm,
        );
        stepped.clamp(-self.torque_nm, self.torque_nm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_bounds_magnitude_and_rate_and_rejects_nan() {
        let l = Limits {
            torque_nm: 10.0,
            torque_step_nm: 1.0,
            theta_rad: [-1.0, 1.0],
            tau_c_nm: 50.0,
        };
        assert_eq!(l.clamp(5.0, 0.0), 1.0);
        assert_eq!(l.clamp(-5.0, 0.0), -1.0);
        assert_eq!(l.clamp(100.0, 9.5), 10.0);
        assert_eq!(l.clamp(f64::NAN, 3.0), 3.0);
        assert_eq!(l.clamp(f64::INFINITY, 3.0), 3.0);
    }

    #[test]
    fn latch_keeps_the_first_fault_until_reset() {
        let mut latch = FaultLatch::default();
        latch.raise(Fault::SampleTimeout);
        latch.raise(Fault::NonFiniteSample { field: "tau_c" });
        assert_eq!(latch.fault(), Some(Fault::SampleTimeout));
        latch.reset();
        assert!(!latch.is_latched());
    }
}
