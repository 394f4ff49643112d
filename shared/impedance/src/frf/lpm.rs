//! A window's noise from the bins beside the line ([`mean_standard_error`])
//! and the local polynomial method ([`local_polynomial_ratio`]): a line
//! with the window's transient taken out.

use nalgebra::{Matrix4, Vector4};
use num_complex::Complex64;

use super::sine::block_end;

/// Whole cycles `c` of ω in the block `t_s` (its span rounded).
fn cycles_in(t_s: &[f64], omega_rad_s: f64) -> Option<i64> {
    let end = block_end(t_s)?;
    let c = (omega_rad_s * (end - t_s[0]) / std::f64::consts::TAU).round();
    (c >= 1.0).then_some(c as i64)
}

/// Each signal less its mean and linear trend, fitted jointly with the
/// line at ω (over whole cycles a trend is not orthogonal to the line, so
/// taking it out alone would bias the line), and less the line too when
/// `keep_line` is false.
fn without_mean_and_trend<const M: usize>(
    t_s: &[f64],
    omega_rad_s: f64,
    signals: [&[f64]; M],
    keep_line: bool,
) -> Option<[Vec<f64>; M]> {
    let n = t_s.len();
    let t0 = t_s[0];
    let tm = t_s.iter().sum::<f64>() / n as f64;
    let reg = |i: usize| {
        let tau = t_s[i] - t0;
        Vector4::new(
            1.0,
            t_s[i] - tm,
            (omega_rad_s * tau).cos(),
            (omega_rad_s * tau).sin(),
        )
    };
    let mut gram = Matrix4::<f64>::zeros();
    for i in 0..n {
        let a = reg(i);
        gram += a * a.transpose();
    }
    let inv = gram.try_inverse()?;
    Some(signals.map(|v| {
        let mut rhs = Vector4::<f64>::zeros();
        for (i, vi) in v.iter().enumerate() {
            rhs += reg(i) * *vi;
        }
        let mut beta = inv * rhs;
        if keep_line {
            beta[2] = 0.0;
            beta[3] = 0.0;
        }
        v.iter()
            .enumerate()
            .map(|(i, vi)| vi - reg(i).dot(&beta))
            .collect()
    }))
}

/// The complex amplitude `(2/n) Σ v e^{−jω(t − t₀)}` of `v` at `omega_rad_s`.
fn dft_at(t_s: &[f64], v: &[f64], omega_rad_s: f64) -> Complex64 {
    let scale = 2.0 / v.len() as f64;
    let t0 = t_s[0];
    t_s.iter()
        .zip(v)
        .map(|(t, v)| Complex64::from_polar(scale * v, -omega_rad_s * (t - t0)))
        .sum()
}

/// The standard error (units of `y`) of the mean of `y` over a window of
/// whole cycles of ω, from the noise at the lowest DFT bins `k = 1…4` of
/// the window (mean, trend and the line out; harmonics of ω left out): a
/// mean is a zero-frequency estimate, and its noise is the noise near zero
/// frequency (slow wander, a twitch's or a mode's low-frequency content),
/// not the residual's variance spread over the band. For white noise of
/// variance `s²` each bin holds `E|Y_k|² = 4 s²/n`, so the mean's variance
/// `s²/n` is `E|Y_k|²/4`. The line is taken out too: a block of samples
/// is whole cycles only to a sample, and the rest of a large line would
/// leak into the bins. `None` with fewer than two such bins (one cycle:
/// the bins are harmonics).
pub fn mean_standard_error(t_s: &[f64], y: &[f64], omega_rad_s: f64) -> Option<(f64, usize)> {
    let n = t_s.len();
    if n < 16 || y.len() != n || !omega_rad_s.is_finite() || omega_rad_s <= 0.0 {
        return None;
    }
    let c = cycles_in(t_s, omega_rad_s)?;
    let [yd] = without_mean_and_trend(t_s, omega_rad_s, [y], false)?;
    let (mut sum, mut bins) = (0.0, 0usize);
    for k in (1..=4i64).filter(|k| k % c != 0) {
        let wk = omega_rad_s * k as f64 / c as f64;
        sum += dft_at(t_s, &yd, wk).norm_sqr();
        bins += 1;
    }
    (bins >= 2).then(|| ((sum / bins as f64 / 4.0).sqrt(), bins))
}

/// Bins each side of the line the local polynomial method looks at.
const LPM_HALF_WIDTH: i64 = 4;

