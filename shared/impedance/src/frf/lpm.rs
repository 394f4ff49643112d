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
/// `s²/n` is `E|Y_k|²/4`, less the share of the bins the trend took out
/// (stop 37: unaccounted, it left the estimate 6 % low). The line is
/// taken out too: a block of samples is whole cycles only to a sample,
/// and the rest of a large line would leak into the bins. `None` with fewer than two such bins (one cycle:
/// the bins are harmonics).
pub fn mean_standard_error(t_s: &[f64], y: &[f64], omega_rad_s: f64) -> Option<(f64, usize)> {
    low_bin_noise(t_s, y, None, omega_rad_s).map(|(se, _, bins)| (se, bins))
}

/// [`mean_standard_error`] of a torque balance `y` with what the motion of
/// the angle explains at the bins taken out first, read at the bins
/// `k = 1…`[`BESIDE_BINS`] (multiples of the window's cycles left out). `x`
/// is `sin θ`; `y` a balance of torques on a rigid link,
/// `y = M θ̈ + b θ̇ + g sin θ + noise` (`τ_s − τ_gravity − τ_c` on the arm).
/// At bin `k` the window's DFT of that is linear in five regressors fitted
/// with real coefficients by least squares: `X_k`, `jω_k X_k`,
/// `ω_k² X_k` (gravity's moment, the damping, the inertia; `sin θ`
/// stands for `θ` about the window's posture) and the two boundary terms
/// of a motion that is not periodic in the window, `1` and `jω_k` (the
/// DFT of `θ̈` over a window `T` is `−ω_k² Θ_k + (2/T)(Δθ̇ + jω_k Δθ)`,
/// `Δ` the change over the window). Without them a mode still ringing in
/// the window (the arm's lightly damped mode near bins 2–3 of a window of
/// ten cycles, 10–500 times the white noise's power there on the
/// independent rig's nulls, docs/diagnose.md) was read as noise of the
/// mean, where the Hann-tapered mean ([`hann_mean`]) hardly holds it.
/// Where `y` follows the posture's slow wander the same way, that response
/// is no noise of the balance either. Returns the standard error and its
/// real degrees of freedom (two per bin less the regressors' rank and the
/// share the trend took); `None` with fewer than two bins or no degree of
/// freedom left.
pub fn mean_standard_error_beside(
    t_s: &[f64],
    y: &[f64],
    x: &[f64],
    omega_rad_s: f64,
) -> Option<(f64, f64)> {
    low_bin_noise(t_s, y, Some(x), omega_rad_s).map(|(se, dof, _)| (se, dof))
}

/// The highest bin of the window [`mean_standard_error_beside`] reads: twelve
/// bins for six cycles leave it ten (the line's and its harmonic's out),
/// twenty real components for five regressors. Four (as
/// [`mean_standard_error`] reads) would leave three degrees of freedom.
/// An assumption: the noise of the balance is flat from zero frequency to
/// twelve times the window's (white sensor noise; the motion that colours
/// it is taken out); a sensor's own slow drift within a window would be
/// read low.
pub const BESIDE_BINS: i64 = 12;

