//! Frequency-response estimation from sampled signals: what turns a
//! recorded period into the FRF points the models are fitted to.
//!
//! - [`sine_amplitude`] / [`SinePoint`]: single-frequency correlation at a
//!   known excitation frequency (the paper's single-sine protocol). The
//!   window is trimmed to the largest whole number of cycles from its start
//!   (the remainder, less than one cycle, is dropped: over whole cycles the
//!   correlation with `e^{−jωt}` is orthogonal to the mean and to every
//!   other harmonic of ω); the mean is removed, and optionally a linear
//!   trend (slow drift of posture or bias). The noise of each complex
//!   amplitude comes from the residual after removing the fitted sinusoid:
//!   for white residual of variance σ² over N samples, each quadrature
//!   component of `Â = (2/N) Σ y e^{−jωt}` has variance `2σ²/N`, so the
//!   relative standard error of a ratio `Y/X` is
//!   `√(4σ_y²/(N|Y|²) + 4σ_x²/(N|X|²))`. Coherence is reported as the
//!   fraction of each signal's variance the sinusoid explains, the smaller
//!   of input and output.
//! - [`welch_h1`]: broadband excitation (chirp, multisine, random): the H1
//!   estimator `H = S_xy/S_xx` with Welch averaging (Hann window, 50 %
//!   overlap) and magnitude-squared coherence `γ² = |S_xy|²/(S_xx S_yy)`;
//!   [`select_band`] keeps the bins where the input carries power and the
//!   coherence is high, averaged into log-spaced points.
//!
//! No allocation in the sine path; Welch allocates its spectra once per call.

use num_complex::Complex64;

use crate::error::{Result, ScienceError};

/// The complex amplitude of one signal at ω.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineAmplitude {
    /// `Â` with `y(t) ≈ mean + Re(Â e^{jωt})` (signal units).
    pub amplitude: Complex64,
    /// Residual variance after the fit (signal units²).
    pub residual_var: f64,
    /// Total variance of the (detrended) signal (signal units²).
    pub total_var: f64,
    /// Samples used (whole cycles).
    pub n: usize,
}

