//! The estimate of a periodic (multisine) excitation's response, line by
//! line, from whole periods (issue 34 item 2): the nonparametric estimate
//! for periodic excitations of R. Pintelon and J. Schoukens, *System
//! Identification: A Frequency Domain Approach* (2nd ed., Wiley–IEEE 2012),
//! section 2.4: each period's DFT at the excited bins, averaged over the
//! periods, and the noise from the spread between periods. A signal made
//! of lines on a period's own bins puts each line in its own bin with no
//! leakage; the noise needs no model of its colour, since it is measured
//! at each line from the periods' disagreement.
//!
//! For `P` periods with DFTs `X_p(k)`, `Y_p(k)` at bin `k`:
//! `X̄ = Σ X_p / P`, `Ȳ` likewise, `Ĝ = Ȳ / X̄`; the sample (co)variances
//! `σ̂²_X = Σ |X_p − X̄|² / (P − 1)`, `σ̂²_Y`, `σ̂²_YX = Σ (Y_p − Ȳ)(X_p − X̄)* / (P − 1)`;
//! and to first order (circular noise)
//! `σ̂²_Ĝ = |Ĝ|² / P · (σ̂²_Y/|Ȳ|² + σ̂²_X/|X̄|² − 2 Re(σ̂²_YX / (Ȳ X̄*)))`,
//! half of it in each of the real and imaginary parts.
//!
//! The caller leaves out the periods in which the system had not reached
//! its steady state (a transient is not periodic and would be read as
//! noise and bias).

use num_complex::Complex64;

use super::welch::Fft;
use crate::error::{Result, ScienceError};

/// One excited line's response over whole periods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodicLine {
    /// Its bin in the period (cycles per period).
    pub bin: usize,
    /// Its frequency (rad/s): `2π · bin · rate_hz / period_samples`.
    pub omega_rad_s: f64,
    /// `Ȳ/X̄` (units of `y` over units of `x`).
    pub ratio: Complex64,
    /// Covariance of `(Re Ĝ, Im Ĝ)` from the spread between periods
    /// (ratio units²; circular: the two variances equal, no covariance).
    pub cov: [[f64; 2]; 2],
    /// Relative standard error `σ̂_Ĝ / |Ĝ|` (dimensionless); infinite when
    /// `Ĝ = 0`.
    pub noise_rel: f64,
    /// Periods averaged; the variance has `P − 1` degrees of freedom.
    pub periods: usize,
}

/// One excited line's estimate, or why it has none (its input has nothing
/// at that bin beyond its noise: [`periodic_frf_each`]).
pub type LineEstimate = Result<PeriodicLine>;

/// `Y/X` at each of `bins` from the whole periods of `period_samples`
/// samples in `x` and `y` (sampled at `rate_hz`, starting on a period's
/// first sample), with its noise from the spread between the periods
/// (module docs). Refused, naming what is wrong: lengths that differ or are
/// not whole periods, fewer than two periods (no spread to measure), a bin
/// at 0 or not below Nyquist, a sample that is not finite, or an input with
/// nothing at an excited bin (its line not above its own scatter between
/// periods at the 1 % level of F(2, 2(P − 1)), or below 2e-9 of the
/// input's RMS). [`periodic_frf_each`] keeps the other lines when one has
/// nothing.
pub fn periodic_frf(
    x: &[f64],
    y: &[f64],
    rate_hz: f64,
    period_samples: usize,
    bins: &[usize],
) -> Result<Vec<PeriodicLine>> {
    periodic_frf_each(x, y, rate_hz, period_samples, bins)?
        .into_iter()
        .collect()
}

