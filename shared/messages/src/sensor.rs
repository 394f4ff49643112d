//! The calibrated sensor sample: sensor driver → controller, identifier, recorder.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_abs, check_finite, check_flags, check_range, MessageError};

/// Bit flags of [`SensorSample::status`]. Bits 0–4 are the sensor driver's
/// own flags (same numbers as in `exo-sensor-driver`); bits above
/// [`KNOWN`](status::KNOWN) are reserved and rejected by
/// [`SensorSample::validate`].
pub mod status {
    /// The joint encoder reading was invalid; `theta_e`/`omega_e` repeat the last good value.
    pub const ENCODER_FAULT: u32 = 1 << 0;
    /// The cuff force/torque reading was NaN, infinite or flagged; `tau_c` repeats the last good value.
    pub const FT_FAULT: u32 = 1 << 1;
    /// The SEA deflection reading was invalid; `tau_s` repeats the last good value.
    pub const SEA_FAULT: u32 = 1 << 2;
    /// The hardware bus flagged the frame (see `BusSensorFrame::status`).
    pub const BUS_FAULT: u32 = 1 << 3;
    /// The sensor driver is in its latched safe state (actuator held safe, no commands applied).
    pub const SAFE_STATE: u32 = 1 << 4;
    /// No new bus frame arrived in time: the sample repeats the previous one with a new stamp.
    pub const STALE: u32 = 1 << 5;
    /// A reading hit its sensor's measuring range (e.g. F/T overload); the value is clipped.
    pub const SATURATED: u32 = 1 << 6;
    /// The sample was replayed from a recording, not measured.
    pub const REPLAY: u32 = 1 << 7;
    /// Bus frames just before this one never reached the driver (it fell
    /// behind and its bus buffer overflowed): the gap in `seq` before this
    /// sample is the control path's, not a loss of whoever records it.
    pub const FRAMES_SKIPPED: u32 = 1 << 8;
    /// The bus frame behind this sample was late (`bus_status::LATE`: the
    /// bus or its master missed the cycle's deadline before it). Counted,
    /// not acted on; the bus decides how many in a row it tolerates.
    pub const LATE: u32 = 1 << 9;
    /// Bits that mean "do not act on this sample" (the driver's own mask). [`STALE`]
    /// is not among them: how many stale samples in a row to tolerate is the
    /// consumer's decision.
    pub const FAULT_MASK: u32 = ENCODER_FAULT | FT_FAULT | SEA_FAULT | BUS_FAULT;
    /// Every bit with a meaning.
    pub const KNOWN: u32 = ENCODER_FAULT
        | FT_FAULT
        | SEA_FAULT
        | BUS_FAULT
        | SAFE_STATE
        | STALE
        | SATURATED
        | REPLAY
        | FRAMES_SKIPPED
        | LATE;
}

/// A calibrated sensor sample, one per control tick.
///
/// Recording contract: field names and order are fixed; 56 bytes, 8-aligned,
/// no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.SensorSample.v1")
)]
#[repr(C)]
pub struct SensorSample {
    /// Sequence number (count), incremented by one per control tick; a gap means lost samples.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock (`CLOCK_MONOTONIC`), taken when the bus frame arrived.
    pub stamp_ns: u64,
    /// Exoskeleton joint angle θ_e (rad), 0 with the arm hanging down.
    pub theta_e: f64,
    /// Exoskeleton joint angular velocity ω_e (rad/s), filtered derivative of `theta_e`.
    pub omega_e: f64,
    /// Human–cuff interaction torque τ_c (Nm) about the joint axis: the torque the cuff applies to the human.
    pub tau_c: f64,
    /// Series-elastic-actuator spring torque τ_s (Nm): spring stiffness × deflection.
    pub tau_s: f64,
    /// Status bit flags ([`status`]); 0 means a good, live sample.
    pub status: u32,
    /// Explicit padding to the 8-byte alignment (always 0), so the struct has no implicit padding.
    pub _pad: u32,
}

/// Limits a [`SensorSample`] is checked against by [`SensorSample::validate`].
/// The default is unbounded: only finiteness and status bits are checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorLimits {
    /// Allowed joint angle range `[min, max]` (rad).
    pub theta_e_rad: [f64; 2],
    /// Largest allowed |ω_e| (rad/s).
    pub omega_e_abs_max_rad_s: f64,
    /// Largest allowed |τ_c| (Nm).
    pub tau_c_abs_max_nm: f64,
    /// Largest allowed |τ_s| (Nm).
    pub tau_s_abs_max_nm: f64,
}

impl Default for SensorLimits {
    fn default() -> Self {
        SensorLimits {
            theta_e_rad: [f64::NEG_INFINITY, f64::INFINITY],
            omega_e_abs_max_rad_s: f64::INFINITY,
            tau_c_abs_max_nm: f64::INFINITY,
            tau_s_abs_max_nm: f64::INFINITY,
        }
    }
}

crate::impl_message!(SensorSample, "exo.SensorSample.v1", |s| [
    "theta_e" => s.theta_e,
    "omega_e" => s.omega_e,
    "tau_c" => s.tau_c,
    "tau_s" => s.tau_s,
]);

