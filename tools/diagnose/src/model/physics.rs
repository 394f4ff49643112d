//! Every coefficient of the forward model ([`Physics`]): read from a plant
//! model, got and set by parameter.

use std::collections::BTreeMap;

use exo_plant_model::PlantModel;
use serde::Serialize;

use super::param::Param;

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
}
