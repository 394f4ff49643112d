//! The forward model: what a plant model (the simulator's TOML, every term
//! in it) predicts for each transfer function a recording supports, in the
//! frequency domain, linearised about each window's posture.
//!
//! With phasors at ω (`s = jω`), for each window:
//!
//! ```text
//! Z_imp  = K_e + j H_e + jω B_h                      human joint impedance (paper eq. M1–M3 terms)
//!          + G jω e^{−jωδ}/(1 + jω/ω_c)²              stretch reflex (when on)
//! Z_h    = Z_imp − M_h ω²                             forearm on the cuff
//! S_cuff = Z_c Z_h / (Z_c + Z_h),  Z_c = k_c + jω b_c  (rigid cuff: S_cuff = Z_h)
//! S_exo  = −M_e ω² + S_cuff + m g l cos θ₀ + jω b_f + j 4 F_c/(π A)
//! S_h    = g_c e^{−jω d_c} S_cuff / (g_θ e^{−jω d_θ})
//! S_h-e  = g_s e^{−jω d_s} S_exo / (g_θ e^{−jω d_θ}) − G_comp
//! τ_s/τ_d = g_s e^{−jω d_s} e^{−jω (d_a + h/2)} ω_n² / (ω_n² − ω² + 2jζω_nω)
//!           (ideal actuator: e^{−jω (d_s + d_a + h)}, and S_h-e gains e^{−jω h/2})
//! ```
//!
//! `K_e`, `H_e` per experiment (the subject file's), `M_e = M_arm + m_load
//! l²` (+ an inertia error), `m g l` the plant's gravity (+ an error), `A`
//! the window's angle amplitude (Coulomb friction's describing function),
//! `G_comp` the controller's own gravity compensation measured in the
//! recording, `h` the control period (the command is held over it), `d_*`
//! the sensor and actuator delays, `g_*` the sensor gains. Every symbol is
//! a named term of the plant TOML; [`Physics::from_plant`] reads them and
//! [`Physics::write_plant`] writes them back.
//!
//! Assumptions: the hysteretic damping is `K + jH` exactly at the excitation
//! (the simulator's `equivalent_viscous` and `prony_matched` modes are; the
//! plain `prony` bank differs by its few-per-cent Kramers–Kronig drift);
//! gravity's moment at the fundamental is taken from the window's measured
//! angle (about the centre of its swing, its harmonics included), friction
//! by its describing function; sensor offsets do not enter transfer
//! functions and are not diagnosed.
//!
//! Accuracy against the simulator (`tests/it/forward.rs`, every term alone):
//! linear terms within the measured noise (the fit's floor,
//! `fit::MODEL_ACCURACY`, is 0.5 %);
//! Coulomb friction's describing function within 1.7 % (it ignores the
//! harmonics); an ideal actuator (no SEA dynamics) within 0.8 %.

use std::collections::BTreeMap;

use exo_plant_model::PlantModel;
use num_complex::Complex64;
use serde::Serialize;

use crate::data::{Condition, Observation, Tf};

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
    /// backlash whose describing function is [`Mesh::describing`].
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

/// Every coefficient of the forward model (SI units as in [`Param`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Physics {
    /// `K_h` per experiment.
    pub k: BTreeMap<u32, f64>,
    /// `H_h` per experiment (0 without hysteretic damping).
    pub h: BTreeMap<u32, f64>,
    /// `B_h`.
    pub b_h: f64,
    /// `M_h`.
    pub m_h: f64,
    /// Coulomb friction torque.
    pub coulomb_nm: f64,
    /// Velocity over which the simulator's `tanh` smooths the friction's sign (rad/s).
    pub coulomb_smoothing_rad_s: f64,
    /// Joint viscous friction.
    pub b_f: f64,
    /// Delays: encoder, cuff F/T, SEA sensor, actuator (s).
    pub delay_s: [f64; 4],
    /// Cuff compliance `1/k_c` (0 = rigid) and damping `b_c`.
    pub cuff_compliance: f64,
    /// Cuff damping (Nm·s/rad), used when compliant.
    pub cuff_b: f64,
    /// SEA `(ω_n, ζ)`, `None` for an ideal actuator.
    pub sea: Option<(f64, f64)>,
    /// Exoskeleton arm inertia without load (kg·m²).
    pub arm_inertia: f64,
    /// Load lever arm (m).
    pub lever_m: f64,
    /// Plant gravity: `g (m_arm c_arm)` (Nm) and `g` (m/s²); 0 when off.
    pub gravity_arm_nm: f64,
    /// Gravitational acceleration used with the load (m/s²; 0 when gravity is off).
    pub g_load: f64,
    /// Inertia error (kg·m²).
    pub inertia_error: f64,
    /// Gravity error (Nm).
    pub gravity_error: f64,
    /// Sensor gains: encoder, cuff F/T, SEA torque.
    pub gain: [f64; 3],
    /// Encoder offset (rad).
    pub theta_offset: f64,
    /// Offset of the SEA torque sensor less that of the cuff sensor (Nm).
    pub torque_offset_nm: f64,
    /// Stretch reflex `[G (Nm·s/rad), δ (s), ω_c (rad/s)]`; G = 0 is off.
    pub reflex: [f64; 3],
    /// Cubic stiffness `K₃` of the human joint (Nm/rad³; 0 = linear spring).
    pub k3: f64,
    /// Cubic damping `B₃` of the human joint (Nm·s³/rad³; generic form).
    pub b3: f64,
    /// Stiffness drift within an experiment (fraction per minute; generic form).
    pub k_drift_per_min: f64,
    /// Quadratic stiffness `K₂` of the human joint (Nm/rad²; generic form,
    /// the posture dependence `dK/dθ`): no effect on [`Physics::predict_tf`]'s
    /// fundamental; its 2nd harmonic is [`crate::posture`]'s.
    pub k2: f64,
    /// Half the lost motion `δ` of the joint's gear mesh (rad; 0 = none;
    /// generic form).
    pub lash_half_rad: f64,
    /// The motor side's inertia `J_m` behind the mesh (kg·m²), from the
    /// plant model's `exo.backlash.motor_inertia_kg_m2` (a drive's
    /// datasheet value: not fitted).
    pub motor_inertia: f64,
    /// The inverse of the drive's torque limit `1/τ_max` (1/Nm; 0 = no
    /// limit), from the plant's `sea.torque_limit_nm`.
    pub saturation_per_nm: f64,
    /// The subject's posture during a period (rad), the plant's
    /// `human.active_angle_rad`, and what its reference does
    /// (`human.posture_reference`): the static equilibrium
    /// [`crate::equilibrium`] compares each experiment with.
    pub active_angle_rad: f64,
    /// See [`Physics::active_angle_rad`].
    pub posture_reference: exo_plant_model::PostureReference,
}

