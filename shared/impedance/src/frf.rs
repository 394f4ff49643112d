//! Frequency-response estimation from sampled signals: what turns a
//! recorded period into the FRF points the models are fitted to.
//!
//! # Single frequency (the paper's sine periods)
//!
//! [`SineCorrelator`] is a lock-in: a least-squares fit, at the known
//! excitation frequency ω, of every channel of a block of samples (input
//! `x(t) = θ_e`, outputs `τ_c`, `τ_s`, …) to
//!
//! ```text
//! y(t) ≈ c0 + c1·τ + a·cos ωτ + b·sin ωτ = c0 + c1·τ + Re(Â e^{jωτ}),  Â = a − j b,
//! ```
//!
//! with `τ = t − origin`. The mean `c0` is the bias (gravity, bias torque,
//! posture) and the trend `c1` a slow drift; the trend column is optional
//! (`detrend`). The mean and trend are fitted jointly with the sinusoid
//! rather than removed first: `τ·sin ωτ` does not average out over whole
//! cycles, so a trend removed on its own would take part of the sinusoid
//! with it. Over whole cycles the sinusoid is orthogonal to the mean and
//! to every other harmonic of ω, and the fit reduces to the single-bin DFT
//! `Â = (2/N) Σ y e^{−jωτ}`.
//!
//! **Whole cycles.** The window is trimmed to the largest whole number of
//! cycles counted from `origin`, `[origin, origin + c·2π/ω)`; the remainder
//! (less than one cycle, at the end) is dropped, not used: keeping it would
//! let harmonics and nonlinear distortion of the response leak into the
//! estimate, and the paper's analysis is over whole cycles. Streaming, this
//! costs nothing: the running sums are copied at each cycle boundary, so
//! [`SineCorrelator::finish`] uses the last boundary (or the window's end,
//! when it completes a cycle). Samples need not be evenly spaced (the fit
//! uses their time stamps), and a dropped sample only costs its weight.
//!
//! **Noise.** The residual of the fit gives the noise variance `σ²` of each
//! channel (`RSS/(N − p)`, `p` = 3 or 4 columns), and the covariance of
//! `(a, b)` is `σ² (AᵀA)⁻¹` restricted to the two sinusoid columns — exact
//! for white residuals, including the loss of precision when few cycles
//! make the trend column correlate with the sinusoid (one cycle with
//! `detrend`: the variance of `b` grows 2.6×; a plain `2σ²/N` per component
//! would hide this). The covariance of a ratio `R = Y/X` follows to first
//! order, `δR = δY/X − R δX/X`, input and output noise taken as
//! independent; `noise_rel = √(E|δR|²)/|R|`. The error `R̂ − R` lies inside
//! the 95 % ellipse of [`SinePoint::cov`] (`eᵀ cov⁻¹ e < 5.99`, χ² with two
//! degrees of freedom) in 95 % of windows, and within `2·noise_rel·|R|` in
//! 95–98 % (98 % when the error is circular, as over many cycles).
//! Coloured residual noise (drift beyond a line, tremor) breaks the white
//! assumption: the estimate is then right only as far as the residual's
//! spectrum near ω equals its average over the band.
//!
//! **Coherence.** For each channel, the fraction of its variance (about
//! mean and trend) that the sinusoid explains; a ratio reports the smaller
//! of input and output. Like the magnitude-squared coherence of a
//! broadband estimate, it is 1 for a noise-free linear response and falls
//! as noise (or response at other frequencies) grows: with output
//! signal-to-noise power ratio `q`, it is `q/(1 + q)`.
//!
//! Pushing a sample is O(1) and allocation-free (the sums are `4 × 4` on
//! the stack); [`sine_amplitude`] and [`sine_ratio`] are the block forms.
//!
//! # Broadband (chirp, multisine, random)
//!
//! [`welch_h1`]: the H1 estimator `H = S_xy/S_xx` with Welch averaging
//! (Hann window, 50 % overlap) and magnitude-squared coherence
//! `γ² = |S_xy|²/(S_xx S_yy)`; [`select_band`] keeps the bins where the input
//! carries power and the coherence is high, averaged into log-spaced
//! points. H1 is unbiased by output noise (it only lowers `γ²`); input
//! noise biases it low. Welch allocates its spectra once per call.

use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};
use num_complex::Complex64;

