//! Raw bus values to physical units. The same code runs on hardware and on
//! the simulator's bus, with constants from the run file's `[rig]` table.

use exo_config::RigSettings;

/// Conversion constants of the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    rad_per_count: f64,
    cuff_lever_arm_m: f64,
    sea_nm_per_count: f64,
}

impl Calibration {
    /// From the rig settings.
    pub fn new(rig: &RigSettings) -> Self {
        let tau = std::f64::consts::TAU;
        Calibration {
            rad_per_count: tau / rig.encoder_counts_per_rev,
            cuff_lever_arm_m: rig.cuff_lever_arm_m,
            sea_nm_per_count: rig.sea_stiffness_nm_per_rad * tau / rig.sea_counts_per_rev,
        }
    }

    /// Joint angle θ_e (rad) from encoder counts.
    pub fn theta_rad(&self, counts: i64) -> f64 {
        counts as f64 * self.rad_per_count
    }

    /// Interaction torque `τ_c = Jᵀ f_c` (Nm) from the cuff's 6-axis reading
    /// `[f_x, f_y, f_z, t_x, t_y, t_z]` (N, Nm) in the sensor frame: x along
    /// the arm away from the joint, z along the joint axis, y completing the
    /// right-handed frame (the direction of positive θ). The sensor sits at
    /// `r` = `cuff_lever_arm_m` from the joint, so the only non-zero row of
    /// the Jacobian gives `τ_c = r f_y + t_z`. Sign: the torque the cuff
    /// applies to the human (the paper's `τ_c`, `S_h = τ_c/θ_e`).
    pub fn tau_c_nm(&self, wrench: &[f64; 6]) -> f64 {
        self.cuff_lever_arm_m * wrench[1] + wrench[5]
    }

    /// SEA spring torque τ_s (Nm) from the spring-deflection encoder counts.
    pub fn tau_s_nm(&self, deflection_counts: i64) -> f64 {
        deflection_counts as f64 * self.sea_nm_per_count
    }
}

/// Joint velocity from successive angles: a backward difference low-passed
/// by a first-order filter discretised exactly (`a = e^{−2π f_c T}`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityFilter {
    a: f64,
    rate_hz: f64,
    previous_theta: Option<f64>,
    omega: f64,
}

impl VelocityFilter {
    /// A filter with cut-off `cutoff_hz` at sample rate `rate_hz`.
    pub fn new(cutoff_hz: f64, rate_hz: f64) -> Self {
        VelocityFilter {
            a: (-std::f64::consts::TAU * cutoff_hz / rate_hz).exp(),
            rate_hz,
            previous_theta: None,
            omega: 0.0,
        }
    }

    /// The velocity estimate (rad/s) after angle `theta_rad`.
    #[inline]
    pub fn update(&mut self, theta_rad: f64) -> f64 {
        let raw = match self.previous_theta {
            Some(p) => (theta_rad - p) * self.rate_hz,
            None => 0.0,
        };
        self.previous_theta = Some(theta_rad);
        self.omega = self.a * self.omega + (1.0 - self.a) * raw;
        self.omega
    }
}

/// The rig the crate's unit tests calibrate against (the default plant's
/// arm and sensors, 4096-count encoders, a 50 Hz velocity filter).
#[cfg(test)]
pub(crate) fn test_rig() -> RigSettings {
    RigSettings {
        arm_inertia_kg_m2: 0.1,
        arm_mass_kg: 1.5,
        arm_com_m: 0.2,
        load_lever_arm_m: 0.45,
        encoder_counts_per_rev: 4096.0,
        cuff_lever_arm_m: 0.25,
        sea_stiffness_nm_per_rad: 350.0,
        sea_counts_per_rev: 4096.0,
        velocity_cutoff_hz: 50.0,
        gravity_m_s2: exo_config::GRAVITY_M_S2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> RigSettings {
        test_rig()
    }

    #[test]
    fn conversions() {
        let c = Calibration::new(&rig());
        assert!((c.theta_rad(1024) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(
            c.tau_c_nm(&[3.0, 8.0, 1.0, 0.5, 0.2, 0.5]),
            0.25 * 8.0 + 0.5
        );
        assert!((c.tau_s_nm(-1024) + 350.0 * std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }

    #[test]
    fn velocity_of_a_ramp_converges_to_its_slope() {
        let mut v = VelocityFilter::new(50.0, 1000.0);
        let mut w = 0.0;
        for k in 0..200 {
            w = v.update(0.002 * k as f64);
        }
        assert!((w - 2.0).abs() < 1e-9, "{w}");
    }
}