impl Physics {
    /// The coefficients of a plant model, with `K_h`, `H_h` for each
    /// experiment from the model's defaults (the fit refines them).
    pub fn from_plant(m: &PlantModel, experiments: &[u32]) -> Self {
        let hd = m.human.hysteretic_damping;
        let k0 = m.human.stiffness_nm_per_rad;
        let h0 = if hd.enabled { hd.loss_factor * k0 } else { 0.0 };
        let g = &m.gravity;
        Self {
            k: experiments.iter().map(|&e| (e, k0)).collect(),
            h: experiments.iter().map(|&e| (e, h0)).collect(),
            b_h: if m.human.viscous_damping.enabled {
                m.human.viscous_damping.b_nm_s_per_rad
            } else {
                0.0
            },
            m_h: m.human.inertia_kg_m2,
            coulomb_nm: if m.joint_friction.coulomb.enabled {
                m.joint_friction.coulomb.torque_nm
            } else {
                0.0
            },
            coulomb_smoothing_rad_s: m.joint_friction.coulomb.smoothing_rad_s,
            b_f: if m.joint_friction.viscous.enabled {
                m.joint_friction.viscous.b_nm_s_per_rad
            } else {
                0.0
            },
            delay_s: [
                m.sensors.encoder.terms.delay_s,
                m.sensors.cuff_ft.terms.delay_s,
                m.sensors.sea_deflection.terms.delay_s,
                m.actuator.delay_s,
            ],
            cuff_compliance: if m.cuff.compliance.enabled {
                1.0 / m.cuff.compliance.stiffness_nm_per_rad
            } else {
                0.0
            },
            cuff_b: m.cuff.compliance.damping_nm_s_per_rad,
            sea: m.sea.dynamics.enabled.then_some({
                (
                    std::f64::consts::TAU * m.sea.dynamics.natural_frequency_hz,
                    m.sea.dynamics.damping_ratio,
                )
            }),
            arm_inertia: m.exo.arm_inertia_kg_m2,
            lever_m: m.exo.load_lever_arm_m,
            gravity_arm_nm: if g.enabled {
                g.g_m_s2 * g.arm_mass_kg * g.arm_com_m
            } else {
                0.0
            },
            g_load: if g.enabled { g.g_m_s2 } else { 0.0 },
            inertia_error: 0.0,
            gravity_error: 0.0,
            gain: [
                m.sensors.encoder.terms.gain,
                m.sensors.cuff_ft.terms.gain,
                m.sensors.sea_deflection.terms.gain,
            ],
            theta_offset: m.sensors.encoder.terms.offset,
            torque_offset_nm: m.sensors.sea_deflection.terms.offset
                - m.sensors.cuff_ft.terms.offset,
            reflex: {
                let r = m.human.stretch_reflex;
                [
                    if r.enabled { r.gain_nm_s_per_rad } else { 0.0 },
                    r.delay_s,
                    r.cutoff_rad_s,
                ]
            },
            k3: m.human.cubic_stiffness_nm_per_rad3,
            b3: m.human.cubic_damping_nm_s3_per_rad3,
            k_drift_per_min: m.human.stiffness_drift_per_min,
            k2: m.human.quadratic_stiffness_nm_per_rad2,
            lash_half_rad: 0.5 * m.exo.backlash.lash_rad,
            motor_inertia: m.exo.backlash.motor_inertia_kg_m2,
            saturation_per_nm: 1.0 / m.sea.torque_limit_nm,
            active_angle_rad: m.human.active_angle_rad,
            posture_reference: m.human.posture_reference,
        }
    }

    /// The value of a parameter.
    pub fn get(&self, p: Param) -> f64 {
        match p {
            Param::K(e) => self.k.get(&e).copied().unwrap_or(0.0),
            Param::H(e) => self.h.get(&e).copied().unwrap_or(0.0),
            Param::Bh => self.b_h,
            Param::Mh => self.m_h,
            Param::Coulomb => self.coulomb_nm,
            Param::Bf => self.b_f,
            Param::DelayTheta => self.delay_s[0],
            Param::DelayTauC => self.delay_s[1],
            Param::DelayTauS => self.delay_s[2],
            Param::DelayAct => self.delay_s[3],
            Param::CuffCompliance => self.cuff_compliance,
            Param::SeaWn => self.sea.map_or(0.0, |s| s.0),
            Param::SeaZeta => self.sea.map_or(0.0, |s| s.1),
            Param::InertiaError => self.inertia_error,
            Param::GravityError => self.gravity_error,
            Param::GainTauC => self.gain[1],
            Param::GainTauS => self.gain[2],
            Param::TorqueOffset => self.torque_offset_nm,
            Param::ReflexGain => self.reflex[0],
            Param::ReflexDelay => self.reflex[1],
            Param::ReflexCutoff => self.reflex[2],
            Param::CubicStiffness => self.k3,
            Param::CubicDamping => self.b3,
            Param::StiffnessDrift => self.k_drift_per_min,
            Param::QuadraticStiffness => self.k2,
            Param::Backlash => self.lash_half_rad,
            Param::Saturation => self.saturation_per_nm,
        }
    }

    /// Sets a parameter (clamped to its lower bound).
    pub fn set(&mut self, p: Param, v: f64) {
        let v = v.max(p.lower());
        match p {
            Param::K(e) => {
                self.k.insert(e, v);
            }
            Param::H(e) => {
                self.h.insert(e, v);
            }
            Param::Bh => self.b_h = v,
            Param::Mh => self.m_h = v,
            Param::Coulomb => self.coulomb_nm = v,
            Param::Bf => self.b_f = v,
            Param::DelayTheta => self.delay_s[0] = v,
            Param::DelayTauC => self.delay_s[1] = v,
            Param::DelayTauS => self.delay_s[2] = v,
            Param::DelayAct => self.delay_s[3] = v,
            Param::CuffCompliance => self.cuff_compliance = v,
            Param::SeaWn => {
                let z = self.sea.map_or(0.7, |s| s.1);
                self.sea = Some((v, z));
            }
            Param::SeaZeta => {
                let w = self.sea.map_or(62.8, |s| s.0);
                self.sea = Some((w, v));
            }
            Param::InertiaError => self.inertia_error = v,
            Param::GravityError => self.gravity_error = v,
            Param::GainTauC => self.gain[1] = v,
            Param::GainTauS => self.gain[2] = v,
            Param::TorqueOffset => self.torque_offset_nm = v,
            Param::ReflexGain => self.reflex[0] = v,
            Param::ReflexDelay => self.reflex[1] = v.min(0.5),
            Param::ReflexCutoff => self.reflex[2] = v,
            Param::CubicStiffness => self.k3 = v,
            Param::CubicDamping => self.b3 = v,
            Param::StiffnessDrift => self.k_drift_per_min = v,
            Param::QuadraticStiffness => self.k2 = v,
            Param::Backlash => self.lash_half_rad = v,
            Param::Saturation => self.saturation_per_nm = v,
        }
    }

