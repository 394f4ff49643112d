//! A designed periodic multisine excitation (issue 34 item 1): lines
//! log-spaced over a band on the frequencies one period resolves exactly,
//! Schroeder's phases, then iterative clipping to lower the crest factor.
//!
//! A period of `N` samples at `rate_hz` resolves the frequencies
//! `ω_b = 2π b · rate_hz / N` (bin `b`); a signal made only of such lines
//! repeats exactly every period, so the DFT of one whole period holds each
//! line in its own bin, with no leakage. The signal is
//! `x[n] = Σ_l A_l cos(2π b_l n / N + φ_l)`.
//!
//! - [`log_spaced_bins`]: the bins nearest to `lines` log-spaced targets
//!   over the band, distinct and increasing.
//! - [`Multisine::schroeder`]: Schroeder's phases (M. R. Schroeder,
//!   "Synthesis of low-peak-factor signals and binary sequences with low
//!   autocorrelation", IEEE Trans. Inf. Theory 16, 1970) in their form
//!   for any amplitudes and harmonic numbers:
//!   `φ_k = −2π Σ_{b_l < b_k} (b_k − b_l) p_l`, `p_l = A_l² / Σ A²`.
//! - [`Multisine::clipped`]: the clipping iteration (E. Van der Ouderaa,
//!   J. Schoukens, J. Renneboog, "Peak factor minimization using a
//!   time-frequency domain swapping algorithm", IEEE Trans. Instrum. Meas.
//!   37, 1988): clip the period at a fraction of its peak, keep the
//!   phases of the clipped signal's lines with the designed amplitudes,
//!   repeat; the lowest crest factor seen is kept.
//!
//! Amplitudes are in the excitation's own unit (Nm for a torque).

use crate::error::{finite, positive, Result, ScienceError};

/// One line of a multisine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultisineLine {
    /// Its bin in the period (cycles per period).
    pub bin: usize,
    /// Its frequency (rad/s): `2π · bin · rate_hz / period_samples`.
    pub omega_rad_s: f64,
    /// Its amplitude (the excitation's unit, peak of the cosine).
    pub amplitude: f64,
    /// Its phase (rad) at sample 0 of each period.
    pub phase_rad: f64,
}

/// A periodic multisine: one period of `period_samples` samples at
/// `rate_hz`, made of its lines.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    rate_hz: f64,
    period_samples: usize,
    lines: Vec<MultisineLine>,
}

/// The bins of `lines` lines log-spaced over `band_rad_s` on the grid of a
/// period of `period_samples` samples at `rate_hz`: each the bin nearest
/// to its target `ω_lo (ω_hi/ω_lo)^(i/(lines−1))`, moved up (from the low
/// end) or down (from the high end) where two would share a bin, all
/// within the band and below Nyquist. Errors name what cannot be met: a
/// band beyond Nyquist or below the period's first bin, or more lines than
/// the band holds bins.
pub fn log_spaced_bins(
    rate_hz: f64,
    period_samples: usize,
    band_rad_s: [f64; 2],
    lines: usize,
) -> Result<Vec<usize>> {
    let rate_hz = positive("rate_hz", rate_hz)?;
    let lo = positive("band_rad_s[0]", band_rad_s[0])?;
    let hi = positive("band_rad_s[1]", band_rad_s[1])?;
    if period_samples < 4 {
        return Err(ScienceError::Infeasible(format!(
            "a multisine period of {period_samples} samples resolves no band (at least 4)"
        )));
    }
    if hi <= lo {
        return Err(ScienceError::Infeasible(format!(
            "multisine band [{lo}, {hi}] rad/s: its upper edge must be above its lower"
        )));
    }
    if lines == 0 {
        return Err(ScienceError::Infeasible(
            "a multisine needs at least one line".into(),
        ));
    }
    let d_omega = std::f64::consts::TAU * rate_hz / period_samples as f64;
    let nyquist_bin = period_samples.div_ceil(2) - 1; // the last bin below Nyquist
    let first = (lo / d_omega).ceil().max(1.0) as usize;
    let last = ((hi / d_omega).floor() as usize).min(nyquist_bin);
    let nyquist_rad_s = std::f64::consts::PI * rate_hz;
    if hi >= nyquist_rad_s {
        return Err(ScienceError::Infeasible(format!(
            "multisine band [{lo}, {hi}] rad/s reaches beyond Nyquist ({nyquist_rad_s:.2} rad/s at {rate_hz} Hz)"
        )));
    }
    if first > last {
        return Err(ScienceError::Infeasible(format!(
            "multisine band [{lo}, {hi}] rad/s holds no frequency a period of {period_samples} samples at {rate_hz} Hz resolves (spacing {d_omega:.4} rad/s, Nyquist {:.2} rad/s)",
            std::f64::consts::PI * rate_hz
        )));
    }
    if last - first + 1 < lines {
        return Err(ScienceError::Infeasible(format!(
            "multisine band [{lo}, {hi}] rad/s holds {} resolved frequencies (spacing {d_omega:.4} rad/s), fewer than the {lines} lines asked: lengthen the period or ask fewer lines",
            last - first + 1
        )));
    }
    let (w_lo, w_hi) = (first as f64 * d_omega, last as f64 * d_omega);
    let mut bins: Vec<usize> = (0..lines)
        .map(|i| {
            let t = if lines == 1 {
                0.0
            } else {
                i as f64 / (lines - 1) as f64
            };
            let w = w_lo * (w_hi / w_lo).powf(t);
            ((w / d_omega).round() as usize).clamp(first, last)
        })
        .collect();
    for i in 1..lines {
        bins[i] = bins[i].max(bins[i - 1] + 1);
    }
    // The pushes up may have passed the band's top: pull back from there.
    bins[lines - 1] = bins[lines - 1].min(last);
    for i in (0..lines - 1).rev() {
        bins[i] = bins[i].min(bins[i + 1] - 1);
    }
    Ok(bins)
}

