//! The describing functions of the joint's smoothed Coulomb friction and of
//! gravity about the mean angle.

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

#[cfg(test)]
mod tests {
    use super::*;

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
}