    /// The model's value of `o`'s transfer function in window `c`.
    pub fn predict(&self, o: &Observation, c: &Condition) -> Complex64 {
        if o.tf == Tf::Balance {
            return Complex64::new(self.predict_balance(c, o.statics), 0.0);
        }
        self.predict_tf(o.tf, o.omega_rad_s, c, o.gravity_comp)
    }

    /// The static balance `mean(τ_s − τ_gravity − τ_c)` (Nm) of window `c`
    /// given its mean `[τ_gravity, τ_c]`: at rest on average the SEA holds
    /// the cuff torque and the plant's gravity, so with sensor gains `g`
    /// and the sensors' offset difference `Δ`:
    /// `(g_s − g_c) τ_c + g_s m g l ⟨sin θ⟩ + Δ − τ_gravity`.
    /// (Encoder gain 1 and offset 0 assumed here.)
    pub fn predict_balance(&self, c: &Condition, statics: [f64; 2]) -> f64 {
        let [tau_g, tau_c_meas] = statics;
        let tau_c = tau_c_meas / self.gain[1];
        let mgl = self.mgl_nm(c);
        (self.gain[2] - self.gain[1]) * tau_c
            + self.gain[2] * mgl * c.sin_theta_mean
            + self.torque_offset_nm
            - tau_g
    }

    /// The model's value of `tf` at ω in window `c`, with the controller's
    /// measured gravity compensation `gravity_comp` (for `S_h-e`).
    pub fn predict_tf(&self, tf: Tf, w: f64, c: &Condition, gravity_comp: Complex64) -> Complex64 {
        let delay = |d: f64| Complex64::from_polar(1.0, -w * d);
        let e_theta = self.gain[0] * delay(self.delay_s[0]);
        match tf {
            Tf::Sh => self.gain[1] * delay(self.delay_s[1]) * self.s_cuff(w, c) / e_theta,
            Tf::She => {
                let mut s_exo = self.s_exo_linear(w, c);
                if self.lash_half_rad > 0.0 {
                    s_exo += self.mesh(self.lash_half_rad, s_exo, w, c).describing();
                }
                // An ideal actuator's torque is the held command: the sample
                // reads the previous hold, half a control period behind
                // the torque acting on average over the period.
                let hold = if self.sea.is_some() {
                    0.0
                } else {
                    0.5 * c.sample_period_s
                };
                self.gain[2] * delay(self.delay_s[2] + hold) * s_exo / e_theta - gravity_comp
            }
            Tf::Balance => Complex64::new(0.0, 0.0),
            Tf::Sea => {
                let sea = match self.sea {
                    Some((wn, z)) => {
                        Complex64::new(wn * wn, 0.0)
                            / Complex64::new(wn * wn - w * w, 2.0 * z * wn * w)
                    }
                    None => Complex64::new(1.0, 0.0),
                };
                // The command is held over a control period (zero-order
                // hold, half a period of delay through the SEA's filter);
                // an ideal actuator's sampled torque is the previous hold.
                let hold = if self.sea.is_some() { 0.5 } else { 1.0 } * c.sample_period_s;
                self.gain[2]
                    * delay(self.delay_s[2] + self.delay_s[3] + hold)
                    * sea
                    * self.saturation_gain(c)
            }
        }
    }

    /// The exoskeleton joint's impedance `S_exo` at ω in window `c` (Nm/rad,
    /// the table of docs/diagnose.md §2) without backlash: arm and load
    /// inertia, the human through the cuff, gravity's describing function
    /// about the window's mean angle ([`gravity_describing`]), viscous and
    /// Coulomb friction.
    pub fn s_exo_linear(&self, w: f64, c: &Condition) -> Complex64 {
        let j = Complex64::i();
        let a_true = self.true_amplitude_rad(c);
        let m_e = self.arm_inertia + c.load_kg * self.lever_m * self.lever_m + self.inertia_error;
        let mgl = self.mgl_nm(c);
        -m_e * w * w
            + self.s_cuff(w, c)
            + mgl * self.gravity_gain(c)
            + j * w * self.b_f
            + j * coulomb_describing(self.coulomb_nm, self.coulomb_smoothing_rad_s, a_true, w)
    }

    /// The drive's torque limit `τ_max` (Nm; infinite when there is none).
    pub fn torque_limit_nm(&self) -> f64 {
        if self.saturation_per_nm > 0.0 {
            1.0 / self.saturation_per_nm
        } else {
            f64::INFINITY
        }
    }

    /// The gain of the drive's torque limit at the fundamental in window
    /// `c`, from the window's recorded command
    /// ([`crate::data::CommandPeaks::clip_gain`]); 1 where the command was
    /// not recorded or the window is broadband (an assumption: a broadband
    /// window's limit is not modelled).
    pub fn saturation_gain(&self, c: &Condition) -> Complex64 {
        match &c.command {
            Some(cmd) if self.saturation_per_nm > 0.0 => cmd.clip_gain(self.torque_limit_nm()),
            _ => Complex64::new(1.0, 0.0),
        }
    }

    /// The joint's gravity moment `m g l` (Nm): arm, load and the gravity error.
    fn mgl_nm(&self, c: &Condition) -> f64 {
        self.gravity_arm_nm + self.g_load * c.load_kg * self.lever_m + self.gravity_error
    }

