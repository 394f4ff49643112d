//! # exo-messages
//!
//! Every message the exo processes exchange: `#[repr(C)]`, fixed size,
//! `Copy`, deriving iceoryx2's `ZeroCopySend`, so a sample is written once
//! into shared memory and read in place by every subscriber. Field docs give
//! units. Padding is explicit (`_pad` fields), so the layout tests pin every
//! byte and the recording contract can mirror it.
//!
//! Sign convention (the paper's): `tau_c` is the torque the cuff applies to
//! the human, so `S_h = τ_c/θ_e = M_h s² + K(1 + cj)`; `tau_s` is the SEA
//! spring torque driving the exoskeleton joint in the direction of `theta_e`.
//!
//! [`services`] names every service and who publishes and subscribes;
//! [`ipc`] builds nodes (with the project's iceoryx2 configuration loaded
//! explicitly), ports and wake-up events.

pub mod ipc;
pub mod services;

use iceoryx2::prelude::ZeroCopySend;

/// Status bits of a [`SensorSample`].
pub mod status {
    /// The joint encoder reading was invalid.
    pub const ENCODER_FAULT: u32 = 1 << 0;
    /// The cuff force/torque reading was NaN or infinite (last good value kept).
    pub const FT_FAULT: u32 = 1 << 1;
    /// The SEA deflection reading was invalid.
    pub const SEA_FAULT: u32 = 1 << 2;
    /// The hardware bus flagged the frame.
    pub const BUS_FAULT: u32 = 1 << 3;
    /// The driver is in its latched safe state.
    pub const SAFE_STATE: u32 = 1 << 4;
    /// The sample comes from a replayed recording, not from hardware.
    pub const REPLAY: u32 = 1 << 5;
    /// Bits that mean "do not act on this sample".
    pub const FAULT_MASK: u32 = ENCODER_FAULT | FT_FAULT | SEA_FAULT | BUS_FAULT;
}

/// A calibrated sensor sample: sensor driver → controller, identifier, recorder.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::SensorSample")]
#[repr(C)]
pub struct SensorSample {
    /// Sequence number, one per control tick.
    pub seq: u64,
    /// Monotonic time stamp (ns): the wall clock in real time, simulated time in lockstep.
    pub stamp_ns: u64,
    /// Exoskeleton joint angle θ_e (rad), 0 hanging down.
    pub theta_e: f64,
    /// Joint velocity ω_e (rad/s), filtered.
    pub omega_e: f64,
    /// Human–cuff interaction torque τ_c (Nm): torque the cuff applies to the human.
    pub tau_c: f64,
    /// SEA spring torque τ_s (Nm).
    pub tau_s: f64,
    /// Status bits ([`status`]).
    pub status: u32,
    /// Explicit padding to 8-byte alignment (always 0).
    pub _pad: u32,
}

/// Control modes of an [`ActuatorCommand`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ControlMode {
    /// Not yet running.
    Idle = 0,
    /// Normal operation.
    Run = 1,
    /// Latched fault: gravity compensation only.
    SafeGravityOnly = 2,
    /// Latched fault: zero torque.
    SafeZeroTorque = 3,
    /// Protocol finished: gravity compensation only.
    Done = 4,
}

impl ControlMode {
    /// The mode of a raw value, if it is one.
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => ControlMode::Idle,
            1 => ControlMode::Run,
            2 => ControlMode::SafeGravityOnly,
            3 => ControlMode::SafeZeroTorque,
            4 => ControlMode::Done,
            _ => return None,
        })
    }
    /// The raw value.
    pub fn as_u32(self) -> u32 {
        self as u32
    }
}

/// The controller's answer to one sample: controller → sensor driver, recorder.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::ActuatorCommand")]
#[repr(C)]
pub struct ActuatorCommand {
    /// Sequence number of this command.
    pub seq: u64,
    /// Time stamp (ns), same clock as the sample answered.
    pub stamp_ns: u64,
    /// `seq` of the [`SensorSample`] this command answers.
    pub sensor_seq: u64,
    /// Desired actuator torque τ_d (Nm), after torque and rate limits.
    pub tau_d: f64,
    /// Gravity-compensation part (Nm).
    pub tau_gravity: f64,
    /// Amplification part `−(α(s) − 1) τ_c` (Nm).
    pub tau_amplification: f64,
    /// Bias-torque part (Nm).
    pub tau_bias: f64,
    /// Excitation part (Nm).
    pub tau_excitation: f64,
    /// [`ControlMode`] as `u32`.
    pub mode: u32,
    /// Explicit padding (always 0).
    pub _pad: u32,
}

