//! The forward model's free parameters ([`Param`]).

use serde::Serialize;

/// One free parameter of the forward model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Param {
    /// Human stiffness `K_h` of an experiment (Nm/rad).
    K(u32),
    /// Hysteretic damping `H_h` of an experiment (Nm/rad).
    H(u32),
    /// Human viscous damping `B_h` (Nm·s/rad).
    Bh,
    /// Forearm inertia `M_h` (kg·m²).
    Mh,
    /// Coulomb friction torque of the exoskeleton joint (Nm).
    Coulomb,
    /// Viscous friction of the exoskeleton joint (Nm·s/rad).
    Bf,
    /// Encoder delay (s).
    DelayTheta,
    /// Cuff force/torque sensor delay (s).
    DelayTauC,
    /// SEA torque (deflection) sensor delay (s).
    DelayTauS,
    /// Actuator (motor command) delay (s).
    DelayAct,
    /// Cuff compliance `1/k_c` (rad/Nm); 0 is a rigid cuff.
    CuffCompliance,
    /// SEA torque bandwidth `ω_n` (rad/s).
    SeaWn,
    /// SEA damping ratio.
    SeaZeta,
    /// Exoskeleton inertia error (kg·m²), added to `M_arm + m_load l²`.
    InertiaError,
    /// Gravity torque error `Δ(m g l)` (Nm): plant gravity the model lacks.
    GravityError,
    /// Cuff F/T sensor gain.
    GainTauC,
    /// SEA torque sensor gain.
    GainTauS,
    /// Offset between the SEA and cuff torque sensors (Nm).
    TorqueOffset,
    /// Stretch-reflex velocity gain `G` (Nm·s/rad).
    ReflexGain,
    /// Stretch-reflex delay `δ` (s).
    ReflexDelay,
    /// Stretch-reflex low-pass corner `ω_c` (rad/s).
    ReflexCutoff,
    /// Cubic stiffness `K₃` of the human joint (Nm/rad³), a generic form:
    /// `τ = K θ + K₃ θ³`, describing function `K + ¾ K₃ A²`.
    CubicStiffness,
    /// Cubic damping `B₃` of the human joint (Nm·s³/rad³), a generic form:
    /// `τ = B₃ θ̇³`, describing function `j ¾ B₃ ω³ A²`.
    CubicDamping,
    /// Drift of the human stiffness within an experiment (fraction per
    /// minute), a generic form: `K(t) = K_e (1 + ρ t)`, `t` from the
    /// experiment's first window.
    StiffnessDrift,
    /// Quadratic stiffness `K₂` of the human joint (Nm/rad²), a generic
    /// form: `τ = K θ + ½ K₂ θ²`, a stiffness `K + K₂ θ` that depends on
    /// posture. It leaves the fundamental (to first order) and puts
    /// `¼ K₂ Θ₁²` into the 2nd harmonic of `τ_c`: fitted there
    /// ([`crate::posture`]), not from the transfer functions.
    QuadraticStiffness,
    /// Half the lost motion `δ` of a gear mesh between the drive's output
    /// (motor side, inertia `J_m`) and the arm (rad), a generic form: a
    /// backlash whose describing function is [`Mesh::describing`](super::Mesh::describing).
    Backlash,
    /// The inverse of the drive's torque limit `1/τ_max` (1/Nm; 0 = no
    /// limit): the motor torque is `clip(τ_d, −τ_max, τ_max)`, whose
    /// fundamental is [`crate::data::CommandPeaks::clip_gain`]'s. Fitted as the inverse so
    /// that "absent" is 0 and the fit is smooth where the limit is first
    /// reached.
    Saturation,
}

impl Param {
    /// A delay of a sensor or of the motor command (s): one of the timing
    /// terms a sample period bounds from below (a reflex's delay is not).
    pub fn is_delay(self) -> bool {
        matches!(
            self,
            Param::DelayTheta | Param::DelayTauC | Param::DelayTauS | Param::DelayAct
        )
    }