    /// Gravity's moment at the fundamental per unit `m g l` and per radian
    /// of the true angle's fundamental in window `c`, `[sin θ]₁ / [θ]₁`.
    /// From the window's measured angle where it was recorded
    /// ([`crate::data::GravityFundamentals`]: exact whatever harmonics the
    /// swing holds; with experiment 1's 0.2 rad swings about 45° the arm's
    /// own second harmonic moves the fundamental by about 0.5 %, beyond
    /// the describing function of a pure sine), with the encoder's offset
    /// exactly and its gain by the describing function's ratio; otherwise
    /// `cos θ₀ · 2 J₁(A)/A` about the window's mean ([`gravity_describing`]).
    pub fn gravity_gain(&self, c: &Condition) -> Complex64 {
        let a_true = self.true_amplitude_rad(c);
        let theta0 = (c.theta0_rad - self.theta_offset) / self.gain[0];
        let describing = theta0.cos() * gravity_describing(a_true);
        match &c.gravity {
            Some(f) => {
                let (sd, cd) = self.theta_offset.sin_cos();
                let measured = (f.sin * cd - f.cos * sd) / f.theta;
                // The gain's share (1 at gain 1): the describing function
                // at the true angle over the one at the measured angle.
                let at_measured =
                    (c.theta0_rad - self.theta_offset).cos() * gravity_describing(c.theta_amp_rad);
                if self.gain[0] == 1.0 || at_measured == 0.0 {
                    measured
                } else {
                    measured * (describing / at_measured)
                }
            }
            None => Complex64::new(describing, 0.0),
        }
    }

    /// The true angle amplitude of window `c` (rad): the measured one over
    /// the encoder's gain.
    pub fn true_amplitude_rad(&self, c: &Condition) -> f64 {
        (c.theta_amp_rad / self.gain[0]).max(1e-9)
    }

    /// The gear mesh in window `c` at ω with half lost motion
    /// `half_lash_rad`, the joint's impedance `s_exo` (without backlash)
    /// giving its arm's side.
    pub fn mesh(&self, half_lash_rad: f64, s_exo: Complex64, w: f64, c: &Condition) -> Mesh {
        Mesh {
            half_lash_rad,
            motor_inertia_kg_m2: self.motor_inertia,
            z_arm: self.z_arm(s_exo, w),
            preload_nm: self.mesh_preload_nm(c),
            amplitude_rad: self.true_amplitude_rad(c),
            omega_rad_s: w,
        }
    }

    /// The arm's side of the gear mesh at ω, `Z_arm`: the joint's impedance
    /// `s_exo` (without backlash) less the motor side's inertia.
    pub fn z_arm(&self, s_exo: Complex64, w: f64) -> Complex64 {
        s_exo + self.motor_inertia * w * w
    }

    /// The mesh's mean torque in window `c` (Nm): the window's mean SEA
    /// torque, or, where it was not recorded, gravity at the mean angle
    /// plus the bias.
    pub fn mesh_preload_nm(&self, c: &Condition) -> f64 {
        if c.tau_s_mean_nm.is_finite() {
            c.tau_s_mean_nm
        } else {
            self.mgl_nm(c) * c.sin_theta_mean + c.bias_nm
        }
    }

    fn s_cuff(&self, w: f64, c: &Condition) -> Complex64 {
        let k = self.k.get(&c.experiment).copied().unwrap_or(0.0)
            * (1.0 + self.k_drift_per_min * c.elapsed_s / 60.0);
        let h = self.h.get(&c.experiment).copied().unwrap_or(0.0);
        // The human's angle amplitude (rigid cuff: the exoskeleton's; with
        // a compliant cuff the exoskeleton's stands in for it).
        let a_h = c.theta_amp_rad / self.gain[0];
        let a2 = a_h * a_h;
        // A posture-dependent stiffness `½ K₂ θ²` has no fundamental of its
        // own; its mean torque `¼ K₂ A²` moves the posture by `−K₂ A²/4K`
        // (the human's spring holds the mean: with the exoskeleton's gravity
        // compensated and amplification α, the cuff's mean torque is fixed
        // by the bias), where the stiffness is `K − K₂² A²/4K` (second order
        // in K₂; `services/plant-sim/tests/physics.rs`).
        let posture_shift = if self.k2 != 0.0 && k > 0.0 {
            self.k2 * self.k2 * a2 / (4.0 * k)
        } else {
            0.0
        };
        let mut z_h = Complex64::new(
            k + 0.75 * self.k3 * a2 - posture_shift - self.m_h * w * w,
            h + w * self.b_h + 0.75 * self.b3 * w * w * w * a2,
        );
        let [g, delay, wc] = self.reflex;
        if g > 0.0 {
            let lp = Complex64::new(1.0, w / wc);
            z_h += Complex64::new(0.0, g * w) * Complex64::from_polar(1.0, -w * delay) / (lp * lp);
        }
        if self.cuff_compliance > 0.0 {
            let z_c = Complex64::new(1.0 / self.cuff_compliance, w * self.cuff_b);
            z_c * z_h / (z_c + z_h)
        } else {
            z_h
        }
    }

