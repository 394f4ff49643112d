//! The conditions of one analysis window ([`Condition`]), with what the
//! forward model needs of its measured angle ([`GravityFundamentals`]) and
//! of its motor command ([`CommandPeaks`]).

use num_complex::Complex64;
use serde::Serialize;

/// The conditions of one analysis window.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Condition {
    /// Experiment (1–9, or the recording's own numbering).
    pub experiment: u32,
    /// Period within the experiment.
    pub period: u32,
    /// Load on the exoskeleton (kg).
    pub load_kg: f64,
    /// Bias torque of the period (Nm).
    pub bias_nm: f64,
    /// Amplification α of the period.
    pub alpha: f64,
    /// Excitation amplitude (Nm; 0 for broadband).
    pub amplitude_nm: f64,
    /// Mean measured angle over the window (rad): the posture the plant is linearised at.
    pub theta0_rad: f64,
    /// Amplitude of θ_e at the excitation frequency (rad; the RMS·√2 of the band for broadband).
    pub theta_amp_rad: f64,
    /// Mean of `sin θ_e` over the window's whole cycles (the plant's gravity is `m g l sin θ`).
    pub sin_theta_mean: f64,
    /// Mean SEA torque `τ_s` over the window's whole cycles (Nm; NaN when
    /// not measured): the torque the joint's drive holds on average, the
    /// preload of a gear mesh behind it.
    pub tau_s_mean_nm: f64,
    /// Mean cuff torque `τ_c` over the window's whole cycles (the whole
    /// window when broadband; Nm): at rest on average what the subject's
    /// spring carries ([`crate::equilibrium`]).
    pub tau_c_mean_nm: f64,
    /// The window's motor command as a torque limit sees it (`None` when
    /// not recorded in every sample of its whole cycles, or broadband).
    #[serde(skip)]
    pub command: Option<std::sync::Arc<CommandPeaks>>,
    /// The measured angle's gravity fundamentals over the window's whole
    /// cycles (`None` when broadband or not measurable).
    #[serde(skip)]
    pub gravity: Option<GravityFundamentals>,
    /// Control period of the recording (s).
    pub sample_period_s: f64,
    /// Start of the window (s from the recording's first sensor sample).
    pub start_s: f64,
    /// Time from the start of the experiment's first window to this
    /// window's start (s): its place in time within the experiment.
    pub elapsed_s: f64,
}

#[cfg(test)]
impl Condition {
    /// A single-sine window for the unit tests: experiment 1, period 1, no
    /// load, no bias, `α = 1`, a 2 Nm excitation, the posture `theta0_rad`
    /// (`sin θ` its sine), the angle amplitude `theta_amp_rad` and the control
    /// period `sample_period_s`; the SEA's mean torque not measured (NaN), no
    /// cuff torque, command or gravity fundamentals, at the recording's start.
    /// A test sets what else it needs with `..Condition::test_window(..)`.
    pub(crate) fn test_window(theta0_rad: f64, theta_amp_rad: f64, sample_period_s: f64) -> Self {
        Condition {
            experiment: 1,
            period: 1,
            load_kg: 0.0,
            bias_nm: 0.0,
            alpha: 1.0,
            amplitude_nm: 2.0,
            theta0_rad,
            theta_amp_rad,
            sin_theta_mean: theta0_rad.sin(),
            tau_s_mean_nm: f64::NAN,
            tau_c_mean_nm: 0.0,
            command: None,
            gravity: None,
            sample_period_s,
            start_s: 0.0,
            elapsed_s: 0.0,
        }
    }
}

/// The fundamentals `(2/n) Σ y_k e^{−jωt_k}` (detrended, over one window's
/// whole cycles) of the measured angle `θ_m`, of `sin θ_m` and of
/// `cos θ_m`: gravity's moment at the fundamental is `m g l [sin θ]₁`
/// exactly, whatever harmonics the arm's swing holds, and an encoder offset
/// `δ` moves it to `cos δ [sin θ_m]₁ − sin δ [cos θ_m]₁`
/// ([`crate::model::Physics::gravity_gain`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravityFundamentals {
    /// `[θ_m]₁` (rad).
    pub theta: Complex64,
    /// `[sin θ_m]₁`.
    pub sin: Complex64,
    /// `[cos θ_m]₁`.
    pub cos: Complex64,
}