impl SensorSample {
    /// Whether any bit of [`status::FAULT_MASK`] is set (do not act on this sample).
    pub fn has_fault(&self) -> bool {
        self.status & status::FAULT_MASK != 0
    }

    /// Checks that every physical field is finite and within `limits` and
    /// that `status` sets only known bits; the error names the first
    /// offending field.
    pub fn validate(&self, limits: &SensorLimits) -> Result<(), MessageError> {
        const M: &str = "SensorSample";
        check_finite(M, self.first_non_finite())?;
        check_range(
            M,
            "theta_e",
            self.theta_e,
            limits.theta_e_rad[0],
            limits.theta_e_rad[1],
        )?;
        check_abs(M, "omega_e", self.omega_e, limits.omega_e_abs_max_rad_s)?;
        check_abs(M, "tau_c", self.tau_c, limits.tau_c_abs_max_nm)?;
        check_abs(M, "tau_s", self.tau_s, limits.tau_s_abs_max_nm)?;
        check_flags(M, "status", self.status, status::KNOWN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn layout() {
        assert_eq!(size_of::<SensorSample>(), 56);
        assert_eq!(align_of::<SensorSample>(), 8);
        assert_eq!(offset_of!(SensorSample, seq), 0);
        assert_eq!(offset_of!(SensorSample, stamp_ns), 8);
        assert_eq!(offset_of!(SensorSample, theta_e), 16);
        assert_eq!(offset_of!(SensorSample, omega_e), 24);
        assert_eq!(offset_of!(SensorSample, tau_c), 32);
        assert_eq!(offset_of!(SensorSample, tau_s), 40);
        assert_eq!(offset_of!(SensorSample, status), 48);
        assert_eq!(offset_of!(SensorSample, _pad), 52);
    }

    #[test]
    fn status_bits_are_distinct_and_match_the_driver() {
        let all = [
            status::ENCODER_FAULT,
            status::FT_FAULT,
            status::SEA_FAULT,
            status::BUS_FAULT,
            status::SAFE_STATE,
            status::STALE,
            status::SATURATED,
            status::REPLAY,
            status::FRAMES_SKIPPED,
            status::LATE,
        ];
        let mut seen = 0u32;
        for b in all {
            assert_eq!(b.count_ones(), 1);
            assert_eq!(seen & b, 0);
            seen |= b;
        }
        assert_eq!(seen, status::KNOWN);
        // The numbers the sensor driver already uses.
        assert_eq!(
            (
                status::ENCODER_FAULT,
                status::FT_FAULT,
                status::SEA_FAULT,
                status::BUS_FAULT,
                status::SAFE_STATE
            ),
            (1, 2, 4, 8, 16)
        );
    }

    #[test]
    fn validate_names_the_offending_field() {
        let good = SensorSample {
            theta_e: 0.5,
            tau_c: 1.0,
            ..Default::default()
        };
        assert!(good.is_finite());
        assert_eq!(good.validate(&SensorLimits::default()), Ok(()));

        for (field, bad) in [
            (
                "theta_e",
                SensorSample {
                    theta_e: f64::NAN,
                    ..good
                },
            ),
            (
                "omega_e",
                SensorSample {
                    omega_e: f64::INFINITY,
                    ..good
                },
            ),
            (
                "tau_c",
                SensorSample {
                    tau_c: f64::NEG_INFINITY,
                    ..good
                },
            ),
            (
                "tau_s",
                SensorSample {
                    tau_s: f64::NAN,
                    ..good
                },
            ),
        ] {
            assert!(!bad.is_finite());
            let e = bad.validate(&SensorLimits::default()).unwrap_err();
            assert!(matches!(e, MessageError::NonFinite { .. }), "{e}");
            assert_eq!(e.field(), field);
            assert_eq!(e.message(), "SensorSample");
            assert!(e.to_string().contains(field), "{e}");
        }

        let limits = SensorLimits {
            tau_c_abs_max_nm: 0.5,
            ..Default::default()
        };
        let e = good.validate(&limits).unwrap_err();
        assert_eq!(e.field(), "tau_c");
        assert!(matches!(e, MessageError::OutOfRange { .. }));

        let limits = SensorLimits {
            theta_e_rad: [0.6, 2.0],
            ..Default::default()
        };
        assert_eq!(good.validate(&limits).unwrap_err().field(), "theta_e");

        let flagged = SensorSample {
            status: 1 << 20,
            ..good
        };
        assert_eq!(
            flagged.validate(&SensorLimits::default()),
            Err(MessageError::UnknownFlags {
                message: "SensorSample",
                field: "status",
                value: 1 << 20,
                unknown: 1 << 20
            })
        );
        assert!(SensorSample {
            status: status::FT_FAULT,
            ..good
        }
        .has_fault());
        assert!(!SensorSample {
            status: status::STALE,
            ..good
        }
        .has_fault());
        assert!(!SensorSample {
            status: status::REPLAY,
            ..good
        }
        .has_fault());
    }
}
