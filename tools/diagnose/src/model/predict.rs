//! What the coefficients predict for each transfer function in a window:
//! the frequency-domain forward model itself.

use num_complex::Complex64;

use super::describing::{coulomb_describing, gravity_describing};
use super::mesh::Mesh;
use super::physics::Physics;
use crate::data::{Condition, Observation, Tf};

impl Physics {
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
}

#[cfg(test)]
mod tests {
    use exo_plant_model::PlantModel;

    use super::*;

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
}