impl SineAmplitude {
    /// Fraction of the variance explained by the sinusoid (0–1).
    pub fn explained(&self) -> f64 {
        if self.total_var > 0.0 {
            (1.0 - self.residual_var / self.total_var).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Variance of each quadrature component of the amplitude, `2σ²/N`.
    pub fn component_var(&self) -> f64 {
        2.0 * self.residual_var / self.n.max(1) as f64
    }
}

/// How many samples from the start cover whole cycles of ω; `None` if less than one.
pub fn whole_cycles(t_s: &[f64], omega_rad_s: f64) -> Option<usize> {
    let (first, last) = (*t_s.first()?, *t_s.last()?);
    let period = std::f64::consts::TAU / omega_rad_s;
    let cycles = ((last - first) / period + 1e-9).floor();
    if cycles < 1.0 {
        return None;
    }
    let end = first + cycles * period;
    Some(t_s.iter().take_while(|t| **t < end - 1e-9 * period).count())
}

/// Fits `y(t) ≈ c0 [+ c1 (t − t̄)] + Re(Â e^{jωt})` by least squares over
/// the whole cycles of the samples (the trend term when `detrend`).
/// Allocation-free (4 × 4 normal equations on the stack).
pub fn sine_amplitude(
    t_s: &[f64],
    y: &[f64],
    omega_rad_s: f64,
    detrend: bool,
) -> Result<SineAmplitude> {
    if t_s.len() != y.len() {
        return Err(ScienceError::LengthMismatch {
            what: "sine correlation",
            left: t_s.len(),
            right: y.len(),
        });
    }
    if !(omega_rad_s.is_finite() && omega_rad_s > 0.0) {
        return Err(ScienceError::OutOfRange {
            name: "omega_rad_s",
            value: omega_rad_s,
            allowed: "(0, ∞)",
        });
    }
    let n = whole_cycles(t_s, omega_rad_s).ok_or_else(|| ScienceError::TooFewSamples {
        what: format!("sine correlation at {omega_rad_s} rad/s (less than one cycle)"),
        needed: 2,
        given: t_s.len(),
    })?;
    if n < 4 {
        return Err(ScienceError::TooFewSamples {
            what: "sine correlation".into(),
            needed: 4,
            given: n,
        });
    }
    let (t, y) = (&t_s[..n], &y[..n]);
    if let Some((i, v)) = y.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(ScienceError::NonFiniteData {
            index: i,
            omega: omega_rad_s,
            re: *v,
            im: 0.0,
        });
    }
    let nf = n as f64;
    let t_mean = t.iter().sum::<f64>() / nf;
    // Joint least squares of y on [1, t − t̄, cos ωt, sin ωt] (or without the
    // trend column): a trend removed on its own would absorb part of the
    // sinusoid, since t·sin ωt does not average out over whole cycles.
    let p = if detrend { 4 } else { 3 };
    let row = |ti: f64| -> [f64; 4] {
        let (s, c) = (omega_rad_s * ti).sin_cos();
        if detrend {
            [c, s, 1.0, ti - t_mean]
        } else {
            [c, s, 1.0, 0.0]
        }
    };
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut aty = nalgebra::Vector4::<f64>::zeros();
    for (&ti, &yi) in t.iter().zip(y) {
        let r = nalgebra::Vector4::from(row(ti));
        ata += r * r.transpose();
        aty += r * yi;
    }
    if !detrend {
        ata[(3, 3)] = 1.0;
    }
    let coef = ata.cholesky().map(|c| c.solve(&aty)).ok_or_else(|| {
        ScienceError::Infeasible(format!(
            "sine correlation at {omega_rad_s} rad/s: samples do not resolve the sinusoid"
        ))
    })?;
    let (a, b) = (coef[0], coef[1]);
    let (mut rss, mut tss) = (0.0, 0.0);
    for (&ti, &yi) in t.iter().zip(y) {
        let r = row(ti);
        let background = coef[2] + coef[3] * r[3];
        let d = yi - background;
        let e = d - a * r[0] - b * r[1];
        rss += e * e;
        tss += d * d;
    }
    // y ≈ a cos + b sin = Re((a − j b) e^{jωt}).
    Ok(SineAmplitude {
        amplitude: Complex64::new(a, -b),
        residual_var: rss / (nf - p as f64).max(1.0),
        total_var: tss / nf,
        n,
    })
}

/// A transfer-function point `Y/X` from single-frequency correlation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinePoint {
    /// `Y/X` at ω.
    pub ratio: Complex64,
    /// Relative standard error of the ratio (dimensionless).
    pub noise_rel: f64,
    /// The smaller fraction of input and output variance the sinusoid explains (0–1).
    pub coherence: f64,
}

/// `Y/X` at ω from the amplitudes of input and output.
pub fn sine_ratio(x: &SineAmplitude, y: &SineAmplitude) -> Result<SinePoint> {
    let (xn, yn) = (x.amplitude.norm(), y.amplitude.norm());
    if xn.is_nan() || xn <= 0.0 {
        return Err(ScienceError::Infeasible(
            "sine correlation: the input has no component at ω".into(),
        ));
    }
    let ratio = y.amplitude / x.amplitude;
    // E|δA|² = 2 · component variance.
    let rel_y = if yn > 0.0 {
        2.0 * y.component_var() / (yn * yn)
    } else {
        f64::INFINITY
    };
    let rel_x = 2.0 * x.component_var() / (xn * xn);
    Ok(SinePoint {
        ratio,
        noise_rel: (rel_y + rel_x).sqrt(),
        coherence: x.explained().min(y.explained()),
    })
}