/// [`periodic_frf`] line by line: the record's faults (lengths, periods,
/// bins, samples that are not finite) refuse the whole, while a line whose
/// input has nothing at its bin beyond its noise is refused alone, in its
/// place, and the others are estimated (a multisine's weakest line in a
/// noisy window must not cost the experiment its other lines).
pub fn periodic_frf_each(
    x: &[f64],
    y: &[f64],
    rate_hz: f64,
    period_samples: usize,
    bins: &[usize],
) -> Result<Vec<LineEstimate>> {
    let rate_hz = crate::error::positive("rate_hz", rate_hz)?;
    if x.len() != y.len() {
        return Err(ScienceError::LengthMismatch {
            what: "periodic response: input and output",
            left: x.len(),
            right: y.len(),
        });
    }
    if period_samples == 0 || !x.len().is_multiple_of(period_samples) {
        return Err(ScienceError::Infeasible(format!(
            "periodic response: {} samples are not whole periods of {period_samples}",
            x.len()
        )));
    }
    let periods = x.len() / period_samples;
    if periods < 2 {
        return Err(ScienceError::Infeasible(format!(
            "periodic response: {periods} period(s); at least two are needed to measure the noise"
        )));
    }
    crate::multisine::check_bins(period_samples, bins)?;
    if let Some(i) = x.iter().chain(y).position(|v| !v.is_finite()) {
        let (which, at) = if i < x.len() {
            ("input", i)
        } else {
            ("output", i - x.len())
        };
        return Err(ScienceError::Infeasible(format!(
            "periodic response: the {which}'s sample {at} is not finite"
        )));
    }
    let mut fft = Fft::new(period_samples)?;
    let mut buf = vec![Complex64::new(0.0, 0.0); period_samples];
    // Per signal, period and bin: the DFT at the excited bins.
    let mut spectra = |s: &[f64]| -> Result<Vec<Vec<Complex64>>> {
        s.chunks_exact(period_samples)
            .map(|p| {
                for (b, v) in buf.iter_mut().zip(p) {
                    *b = Complex64::new(*v, 0.0);
                }
                fft.forward(&mut buf)?;
                Ok(bins.iter().map(|&k| buf[k]).collect())
            })
            .collect()
    };
    let xs = spectra(x)?;
    let ys = spectra(y)?;
    let p = periods as f64;
    // The input's RMS times the period's length: what a line is compared
    // with before it is taken as excited.
    let x_scale =
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt() * period_samples as f64;
    let d_omega = std::f64::consts::TAU * rate_hz / period_samples as f64;
    Ok(bins
        .iter()
        .enumerate()
        .map(|(j, &bin)| {
            let xm = xs.iter().map(|s| s[j]).sum::<Complex64>() / p;
            let ym = ys.iter().map(|s| s[j]).sum::<Complex64>() / p;
            let (mut vx, mut vy, mut vyx) = (0.0, 0.0, Complex64::new(0.0, 0.0));
            for (xp, yp) in xs.iter().zip(&ys) {
                let (dx, dy) = (xp[j] - xm, yp[j] - ym);
                vx += dx.norm_sqr();
                vy += dy.norm_sqr();
                vyx += dy * dx.conj();
            }
            let dof = p - 1.0;
            let (vx, vy, vyx) = (vx / dof, vy / dof, vyx / dof);
            // An excited line stands above its own scatter between periods
            // at the 1 % level (under noise alone F = |X̄|² P / σ̂²_X follows
            // F(2, 2(P − 1)), whose 99th percentile is (d/2)(0.01^(−2/d) − 1),
            // d = 2(P − 1)), and above the rounding of the period's
            // transform (a line of amplitude A in a signal of RMS r has
            // |X| = A N/2 against r N: refused below A = 2e-9 r).
            let d2 = 2.0 * dof;
            let f_crit = 0.5 * d2 * (0.01f64.powf(-2.0 / d2) - 1.0);
            if xm.norm_sqr() * p <= f_crit * vx || xm.norm() <= 1e-9 * x_scale {
                return Err(ScienceError::Infeasible(format!(
                    "periodic response: the input has nothing at bin {bin} beyond its noise between periods"
                )));
            }
            let ratio = ym / xm;
            // |Ĝ|²(σ²_Y/|Ȳ|² + ...) written without dividing by Ȳ, which
            // may be zero: |Ĝ|²σ²_Y/|Ȳ|² = σ²_Y/|X̄|², and
            // |Ĝ|² Re(σ²_YX/(Ȳ X̄*)) = Re(Ĝ* σ²_YX)/|X̄|².
            let x2 = xm.norm_sqr();
            let var = ((vy + ratio.norm_sqr() * vx - 2.0 * (ratio.conj() * vyx).re) / x2 / p)
                .max(0.0);
            let rn = ratio.norm();
            Ok(PeriodicLine {
                bin,
                omega_rad_s: bin as f64 * d_omega,
                ratio,
                cov: [[0.5 * var, 0.0], [0.0, 0.5 * var]],
                noise_rel: if rn > 0.0 {
                    var.sqrt() / rn
                } else {
                    f64::INFINITY
                },
                periods,
            })
        })
        .collect())
}

