//! The (simulated) hardware bus: raw values as a real rig delivers them.
//!
//! The plant simulator publishes [`BusSensorFrame`]s and reads
//! [`BusMotorCommand`]s exactly as an EtherCAT/CAN/UDP backend would, so the
//! sensor driver's calibration (counts → rad, wrench → joint torque) is the
//! same code on hardware and in simulation.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_abs, check_finite, check_flags, MessageError};

/// Bit flags of [`BusSensorFrame::status`]; 0 means a good frame.
pub mod bus_status {
    /// The frame failed its integrity check (CRC, length, sequence).
    pub const FRAME_ERROR: u32 = 1 << 0;
    /// The joint encoder reported an error (e.g. lost signal).
    pub const ENCODER_ERROR: u32 = 1 << 1;
    /// The cuff force/torque sensor reported an error or overload.
    pub const FT_ERROR: u32 = 1 << 2;
    /// The SEA deflection encoder reported an error.
    pub const SEA_ENCODER_ERROR: u32 = 1 << 3;
    /// The motor drive reported a fault (over-current, over-temperature, disabled).
    pub const DRIVE_FAULT: u32 = 1 << 4;
    /// Not a fault of the devices: the bus sent this frame past its
    /// cycle's deadline (the simulated bus, in real time, missed a
    /// deadline before it; the EtherCAT master woke more than a period
    /// late for it). The sensor driver does not latch on it; the EtherCAT
    /// backend latches after `bus.ethercat.max_missed_cycles` missed
    /// cycles in a row; `exo run` counts and names it in its summary.
    pub const LATE: u32 = 1 << 5;
    /// Not a fault of the devices: the cycle's reply did not come back
    /// within the PDU time-out, so the frame repeats the last values
    /// received (the drive holds its last set-point meanwhile). The
    /// EtherCAT backend latches after `bus.ethercat.max_missed_cycles`
    /// missed cycles in a row.
    pub const STALE: u32 = 1 << 6;
    /// The bits that report a fault of the devices or the frame.
    pub const FAULTS: u32 =
        FRAME_ERROR | ENCODER_ERROR | FT_ERROR | SEA_ENCODER_ERROR | DRIVE_FAULT;
    /// Every bit with a meaning.
    pub const KNOWN: u32 = FAULTS | LATE | STALE;
}

/// Indices into [`BusSensorFrame::cuff_wrench`].
pub mod wrench {
    /// Force along the sensor's x axis (N).
    pub const FX: usize = 0;
    /// Force along the sensor's y axis (N).
    pub const FY: usize = 1;
    /// Force along the sensor's z axis (N).
    pub const FZ: usize = 2;
    /// Torque about the sensor's x axis (Nm).
    pub const TX: usize = 3;
    /// Torque about the sensor's y axis (Nm).
    pub const TY: usize = 4;
    /// Torque about the sensor's z axis (Nm).
    pub const TZ: usize = 5;
    /// Field names used in validation errors, by index.
    pub const FIELD_NAMES: [&str; 6] = [
        "cuff_wrench[0] (fx)",
        "cuff_wrench[1] (fy)",
        "cuff_wrench[2] (fz)",
        "cuff_wrench[3] (tx)",
        "cuff_wrench[4] (ty)",
        "cuff_wrench[5] (tz)",
    ];
}

/// One raw frame from the hardware bus: plant simulator (or rig) → sensor driver.
///
/// 88 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.BusSensorFrame.v1")
)]
#[repr(C)]
pub struct BusSensorFrame {
    /// Frame sequence number (count), one per bus cycle.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when the frame was sampled.
    pub stamp_ns: u64,
    /// Joint encoder position (counts), as read; the driver converts to rad.
    pub encoder_counts: i64,
    /// Cuff 6-axis force/torque reading in the F/T sensor frame:
    /// `[fx, fy, fz]` (N) then `[tx, ty, tz]` (Nm); index with [`wrench`].
    pub cuff_wrench: [f64; 6],
    /// SEA spring-deflection encoder (counts), as read; the driver converts to Nm.
    pub sea_deflection_counts: i64,
    /// Bus status bit flags ([`bus_status`]); 0 means a good frame.
    pub status: u32,
    /// Explicit padding to the 8-byte alignment (always 0), so the struct has no implicit padding.
    pub _pad: u32,
}

