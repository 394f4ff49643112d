//! The coefficients written back into a plant model and a subject file.

use std::collections::BTreeMap;

use exo_plant_model::PlantModel;

use super::physics::Physics;

impl Physics {
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