use crate::error::{Result, ScienceError};

/// Relative tolerance (of a period) for a time stamp to count as on a cycle boundary.
const BOUNDARY_TOL: f64 = 1e-9;

/// The complex amplitude of one signal at ω.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SineAmplitude {
    /// `Â` with `y(t) ≈ c0 + c1 τ + Re(Â e^{jωτ})`, `τ` from the
    /// correlator's origin (signal units).
    pub amplitude: Complex64,
    /// Covariance of `(Re Â, Im Â)` (signal units²): `σ²` times the
    /// sinusoid block of `(AᵀA)⁻¹`, with the sign of `Im Â = −b`.
    pub amplitude_cov: [[f64; 2]; 2],
    /// Residual variance `σ² = RSS/(N − p)` after the fit (signal units²).
    pub residual_var: f64,
    /// Variance of the signal about its fitted mean and trend (signal units²).
    pub total_var: f64,
    /// Fraction of the variance about mean and trend that the sinusoid
    /// explains, `1 − RSS/TSS` (0–1).
    pub explained_fraction: f64,
    /// Samples used (those in whole cycles).
    pub n: usize,
    /// Whole cycles of ω the samples span.
    pub cycles: u64,
}

impl SineAmplitude {
    /// Fraction of the variance explained by the sinusoid (0–1).
    pub fn explained(&self) -> f64 {
        self.explained_fraction
    }

    /// Mean variance of the two quadrature components of `Â` (signal units²);
    /// `2σ²/N` over whole cycles without trend.
    pub fn component_var(&self) -> f64 {
        0.5 * (self.amplitude_cov[0][0] + self.amplitude_cov[1][1])
    }
}

/// Running sums of the least-squares fit: `AᵀA`, `Aᵀy` and `yᵀy` per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sums<const N: usize> {
    gram: Matrix4<f64>,
    rhs: [Vector4<f64>; N],
    yy: [f64; N],
    n: usize,
}

impl<const N: usize> Sums<N> {
    fn zero() -> Self {
        Sums {
            gram: Matrix4::zeros(),
            rhs: [Vector4::zeros(); N],
            yy: [0.0; N],
            n: 0,
        }
    }
}

/// Streaming single-frequency correlation of `N` channels sampled together
/// (channel 0 usually the input `θ_e`): push samples one at a time, ask for
/// the amplitudes over whole cycles at the end. No allocation, O(1) per
/// sample; see the [module documentation](self) for the model, the
/// treatment of the remainder and the noise estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct SineCorrelator<const N: usize> {
    omega_rad_s: f64,
    period_s: f64,
    origin_s: f64,
    detrend: bool,
    names: [&'static str; N],
    /// First sample of each channel, subtracted before summing (keeps `yᵀy`
    /// small when a signal sits on a large bias, so `RSS = yᵀy − ĉᵀAᵀy`
    /// loses no precision).
    y_ref: [f64; N],
    last_t_s: f64,
    pushed: usize,
    current: Sums<N>,
    whole: Sums<N>,
    cycles: u64,
}

fn check_omega(omega_rad_s: f64) -> Result<f64> {
    if omega_rad_s.is_finite() && omega_rad_s > 0.0 {
        Ok(omega_rad_s)
    } else {
        Err(ScienceError::OutOfRange {
            name: "omega_rad_s",
            value: omega_rad_s,
            allowed: "(0, ∞)",
        })
    }
}

impl<const N: usize> SineCorrelator<N> {
    /// A correlator at `omega_rad_s` (rad/s) whose cycles count from
    /// `origin_s` (s); `detrend` adds the linear-trend column. Channels are
    /// named `channel` in errors until [`with_names`](Self::with_names).
    pub fn new(omega_rad_s: f64, origin_s: f64, detrend: bool) -> Result<Self> {
        check_omega(omega_rad_s)?;
        if !origin_s.is_finite() {
            return Err(ScienceError::NotFinite {
                name: "origin_s",
                value: origin_s,
            });
        }
        Ok(SineCorrelator {
            omega_rad_s,
            period_s: std::f64::consts::TAU / omega_rad_s,
            origin_s,
            detrend,
            names: ["channel"; N],
            y_ref: [0.0; N],
            last_t_s: f64::NEG_INFINITY,
            pushed: 0,
            current: Sums::zero(),
            whole: Sums::zero(),
            cycles: 0,
        })
    }