    /// Name with unit, for tables.
    pub fn label(self) -> String {
        match self {
            Param::K(e) => format!("K_h[exp {e}] (Nm/rad)"),
            Param::H(e) => format!("H_h[exp {e}] (Nm/rad)"),
            Param::Bh => "B_h (Nm·s/rad)".into(),
            Param::Mh => "M_h (kg·m²)".into(),
            Param::Coulomb => "Coulomb friction (Nm)".into(),
            Param::Bf => "joint viscous friction (Nm·s/rad)".into(),
            Param::DelayTheta => "encoder delay (s)".into(),
            Param::DelayTauC => "cuff F/T delay (s)".into(),
            Param::DelayTauS => "SEA torque sensor delay (s)".into(),
            Param::DelayAct => "actuator delay (s)".into(),
            Param::CuffCompliance => "cuff compliance 1/k_c (rad/Nm)".into(),
            Param::SeaWn => "SEA bandwidth ω_n (rad/s)".into(),
            Param::SeaZeta => "SEA damping ratio".into(),
            Param::InertiaError => "exoskeleton inertia error (kg·m²)".into(),
            Param::GravityError => "gravity torque error Δ(mgl) (Nm)".into(),
            Param::GainTauC => "cuff F/T gain".into(),
            Param::GainTauS => "SEA torque sensor gain".into(),
            Param::TorqueOffset => "torque sensor offset τ_s − τ_c (Nm)".into(),
            Param::ReflexGain => "stretch-reflex gain (Nm·s/rad)".into(),
            Param::ReflexDelay => "stretch-reflex delay (s)".into(),
            Param::ReflexCutoff => "stretch-reflex corner (rad/s)".into(),
            Param::CubicStiffness => "cubic stiffness K₃ (Nm/rad³)".into(),
            Param::CubicDamping => "cubic damping B₃ (Nm·s³/rad³)".into(),
            Param::StiffnessDrift => "stiffness drift ρ (1/min)".into(),
            Param::QuadraticStiffness => "posture stiffness slope K₂ (Nm/rad²)".into(),
            Param::Backlash => "backlash half lost motion δ (rad)".into(),
            Param::Saturation => "inverse torque limit 1/τ_max (1/Nm)".into(),
        }
    }

    /// Typical size, for finite differences and step control.
    pub fn scale(self) -> f64 {
        match self {
            Param::K(_) => 10.0,
            Param::H(_) => 3.0,
            Param::Bh => 0.3,
            Param::Mh => 0.05,
            Param::Coulomb => 0.3,
            Param::Bf => 0.1,
            Param::DelayTheta | Param::DelayTauC | Param::DelayTauS | Param::DelayAct => 2e-3,
            Param::CuffCompliance => 1e-3,
            Param::SeaWn => 10.0,
            Param::SeaZeta => 0.1,
            Param::InertiaError => 0.03,
            Param::GravityError => 0.5,
            Param::GainTauC | Param::GainTauS => 0.05,
            Param::TorqueOffset => 0.1,
            Param::ReflexGain => 1.0,
            Param::ReflexDelay => 0.01,
            Param::ReflexCutoff => 5.0,
            Param::CubicStiffness => 50.0,
            Param::CubicDamping => 1.0,
            Param::StiffnessDrift => 0.01,
            Param::QuadraticStiffness => 50.0,
            Param::Backlash => 0.01,
            Param::Saturation => 2e-3,
        }
    }

    /// Its value when the term it belongs to is absent: 1 for a sensor
    /// gain, 0 otherwise.
    pub fn absent(self) -> f64 {
        match self {
            Param::GainTauC | Param::GainTauS => 1.0,
            _ => 0.0,
        }
    }

    /// Smallest allowed value.
    pub fn lower(self) -> f64 {
        match self {
            Param::K(_) => 1e-3,
            Param::SeaWn => 1.0,
            Param::SeaZeta => 0.01,
            Param::ReflexCutoff => 1.0,
            Param::GainTauC | Param::GainTauS => 0.05,
            Param::InertiaError
            | Param::GravityError
            | Param::TorqueOffset
            | Param::CubicStiffness
            | Param::QuadraticStiffness
            | Param::StiffnessDrift => f64::NEG_INFINITY,
            // A cubic damper is passive (the simulator's range is [0, 1e3]):
            // one that fed energy into the joint would not be a damper.
            _ => 0.0,
        }
    }
}