/// Protocol phases of a [`ProtocolState`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ProtocolPhase {
    /// No period running.
    Idle = 0,
    /// Bias ramping in.
    RampIn = 1,
    /// Sine on, settling.
    Settling = 2,
    /// Sine on, analysis window.
    Analysis = 3,
    /// Bias ramping out.
    RampOut = 4,
    /// Rest.
    Rest = 5,
}

impl ProtocolPhase {
    /// The phase of a raw value, if it is one.
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            0 => ProtocolPhase::Idle,
            1 => ProtocolPhase::RampIn,
            2 => ProtocolPhase::Settling,
            3 => ProtocolPhase::Analysis,
            4 => ProtocolPhase::RampOut,
            5 => ProtocolPhase::Rest,
            _ => return None,
        })
    }
}

/// Where the protocol is: controller → plant simulator, identifier, recorder.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::ProtocolState")]
#[repr(C)]
pub struct ProtocolState {
    /// Experiment number (1–9 in Table I; 0 none).
    pub experiment: u32,
    /// Period number (1–10; 0 none).
    pub period: u32,
    /// [`ProtocolPhase`] as `u32`.
    pub phase: u32,
    /// Explicit padding before the first `f64` (always 0).
    pub _pad: u32,
    /// Excitation frequency (rad/s); 0 in the analysis phase means broadband excitation.
    pub omega: f64,
    /// Excitation amplitude (Nm).
    pub amplitude: f64,
    /// Constant amplification α of the experiment.
    pub alpha: f64,
    /// Load on the exoskeleton arm (kg).
    pub load_kg: f64,
    /// Grip force the subject holds (kg).
    pub grip_kg: f64,
    /// Bias torque of the experiment (Nm).
    pub bias_nm: f64,
    /// Time stamp (ns) of the tick that produced this state.
    pub stamp_ns: u64,
    /// `seq` of the sample whose tick produced this state.
    pub sensor_seq: u64,
}

/// One raw frame on the (simulated) hardware bus: plant simulator → sensor driver.
/// Raw units, as a rig's bus delivers them.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::BusSensorFrame")]
#[repr(C)]
pub struct BusSensorFrame {
    /// Frame sequence number.
    pub seq: u64,
    /// Time stamp (ns).
    pub stamp_ns: u64,
    /// Joint encoder counts.
    pub encoder_counts: i64,
    /// Cuff 6-axis F/T reading `[f_x, f_y, f_z, t_x, t_y, t_z]` (N, Nm), sensor frame.
    pub cuff_wrench: [f64; 6],
    /// SEA spring-deflection encoder counts.
    pub sea_deflection_counts: i64,
    /// Bus status (non-zero: fault).
    pub status: u32,
    /// Explicit padding (always 0).
    pub _pad: u32,
}

/// The motor command on the (simulated) hardware bus: sensor driver → plant simulator.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::BusMotorCommand")]
#[repr(C)]
pub struct BusMotorCommand {
    /// Command sequence number.
    pub seq: u64,
    /// Time stamp (ns).
    pub stamp_ns: u64,
    /// `seq` of the [`BusSensorFrame`] this answers.
    pub frame_seq: u64,
    /// Desired motor (SEA) torque (Nm).
    pub tau_motor_nm: f64,
    /// 1: motor enabled; 0: powered down.
    pub enable: u32,
    /// Explicit padding (always 0).
    pub _pad: u32,
}

