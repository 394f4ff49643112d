//! The single-frequency estimate: the streaming lock-in
//! ([`SineCorrelator`]) and its block forms (see the module `frf`).

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
/// sample; see the [module documentation](super) for the model, the
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
pub(super) fn block_end(t_s: &[f64]) -> Option<f64> {
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