    /// Names the channels (e.g. `["theta_e_rad", "tau_c_nm"]`) for error messages.
    pub fn with_names(mut self, names: [&'static str; N]) -> Self {
        self.names = names;
        self
    }

    /// Empties the correlator for a new window at `omega_rad_s` from
    /// `origin_s`, keeping `detrend` and the names. Allocation-free.
    pub fn restart(&mut self, omega_rad_s: f64, origin_s: f64) -> Result<()> {
        let names = self.names;
        *self = SineCorrelator::new(omega_rad_s, origin_s, self.detrend)?.with_names(names);
        Ok(())
    }

    /// The excitation frequency (rad/s).
    pub fn omega_rad_s(&self) -> f64 {
        self.omega_rad_s
    }

    /// Samples pushed so far.
    pub fn samples_pushed(&self) -> usize {
        self.pushed
    }

    /// Whole cycles completed by the samples so far (a cycle completes when
    /// a sample at or past its end arrives).
    pub fn whole_cycles(&self) -> u64 {
        self.cycles
    }

    /// Samples inside the completed whole cycles.
    pub fn samples_in_whole_cycles(&self) -> usize {
        self.whole.n
    }

    /// Adds one sample taken at `t_s` (s, not before the origin, not before
    /// the previous sample). O(1), allocation-free. A non-finite value or a
    /// time going backwards is an error naming the channel and the sample's
    /// index; the correlator is left unchanged.
    pub fn push(&mut self, t_s: f64, y: &[f64; N]) -> Result<()> {
        if !(t_s.is_finite() && t_s >= self.origin_s && t_s >= self.last_t_s) {
            return Err(ScienceError::BadSample {
                series: "t_s",
                index: self.pushed,
                value: t_s,
                why: "sample times must be finite, not before the window's origin, and not decreasing",
            });
        }
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            return Err(ScienceError::BadSample {
                series: self.names[i],
                index: self.pushed,
                value: y[i],
                why: "not a finite number",
            });
        }
        if self.pushed == 0 {
            self.y_ref = *y;
        }
        let tau = t_s - self.origin_s;
        let boundary = (tau / self.period_s + BOUNDARY_TOL).floor() as u64;
        if boundary > self.cycles {
            // Every earlier sample lies before this boundary.
            self.whole = self.current;
            self.cycles = boundary;
        }
        let (s, c) = (self.omega_rad_s * tau).sin_cos();
        let phi = Vector4::new(c, s, 1.0, tau);
        let sums = &mut self.current;
        sums.gram += phi * phi.transpose();
        for ((rhs, yy), (v, r)) in sums
            .rhs
            .iter_mut()
            .zip(sums.yy.iter_mut())
            .zip(y.iter().zip(&self.y_ref))
        {
            let d = v - r;
            *rhs += phi * d;
            *yy += d * d;
        }
        sums.n += 1;
        self.pushed += 1;
        self.last_t_s = t_s;
        Ok(())
    }

