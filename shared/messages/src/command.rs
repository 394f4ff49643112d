//! The controller's command: controller → sensor driver, identifier, recorder.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_abs, check_finite, MessageError};

/// What the controller is doing; [`ActuatorCommand::mode`] as a `u32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum ControlMode {
    /// Not yet running: no sample answered yet, zero torque.
    Idle = 0,
    /// Normal operation: gravity compensation, amplification, bias and excitation.
    Run = 1,
    /// Safe state after a latched fault: gravity compensation only.
    SafeGravityOnly = 2,
    /// Safe state after a latched fault: zero torque.
    SafeZeroTorque = 3,
    /// A fault is latched and the actuator is to be disabled; only an operator
    /// reset (`OperatorCommandKind::ResetFault`) leaves this mode.
    FaultLatched = 4,
    /// Protocol finished: gravity compensation only, no amplification.
    Done = 5,
}

impl ControlMode {
    /// Every mode, in code order.
    pub const ALL: [ControlMode; 6] = [
        ControlMode::Idle,
        ControlMode::Run,
        ControlMode::SafeGravityOnly,
        ControlMode::SafeZeroTorque,
        ControlMode::FaultLatched,
        ControlMode::Done,
    ];

    /// The mode of a raw code, or `None` for a code without meaning.
    pub fn from_u32(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// The raw code sent in [`ActuatorCommand::mode`].
    pub fn as_u32(self) -> u32 {
        self as u32
    }

    /// Short name, e.g. `"SafeGravityOnly"`.
    pub fn name(self) -> &'static str {
        match self {
            ControlMode::Idle => "Idle",
            ControlMode::Run => "Run",
            ControlMode::SafeGravityOnly => "SafeGravityOnly",
            ControlMode::SafeZeroTorque => "SafeZeroTorque",
            ControlMode::FaultLatched => "FaultLatched",
            ControlMode::Done => "Done",
        }
    }

    /// Whether the mode is one of the latched safe states.
    pub fn is_safe_state(self) -> bool {
        matches!(
            self,
            ControlMode::SafeGravityOnly | ControlMode::SafeZeroTorque | ControlMode::FaultLatched
        )
    }
}

impl TryFrom<u32> for ControlMode {
    type Error = u32;
    /// The mode of a raw code; the code itself as the error.
    fn try_from(code: u32) -> Result<Self, u32> {
        ControlMode::from_u32(code).ok_or(code)
    }
}

impl From<ControlMode> for u32 {
    fn from(m: ControlMode) -> u32 {
        m.as_u32()
    }
}

/// The controller's answer to one [`SensorSample`](crate::SensorSample).
///
/// `tau_d` is the torque after the torque and rate limits; the five parts are
/// the unclamped contributions, so `tau_gravity + tau_amplification +
/// tau_bias + tau_excitation` equals `tau_d` only when no limit was active.
///
/// Recording contract: field names and order are fixed; 72 bytes, 8-aligned,
/// no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.ActuatorCommand.v1")
)]
#[repr(C)]
pub struct ActuatorCommand {
    /// Sequence number (count) of this command, one per answered sample.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock, taken when the command was computed.
    pub stamp_ns: u64,
    /// `seq` of the `SensorSample` this command answers (latency and loss accounting).
    pub sensor_seq: u64,
    /// Desired actuator (SEA) torque τ_d (Nm), after the torque and rate limits: what is applied.
    pub tau_d: f64,
    /// Gravity-compensation part of τ_d (Nm): arm and load weight about the joint.
    pub tau_gravity: f64,
    /// Amplification part of τ_d (Nm): `−(α(s) − 1) τ_c`, the controller's output on the cuff torque.
    pub tau_amplification: f64,
    /// Bias-torque part of τ_d (Nm): the protocol's constant bias, ramped in and out.
    pub tau_bias: f64,
    /// Excitation part of τ_d (Nm): the protocol's identification sine (or broadband signal).
    pub tau_excitation: f64,
    /// [`ControlMode`] code (`ControlMode::as_u32`).
    pub mode: u32,
    /// Explicit padding to the 8-byte alignment (always 0), so the struct has no implicit padding.
    pub _pad: u32,
}

/// Limits an [`ActuatorCommand`] is checked against by
/// [`ActuatorCommand::validate`]; the default checks finiteness and the mode only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandLimits {
    /// Largest allowed |τ_d| (Nm): the actuator's torque limit.
    pub tau_d_abs_max_nm: f64,
}