/// In-place iterative radix-2 FFT (`n` a power of two), forward (`e^{−j}`).
pub fn fft_in_place(a: &mut [Complex64]) -> Result<()> {
    let n = a.len();
    if n == 0 || !n.is_power_of_two() {
        return Err(ScienceError::Infeasible(format!(
            "FFT length {n} is not a power of two"
        )));
    }
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            a.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let w = Complex64::from_polar(1.0, -std::f64::consts::TAU / len as f64);
        for start in (0..n).step_by(len) {
            let mut wk = Complex64::new(1.0, 0.0);
            for k in 0..len / 2 {
                let u = a[start + k];
                let v = a[start + k + len / 2] * wk;
                a[start + k] = u + v;
                a[start + k + len / 2] = u - v;
                wk *= w;
            }
        }
        len <<= 1;
    }
    Ok(())
}

/// One frequency bin of an H1 estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct H1Bin {
    /// Frequency (rad/s).
    pub omega_rad_s: f64,
    /// `H = S_xy/S_xx`.
    pub h: Complex64,
    /// Magnitude-squared coherence (0–1).
    pub coherence: f64,
    /// Input auto-spectrum (input units² per bin, Welch-averaged).
    pub s_xx: f64,
    /// Number of segments averaged.
    pub segments: usize,
}

/// Welch H1 estimate of `y/x` sampled at `rate_hz`, segments of
/// `segment_len` (a power of two) with a Hann window and 50 % overlap,
/// each segment's mean removed. Bins 1 … `segment_len/2 − 1`.
pub fn welch_h1(x: &[f64], y: &[f64], rate_hz: f64, segment_len: usize) -> Result<Vec<H1Bin>> {
    if x.len() != y.len() {
        return Err(ScienceError::LengthMismatch {
            what: "H1 estimate",
            left: x.len(),
            right: y.len(),
        });
    }
    if !segment_len.is_power_of_two() || segment_len < 16 {
        return Err(ScienceError::Infeasible(format!(
            "H1 segment length {segment_len} must be a power of two ≥ 16"
        )));
    }
    if x.len() < segment_len {
        return Err(ScienceError::TooFewSamples {
            what: "H1 estimate".into(),
            needed: segment_len,
            given: x.len(),
        });
    }
    if let Some(i) = x.iter().chain(y).position(|v| !v.is_finite()) {
        return Err(ScienceError::NonFiniteData {
            index: i % x.len(),
            omega: 0.0,
            re: f64::NAN,
            im: 0.0,
        });
    }
    let half = segment_len / 2;
    let window: Vec<f64> = (0..segment_len)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / segment_len as f64).cos())
        .collect();
    let mut sxx = vec![0.0; half];
    let mut syy = vec![0.0; half];
    let mut sxy = vec![Complex64::new(0.0, 0.0); half];
    let mut fx = vec![Complex64::new(0.0, 0.0); segment_len];
    let mut fy = vec![Complex64::new(0.0, 0.0); segment_len];
    let mut segments = 0;
    let mut start = 0;
    while start + segment_len <= x.len() {
        let (xs, ys) = (
            &x[start..start + segment_len],
            &y[start..start + segment_len],
        );
        let (mx, my) = (
            xs.iter().sum::<f64>() / segment_len as f64,
            ys.iter().sum::<f64>() / segment_len as f64,
        );
        for i in 0..segment_len {
            fx[i] = Complex64::new((xs[i] - mx) * window[i], 0.0);
            fy[i] = Complex64::new((ys[i] - my) * window[i], 0.0);
        }
        fft_in_place(&mut fx)?;
        fft_in_place(&mut fy)?;
        for k in 1..half {
            sxx[k] += fx[k].norm_sqr();
            syy[k] += fy[k].norm_sqr();
            sxy[k] += fx[k].conj() * fy[k];
        }
        segments += 1;
        start += half;
    }
    Ok((1..half)
        .map(|k| {
            let coherence = if sxx[k] > 0.0 && syy[k] > 0.0 {
                (sxy[k].norm_sqr() / (sxx[k] * syy[k])).clamp(0.0, 1.0)
            } else {
                0.0
            };
            H1Bin {
                omega_rad_s: std::f64::consts::TAU * k as f64 * rate_hz / segment_len as f64,
                h: if sxx[k] > 0.0 {
                    sxy[k] / sxx[k]
                } else {
                    Complex64::new(0.0, 0.0)
                },
                coherence,
                s_xx: sxx[k] / segments as f64,
                segments,
            }
        })
        .collect())
}

