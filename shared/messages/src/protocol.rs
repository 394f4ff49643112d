//! Where the identification protocol is: controller → plant simulator, identifier, recorder.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_finite, check_range, MessageError};

/// Phase of a protocol period; [`ProtocolState::phase`] as a `u32`.
/// Every period runs `RampIn → Settling → Analysis → RampOut → Rest`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum ProtocolPhase {
    /// No period running (before the first, after the last).
    Idle = 0,
    /// The bias torque ramps in (raised cosine).
    RampIn = 1,
    /// Excitation on, the response settles; not analysed.
    Settling = 2,
    /// Excitation on, inside the analysis window the identifier uses.
    Analysis = 3,
    /// The bias torque ramps out.
    RampOut = 4,
    /// Rest between periods: no bias, no excitation.
    Rest = 5,
}

impl ProtocolPhase {
    /// Every phase, in code order.
    pub const ALL: [ProtocolPhase; 6] = [
        ProtocolPhase::Idle,
        ProtocolPhase::RampIn,
        ProtocolPhase::Settling,
        ProtocolPhase::Analysis,
        ProtocolPhase::RampOut,
        ProtocolPhase::Rest,
    ];

    /// The phase of a raw code, or `None` for a code without meaning.
    pub fn from_u32(code: u32) -> Option<Self> {
        Self::ALL.get(code as usize).copied()
    }

    /// The raw code sent in [`ProtocolState::phase`].
    pub fn as_u32(self) -> u32 {
        self as u32
    }

    /// Short name, e.g. `"RampIn"`.
    pub fn name(self) -> &'static str {
        match self {
            ProtocolPhase::Idle => "Idle",
            ProtocolPhase::RampIn => "RampIn",
            ProtocolPhase::Settling => "Settling",
            ProtocolPhase::Analysis => "Analysis",
            ProtocolPhase::RampOut => "RampOut",
            ProtocolPhase::Rest => "Rest",
        }
    }
}

impl TryFrom<u32> for ProtocolPhase {
    type Error = u32;
    /// The phase of a raw code; the code itself as the error.
    fn try_from(code: u32) -> Result<Self, u32> {
        ProtocolPhase::from_u32(code).ok_or(code)
    }
}

impl From<ProtocolPhase> for u32 {
    fn from(p: ProtocolPhase) -> u32 {
        p.as_u32()
    }
}

/// Largest experiment number (Table I has experiments 1–9).
pub const MAX_EXPERIMENT: u32 = 9;
/// Largest period number within an experiment.
pub const MAX_PERIOD: u32 = 10;

/// The protocol's state at one control tick, published by the controller.
///
/// Recording contract: field names and order are fixed; 72 bytes, 8-aligned,
/// no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.ProtocolState.v1")
)]
#[repr(C)]
pub struct ProtocolState {
    /// Experiment number (1–9, Table I); 0 when none is running.
    pub experiment: u32,
    /// Period number within the experiment (1–10); 0 when none is running.
    pub period: u32,
    /// [`ProtocolPhase`] code (`ProtocolPhase::as_u32`).
    pub phase: u32,
    /// Explicit padding before the first `f64` (always 0), so the struct has no implicit padding.
    pub _pad: u32,
    /// Excitation angular frequency ω (rad/s) of this period; 0 means broadband excitation.
    pub omega: f64,
    /// Excitation torque amplitude (Nm).
    pub amplitude: f64,
    /// Constant amplification factor α of the experiment (dimensionless, 1 = no amplification).
    pub alpha: f64,
    /// Mass of the load on the exoskeleton arm (kg).
    pub load_kg: f64,
    /// Grip force the subject holds, as a mass on a hand dynamometer (kg).
    pub grip_kg: f64,
    /// Bias torque of the experiment (Nm), before ramping.
    pub bias_nm: f64,
    /// Time stamp (ns) on the monotonic clock of the control tick this state belongs to.
    pub stamp_ns: u64,
}

crate::impl_message!(ProtocolState, "exo.ProtocolState.v1", |p| [
    "omega" => p.omega,
    "amplitude" => p.amplitude,
    "alpha" => p.alpha,
    "load_kg" => p.load_kg,
    "grip_kg" => p.grip_kg,
    "bias_nm" => p.bias_nm,
]);