    /// Writes these coefficients into a plant model: terms with a
    /// non-identity value are enabled with it. `K_h`, `H_h` per experiment
    /// go to a subject file ([`Physics::subject_toml`]); the plant keeps
    /// their means as its defaults.
    pub fn write_plant(&self, base: &PlantModel) -> PlantModel {
        let mut m = *base;
        let mean = |v: &BTreeMap<u32, f64>| {
            if v.is_empty() {
                0.0
            } else {
                v.values().sum::<f64>() / v.len() as f64
            }
        };
        let k = mean(&self.k);
        if k > 0.0 {
            m.human.stiffness_nm_per_rad = k;
        }
        let h = mean(&self.h);
        let hd = &mut m.human.hysteretic_damping;
        hd.enabled = h > 0.0;
        if h > 0.0 && k > 0.0 {
            hd.loss_factor = h / k;
        }
        m.human.viscous_damping.enabled = self.b_h > 0.0;
        m.human.viscous_damping.b_nm_s_per_rad = self.b_h;
        m.human.inertia_kg_m2 = self.m_h;
        let r = &mut m.human.stretch_reflex;
        r.enabled = self.reflex[0] > 0.0;
        r.gain_nm_s_per_rad = self.reflex[0];
        r.delay_s = self.reflex[1];
        r.cutoff_rad_s = self.reflex[2];
        m.human.cubic_stiffness_nm_per_rad3 = self.k3;
        m.human.cubic_damping_nm_s3_per_rad3 = self.b3;
        m.human.quadratic_stiffness_nm_per_rad2 = self.k2;
        m.exo.backlash.lash_rad = 2.0 * self.lash_half_rad;
        // The simulator's drift counts from the experiment's start, the
        // form's from its first window: the same ρ up to the fitted K_h.
        m.human.stiffness_drift_per_min = self.k_drift_per_min;
        m.joint_friction.coulomb.enabled = self.coulomb_nm > 0.0;
        m.joint_friction.coulomb.torque_nm = self.coulomb_nm;
        m.joint_friction.viscous.enabled = self.b_f > 0.0;
        m.joint_friction.viscous.b_nm_s_per_rad = self.b_f;
        m.sensors.encoder.terms.delay_s = self.delay_s[0];
        m.sensors.cuff_ft.terms.delay_s = self.delay_s[1];
        m.sensors.sea_deflection.terms.delay_s = self.delay_s[2];
        m.actuator.delay_s = self.delay_s[3];
        m.cuff.compliance.enabled = self.cuff_compliance > 0.0;
        if self.cuff_compliance > 0.0 {
            m.cuff.compliance.stiffness_nm_per_rad = 1.0 / self.cuff_compliance;
        }
        match self.sea {
            Some((wn, z)) => {
                m.sea.dynamics.enabled = true;
                m.sea.dynamics.natural_frequency_hz = wn / std::f64::consts::TAU;
                m.sea.dynamics.damping_ratio = z;
            }
            None => m.sea.dynamics.enabled = false,
        }
        // Errors of the rig's inertia and gravity are the plant's own values.
        m.exo.arm_inertia_kg_m2 = (self.arm_inertia + self.inertia_error).max(1e-6);
        if self.gravity_error != 0.0 {
            m.gravity.enabled = true;
            let g = if m.gravity.g_m_s2 > 0.0 {
                m.gravity.g_m_s2
            } else {
                9.80665
            };
            let com = if m.gravity.arm_com_m > 0.0 {
                m.gravity.arm_com_m
            } else {
                0.2
            };
            m.gravity.arm_mass_kg =
                ((self.gravity_arm_nm + self.gravity_error) / (g * com)).max(0.0);
        }
        m.sensors.cuff_ft.terms.gain = self.gain[1];
        m.sensors.sea_deflection.terms.offset =
            m.sensors.cuff_ft.terms.offset + self.torque_offset_nm;
        m.sensors.sea_deflection.terms.gain = self.gain[2];
        // The plant's range for the limit is (0, 1000] Nm.
        if self.saturation_per_nm > 1e-3 {
            m.sea.torque_limit_nm = 1.0 / self.saturation_per_nm;
        }
        m
    }

    /// A subject file (the format of `configs/subjects/*.toml`) with the
    /// fitted `K_h`, `H_h` of every experiment.
    pub fn subject_toml(&self, name: &str) -> String {
        let mut s = format!(
            "# Fitted by exo diagnose: K_h and H_h per experiment (Nm/rad).\n\nname = \"{name}\"\ninertia_kg_m2 = {}\n",
            self.m_h
        );
        for (e, k) in &self.k {
            let h = self.h.get(e).copied().unwrap_or(0.0);
            s.push_str(&format!(
                "\n[[experiment]]\nnumber = {e}\nstiffness_nm_per_rad = {k}\nhysteretic_damping_nm_per_rad = {h}\n"
            ));
        }
        s
    }
}

/// Describing function of the joint's smoothed Coulomb friction
/// `F tanh(θ̇/v_s)` for `θ = A sin ωt`: the in-quadrature (velocity) part
/// of the fundamental over the angle amplitude (Nm/rad). It tends to
/// `4F/(πA)` for `v_s ≪ Aω`; computed by quadrature (64 points), exact
/// for the simulator's smoothing.
pub fn coulomb_describing(f_nm: f64, smoothing_rad_s: f64, a_rad: f64, w: f64) -> f64 {
    if f_nm == 0.0 {
        return 0.0;
    }
    let v = a_rad * w;
    if smoothing_rad_s <= 0.0 {
        return 4.0 * f_nm / (std::f64::consts::PI * a_rad);
    }
    const N: usize = 64;
    let mut b1 = 0.0;
    for i in 0..N {
        let phi = std::f64::consts::TAU * (i as f64 + 0.5) / N as f64;
        b1 += (v * phi.cos() / smoothing_rad_s).tanh() * phi.cos();
    }
    b1 *= 2.0 / N as f64;
    f_nm * b1 / a_rad
}

/// Gravity's describing function about the mean angle, relative to its
/// slope there: the fundamental of `sin(θ₀ + A cos φ)` is `cos θ₀ · 2 J₁(A)
/// cos φ` (`sin(A cos φ)`'s Fourier–Bessel series; `cos(A cos φ)` has only
/// even harmonics), so the moment's gain at the fundamental is `m g l cos θ₀
/// · 2 J₁(A)/A`, which falls as `1 − A²/8` below the linearisation: 0.4 %
/// at A = 0.18 rad, the paper's protocol's largest amplitudes. `J₁` from
/// its power series `Σ (−1)^k (A/2)^{2k+1} / (k! (k+1)!)`, summed until a
/// term is below 1e-16 of the sum (a few terms for any angle a joint
/// moves through).
pub fn gravity_describing(amplitude_rad: f64) -> f64 {
    let half = 0.5 * amplitude_rad;
    if !half.is_finite() || half == 0.0 {
        return 1.0;
    }
    // 2 J₁(A)/A = Σ (−1)^k (A/2)^{2k} / (k! (k+1)!).
    let (mut term, mut sum) = (1.0_f64, 1.0_f64);
    for k in 1..60 {
        let kf = f64::from(k);
        term *= -half * half / (kf * (kf + 1.0));
        sum += term;
        if term.abs() < 1e-16 * sum.abs() {
            break;
        }
    }
    sum
}

/// A gear mesh with lost motion `2δ` between the drive's output (motor
/// side, inertia `J_m`, where the SEA's torque acts) and the arm, as one
/// analysis window drives it: the arm's side of the joint `Z_arm` at ω, so
/// the mesh passes `Z_arm Θ` (amplitude `T = |Z_arm| A`) on top of its mean
/// `P`, the preload. Exactly, `τ_s = Z_arm θ + J_m θ̈_m` with `θ_m = θ + Δ`,
/// `Δ` the motor side's angle relative to the arm
/// ([`Mesh::lost_motion_harmonic`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mesh {
    /// Half the lost motion, δ (rad).
    pub half_lash_rad: f64,
    /// The motor side's inertia `J_m` (kg·m²).
    pub motor_inertia_kg_m2: f64,
    /// The arm's side of the joint at ω, `Z_arm` (Nm/rad).
    pub z_arm: Complex64,
    /// The mesh's mean torque `P` (Nm).
    pub preload_nm: f64,
    /// The angle's amplitude `A` (rad).
    pub amplitude_rad: f64,
    /// The excitation ω (rad/s).
    pub omega_rad_s: f64,
}