/// The groups of bin indices of [`select_band`]: the bins of the excited
/// band (input power at least `min_rel_power` of the strongest bin,
/// coherence at least `min_coherence`, within `[omega_lo, omega_hi]`, not the
/// two lowest bins, which carry the Hann window's leakage of the removed
/// segment mean), grouped into at most `n_points` log-spaced bands; empty
/// bands are left out.
pub fn band_groups(
    bins: &[H1Bin],
    min_coherence: f64,
    min_rel_power: f64,
    omega_lo_rad_s: f64,
    omega_hi_rad_s: f64,
    n_points: usize,
) -> Vec<Vec<usize>> {
    let peak = bins.iter().map(|b| b.s_xx).fold(0.0, f64::max);
    let kept: Vec<usize> = (0..bins.len())
        .skip(2)
        .filter(|&i| {
            let b = &bins[i];
            b.omega_rad_s >= omega_lo_rad_s
                && b.omega_rad_s <= omega_hi_rad_s
                && b.s_xx >= min_rel_power * peak
                && b.s_xx > 0.0
                && b.coherence >= min_coherence
        })
        .collect();
    let (Some(&first), Some(&last)) = (kept.first(), kept.last()) else {
        return Vec::new();
    };
    if n_points == 0 {
        return Vec::new();
    }
    let (lo, hi) = (
        bins[first].omega_rad_s.ln(),
        bins[last].omega_rad_s.ln() + 1e-9,
    );
    let width = (hi - lo) / n_points as f64;
    (0..n_points)
        .map(|g| {
            let (a, b) = (lo + width * g as f64, lo + width * (g + 1) as f64);
            kept.iter()
                .copied()
                .filter(|&i| {
                    let l = bins[i].omega_rad_s.ln();
                    l >= a && l < b
                })
                .collect::<Vec<usize>>()
        })
        .filter(|g| !g.is_empty())
        .collect()
}

/// The average of `bins[group]`: `H` and the frequency weighted alike by
/// `S_xx` (so an FRF that varies linearly across the band is unbiased at the
/// reported frequency), coherence and `S_xx` plain means.
pub fn average_bins(bins: &[H1Bin], group: &[usize]) -> Option<H1Bin> {
    let g: Vec<&H1Bin> = group.iter().filter_map(|&i| bins.get(i)).collect();
    let w: f64 = g.iter().map(|b| b.s_xx).sum();
    if g.is_empty() || w.is_nan() || w <= 0.0 {
        return None;
    }
    let n = g.len() as f64;
    Some(H1Bin {
        omega_rad_s: g.iter().map(|b| b.omega_rad_s * b.s_xx).sum::<f64>() / w,
        h: g.iter().map(|b| b.h * b.s_xx).sum::<Complex64>() / w,
        coherence: g.iter().map(|b| b.coherence).sum::<f64>() / n,
        s_xx: w / n,
        segments: g[0].segments,
    })
}

/// [`band_groups`] averaged with [`average_bins`]: the excited band in at
/// most `n_points` log-spaced points.
pub fn select_band(
    bins: &[H1Bin],
    min_coherence: f64,
    min_rel_power: f64,
    omega_lo_rad_s: f64,
    omega_hi_rad_s: f64,
    n_points: usize,
) -> Vec<H1Bin> {
    band_groups(
        bins,
        min_coherence,
        min_rel_power,
        omega_lo_rad_s,
        omega_hi_rad_s,
        n_points,
    )
    .iter()
    .filter_map(|g| average_bins(bins, g))
    .collect()
}