impl ProtocolState {
    /// The phase, or `None` if `phase` holds an unknown code.
    pub fn protocol_phase(&self) -> Option<ProtocolPhase> {
        ProtocolPhase::from_u32(self.phase)
    }

    /// Checks finiteness, the experiment (0–9) and period (0–10) numbers,
    /// the phase code, and that ω, amplitude, load and grip are not negative.
    pub fn validate(&self) -> Result<(), MessageError> {
        const M: &str = "ProtocolState";
        check_finite(M, self.first_non_finite())?;
        check_range(
            M,
            "experiment",
            self.experiment as f64,
            0.0,
            MAX_EXPERIMENT as f64,
        )?;
        check_range(M, "period", self.period as f64, 0.0, MAX_PERIOD as f64)?;
        if self.protocol_phase().is_none() {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "phase",
                value: self.phase,
            });
        }
        check_range(M, "omega", self.omega, 0.0, f64::INFINITY)?;
        check_range(M, "amplitude", self.amplitude, 0.0, f64::INFINITY)?;
        check_range(M, "load_kg", self.load_kg, 0.0, f64::INFINITY)?;
        check_range(M, "grip_kg", self.grip_kg, 0.0, f64::INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn layout() {
        assert_eq!(size_of::<ProtocolState>(), 72);
        assert_eq!(align_of::<ProtocolState>(), 8);
        assert_eq!(offset_of!(ProtocolState, experiment), 0);
        assert_eq!(offset_of!(ProtocolState, period), 4);
        assert_eq!(offset_of!(ProtocolState, phase), 8);
        assert_eq!(offset_of!(ProtocolState, _pad), 12);
        assert_eq!(offset_of!(ProtocolState, omega), 16);
        assert_eq!(offset_of!(ProtocolState, amplitude), 24);
        assert_eq!(offset_of!(ProtocolState, alpha), 32);
        assert_eq!(offset_of!(ProtocolState, load_kg), 40);
        assert_eq!(offset_of!(ProtocolState, grip_kg), 48);
        assert_eq!(offset_of!(ProtocolState, bias_nm), 56);
        assert_eq!(offset_of!(ProtocolState, stamp_ns), 64);
    }

    #[test]
    fn phase_codes_round_trip() {
        for (i, p) in ProtocolPhase::ALL.into_iter().enumerate() {
            assert_eq!(p.as_u32(), i as u32);
            assert_eq!(ProtocolPhase::from_u32(i as u32), Some(p));
            assert_eq!(ProtocolPhase::try_from(u32::from(p)), Ok(p));
        }
        assert_eq!(ProtocolPhase::Analysis.as_u32(), 3);
        assert_eq!(ProtocolPhase::Rest.name(), "Rest");
        assert_eq!(ProtocolPhase::from_u32(6), None);
    }

    #[test]
    fn validate_names_the_offending_field() {
        let good = ProtocolState {
            experiment: 3,
            period: 10,
            phase: ProtocolPhase::Analysis.as_u32(),
            omega: 6.0,
            amplitude: 1.0,
            alpha: 2.0,
            ..Default::default()
        };
        assert_eq!(good.validate(), Ok(()));
        assert_eq!(ProtocolState::default().validate(), Ok(()));
        let cases = [
            (
                "experiment",
                ProtocolState {
                    experiment: 10,
                    ..good
                },
            ),
            ("period", ProtocolState { period: 11, ..good }),
            ("phase", ProtocolState { phase: 6, ..good }),
            (
                "alpha",
                ProtocolState {
                    alpha: f64::NAN,
                    ..good
                },
            ),
            (
                "omega",
                ProtocolState {
                    omega: -1.0,
                    ..good
                },
            ),
            (
                "load_kg",
                ProtocolState {
                    load_kg: -0.1,
                    ..good
                },
            ),
        ];
        for (field, bad) in cases {
            assert_eq!(bad.validate().unwrap_err().field(), field);
        }
    }
}