    /// The amplitudes of every channel over the whole cycles so far. With
    /// `t_end_s` (the end of the window, exclusive), the samples pushed
    /// count as whole cycles when the window reaches the next boundary
    /// (e.g. a window of exactly `c` periods). Errors: less than one whole
    /// cycle; too few samples for the fit (`p + 1`); samples that do not
    /// resolve the sinusoid (fewer than about three per cycle).
    pub fn finish(&self, t_end_s: Option<f64>) -> Result<[SineAmplitude; N]> {
        let (sums, cycles) = match t_end_s {
            Some(end) if end.is_finite() => {
                let c_end = ((end - self.origin_s) / self.period_s + BOUNDARY_TOL).floor();
                if c_end >= (self.cycles + 1) as f64 {
                    (&self.current, c_end as u64)
                } else {
                    (&self.whole, self.cycles)
                }
            }
            Some(end) => {
                return Err(ScienceError::NotFinite {
                    name: "t_end_s",
                    value: end,
                })
            }
            None => (&self.whole, self.cycles),
        };
        let what = || {
            format!(
                "sine correlation at {} rad/s ({} samples, period {:.4} s)",
                self.omega_rad_s, self.pushed, self.period_s
            )
        };
        if cycles == 0 {
            return Err(ScienceError::TooFewSamples {
                what: format!("{} (less than one whole cycle)", what()),
                needed: 1,
                given: 0,
            });
        }
        let p = if self.detrend { 4 } else { 3 };
        if sums.n <= p {
            return Err(ScienceError::TooFewSamples {
                what: what(),
                needed: p + 1,
                given: sums.n,
            });
        }
        let mut gram = sums.gram;
        if !self.detrend {
            for i in 0..4 {
                gram[(3, i)] = 0.0;
                gram[(i, 3)] = 0.0;
            }
            gram[(3, 3)] = 1.0;
        }
        // Cholesky of the unit-diagonal (correlation) form: its pivots say
        // how independent each column is of the others.
        let d = Vector4::from_fn(|i, _| gram[(i, i)].sqrt());
        if d.iter().any(|v| v.is_nan() || *v <= 0.0) {
            return Err(ScienceError::Infeasible(format!(
                "{}: the samples do not resolve the sinusoid",
                what()
            )));
        }
        let corr = Matrix4::from_fn(|i, j| gram[(i, j)] / (d[i] * d[j]));
        let chol = corr.cholesky().ok_or_else(|| {
            ScienceError::Infeasible(format!(
                "{}: the samples do not resolve the sinusoid",
                what()
            ))
        })?;
        let l = chol.l();
        if (0..4).any(|i| l[(i, i)] * l[(i, i)] < 1e-10) {
            return Err(ScienceError::Infeasible(format!(
                "{}: the samples do not resolve the sinusoid (too few samples per cycle?)",
                what()
            )));
        }
        let inv_corr = chol.inverse();
        let inv = Matrix4::from_fn(|i, j| inv_corr[(i, j)] / (d[i] * d[j]));
        let nf = sums.n as f64;
        let mut out = [SineAmplitude::default(); N];
        for (k, o) in out.iter_mut().enumerate() {
            let mut rhs = sums.rhs[k];
            if !self.detrend {
                rhs[3] = 0.0;
            }
            let coef = inv * rhs;
            let yy = sums.yy[k];
            let rss = (yy - coef.dot(&rhs)).max(0.0);
            // The background alone (mean, and trend): its residual is the
            // variance the sinusoid may explain.
            let tss = if self.detrend {
                let g = Matrix2::new(gram[(2, 2)], gram[(2, 3)], gram[(3, 2)], gram[(3, 3)]);
                let r = Vector2::new(rhs[2], rhs[3]);
                match g.try_inverse() {
                    Some(gi) => yy - (gi * r).dot(&r),
                    None => yy - rhs[2] * rhs[2] / gram[(2, 2)],
                }
            } else {
                yy - rhs[2] * rhs[2] / gram[(2, 2)]
            }
            .max(rss);
            let sigma2 = rss / (nf - p as f64);
            let (c00, c01, c11) = (inv[(0, 0)], inv[(0, 1)], inv[(1, 1)]);
            *o = SineAmplitude {
                amplitude: Complex64::new(coef[0], -coef[1]),
                amplitude_cov: [[sigma2 * c00, -sigma2 * c01], [-sigma2 * c01, sigma2 * c11]],
                residual_var: sigma2,
                total_var: tss / nf,
                explained_fraction: if tss > 0.0 {
                    (1.0 - rss / tss).clamp(0.0, 1.0)
                } else {
                    0.0
                },
                n: sums.n,
                cycles,
            };
        }
        Ok(out)
    }
}

/// The end (exclusive) of a block of samples: the last time stamp plus the
/// mean spacing, so `N` samples `h` apart span `N·h`.
fn block_end(t_s: &[f64]) -> Option<f64> {
    let (first, last) = (*t_s.first()?, *t_s.last()?);
    (t_s.len() >= 2).then(|| last + (last - first) / (t_s.len() - 1) as f64)
}

/// How many samples from the start lie in whole cycles of ω (the rule of
/// [`SineCorrelator`], the block spanning `N` mean sample spacings);
/// `None` if less than one cycle.
pub fn whole_cycles(t_s: &[f64], omega_rad_s: f64) -> Option<usize> {
    let end = block_end(t_s)?;
    let first = t_s[0];
    let period = std::f64::consts::TAU / omega_rad_s;
    let cycles = ((end - first) / period + BOUNDARY_TOL).floor();
    if cycles.is_nan() || cycles < 1.0 {
        return None;
    }
    Some(
        t_s.iter()
            .take_while(|t| ((**t - first) / period + BOUNDARY_TOL).floor() < cycles)
            .count(),
    )
}

