//! Matrix exponential by scaling and squaring with a Taylor series, used once
//! per parameter change to discretise the plant exactly.

use nalgebra::DMatrix;

/// `e^A` for a square matrix: scale `A` by `2^-s` so its 1-norm is below
/// 0.5, sum the Taylor series to machine precision, square `s` times.
pub fn expm(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let norm = (0..n)
        .map(|j| (0..n).map(|i| a[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let s = if norm > 0.5 {
        (norm / 0.5).log2().ceil() as i32
    } else {
        0
    };
    let scaled = a / 2f64.powi(s);
    let mut result = DMatrix::<f64>::identity(n, n);
    let mut term = DMatrix::<f64>::identity(n, n);
    for k in 1..40 {
        term = &term * &scaled / k as f64;
        result += &term;
        if term.iter().map(|v| v.abs()).fold(0.0, f64::max) < 1e-18 {
            break;
        }
    }
    for _ in 0..s {
        result = &result * &result;
    }
    result
}

/// Zero-order-hold discretisation of `ẋ = A x + B u` over `h`:
/// `Φ = e^{Ah}`, `Γ = ∫₀ʰ e^{As} ds B`, from one exponential of the
/// augmented matrix `[[A, B], [0, 0]] h`.
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut aug = DMatrix::<f64>::zeros(n + m, n + m);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * h));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * h));
    let e = expm(&aug);
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_generator_gives_rotation() {
        let w = 3.0;
        let a = DMatrix::from_row_slice(2, 2, &[0.0, -w, w, 0.0]);
        let e = expm(&(a * 0.7));
        let (c, s) = ((w * 0.7).cos(), (w * 0.7).sin());
        let expected = DMatrix::from_row_slice(2, 2, &[c, -s, s, c]);
        assert!((e - expected).amax() < 1e-13);
    }

    #[test]
    fn damped_oscillator_matches_analytic_solution() {
        // ẍ + 2ζω ẋ + ω² x = 0, x(0) = 1, ẋ(0) = 0, over 2.3 s with a large norm.
        let (w, z, t) = (40.0, 0.1, 2.3);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * z * w]);
        let e = expm(&(a * t));
        let wd = w * (1.0 - z * z).sqrt();
        let x = (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin());
        assert!((e[(0, 0)] - x).abs() < 1e-10, "{} vs {x}", e[(0, 0)]);
    }

    #[test]
    fn zoh_of_an_integrator_is_exact() {
        let a = DMatrix::from_row_slice(1, 1, &[-2.0]);
        let b = DMatrix::from_row_slice(1, 1, &[2.0]);
        let (phi, gamma) = zoh(&a, &b, 0.1);
        assert!((phi[(0, 0)] - (-0.2f64).exp()).abs() < 1e-15);
        assert!((gamma[(0, 0)] - (1.0 - (-0.2f64).exp())).abs() < 1e-15);
    }
}