/// Whether `bins` can be the excited lines of a period of
/// `period_samples` samples: each between 1 and below Nyquist
/// (`2·bin < period_samples`), each once. The error names the line and
/// its bin. The one check of a line set that the design, the per-line
/// estimate, the trend removal and the identifier share.
pub fn check_bins(period_samples: usize, bins: &[usize]) -> Result<()> {
    for (i, &b) in bins.iter().enumerate() {
        if b == 0 || 2 * b >= period_samples {
            return Err(ScienceError::Infeasible(format!(
                "line {i}: bin {b} is not between 1 and Nyquist of a {period_samples}-sample period"
            )));
        }
        if bins[..i].contains(&b) {
            return Err(ScienceError::Infeasible(format!(
                "line {i}: bin {b} is excited twice"
            )));
        }
    }
    Ok(())
}

impl Multisine {
    /// The multisine of `bins` (distinct, each below Nyquist) with
    /// `amplitudes` and Schroeder's phases, a period of `period_samples`
    /// at `rate_hz`.
    pub fn schroeder(
        rate_hz: f64,
        period_samples: usize,
        bins: &[usize],
        amplitudes: &[f64],
    ) -> Result<Self> {
        let rate_hz = positive("rate_hz", rate_hz)?;
        if bins.len() != amplitudes.len() {
            return Err(ScienceError::LengthMismatch {
                what: "multisine bins and amplitudes",
                left: bins.len(),
                right: amplitudes.len(),
            });
        }
        if bins.is_empty() {
            return Err(ScienceError::Infeasible(
                "a multisine needs at least one line".into(),
            ));
        }
        check_bins(period_samples, bins)?;
        for &a in amplitudes {
            positive("multisine amplitude", a)?;
        }
        let power: f64 = amplitudes.iter().map(|a| a * a).sum();
        let d_omega = std::f64::consts::TAU * rate_hz / period_samples as f64;
        let lines = bins
            .iter()
            .zip(amplitudes)
            .map(|(&bk, &ak)| {
                let phase: f64 = bins
                    .iter()
                    .zip(amplitudes)
                    .filter(|(&bl, _)| bl < bk)
                    .map(|(&bl, &al)| (bk - bl) as f64 * al * al / power)
                    .sum();
                MultisineLine {
                    bin: bk,
                    omega_rad_s: bk as f64 * d_omega,
                    amplitude: ak,
                    phase_rad: wrap(-std::f64::consts::TAU * phase),
                }
            })
            .collect();
        Ok(Multisine {
            rate_hz,
            period_samples,
            lines,
        })
    }

    /// The same lines with phases from `iterations` rounds of clipping
    /// (each at `clip` of the current peak, `0 < clip < 1`), the lowest
    /// crest factor seen kept (never above this one's).
    pub fn clipped(&self, iterations: usize, clip: f64) -> Result<Self> {
        let clip = finite("clip", clip)?;
        if !(clip > 0.0 && clip < 1.0) {
            return Err(ScienceError::OutOfRange {
                name: "clip",
                value: clip,
                allowed: "(0, 1)",
            });
        }
        let table = CosTable::new(self.period_samples);
        let mut best = self.clone();
        let mut best_cf = best.crest_factor_with(&table);
        let mut current = self.clone();
        let mut x = vec![0.0; self.period_samples];
        for _ in 0..iterations {
            current.fill_period(&table, &mut x);
            let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let level = clip * peak;
            for v in &mut x {
                *v = v.clamp(-level, level);
            }
            for line in &mut current.lines {
                let (re, im) = table.dft_at(&x, line.bin);
                line.phase_rad = im.atan2(re);
            }
            let cf = current.crest_factor_with(&table);
            if cf < best_cf {
                best_cf = cf;
                best = current.clone();
            }
        }
        Ok(best)
    }

