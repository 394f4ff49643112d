//! A gear mesh with lost motion (backlash) as one window drives it
//! ([`Mesh`]).

use num_complex::Complex64;

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
}