/// Removes a slow trend from each of `signals` (the same record's
/// channels: whole periods of `period_samples` samples, one length) in
/// place: the polynomial of degree `degree` in time that, fitted by least
/// squares together with a cosine and a sine at each of the excited
/// `bins` (cycles per period) over the whole record, explains what is not
/// periodic at those lines; only the polynomial is subtracted. What it is
/// for: a creep or a drift of the operating point across the analysis
/// window (a viscoelastic joint relaxing under a bias) is not periodic, so
/// without this it enters every line's spread between periods as "noise"
/// and its leakage biases `X̄` and `Ȳ`. Fitted jointly with the lines, the
/// polynomial takes none of the periodic signal. Time is scaled to
/// [−1, 1] and the polynomials are Legendre's, nearly orthogonal to each
/// other and to the lines, so the normal equations (one Gram matrix for
/// every channel, solved by Cholesky) are well conditioned: O(samples ·
/// columns²) once. Returns each signal's polynomial coefficients
/// (Legendre basis, the signal's unit). Refused: signals of different
/// lengths, fewer samples than twice the columns, a bin at 0 or not below
/// Nyquist, a sample that is not finite, `degree` above 8.
pub fn remove_slow_trend(
    signals: &mut [&mut [f64]],
    period_samples: usize,
    bins: &[usize],
    degree: usize,
) -> Result<Vec<Vec<f64>>> {
    use nalgebra::DMatrix;
    if degree > 8 {
        return Err(ScienceError::OutOfRange {
            name: "trend degree",
            value: degree as f64,
            allowed: "0 to 8",
        });
    }
    crate::multisine::check_bins(period_samples, bins)?;
    let n = signals.first().map_or(0, |x| x.len());
    for (k, x) in signals.iter().enumerate() {
        if x.len() != n {
            return Err(ScienceError::LengthMismatch {
                what: "trend removal: channels",
                left: n,
                right: x.len(),
            });
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(ScienceError::Infeasible(format!(
                "channel {k}: sample {i} is not finite"
            )));
        }
    }
    let cols = degree + 1 + 2 * bins.len();
    if n < 2 * cols {
        return Err(ScienceError::Infeasible(format!(
            "{n} samples cannot carry a trend of degree {degree} beside {} lines",
            bins.len()
        )));
    }
    let half = (n - 1) as f64 / 2.0;
    // Row `i` of the design: Legendre P_0..P_degree at u, then cos, sin of
    // each line.
    let row = |i: usize, out: &mut [f64]| {
        let u = (i as f64 - half) / half;
        out[0] = 1.0;
        if degree >= 1 {
            out[1] = u;
        }
        for k in 1..degree {
            out[k + 1] = ((2 * k + 1) as f64 * u * out[k] - k as f64 * out[k - 1]) / (k + 1) as f64;
        }
        for (l, &b) in bins.iter().enumerate() {
            let phase =
                std::f64::consts::TAU * ((b * i) % period_samples) as f64 / period_samples as f64;
            out[degree + 1 + 2 * l] = phase.cos();
            out[degree + 2 + 2 * l] = phase.sin();
        }
    };
    let m = signals.len();
    let mut gram = DMatrix::<f64>::zeros(cols, cols);
    let mut rhs = DMatrix::<f64>::zeros(cols, m);
    let mut r = vec![0.0; cols];
    for i in 0..n {
        row(i, &mut r);
        for a in 0..cols {
            for b in a..cols {
                gram[(a, b)] += r[a] * r[b];
            }
            for (k, x) in signals.iter().enumerate() {
                rhs[(a, k)] += r[a] * x[i];
            }
        }
    }
    for a in 0..cols {
        for b in 0..a {
            gram[(a, b)] = gram[(b, a)];
        }
    }
    let chol = gram
        .cholesky()
        .ok_or_else(|| ScienceError::Infeasible("trend removal: the design is singular".into()))?;
    let coef = chol.solve(&rhs);
    let polys: Vec<Vec<f64>> = (0..m)
        .map(|k| (0..=degree).map(|j| coef[(j, k)]).collect())
        .collect();
    for i in 0..n {
        row(i, &mut r);
        for (x, poly) in signals.iter_mut().zip(&polys) {
            let trend: f64 = r[..=degree].iter().zip(poly).map(|(p, c)| p * c).sum();
            x[i] -= trend;
        }
    }
    Ok(polys)
}