/// The block form of [`SineCorrelator`] for one signal: `y` sampled at
/// `t_s` (s), cycles counted from `t_s[0]`, the block spanning `N` mean
/// sample spacings. Allocation-free.
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
    check_omega(omega_rad_s)?;
    let end = block_end(t_s).ok_or_else(|| ScienceError::TooFewSamples {
        what: format!("sine correlation at {omega_rad_s} rad/s"),
        needed: 2,
        given: t_s.len(),
    })?;
    let mut c = SineCorrelator::<1>::new(omega_rad_s, t_s[0], detrend)?.with_names(["y"]);
    for (&t, &v) in t_s.iter().zip(y) {
        c.push(t, &[v])?;
    }
    let [a] = c.finish(Some(end))?;
    Ok(a)
}

/// A transfer-function point `Y/X` from single-frequency correlation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinePoint {
    /// `Y/X` at ω.
    pub ratio: Complex64,
    /// Covariance of `(Re R̂, Im R̂)` (ratio units²), first order, input and
    /// output noise independent.
    pub cov: [[f64; 2]; 2],
    /// Relative standard error `√(E|R̂ − R|²)/|R|` (dimensionless); infinite when `R = 0`.
    pub noise_rel: f64,
    /// The smaller fraction of input and output variance the sinusoid explains (0–1).
    pub coherence: f64,
}

/// `M Σ Mᵀ` for the real 2 × 2 matrix `M` of multiplication by the complex `z`.
fn rotate_cov(cov: &[[f64; 2]; 2], z: Complex64) -> Matrix2<f64> {
    let m = Matrix2::new(z.re, -z.im, z.im, z.re);
    let s = Matrix2::new(cov[0][0], cov[0][1], cov[1][0], cov[1][1]);
    m * s * m.transpose()
}

/// `Y/X` at ω from the amplitudes of input `x` and output `y` (both from
/// the same window and origin), with its covariance from
/// `δR = δY/X − R·δX/X`.
pub fn sine_ratio(x: &SineAmplitude, y: &SineAmplitude) -> Result<SinePoint> {
    let xn = x.amplitude.norm();
    if !(xn.is_finite() && xn > 0.0) {
        return Err(ScienceError::Infeasible(
            "sine correlation: the input has no component at ω".into(),
        ));
    }
    let ratio = y.amplitude / x.amplitude;
    let inv_x = x.amplitude.inv();
    let cov = rotate_cov(&y.amplitude_cov, inv_x) + rotate_cov(&x.amplitude_cov, ratio * inv_x);
    let rn = ratio.norm();
    let noise_rel = if rn > 0.0 {
        (cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt() / rn
    } else {
        f64::INFINITY
    };
    Ok(SinePoint {
        ratio,
        cov: [[cov[(0, 0)], cov[(0, 1)]], [cov[(1, 0)], cov[(1, 1)]]],
        noise_rel,
        coherence: x.explained().min(y.explained()),
    })
}

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

impl H1Bin {
    /// Relative standard error of `H`, `√(E|Ĥ − H|²)/|H| = √((1 − γ²)/(γ² n_d))`
    /// (Bendat & Piersol's normalised random error of the gain,
    /// `√((1 − γ²)/(2 γ² n_d))`, is per component; this is the complex
    /// total, comparable with [`SinePoint::noise_rel`]). Overlapping
    /// segments are counted as independent, which understates it by about
    /// 10 % with a Hann window at 50 % overlap. Infinite when `γ² = 0`.
    pub fn noise_rel(&self) -> f64 {
        let g2 = self.coherence;
        if g2 > 0.0 {
            ((1.0 - g2).max(0.0) / (g2 * self.segments.max(1) as f64)).sqrt()
        } else {
            f64::INFINITY
        }
    }
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
///
/// The reported frequency is the band's input-power-weighted mean
/// frequency `Σ ω_k S_xx,k / Σ S_xx,k` (`S_xx,k` ∝ `|X_k|²`), not its
/// centre: a band where one line dominates is labelled at that line (within
/// the spread of its leakage), a flat band at its mean frequency.
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