impl Mesh {
    /// What backlash adds to `S_h-e` (Nm/rad), from the lost motion's
    /// fundamental:
    ///
    /// `ΔS_h-e = −J_m ω² (4/π) (δ/A) √(1 − (P/T)²) e^{j(∠Z_arm − ω t½)}`
    ///
    /// and nothing where the preload holds the mesh closed (`|P| ≥ T`).
    pub fn describing(&self) -> Complex64 {
        if self.amplitude_rad <= 0.0 {
            return Complex64::new(0.0, 0.0);
        }
        let w = self.omega_rad_s;
        -self.motor_inertia_kg_m2 * w * w * self.lost_motion_harmonic(1) / self.amplitude_rad
    }

    /// The `h`-th harmonic (rad, phasor relative to the angle's fundamental:
    /// `Δ ≈ Re Σ Δ_h e^{jh(ωt + ∠Θ₁)}`) of the motor side's angle relative to
    /// the arm, `Δ`, in a gear mesh with lost motion `2δ` that passes the
    /// torque `P + T cos(ωt + ∠Θ₁ + ∠Z_arm)` (`T = |Z_arm| A`).
    ///
    /// Where the torque reverses (`|P| < T`), `Δ` flips between `−δ` and `+δ`
    /// at each reversal: a pulse wave, `+δ` while the torque is positive, i.e.
    /// for `|x| < φ₀ = arccos(−P/T)` of the torque's phase `x`, whose cosine
    /// series is `δ Σ (4/(hπ)) sin(hφ₀) cos(hx)` (`sin φ₀ = √(1 − (P/T)²)`;
    /// with a preload the duty is not ½ and even harmonics appear). The motor
    /// side, on its own, crosses the lost motion under the torque's ramp through
    /// zero (slope `s = T ω sin φ₀`), `J_m Δ̈ ≈ s t`, and reaches the middle after
    /// `t½ = (6 J_m δ / s)^{1/3}`: each edge lags the torque's zero crossing by
    /// `t½` (capped at a quarter period), so harmonic `h` lags by `h ω t½`:
    ///
    /// `Δ_h = δ (4/(hπ)) sin(hφ₀) e^{jh(∠Z_arm − ω t½)}`.
    ///
    /// The SEA's torque carries `−J_m (hω)² Δ_h` at harmonic `h` beyond what the
    /// arm's linear impedance makes of the angle's own harmonic: backlash's
    /// signature outside the transfer functions
    /// ([`crate::signatures::backlash_harmonic_check`]). Zero where the mesh
    /// stays closed, for `h = 0`, no lost motion, or no motion. Assumptions: the
    /// crossing is short against half a cycle (its shape is left out, only its
    /// middle's lag kept); the impacts' losses and the mesh's own compliance
    /// are left out.
    pub fn lost_motion_harmonic(&self, h: u32) -> Complex64 {
        let t = self.z_arm.norm() * self.amplitude_rad;
        // The mesh stays closed (or nothing is known): no effect. NaN counts as
        // closed, and so does no motion (`A ≤ 0` makes `T ≤ 0`); no lost motion
        // (or a negative one, which means nothing) is no effect.
        let opens = t > self.preload_nm.abs();
        if !opens || self.half_lash_rad <= 0.0 || h == 0 {
            return Complex64::new(0.0, 0.0);
        }
        let phi0 = (-self.preload_nm / t).acos();
        let slope = t * self.omega_rad_s * phi0.sin();
        let lag = (self.omega_rad_s
            * (6.0 * self.motor_inertia_kg_m2 * self.half_lash_rad / slope).cbrt())
        .min(std::f64::consts::FRAC_PI_2);
        let hf = f64::from(h);
        let size = self.half_lash_rad * 2.0 * std::f64::consts::FRAC_2_PI / hf * (hf * phi0).sin();
        size * Complex64::from_polar(1.0, hf * (self.z_arm.arg() - lag))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit's bounds, by what each parameter means: errors and offsets
    /// and the polynomial spring and the drift take either sign; a
    /// stiffness stays positive; the cubic damper stays passive (B₃ ≥ 0,
    /// the simulator's range); delays and dampings are non-negative.
    #[test]
    fn each_parameter_is_clamped_to_what_it_can_physically_be() {
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        let mut p = Physics::from_plant(&PlantModel::from_file(&plant).unwrap(), &[1]);
        for (q, v) in [
            (Param::InertiaError, -0.01),
            (Param::GravityError, -0.5),
            (Param::TorqueOffset, -0.2),
            (Param::CubicStiffness, -50.0),
            (Param::StiffnessDrift, -0.02),
        ] {
            p.set(q, v);
            assert_eq!(p.get(q), v, "{q:?} may be negative");
        }
        for (q, v, floor) in [
            (Param::CubicDamping, -1.0, 0.0),
            (Param::K(1), -5.0, 1e-3),
            (Param::Bh, -0.1, 0.0),
            (Param::DelayTheta, -1e-3, 0.0),
            (Param::SeaWn, 0.5, 1.0),
        ] {
            p.set(q, v);
            assert_eq!(p.get(q), floor, "{q:?} set to {v}");
        }
    }

    /// A posture-dependent stiffness moves the human's stiffness at angle
    /// amplitude A by `−K₂² A²/4K` (its mean torque shifts the posture),
    /// written out: K = 30, K₂ = 20, A = 0.1 rad → −400·0.01/120 =
    /// −0.0333 Nm/rad in S_h's real part, nothing in its imaginary part.
    #[test]
    fn the_posture_form_shifts_the_stiffness_by_k2_squared_a_squared_over_4k() {
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        let mut p = Physics::from_plant(&PlantModel::from_file(&plant).unwrap(), &[1]);
        p.k.insert(1, 30.0);
        p.delay_s = [0.0; 4];
        let c = Condition::test_window(0.0, 0.1 * p.gain[0], 0.001);
        let zero = Complex64::new(0.0, 0.0);
        let before = p.predict_tf(Tf::Sh, 3.0, &c, zero);
        p.k2 = 20.0;
        let after = p.predict_tf(Tf::Sh, 3.0, &c, zero);
        let want = -20.0 * 20.0 * 0.01 / (4.0 * 30.0) * p.gain[1] / p.gain[0];
        assert!(
            ((after - before).re - want).abs() < 1e-9 && (after - before).im.abs() < 1e-9,
            "{} against {want}",
            after - before
        );
    }

    /// Gravity's gain from a window's measured angle: a swing `θ₀ + A cos
    /// ωt + B cos(2ωt + φ)` about 45° sampled at 1 kHz over three cycles,
    /// against `[sin(θ − δ)]₁ / [θ]₁` summed here directly (`(2/n) Σ y
    /// e^{−jωt}`, no detrending: the swing is periodic; the correlator's
    /// trend takes a little of the harmonics, hence 0.1 %), with an encoder
    /// offset δ. Its own second harmonic (B = 0.02 rad at A = 0.2) moves the
    /// gain beyond the pure sine's describing function, which the check
    /// also shows, so it can tell the two apart.
    #[test]
    fn gravitys_gain_is_the_measured_swings_fundamental_of_the_sine() {
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        let mut p = Physics::from_plant(&PlantModel::from_file(&plant).unwrap(), &[1]);
        p.gain[0] = 1.0;
        // ω = π: three cycles are exactly 6000 samples.
        let (w, th0, a, b, phi) = (std::f64::consts::PI, 0.785, 0.2, 0.02, 0.7);
        let n = 6000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let th: Vec<f64> = t
            .iter()
            .map(|t| th0 + a * (w * t).cos() + b * (2.0 * w * t + phi).cos())
            .collect();
        let fund = |y: &dyn Fn(f64) -> f64| -> Complex64 {
            t.iter()
                .zip(&th)
                .map(|(t, th)| y(*th) * Complex64::from_polar(1.0, -w * t))
                .sum::<Complex64>()
                * (2.0 / n as f64)
        };
        let g = crate::data::GravityFundamentals::new(&t[..n], &th, w).expect("measurable");
        let mut c = Condition {
            load_kg: 4.5,
            gravity: Some(g),
            ..Condition::test_window(th0, a, 0.001)
        };
        for delta in [0.0, 0.03] {
            p.theta_offset = delta;
            let want = fund(&|x| (x - delta).sin()) / fund(&|x| x);
            let got = p.gravity_gain(&c);
            eprintln!(
                "δ = {delta}: off by {:.2e}",
                (got - want).norm() / want.norm()
            );
            assert!(
                (got - want).norm() < 1e-3 * want.norm(),
                "δ = {delta}: {got} against {want}"
            );
        }
        p.theta_offset = 0.0;
        let exact = p.gravity_gain(&c);
        c.gravity = None;
        let pure = p.gravity_gain(&c);
        eprintln!(
            "harmonic's share {:.2e}",
            (exact - pure).norm() / pure.norm()
        );
        assert!(
            (exact - pure).norm() > 5e-3 * pure.norm(),
            "the harmonic's share {} is too small to tell",
            (exact - pure).norm() / pure.norm()
        );
    }

    /// A mesh of half lost motion `d`, motor inertia `jm`, arm side `z`,
    /// preload `p`, amplitude `a` at `w`.
    fn mesh(d: f64, jm: f64, z: Complex64, p: f64, a: f64, w: f64) -> Mesh {
        Mesh {
            half_lash_rad: d,
            motor_inertia_kg_m2: jm,
            z_arm: z,
            preload_nm: p,
            amplitude_rad: a,
            omega_rad_s: w,
        }
    }

    /// Gravity's describing function against the fundamental of `sin(θ₀ +
    /// A cos φ)` integrated here by the midpoint rule, over the angles a joint
    /// moves through; and its small-amplitude limit `1 − A²/8`.
    #[test]
    fn gravity_describing_function_is_the_fundamental_of_the_sine() {
        for theta0 in [0.3_f64, 0.785, 1.4] {
            for a in [0.01_f64, 0.18, 0.5, 1.2] {
                let n = 100_000;
                let mut acc = 0.0;
                for i in 0..n {
                    let phi = std::f64::consts::TAU * (i as f64 + 0.5) / n as f64;
                    acc += (theta0 + a * phi.cos()).sin() * phi.cos();
                }
                let fundamental = acc * 2.0 / n as f64;
                let want = fundamental / (a * theta0.cos());
                let got = gravity_describing(a);
                assert!(
                    (got - want).abs() < 1e-9,
                    "θ₀ {theta0}, A {a}: {got} against {want}"
                );
            }
        }
        assert!((gravity_describing(0.01) - (1.0 - 1e-4 / 8.0)).abs() < 1e-9);
        assert_eq!(gravity_describing(0.0), 1.0);
    }

    /// The lost motion's harmonics against a direct Fourier integral of the
    /// pulse wave they describe: `Δ(x) = δ sgn(P + T cos x)` delayed by the
    /// crossing's lag, integrated here by the midpoint rule over one cycle
    /// (`Δ_h = (1/π) ∫ Δ(x) e^{−jhx} dx`), with the lag written out from
    /// `t½ = (6 J_m δ / s)^{1/3}`, at no preload (odd harmonics only) and
    /// at a preload (even ones too).
    #[test]
    fn lost_motion_harmonics_are_the_pulse_waves_fourier_series() {
        let (delta, jm, w, a) = (0.03, 0.02, 5.0, 0.1);
        let z = Complex64::from_polar(30.0, 0.4);
        let t = z.norm() * a;
        for preload in [0.0, 1.2, -2.1] {
            let open = (1.0 - (preload / t).powi(2)).sqrt();
            let lag = w * (6.0 * jm * delta / (t * w * open)).cbrt();
            for h in 1..=4u32 {
                let n = 200_000;
                let mut acc = Complex64::new(0.0, 0.0);
                for i in 0..n {
                    // x: the phase of ωt + ∠Θ₁; the torque's phase is x + ∠Z_arm.
                    let x = std::f64::consts::TAU * (i as f64 + 0.5) / n as f64;
                    let torque = preload + t * (x + z.arg() - lag).cos();
                    let d = if torque > 0.0 { delta } else { -delta };
                    acc += d * Complex64::from_polar(1.0, -f64::from(h) * x);
                }
                let want = acc * (2.0 / n as f64);
                let got = mesh(delta, jm, z, preload, a, w).lost_motion_harmonic(h);
                assert!(
                    (got - want).norm() < 1e-4 * delta,
                    "h = {h}, P = {preload}: {got} against {want}"
                );
            }
        }
        // At no preload the even harmonics vanish; the 3rd is a third of the
        // fundamental's size.
        let h1 = mesh(delta, jm, z, 0.0, a, w).lost_motion_harmonic(1);
        let h2 = mesh(delta, jm, z, 0.0, a, w).lost_motion_harmonic(2);
        let h3 = mesh(delta, jm, z, 0.0, a, w).lost_motion_harmonic(3);
        assert!(h2.norm() < 1e-12 && (h3.norm() * 3.0 - h1.norm()).abs() < 1e-12);
        // Nothing where the mesh stays closed, for h = 0, or without lash.
        for (h, d, p) in [(2, delta, 3.5), (0, delta, 0.0), (3, 0.0, 0.0)] {
            assert_eq!(
                mesh(d, jm, z, p, a, w).lost_motion_harmonic(h),
                Complex64::new(0.0, 0.0)
            );
        }
    }

    /// The backlash describing function with the numbers written out: a
    /// mesh torque of amplitude T = |Z_arm| A = 3 Nm with no preload,
    /// δ = 0.05 rad, J_m = 0.02 kg·m², ω = 5 rad/s: size J_m ω² (4/π) δ/A
    /// = 0.02·25·1.27324·0.5 = 0.318310, lag ω (6 J_m δ/(T ω))^{1/3} =
    /// 5·(4e-4)^{1/3} = 0.368403 rad, along −Z_arm/|Z_arm| = −1; with a
    /// preload of 0.8 T the opening factor is 0.6 (size ×0.6, slope ×0.6);
    /// none where the preload exceeds T.
    #[test]
    fn backlash_describing_function_by_hand() {
        let z = Complex64::new(30.0, 0.0);
        // J_m ω² (4/π) δ/A, written out.
        let size = 0.02 * 25.0 * (4.0 / std::f64::consts::PI) * (0.05 / 0.1);
        let got = mesh(0.05, 0.02, z, 0.0, 0.1, 5.0).describing();
        let want = Complex64::from_polar(size, std::f64::consts::PI - 0.368_403_15);
        assert!((got - want).norm() < 1e-6, "{got} against {want}");
        let got = mesh(0.05, 0.02, z, 2.4, 0.1, 5.0).describing();
        let lag = 5.0 * (6.0 * 0.02 * 0.05 / (3.0 * 5.0 * 0.6_f64)).cbrt();
        let want = Complex64::from_polar(0.6 * size, std::f64::consts::PI - lag);
        assert!((got - want).norm() < 1e-6, "{got} against {want}");
        assert_eq!(
            mesh(0.05, 0.02, z, -3.1, 0.1, 5.0).describing(),
            Complex64::new(0.0, 0.0)
        );
        assert_eq!(
            mesh(0.0, 0.02, z, 0.0, 0.1, 5.0).describing(),
            Complex64::new(0.0, 0.0)
        );
        // Its direction follows the arm's impedance.
        let zi = Complex64::new(0.0, 30.0);
        let got = mesh(0.05, 0.02, zi, 0.0, 0.1, 5.0).describing();
        let want = Complex64::from_polar(size, -std::f64::consts::FRAC_PI_2 - 0.368_403_15);
        assert!((got - want).norm() < 1e-6, "{got} against {want}");
        // A long crossing: the lag is capped at π/2.
        let got = mesh(0.05, 2.0, z, 0.0, 0.1, 5.0).describing();
        let want = Complex64::from_polar(100.0 * size, std::f64::consts::FRAC_PI_2);
        assert!((got - want).norm() < 1e-4, "{got} against {want}");
    }

    /// A torque limit's gain from a window's command samples
    /// ([`crate::data::CommandPeaks::clip_gain`]) against the describing
    /// function of a clipped sine `b + A sin φ`, written out here as the
    /// independent truth: each side clips where `sin φ` passes `u = (L −
    /// b)/A` or `v = (L + b)/A` and removes `f(u) = (π/2 − asin u − u √(1 −
    /// u²))/π` of the fundamental (the textbook `(2/π)(asin u + u √(1 −
    /// u²))` without a mean), at limits above, at and below the peaks, with
    /// and without a mean, and a whole cycle beyond the limit.
    #[test]
    fn the_torque_limits_gain_is_the_clipped_sines_fundamental() {
        let f = |u: f64| {
            let u = u.clamp(-1.0, 1.0);
            (std::f64::consts::FRAC_PI_2 - u.asin() - u * (1.0 - u * u).sqrt())
                / std::f64::consts::PI
        };
        let describing = |l: f64, b: f64, a: f64| (1.0 - f((l - b) / a) - f((l + b) / a)).max(0.0);
        let w = 5.0;
        for (l, b, a) in [
            (30.0, 0.0, 2.0),
            (1.5, 0.0, 2.0),
            (26.0, 24.0, 3.2),
            (22.0, 24.0, 3.2),
            (20.0, 24.0, 3.2),
            (5.0, -4.0, 2.0),
            (3.0, -4.0, 8.0),
            (0.5, 0.0, 4.0),
        ] {
            // Four whole cycles, 20 000 samples, at a phase of 0.3 rad.
            let n = 20_000;
            let t: Vec<f64> = (0..n)
                .map(|k| 4.0 * std::f64::consts::TAU / w * k as f64 / n as f64)
                .collect();
            let x: Vec<f64> = t.iter().map(|t| b + a * (w * t + 0.3).sin()).collect();
            let cmd = crate::data::CommandPeaks::new(&t, &x, w).unwrap();
            let got = cmd.clip_gain(l);
            let want = describing(l, b, a);
            assert!(
                (got - want).norm() < 2e-4,
                "L {l}, b {b}, A {a}: {got} against {want}"
            );
            assert!((cmd.peak_nm() - (b.abs() + a)).abs() < 1e-6);
        }
        // A clip at the mean keeps half the fundamental.
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|t| 24.0 + 3.0 * (std::f64::consts::TAU * t).cos())
            .collect();
        let cmd = crate::data::CommandPeaks::new(&t, &x, std::f64::consts::TAU).unwrap();
        assert!((cmd.clip_gain(24.0) - 0.5).norm() < 1e-3);
        // No limit, or a limit beyond the peaks: no effect.
        assert_eq!(cmd.clip_gain(f64::INFINITY), Complex64::new(1.0, 0.0));
        assert!((cmd.clip_gain(27.5) - 1.0).norm() < 1e-12);
        // A command that is not finite is no command.
        assert!(crate::data::CommandPeaks::new(&t, &[f64::NAN; 1000], 1.0).is_none());
    }
}