/// Limits a [`BusSensorFrame`] is checked against by
/// [`BusSensorFrame::validate`] (the F/T sensor's measuring range); the
/// default checks finiteness and status bits only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusLimits {
    /// Largest allowed |fx|, |fy|, |fz| (N).
    pub cuff_force_abs_max_n: f64,
    /// Largest allowed |tx|, |ty|, |tz| (Nm).
    pub cuff_torque_abs_max_nm: f64,
}

impl Default for BusLimits {
    fn default() -> Self {
        BusLimits {
            cuff_force_abs_max_n: f64::INFINITY,
            cuff_torque_abs_max_nm: f64::INFINITY,
        }
    }
}

impl crate::Message for BusSensorFrame {
    const TYPE_NAME: &'static str = "exo.BusSensorFrame.v1";
    const NAME: &'static str = "BusSensorFrame";
    fn first_non_finite(&self) -> Option<(&'static str, f64)> {
        crate::error::first_non_finite(core::array::from_fn::<_, 6, _>(|i| {
            (wrench::FIELD_NAMES[i], self.cuff_wrench[i])
        }))
    }
}

impl BusSensorFrame {
    /// Whether every wrench component is finite (no NaN, no ±∞).
    pub fn is_finite(&self) -> bool {
        <Self as crate::Message>::is_finite(self)
    }

    /// Checks that every wrench component is finite and within `limits` and
    /// that `status` sets only known bits; the error names the first
    /// offending field (e.g. `cuff_wrench[3] (tx)`).
    pub fn validate(&self, limits: &BusLimits) -> Result<(), MessageError> {
        const M: &str = "BusSensorFrame";
        check_finite(M, <Self as crate::Message>::first_non_finite(self))?;
        for i in 0..6 {
            let max = if i < 3 {
                limits.cuff_force_abs_max_n
            } else {
                limits.cuff_torque_abs_max_nm
            };
            check_abs(M, wrench::FIELD_NAMES[i], self.cuff_wrench[i], max)?;
        }
        check_flags(M, "status", self.status, bus_status::KNOWN)
    }
}

/// The motor torque command on the hardware bus: sensor driver → plant simulator (or rig).
///
/// 40 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.BusMotorCommand.v1")
)]
#[repr(C)]
pub struct BusMotorCommand {
    /// Command sequence number (count).
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when the command was written.
    pub stamp_ns: u64,
    /// `seq` of the [`BusSensorFrame`] this command answers.
    pub frame_seq: u64,
    /// Desired motor (SEA input) torque (Nm) at the joint.
    pub tau_motor_nm: f64,
    /// Drive enable: 1 = powered and following `tau_motor_nm`, 0 = powered down (no torque).
    pub enable: u32,
    /// Explicit padding to the 8-byte alignment (always 0), so the struct has no implicit padding.
    pub _pad: u32,
}

/// Limits a [`BusMotorCommand`] is checked against by
/// [`BusMotorCommand::validate`]; the default checks finiteness and `enable` only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorLimits {
    /// Largest allowed |τ_motor| (Nm): the drive's torque limit.
    pub tau_motor_abs_max_nm: f64,
}

impl Default for MotorLimits {
    fn default() -> Self {
        MotorLimits {
            tau_motor_abs_max_nm: f64::INFINITY,
        }
    }
}

crate::impl_message!(BusMotorCommand, "exo.BusMotorCommand.v1", |c| [
    "tau_motor_nm" => c.tau_motor_nm,
]);

impl BusMotorCommand {
    /// Whether the drive is to be enabled.
    pub fn is_enabled(&self) -> bool {
        self.enable == 1
    }