impl GravityFundamentals {
    /// The fundamentals of the angle samples `theta_rad` at `t_s` (s), all
    /// in whole cycles of `omega_rad_s`; `None` when any is not measurable
    /// or the angle does not move at ω.
    pub fn new(t_s: &[f64], theta_rad: &[f64], omega_rad_s: f64) -> Option<Self> {
        let f = |y: &[f64]| {
            exo_impedance::frf::sine_amplitude(t_s, y, omega_rad_s, true)
                .ok()
                .map(|a| a.amplitude)
        };
        let theta = f(theta_rad)?;
        let sin: Vec<f64> = theta_rad.iter().map(|x| x.sin()).collect();
        let cos: Vec<f64> = theta_rad.iter().map(|x| x.cos()).collect();
        let g = GravityFundamentals {
            theta,
            sin: f(&sin)?,
            cos: f(&cos)?,
        };
        (theta.norm() > 0.0 && [g.theta, g.sin, g.cos].iter().all(|z| z.is_finite())).then_some(g)
    }
}

/// One window's motor command `τ_d` over its whole cycles, as a torque
/// limit sees it: the samples sorted by value with running sums of their
/// share of the fundamental, so that what a limit `L` cuts off the
/// fundamental, `(2/n) Σ (clip(x_k, −L, L) − x_k) e^{−jωt_k}`, is exact for
/// any `L` (a binary search and two sums) and needs no assumption on the
/// command's shape (its harmonics, its noise: the peaks are what they were).
#[derive(Debug, Clone, PartialEq)]
pub struct CommandPeaks {
    /// The command's fundamental `(2/n) Σ x_k e^{−jωt_k}` (Nm).
    pub fundamental: Complex64,
    /// The samples' values, largest first (Nm).
    desc_x: Vec<f64>,
    /// Running sums over that order of `(2/n) e^{−jωt_k}`, from 0 (one more
    /// than the samples).
    sum_e: Vec<Complex64>,
    /// The same of `(2/n) x_k e^{−jωt_k}` (Nm).
    sum_xe: Vec<Complex64>,
}