impl Default for CommandLimits {
    fn default() -> Self {
        CommandLimits {
            tau_d_abs_max_nm: f64::INFINITY,
        }
    }
}

crate::impl_message!(ActuatorCommand, "exo.ActuatorCommand.v1", |c| [
    "tau_d" => c.tau_d,
    "tau_gravity" => c.tau_gravity,
    "tau_amplification" => c.tau_amplification,
    "tau_bias" => c.tau_bias,
    "tau_excitation" => c.tau_excitation,
]);

impl ActuatorCommand {
    /// The control mode, or `None` if `mode` holds an unknown code.
    pub fn control_mode(&self) -> Option<ControlMode> {
        ControlMode::from_u32(self.mode)
    }

    /// Checks that every torque is finite, |τ_d| is within `limits` and the
    /// mode is known; the error names the first offending field.
    pub fn validate(&self, limits: &CommandLimits) -> Result<(), MessageError> {
        const M: &str = "ActuatorCommand";
        check_finite(M, self.first_non_finite())?;
        check_abs(M, "tau_d", self.tau_d, limits.tau_d_abs_max_nm)?;
        if self.control_mode().is_none() {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "mode",
                value: self.mode,
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
    fn layout() {
        assert_eq!(size_of::<ActuatorCommand>(), 72);
        assert_eq!(align_of::<ActuatorCommand>(), 8);
        assert_eq!(offset_of!(ActuatorCommand, seq), 0);
        assert_eq!(offset_of!(ActuatorCommand, stamp_ns), 8);
        assert_eq!(offset_of!(ActuatorCommand, sensor_seq), 16);
        assert_eq!(offset_of!(ActuatorCommand, tau_d), 24);
        assert_eq!(offset_of!(ActuatorCommand, tau_gravity), 32);
        assert_eq!(offset_of!(ActuatorCommand, tau_amplification), 40);
        assert_eq!(offset_of!(ActuatorCommand, tau_bias), 48);
        assert_eq!(offset_of!(ActuatorCommand, tau_excitation), 56);
        assert_eq!(offset_of!(ActuatorCommand, mode), 64);
        assert_eq!(offset_of!(ActuatorCommand, _pad), 68);
    }

    #[test]
    fn mode_codes_round_trip() {
        for (i, m) in ControlMode::ALL.into_iter().enumerate() {
            assert_eq!(m.as_u32(), i as u32);
            assert_eq!(ControlMode::from_u32(m.as_u32()), Some(m));
            assert_eq!(ControlMode::try_from(u32::from(m)), Ok(m));
        }
        assert_eq!(
            [0, 1, 2, 3, 4].map(|c| ControlMode::from_u32(c).map(ControlMode::name)),
            [
                Some("Idle"),
                Some("Run"),
                Some("SafeGravityOnly"),
                Some("SafeZeroTorque"),
                Some("FaultLatched")
            ]
        );
        assert_eq!(ControlMode::from_u32(6), None);
        assert_eq!(ControlMode::try_from(u32::MAX), Err(u32::MAX));
        assert!(ControlMode::FaultLatched.is_safe_state());
        assert!(!ControlMode::Done.is_safe_state());
    }

    #[test]
    fn validate_names_the_offending_field() {
        let good = ActuatorCommand {
            tau_d: 2.0,
            tau_gravity: 2.0,
            mode: ControlMode::Run.as_u32(),
            ..Default::default()
        };
        assert_eq!(good.validate(&CommandLimits::default()), Ok(()));
        let bad = ActuatorCommand {
            tau_bias: f64::NAN,
            ..good
        };
        assert!(!bad.is_finite());
        assert_eq!(
            bad.validate(&CommandLimits::default()).unwrap_err().field(),
            "tau_bias"
        );
        let limits = CommandLimits {
            tau_d_abs_max_nm: 1.5,
        };
        assert_eq!(good.validate(&limits).unwrap_err().field(), "tau_d");
        let bad = ActuatorCommand { mode: 9, ..good };
        assert_eq!(
            bad.validate(&CommandLimits::default()),
            Err(MessageError::UnknownCode {
                message: "ActuatorCommand",
                field: "mode",
                value: 9
            })
        );
    }
}
