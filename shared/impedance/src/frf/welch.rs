//! The broadband estimate: Welch-averaged H1 with coherence
//! ([`welch_h1`]) and its bins grouped into log-spaced points (see the
//! module `frf`).

use num_complex::Complex64;

use crate::error::{Result, ScienceError};

/// A forward FFT (`X_k = Σ x_n e^{−j2πkn/N}`) of one length `N ≥ 1`,
/// planned once and applied to many buffers: rustfft's mixed-radix plans,
/// with Rader's or Bluestein's algorithm for large prime factors, so a
/// multisine's period or a Welch segment need not be a power of two.
pub struct Fft {
    plan: std::sync::Arc<dyn rustfft::Fft<f64>>,
    scratch: Vec<Complex64>,
}

impl std::fmt::Debug for Fft {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fft").field("len", &self.len()).finish()
    }
}

impl Fft {
    /// Plans the FFT of `n` samples; refused for `n = 0`.
    pub fn new(n: usize) -> Result<Self> {
        if n == 0 {
            return Err(ScienceError::Infeasible("FFT of no samples".into()));
        }
        let plan = rustfft::FftPlanner::new().plan_fft_forward(n);
        let scratch = vec![Complex64::new(0.0, 0.0); plan.get_inplace_scratch_len()];
        Ok(Self { plan, scratch })
    }

    /// The length it was planned for.
    pub fn len(&self) -> usize {
        self.plan.len()
    }

    /// Always false: a plan has at least one sample ([`Fft::new`]).
    pub fn is_empty(&self) -> bool {
        self.plan.len() == 0
    }

    /// Transforms `a` in place; refused when its length is not the plan's.
    pub fn forward(&mut self, a: &mut [Complex64]) -> Result<()> {
        if a.len() != self.len() {
            return Err(ScienceError::LengthMismatch {
                what: "FFT buffer against its plan",
                left: a.len(),
                right: self.len(),
            });
        }
        self.plan.process_with_scratch(a, &mut self.scratch);
        Ok(())
    }
}

/// In-place forward FFT of any length ≥ 1 (`e^{−j}`; see [`Fft`], which
/// plans once for many buffers of one length).
pub fn fft_in_place(a: &mut [Complex64]) -> Result<()> {
    Fft::new(a.len())?.forward(a)
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
    /// total, comparable with
    /// [`SinePoint::noise_rel`](super::SinePoint::noise_rel)). Overlapping
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
/// `segment_len` (any length ≥ 16) with a Hann window and 50 % overlap,
/// each segment's mean removed. Bins 1 … `segment_len/2 − 1`.
pub fn welch_h1(x: &[f64], y: &[f64], rate_hz: f64, segment_len: usize) -> Result<Vec<H1Bin>> {
    if x.len() != y.len() {
        return Err(ScienceError::LengthMismatch {
            what: "H1 estimate",
            left: x.len(),
            right: y.len(),
        });
    }
    if segment_len < 16 {
        return Err(ScienceError::Infeasible(format!(
            "H1 segment length {segment_len} must be at least 16"
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
    let mut fft = Fft::new(segment_len)?;
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
        fft.forward(&mut fx)?;
        fft.forward(&mut fy)?;
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