/// One FRF point from the identifier.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::FrfPoint")]
#[repr(C)]
pub struct FrfPoint {
    /// Sequence number.
    pub seq: u64,
    /// Time stamp (ns) of the end of the analysis window.
    pub stamp_ns: u64,
    /// Experiment number.
    pub experiment: u32,
    /// Period number.
    pub period: u32,
    /// Frequency (rad/s).
    pub omega: f64,
    /// `S_h = τ_c/θ_e`, real part (Nm/rad).
    pub s_h_re: f64,
    /// `S_h`, imaginary part (Nm/rad).
    pub s_h_im: f64,
    /// `S_{h-e/α} = τ_s/θ_e`, real part (Nm/rad).
    pub s_hea_re: f64,
    /// `S_{h-e/α}`, imaginary part (Nm/rad).
    pub s_hea_im: f64,
    /// SEA `τ_s/τ_d`, real part.
    pub sea_re: f64,
    /// SEA `τ_s/τ_d`, imaginary part.
    pub sea_im: f64,
    /// Coherence (0–1).
    pub coherence: f64,
    /// Relative noise of `S_h` (standard error / magnitude).
    pub noise_rel: f64,
}

/// The identifier's model estimate after the latest FRF point.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::ImpedanceEstimate")]
#[repr(C)]
pub struct ImpedanceEstimate {
    /// Sequence number.
    pub seq: u64,
    /// Time stamp (ns).
    pub stamp_ns: u64,
    /// Experiment number.
    pub experiment: u32,
    /// Number of FRF points used.
    pub n_points: u32,
    /// Model (1–3 for M1–M3).
    pub model: u32,
    /// Explicit padding (always 0).
    pub _pad: u32,
    /// K_h (Nm/rad) and its standard error.
    pub k_h: f64,
    /// Standard error of K_h.
    pub k_h_se: f64,
    /// H_h (Nm/rad).
    pub h_h: f64,
    /// Standard error of H_h.
    pub h_h_se: f64,
    /// B_h (Nm·s/rad).
    pub b_h: f64,
    /// Standard error of B_h.
    pub b_h_se: f64,
    /// M_h (kg·m²).
    pub m_h: f64,
    /// Standard error of M_h.
    pub m_h_se: f64,
    /// Loss factor c_h = H_h/K_h.
    pub c_h: f64,
    /// R² of the fit.
    pub r2: f64,
    /// F_{M1−M3}.
    pub f_m1_m3: f64,
    /// F_{M2−M3}.
    pub f_m2_m3: f64,
    /// Critical F at 0.05.
    pub f_critical: f64,
    /// The subject's power-law intercept β0 (NaN-free: 0 until known).
    pub beta0: f64,
    /// The power-law slope β1.
    pub beta1: f64,
    /// R² of the power law.
    pub power_law_r2: f64,
    /// Fractional order recommended by eq. f (0 until known).
    pub recommended_f: f64,
}

/// Operator commands (operator console → controller, sensor driver).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum OperatorCommandKind {
    /// Clear a latched fault.
    ResetFault = 1,
    /// Adopt the fractional order in `value` (within the configured bounds).
    AdoptFractionalOrder = 2,
    /// Stop the protocol (safe state, no fault).
    Stop = 3,
}

/// An operator command.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo_msgs::OperatorCommand")]
#[repr(C)]
pub struct OperatorCommand {
    /// Sequence number.
    pub seq: u64,
    /// [`OperatorCommandKind`] as `u32`.
    pub kind: u32,
    /// Explicit padding (always 0).
    pub _pad: u32,
    /// Argument (e.g. the fractional order).
    pub value: f64,
}

impl SensorSample {
    /// The first non-finite physical field, if any.
    pub fn non_finite_field(&self) -> Option<&'static str> {
        [
            ("theta_e", self.theta_e),
            ("omega_e", self.omega_e),
            ("tau_c", self.tau_c),
            ("tau_s", self.tau_s),
        ]
        .into_iter()
        .find(|(_, v)| !v.is_finite())
        .map(|(n, _)| n)
    }
}

#[cfg(test)]
mod layout {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn sensor_sample() {
        assert_eq!(
            (size_of::<SensorSample>(), align_of::<SensorSample>()),
            (56, 8)
        );
        assert_eq!(
            [
                offset_of!(SensorSample, seq),
                offset_of!(SensorSample, stamp_ns),
                offset_of!(SensorSample, theta_e),
                offset_of!(SensorSample, omega_e),
                offset_of!(SensorSample, tau_c),
                offset_of!(SensorSample, tau_s),
                offset_of!(SensorSample, status),
                offset_of!(SensorSample, _pad),
            ],
            [0, 8, 16, 24, 32, 40, 48, 52]
        );
    }