/// The noise of the mean of `y` from its lowest bins, less what the motion
/// of `x` explains there when given: the standard error, its real degrees
/// of freedom and the bins ([`mean_standard_error`],
/// [`mean_standard_error_beside`]).
fn low_bin_noise(
    t_s: &[f64],
    y: &[f64],
    x: Option<&[f64]>,
    omega_rad_s: f64,
) -> Option<(f64, f64, usize)> {
    let n = t_s.len();
    if n < 16 || y.len() != n || x.is_some_and(|x| x.len() != n) || !omega_rad_s.is_finite() {
        return None;
    }
    // (An ω ≤ 0 has no whole cycle.)
    let c = cycles_in(t_s, omega_rad_s)?;
    let [yd, xd] = without_mean_and_trend(t_s, omega_rad_s, [y, x.unwrap_or(y)], false)?;
    // The trend taken out with the mean and the line: its share of the
    // bins' real components is the degrees of freedom it took there,
    // `(n/2) Σ_k |R_k|² / ‖r‖²` for the trend `r` less its line (about 0.88
    // of one for four bins: a ramp's power falls as 1/k²).
    let tm = t_s.iter().sum::<f64>() / n as f64;
    let ramp: Vec<f64> = t_s.iter().map(|t| t - tm).collect();
    let half_n = 0.5 * n as f64;
    let ramp_norm = ramp.iter().map(|r| r * r).sum::<f64>()
        - half_n * dft_at(t_s, &ramp, omega_rad_s).norm_sqr();
    let top = if x.is_some() { BESIDE_BINS } else { 4 };
    // (ω_k, Y_k, X_k) at each bin.
    let mut bins = Vec::with_capacity(top as usize);
    let mut trend_dof = 0.0;
    for k in (1..=top).filter(|k| k % c != 0) {
        let wk = omega_rad_s * k as f64 / c as f64;
        let xk = if x.is_some() {
            dft_at(t_s, &xd, wk)
        } else {
            Complex64::new(0.0, 0.0)
        };
        bins.push((wk, dft_at(t_s, &yd, wk), xk));
        trend_dof += half_n * dft_at(t_s, &ramp, wk).norm_sqr() / ramp_norm;
    }
    if bins.len() < 2 || !trend_dof.is_finite() {
        return None;
    }
    // An `x` with nothing at the bins but rounding (a pure line, taken out
    // with the line) explains nothing there.
    let x_power: f64 = x.map_or(0.0, |x| x.iter().map(|v| v * v).sum());
    if bins.iter().map(|b| b.2.norm_sqr()).sum::<f64>() <= 1e-15 * x_power {
        bins.iter_mut().for_each(|b| b.2 = Complex64::new(0.0, 0.0));
    }
    let (ss, rank) = if x.is_some() {
        beside_motion(&bins)
    } else {
        (bins.iter().map(|(_, yk, _)| yk.norm_sqr()).sum(), 0)
    };
    let dof = 2.0 * bins.len() as f64 - rank as f64 - trend_dof;
    if dof <= 0.0 {
        return None;
    }
    // For white noise of variance s² each real component of a bin holds
    // 2 s²/n, and the mean's variance is s²/n.
    Some(((ss / dof / 2.0).sqrt(), dof, bins.len()))
}

/// The bins' residual sum of squares less the five regressors of
/// [`mean_standard_error_beside`], and their numerical rank: each column
/// scaled to unit norm, singular values below 1e-9 of the largest not
/// counted (an `x` zeroed for having nothing at the bins fits only the
/// boundary terms).
fn beside_motion(bins: &[(f64, Complex64, Complex64)]) -> (f64, usize) {
    use nalgebra::{DMatrix, DVector};
    const REGRESSORS: usize = 5;
    let column = |j: usize, (wk, _, xk): &(f64, Complex64, Complex64)| -> Complex64 {
        let jw = Complex64::new(0.0, *wk);
        match j {
            0 => *xk,
            1 => jw * xk,
            2 => xk * (wk * wk),
            3 => Complex64::new(1.0, 0.0),
            _ => jw,
        }
    };
    let m = 2 * bins.len();
    let mut a = DMatrix::<f64>::from_fn(m, REGRESSORS, |i, j| {
        let v = column(j, &bins[i / 2]);
        if i % 2 == 0 {
            v.re
        } else {
            v.im
        }
    });
    let b = DVector::<f64>::from_fn(m, |i, _| {
        let v = bins[i / 2].1;
        if i % 2 == 0 {
            v.re
        } else {
            v.im
        }
    });
    for mut col in a.column_iter_mut() {
        let norm = col.norm();
        if norm > 0.0 {
            col /= norm;
        }
    }
    let svd = a.clone().svd(true, true);
    let eps = 1e-9 * svd.singular_values.max();
    let rank = svd.singular_values.iter().filter(|s| **s > eps).count();
    match svd.solve(&b, eps) {
        Ok(coef) => ((b - a * coef).norm_squared(), rank),
        Err(_) => (b.norm_squared(), 0),
    }
}