    /// The same multisine with every amplitude scaled so that its peak is
    /// `peak` (the excitation's unit).
    pub fn scaled_to_peak(&self, peak: f64) -> Result<Self> {
        let peak = positive("peak", peak)?;
        let s = peak / self.peak();
        let mut out = self.clone();
        for l in &mut out.lines {
            l.amplitude *= s;
        }
        Ok(out)
    }

    /// The lines, in increasing frequency.
    pub fn lines(&self) -> &[MultisineLine] {
        &self.lines
    }

    /// Samples in one period.
    pub fn period_samples(&self) -> usize {
        self.period_samples
    }

    /// The sample rate (Hz).
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The period's length (s).
    pub fn period_s(&self) -> f64 {
        self.period_samples as f64 / self.rate_hz
    }

    /// Sample `n` (counted from the start of any period; the signal
    /// repeats every `period_samples`). No allocation: for a control loop's
    /// tick.
    pub fn sample(&self, n: u64) -> f64 {
        let k = n % self.period_samples as u64;
        let tau_over_n = std::f64::consts::TAU / self.period_samples as f64;
        self.lines
            .iter()
            .map(|l| {
                let m = (l.bin as u64 * k) % self.period_samples as u64;
                l.amplitude * (tau_over_n * m as f64 + l.phase_rad).cos()
            })
            .sum()
    }

    /// One whole period.
    pub fn period(&self) -> Vec<f64> {
        let mut x = vec![0.0; self.period_samples];
        self.fill_period(&CosTable::new(self.period_samples), &mut x);
        x
    }

    /// RMS over a period: `√(Σ A²/2)`.
    pub fn rms(&self) -> f64 {
        (self
            .lines
            .iter()
            .map(|l| l.amplitude * l.amplitude)
            .sum::<f64>()
            / 2.0)
            .sqrt()
    }

    /// The largest |x| over a period.
    pub fn peak(&self) -> f64 {
        self.period().iter().fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// Peak over RMS (1 for a square wave, √2 for one sine).
    pub fn crest_factor(&self) -> f64 {
        self.crest_factor_with(&CosTable::new(self.period_samples))
    }

    fn crest_factor_with(&self, table: &CosTable) -> f64 {
        let mut x = vec![0.0; self.period_samples];
        self.fill_period(table, &mut x);
        x.iter().fold(0.0f64, |m, v| m.max(v.abs())) / self.rms()
    }

    fn fill_period(&self, table: &CosTable, x: &mut [f64]) {
        x.fill(0.0);
        for l in &self.lines {
            let (c, s) = (l.phase_rad.cos(), l.phase_rad.sin());
            for (n, v) in x.iter_mut().enumerate() {
                // cos(θ + φ) = cos θ cos φ − sin θ sin φ
                let (ct, st) = table.at(l.bin * n);
                *v += l.amplitude * (ct * c - st * s);
            }
        }
    }
}

/// `cos` and `sin` of `2π m / n` for `m` in `0..n`.
struct CosTable {
    cos: Vec<f64>,
    sin: Vec<f64>,
}

impl CosTable {
    fn new(n: usize) -> Self {
        let (cos, sin) = (0..n)
            .map(|m| {
                let t = std::f64::consts::TAU * m as f64 / n as f64;
                (t.cos(), t.sin())
            })
            .unzip();
        CosTable { cos, sin }
    }

    /// `(cos, sin)` of `2π m / n`, `m` taken modulo `n`.
    fn at(&self, m: usize) -> (f64, f64) {
        let i = m % self.cos.len();
        (self.cos[i], self.sin[i])
    }

    /// The DFT of `x` (length `n`) at bin `b`: `Σ x[k] e^{−j2π b k / n}`.
    fn dft_at(&self, x: &[f64], b: usize) -> (f64, f64) {
        x.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, v)| {
            let (c, s) = self.at(b * k);
            (re + v * c, im - v * s)
        })
    }
}

/// `a` wrapped into `(−π, π]`.
fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}