impl CommandPeaks {
    /// From the command `x` (Nm) at `t` (s) over whole cycles of `w`
    /// (rad/s); `None` when a value is not finite or there are none.
    pub fn new(t: &[f64], x: &[f64], w: f64) -> Option<Self> {
        let n = t.len().min(x.len());
        if n == 0 || x[..n].iter().any(|v| !v.is_finite()) {
            return None;
        }
        let scale = 2.0 / n as f64;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| x[b].total_cmp(&x[a]));
        let (mut sum_e, mut sum_xe) = (Vec::with_capacity(n + 1), Vec::with_capacity(n + 1));
        let (mut e_acc, mut xe_acc) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
        sum_e.push(e_acc);
        sum_xe.push(xe_acc);
        for &k in &order {
            let e = scale * Complex64::from_polar(1.0, -w * (t[k] - t[0]));
            e_acc += e;
            xe_acc += x[k] * e;
            sum_e.push(e_acc);
            sum_xe.push(xe_acc);
        }
        Some(Self {
            fundamental: xe_acc,
            desc_x: order.iter().map(|&k| x[k]).collect(),
            sum_e,
            sum_xe,
        })
    }

    /// The largest magnitude of the command (Nm).
    pub fn peak_nm(&self) -> f64 {
        let first = self.desc_x.first().copied().unwrap_or(0.0);
        let last = self.desc_x.last().copied().unwrap_or(0.0);
        first.abs().max(last.abs())
    }

    /// The gain of a torque limit `limit_nm` at the fundamental: the
    /// fundamental of `clip(τ_d, −L, L)` over the command's own (complex:
    /// a command with harmonics can be clipped off its phase). 1 for an
    /// infinite limit or a command with no fundamental.
    pub fn clip_gain(&self, limit_nm: f64) -> Complex64 {
        let one = Complex64::new(1.0, 0.0);
        if !limit_nm.is_finite() || self.fundamental.norm() == 0.0 {
            return one;
        }
        let l = limit_nm.max(0.0);
        let n = self.desc_x.len();
        // Above the limit: the first `up` samples; below −L: the last `low`.
        let up = self.desc_x.partition_point(|&v| v > l);
        let low = n - self.desc_x.partition_point(|&v| v >= -l);
        let cut_up = l * self.sum_e[up] - self.sum_xe[up];
        let (e_low, xe_low) = (
            self.sum_e[n] - self.sum_e[n - low],
            self.sum_xe[n] - self.sum_xe[n - low],
        );
        let cut_low = -l * e_low - xe_low;
        one + (cut_up + cut_low) / self.fundamental
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A torque limit's gain from a window's command samples
    /// ([`crate::data::CommandPeaks::clip_gain`]) against the describing
    /// function of a clipped sine `b + A sin φ`, written out here as the
    /// independent truth: each side clips where `sin φ` passes `u = (L −
    /// b)/A` or `v = (L + b)/A` and removes `f(u) = (π/2 − asin u − u √(1 −
    /// u²))/π` of the fundamental (the textbook `(2/π)(asin u + u √(1 −
    /// u²))` without a mean), at limits above, at and below the peaks, with
    /// and without a mean, and a whole cycle beyond the limit.
    #[test]
    fn the_torque_limits_gain_is_the_clipped_sines_fundamental() {
        let f = |u: f64| {
            let u = u.clamp(-1.0, 1.0);
            (std::f64::consts::FRAC_PI_2 - u.asin() - u * (1.0 - u * u).sqrt())
                / std::f64::consts::PI
        };
        let describing = |l: f64, b: f64, a: f64| (1.0 - f((l - b) / a) - f((l + b) / a)).max(0.0);
        let w = 5.0;
        for (l, b, a) in [
            (30.0, 0.0, 2.0),
            (1.5, 0.0, 2.0),
            (26.0, 24.0, 3.2),
            (22.0, 24.0, 3.2),
            (20.0, 24.0, 3.2),
            (5.0, -4.0, 2.0),
            (3.0, -4.0, 8.0),
            (0.5, 0.0, 4.0),
        ] {
            // Four whole cycles, 20 000 samples, at a phase of 0.3 rad.
            let n = 20_000;
            let t: Vec<f64> = (0..n)
                .map(|k| 4.0 * std::f64::consts::TAU / w * k as f64 / n as f64)
                .collect();
            let x: Vec<f64> = t.iter().map(|t| b + a * (w * t + 0.3).sin()).collect();
            let cmd = crate::data::CommandPeaks::new(&t, &x, w).unwrap();
            let got = cmd.clip_gain(l);
            let want = describing(l, b, a);
            assert!(
                (got - want).norm() < 2e-4,
                "L {l}, b {b}, A {a}: {got} against {want}"
            );
            assert!((cmd.peak_nm() - (b.abs() + a)).abs() < 1e-6);
        }
        // A clip at the mean keeps half the fundamental.
        let t: Vec<f64> = (0..1000).map(|k| k as f64 * 1e-3).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|t| 24.0 + 3.0 * (std::f64::consts::TAU * t).cos())
            .collect();
        let cmd = crate::data::CommandPeaks::new(&t, &x, std::f64::consts::TAU).unwrap();
        assert!((cmd.clip_gain(24.0) - 0.5).norm() < 1e-3);
        // No limit, or a limit beyond the peaks: no effect.
        assert_eq!(cmd.clip_gain(f64::INFINITY), Complex64::new(1.0, 0.0));
        assert!((cmd.clip_gain(27.5) - 1.0).norm() < 1e-12);
        // A command that is not finite is no command.
        assert!(crate::data::CommandPeaks::new(&t, &[f64::NAN; 1000], 1.0).is_none());
    }
}