    /// Checks that the torque is finite and within `limits` and that
    /// `enable` is 0 or 1; the error names the offending field.
    pub fn validate(&self, limits: &MotorLimits) -> Result<(), MessageError> {
        const M: &str = "BusMotorCommand";
        check_finite(M, self.first_non_finite())?;
        check_abs(
            M,
            "tau_motor_nm",
            self.tau_motor_nm,
            limits.tau_motor_abs_max_nm,
        )?;
        if self.enable > 1 {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "enable",
                value: self.enable,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn sensor_frame_layout() {
        assert_eq!(size_of::<BusSensorFrame>(), 88);
        assert_eq!(align_of::<BusSensorFrame>(), 8);
        assert_eq!(offset_of!(BusSensorFrame, seq), 0);
        assert_eq!(offset_of!(BusSensorFrame, stamp_ns), 8);
        assert_eq!(offset_of!(BusSensorFrame, encoder_counts), 16);
        assert_eq!(offset_of!(BusSensorFrame, cuff_wrench), 24);
        assert_eq!(offset_of!(BusSensorFrame, sea_deflection_counts), 72);
        assert_eq!(offset_of!(BusSensorFrame, status), 80);
        assert_eq!(offset_of!(BusSensorFrame, _pad), 84);
    }

    #[test]
    fn motor_command_layout() {
        assert_eq!(size_of::<BusMotorCommand>(), 40);
        assert_eq!(align_of::<BusMotorCommand>(), 8);
        assert_eq!(offset_of!(BusMotorCommand, seq), 0);
        assert_eq!(offset_of!(BusMotorCommand, stamp_ns), 8);
        assert_eq!(offset_of!(BusMotorCommand, frame_seq), 16);
        assert_eq!(offset_of!(BusMotorCommand, tau_motor_nm), 24);
        assert_eq!(offset_of!(BusMotorCommand, enable), 32);
        assert_eq!(offset_of!(BusMotorCommand, _pad), 36);
    }

    #[test]
    fn sensor_frame_validation_names_the_wrench_component() {
        let good = BusSensorFrame {
            cuff_wrench: [1.0, -2.0, 3.0, 0.1, -0.2, 0.3],
            ..Default::default()
        };
        assert!(good.is_finite());
        assert_eq!(good.validate(&BusLimits::default()), Ok(()));
        let mut bad = good;
        bad.cuff_wrench[wrench::TX] = f64::NAN;
        assert!(!bad.is_finite());
        let e = bad.validate(&BusLimits::default()).unwrap_err();
        assert_eq!(e.field(), "cuff_wrench[3] (tx)");
        assert!(e.to_string().contains("BusSensorFrame.cuff_wrench[3] (tx)"));
        let limits = BusLimits {
            cuff_force_abs_max_n: 2.5,
            cuff_torque_abs_max_nm: 10.0,
        };
        assert_eq!(
            good.validate(&limits).unwrap_err().field(),
            "cuff_wrench[2] (fz)"
        );
        let flagged = BusSensorFrame {
            status: bus_status::FT_ERROR | 1 << 31,
            ..good
        };
        assert_eq!(
            flagged.validate(&BusLimits::default()).unwrap_err().field(),
            "status"
        );
    }

    #[test]
    fn motor_command_validation() {
        let good = BusMotorCommand {
            tau_motor_nm: 3.0,
            enable: 1,
            ..Default::default()
        };
        assert!(good.is_enabled());
        assert_eq!(good.validate(&MotorLimits::default()), Ok(()));
        let bad = BusMotorCommand {
            tau_motor_nm: f64::INFINITY,
            ..good
        };
        assert_eq!(
            bad.validate(&MotorLimits::default()).unwrap_err().field(),
            "tau_motor_nm"
        );
        let limits = MotorLimits {
            tau_motor_abs_max_nm: 2.0,
        };
        assert_eq!(good.validate(&limits).unwrap_err().field(), "tau_motor_nm");
        let bad = BusMotorCommand { enable: 2, ..good };
        assert_eq!(
            bad.validate(&MotorLimits::default()).unwrap_err().field(),
            "enable"
        );
    }
}