/// The mean of `v` weighted by the periodic Hann taper
/// `w_i = ½ − ½ cos(2π i/n)` over its `n` samples. Over a block of `c ≥ 2`
/// whole cycles of ω the taper's spectrum (DFT bins 0 and ±1 only) leaves
/// the line and its harmonics out exactly, and since the taper and its
/// slope vanish at both ends, a transient's boundary terms do too: the
/// plain mean of `M θ̈` is `M (θ̇(T) − θ̇(0))/T`, a mode still ringing at
/// the window's ends, where the tapered mean keeps only what is slow in
/// the window. Its noise is that of the plain mean times
/// [`HANN_MEAN_NOISE_GAIN`]. NaN for an empty block.
pub fn hann_mean(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let (mut sum, mut weight) = (0.0, 0.0);
    for (i, x) in v.iter().enumerate() {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n).cos();
        sum += w * x;
        weight += w;
    }
    sum / weight
}

/// The standard error of [`hann_mean`] over that of the plain mean for
/// noise flat near zero frequency: `√(n Σw²)/Σw` with `Σw = n/2` and
/// `Σw² = 3n/8` for the periodic Hann taper of `n ≥ 3` samples, `√(3/2)`.
pub const HANN_MEAN_NOISE_GAIN: f64 = 1.224_744_871_391_589;

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

#[cfg(test)]
mod tests {
    use super::*;

    /// The tapered mean by hand: a constant is itself; a ramp `i` weighs to
    /// `n/2` (the periodic taper is symmetric about sample `n/2`); a sine
    /// of two whole cycles to zero, where its plain mean over a block a
    /// sample short is not; an exponential's boundary term is gone.
    #[test]
    fn the_hann_mean_keeps_the_level_and_drops_whole_cycles_and_ends() {
        assert!((hann_mean(&[2.5; 40]) - 2.5).abs() < 1e-12);
        let ramp: Vec<f64> = (0..40).map(f64::from).collect();
        assert!((hann_mean(&ramp) - 20.0).abs() < 1e-12);
        let n = 100;
        let sine: Vec<f64> = (0..n)
            .map(|i| 3.0 * (std::f64::consts::TAU * 2.0 * i as f64 / n as f64 + 0.4).sin())
            .collect();
        assert!(hann_mean(&sine).abs() < 1e-12);
        let short = &sine[..n - 1];
        assert!((short.iter().sum::<f64>() / (n - 1) as f64).abs() > 1e-3);
        assert!(hann_mean(&[]).is_nan());
        // The velocity of a mode ringing at 4.3 rad/s (decay 0.2/s) over
        // [0, 5] s: its plain mean is the boundary term (g(5) − g(0))/5 =
        // e^{−1} sin 21.5 / 5 ≈ 0.0347; the tapered one keeps only the
        // mode's content near zero frequency, of order (2π/T)²/ω² ≈ 0.09
        // of its size (here −0.0057, a sixth of the plain mean).
        let m = 5000;
        let d: Vec<f64> = (0..m)
            .map(|i| {
                let t = 5.0 * i as f64 / m as f64;
                (-0.2 * t).exp() * (4.3 * (4.3 * t).cos() - 0.2 * (4.3 * t).sin())
            })
            .collect();
        let plain = d.iter().sum::<f64>() / m as f64;
        assert!((plain - 0.0347).abs() < 1e-3, "{plain}");
        assert!(
            hann_mean(&d).abs() < 0.25 * plain.abs(),
            "{}",
            hann_mean(&d)
        );
    }

    /// `√(n Σw²)/Σw` summed directly for a few block lengths.
    #[test]
    fn the_hann_means_noise_gain_is_the_tapers_own() {
        for n in [3usize, 10, 257, 5000] {
            let w: Vec<f64> = (0..n)
                .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
                .collect();
            let (s1, s2): (f64, f64) = (w.iter().sum(), w.iter().map(|x| x * x).sum());
            let gain = (n as f64 * s2).sqrt() / s1;
            assert!((gain - HANN_MEAN_NOISE_GAIN).abs() < 1e-12, "n {n}: {gain}");
        }
    }
}