/// A ratio `Y/X` at a sine's line by the local polynomial method
/// ([`local_polynomial_ratio`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalPolynomialPoint {
    /// `Y/X` at ω with the window's transient taken out.
    pub ratio: Complex64,
    /// The variance of [`Self::ratio`] over that of the line alone
    /// (`Y_c/X_c`) for the same noise per bin (≥ 1: the price of estimating
    /// the transient from the neighbours).
    pub leverage: f64,
    /// The standard deviation per component of [`Self::ratio`] from the
    /// local fit's own residual (what the neighbours hold beyond the
    /// polynomials).
    pub residual_sigma: f64,
    /// Complex degrees of freedom of that residual.
    pub dof: usize,
}

/// `Y/X` at ω over a window of whole cycles, with the window's transient
/// taken out by the local polynomial method (Pintelon, Schoukens et al.,
/// "Estimation of nonparametric noise and FRF models for multivariable
/// systems", MSSP 24, 2010). A window that is not a steady state (a mode
/// still ringing after the last frequency step, an offset that moved)
/// leaks into the line: a linear relation between two signals that are not
/// periodic in the window holds at every DFT bin `k` only up to a term
/// `T(k)` from the signals' ends, smooth in `k`; `Y_k = H(k) X_k + T(k)`.
/// Over the bins `k = c + r` of the window's `c` whole cycles, `|r| ≤ 4`,
/// harmonics of ω other than the line left out (a nonlinearity's periodic
/// response is there), `H` and `T` are fitted as low-degree polynomials in
/// `r` (`H` of degree 1 and `T` of degree 2 with eight neighbours or more,
/// both of degree 1 with five, `H` constant with three) and `H(c)` is the
/// ratio. The mean and a linear trend (fitted jointly with the line, so
/// the line is not biased) are taken out first.
///
/// `None` when the window has fewer than three usable neighbours (under
/// three cycles) or the fit is singular: the caller keeps the line alone.
pub fn local_polynomial_ratio(
    t_s: &[f64],
    x: &[f64],
    y: &[f64],
    omega_rad_s: f64,
) -> Option<LocalPolynomialPoint> {
    use nalgebra::DMatrix;
    let n = t_s.len();
    if n < 16 || x.len() != n || y.len() != n || !omega_rad_s.is_finite() || omega_rad_s <= 0.0 {
        return None;
    }
    let c = cycles_in(t_s, omega_rad_s)?;
    let [xd, yd] = without_mean_and_trend(t_s, omega_rad_s, [x, y], true)?;
    let mut rows: Vec<(f64, Complex64, Complex64)> = Vec::with_capacity(9);
    for r in -LPM_HALF_WIDTH..=LPM_HALF_WIDTH {
        let k = c + r;
        if k <= 0 || (r != 0 && k % c == 0) {
            continue;
        }
        let wk = omega_rad_s * k as f64 / c as f64;
        rows.push((r as f64, dft_at(t_s, &xd, wk), dft_at(t_s, &yd, wk)));
    }
    let neighbours = rows.len() - 1;
    let (h_degree, t_degree) = match neighbours {
        8.. => (1, 2),
        5..=7 => (1, 1),
        3..=4 => (0, 1),
        _ => return None,
    };
    let p = h_degree + 1 + t_degree + 1;
    let m = rows.len();
    let a = DMatrix::<Complex64>::from_fn(m, p, |i, j| {
        let (r, xk, _) = rows[i];
        if j <= h_degree {
            xk * r.powi(j as i32)
        } else {
            Complex64::new(r.powi((j - h_degree - 1) as i32), 0.0)
        }
    });
    let b = DMatrix::<Complex64>::from_fn(m, 1, |i, _| rows[i].2);
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    if smax.is_nan() || smax <= 0.0 {
        return None;
    }
    let v_t = svd.v_t.as_ref()?;
    // (AᴴA)⁻¹₀₀ = Σ |V₀ᵢ|²/sᵢ² over the non-negligible singular values.
    let mut inv00 = 0.0;
    for (i, s) in svd.singular_values.iter().enumerate() {
        if *s > 1e-10 * smax {
            inv00 += v_t[(i, 0)].norm_sqr() / (s * s);
        }
    }
    let theta = svd.solve(&b, 1e-10 * smax).ok()?;
    let line = rows.iter().position(|(r, ..)| *r == 0.0)?;
    let x_line = rows[line].1;
    if x_line.norm() == 0.0 {
        return None;
    }
    let resid = &b - &a * &theta;
    let dof = m - p;
    let ss: f64 = resid.iter().map(|e| e.norm_sqr()).sum();
    let residual_sigma = if dof > 0 {
        (0.5 * ss / dof as f64 * inv00).sqrt()
    } else {
        f64::NAN
    };
    Some(LocalPolynomialPoint {
        ratio: theta[0],
        leverage: x_line.norm_sqr() * inv00,
        residual_sigma,
        dof,
    })
}