    #[test]
    fn actuator_command() {
        assert_eq!(
            (size_of::<ActuatorCommand>(), align_of::<ActuatorCommand>()),
            (72, 8)
        );
        assert_eq!(
            [
                offset_of!(ActuatorCommand, seq),
                offset_of!(ActuatorCommand, stamp_ns),
                offset_of!(ActuatorCommand, sensor_seq),
                offset_of!(ActuatorCommand, tau_d),
                offset_of!(ActuatorCommand, tau_gravity),
                offset_of!(ActuatorCommand, tau_amplification),
                offset_of!(ActuatorCommand, tau_bias),
                offset_of!(ActuatorCommand, tau_excitation),
                offset_of!(ActuatorCommand, mode),
                offset_of!(ActuatorCommand, _pad),
            ],
            [0, 8, 16, 24, 32, 40, 48, 56, 64, 68]
        );
    }

    #[test]
    fn protocol_state() {
        assert_eq!(
            (size_of::<ProtocolState>(), align_of::<ProtocolState>()),
            (80, 8)
        );
        assert_eq!(
            [
                offset_of!(ProtocolState, experiment),
                offset_of!(ProtocolState, period),
                offset_of!(ProtocolState, phase),
                offset_of!(ProtocolState, _pad),
                offset_of!(ProtocolState, omega),
                offset_of!(ProtocolState, amplitude),
                offset_of!(ProtocolState, alpha),
                offset_of!(ProtocolState, load_kg),
                offset_of!(ProtocolState, grip_kg),
                offset_of!(ProtocolState, bias_nm),
                offset_of!(ProtocolState, stamp_ns),
                offset_of!(ProtocolState, sensor_seq),
            ],
            [0, 4, 8, 12, 16, 24, 32, 40, 48, 56, 64, 72]
        );
    }

    #[test]
    fn bus_messages() {
        assert_eq!(
            (size_of::<BusSensorFrame>(), align_of::<BusSensorFrame>()),
            (88, 8)
        );
        assert_eq!(
            [
                offset_of!(BusSensorFrame, seq),
                offset_of!(BusSensorFrame, stamp_ns),
                offset_of!(BusSensorFrame, encoder_counts),
                offset_of!(BusSensorFrame, cuff_wrench),
                offset_of!(BusSensorFrame, sea_deflection_counts),
                offset_of!(BusSensorFrame, status),
            ],
            [0, 8, 16, 24, 72, 80]
        );
        assert_eq!(
            (size_of::<BusMotorCommand>(), align_of::<BusMotorCommand>()),
            (40, 8)
        );
        assert_eq!(
            [
                offset_of!(BusMotorCommand, frame_seq),
                offset_of!(BusMotorCommand, tau_motor_nm),
                offset_of!(BusMotorCommand, enable),
            ],
            [16, 24, 32]
        );
    }

    #[test]
    fn identifier_and_operator_messages() {
        assert_eq!(size_of::<FrfPoint>(), 24 + 9 * 8);
        assert_eq!(offset_of!(FrfPoint, omega), 24);
        assert_eq!(size_of::<ImpedanceEstimate>(), 32 + 17 * 8);
        assert_eq!(offset_of!(ImpedanceEstimate, k_h), 32);
        assert_eq!(size_of::<OperatorCommand>(), 24);
        assert_eq!(offset_of!(OperatorCommand, value), 16);
    }

    #[test]
    fn enums_round_trip() {
        for m in [
            ControlMode::Idle,
            ControlMode::Run,
            ControlMode::SafeGravityOnly,
            ControlMode::SafeZeroTorque,
            ControlMode::Done,
        ] {
            assert_eq!(ControlMode::from_u32(m.as_u32()), Some(m));
        }
        assert_eq!(ControlMode::from_u32(99), None);
        for v in 0..6 {
            assert_eq!(ProtocolPhase::from_u32(v).map(|p| p as u32), Some(v));
        }
        assert_eq!(ProtocolPhase::from_u32(6), None);
    }

    #[test]
    fn non_finite_field_is_named() {
        let s = SensorSample {
            tau_s: f64::NAN,
            ..Default::default()
        };
        assert_eq!(s.non_finite_field(), Some("tau_s"));
        assert_eq!(SensorSample::default().non_finite_field(), None);
    }
}
