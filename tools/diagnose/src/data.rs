//! What a recording says about the plant: one complex observation per
//! transfer function and analysis window (single-sine periods) or per band
//! (broadband windows), each with the noise measured from the data itself.
//!
//! Transfer functions, as the identifier defines them
//! (`docs/recording-format.md`):
//! - `S_h = τ_c/θ_e` (Nm/rad), the human's dynamic stiffness seen by the cuff;
//! - `S_{h-e} = (τ_s − τ_gravity)/θ_e` (Nm/rad), the coupled human–exoskeleton
//!   stiffness with the controller's gravity compensation removed;
//! - `τ_s/τ_d` (dimensionless), the SEA's torque tracking.
//!
//! The controller's own gravity compensation is measured too
//! (`τ_gravity/θ_e` at ω): it is an input of the comparison, not a term of
//! the plant, so a gravity-compensation error shows as the difference between
//! the plant's gravity and what the controller removed.

use std::collections::BTreeMap;

use exo_impedance::frf::{
    average_bins, band_groups, local_polynomial_ratio, sine_ratio, welch_h1, LocalPolynomialPoint,
    SineCorrelator,
};
use exo_recording::Recording;
use num_complex::Complex64;
use serde::Serialize;

/// A transfer function a recording can support.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Tf {
    /// `S_h = τ_c/θ_e` (Nm/rad).
    #[serde(rename = "S_h")]
    Sh,
    /// `S_{h-e} = (τ_s − τ_gravity)/θ_e` (Nm/rad).
    #[serde(rename = "S_h-e")]
    She,
    /// `τ_s/τ_d` (dimensionless).
    #[serde(rename = "tau_s/tau_d")]
    Sea,
    /// The exoskeleton's static balance `mean(τ_s − τ_gravity − τ_c)` over
    /// whole cycles (Nm, real; ω = 0): what the controller's gravity
    /// compensation left to the plant's gravity, plus the torque sensors'
    /// offsets. It needs no knowledge of the human's posture.
    #[serde(rename = "static_balance")]
    Balance,
}

impl Tf {
    /// Every transfer function, in report order.
    pub const ALL: [Tf; 4] = [Tf::Sh, Tf::She, Tf::Sea, Tf::Balance];

    /// Whether it is a frequency response (has a Bode plot).
    pub fn is_dynamic(self) -> bool {
        self != Tf::Balance
    }

    /// The name used in tables and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Tf::Sh => "S_h",
            Tf::She => "S_h-e",
            Tf::Sea => "tau_s/tau_d",
            Tf::Balance => "static_balance",
        }
    }

    /// Which signals it is made of, for messages.
    pub fn signals(self) -> &'static str {
        match self {
            Tf::Sh => "τ_c/θ_e",
            Tf::She => "(τ_s − τ_gravity)/θ_e",
            Tf::Sea => "τ_s/τ_d",
            Tf::Balance => "mean(τ_s − τ_gravity − τ_c)",
        }
    }
}

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

/// One measured transfer-function value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Observation {
    /// Which transfer function.
    pub tf: Tf,
    /// Frequency (rad/s).
    pub omega_rad_s: f64,
    /// Measured value: a single-sine line, a broadband bin average, a
    /// static balance's mean.
    pub value: Complex64,
    /// Standard deviation of the real and of the imaginary part (same units
    /// as `value`), from the window's residual taken as white noise (a
    /// static balance's from the noise of its mean near zero frequency,
    /// with [`Self::sigma_dof`]): what the fits weight with.
    pub sigma: [f64; 2],
    /// The line's own σ, without its window's transient (a single-sine
    /// line whose transient the local polynomials estimated holds it in
    /// [`Self::sigma`]); equal to `sigma` elsewhere. A describing function
    /// is judged on these with the forward model's accuracy
    /// ([`Dataset::held_to`]).
    pub line_sigma: [f64; 2],
    /// The same with the window's transient taken out, where the window
    /// allows it: a single-sine line by the local polynomial method
    /// (`exo_impedance::frf::local_polynomial_ratio`; three cycles or more,
    /// neighbours that hold a smooth transient), with the white σ times
    /// √leverage; a static balance with the mean's noise measured at zero
    /// frequency (`exo_impedance::frf::mean_standard_error_beside`). Reported
    /// ([`crate::fit::noise_only_chi2`], the `residuals` example), not
    /// judged by: judged in place of the lines (stop 33) it cleared every
    /// null but lost two strongly nonlinear cases, whose response its
    /// polynomials partly carry (docs/diagnose.md, "The judgement by the
    /// measured noise").
    pub transient_free: Option<TransientFree>,
    /// The systematic uncertainty beyond the noise this value is held to
    /// (fraction of `|value|`): the forward model's accuracy
    /// [`crate::fit::MODEL_ACCURACY`], combined, for a value divided by the
    /// angle, with the encoder quantiser's gain error at the window's
    /// amplitude (`exo_impedance::quantiser::sine_gain_sd`). A physics with
    /// terms whose forward model is coarser holds every value to more
    /// ([`crate::fit::model_accuracy`]).
    pub accuracy: f64,
    /// Index of its window in [`Dataset::conditions`].
    pub window: usize,
    /// The controller's gravity compensation `τ_gravity/θ_e` at ω (Nm/rad), measured.
    pub gravity_comp: Complex64,
    /// For [`Tf::Balance`]: the window's mean `τ_gravity` and mean `τ_c` (Nm).
    pub statics: [f64; 2],
    /// Degrees of freedom of [`Self::sigma`] where it was estimated from so
    /// few values that a residual over it is Student-t distributed rather
    /// than normal: the static balance's mean noise, two per DFT bin it was
    /// measured at less the posture's slope fitted there and the share the
    /// trend took (`exo_impedance::frf::mean_standard_error_beside`, about
    /// 2.2 for two bins to 6.1 for four). The
    /// lack-of-fit χ² takes such a residual at its normal equivalent
    /// ([`crate::fit::lack_of_fit_chi2`]). `None` where σ is known well
    /// enough to be taken as exact.
    pub sigma_dof: Option<f64>,
}

/// A line with its window's transient taken out ([`Observation::transient_free`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TransientFree {
    /// The value (units of the observation's).
    pub value: Complex64,
    /// Standard deviation of its real and imaginary part.
    pub sigma: [f64; 2],
    /// The noise beside the line (the local polynomials' own residual,
    /// `LocalPolynomialPoint::residual_sigma`) over what the white σ says
    /// there (`σ_white² · leverage`), with that residual's complex degrees
    /// of freedom: below 1 where the white σ also counted a ringing
    /// transient as noise. `None` for a static balance.
    pub local_noise: Option<LocalNoise>,
}

/// The noise measured beside a line against its white σ
/// ([`TransientFree::local_noise`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalNoise {
    /// `residual_sigma² / (σ_white² · leverage)` (1 for white noise).
    pub ratio: f64,
    /// Complex degrees of freedom of the residual.
    pub dof: usize,
}

/// The samples of one analysis window, kept for the time-domain comparison.
#[derive(Debug, Clone, Default)]
pub struct WindowSignals {
    /// Time from the window start (s).
    pub t_s: Vec<f64>,
    /// Measured angle (rad).
    pub theta_rad: Vec<f64>,
    /// Cuff torque (Nm).
    pub tau_c_nm: Vec<f64>,
    /// SEA torque less the controller's gravity compensation (Nm).
    pub tau_s_net_nm: Vec<f64>,
    /// SEA torque as measured (Nm).
    pub tau_s_nm: Vec<f64>,
    /// Motor command (Nm; NaN where the command was not recorded).
    pub tau_d_nm: Vec<f64>,
    /// Excitation frequency (rad/s; 0 for broadband).
    pub omega_rad_s: f64,
}

/// Everything the diagnosis uses from a set of recordings.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    /// Window conditions.
    pub conditions: Vec<Condition>,
    /// Observations (every transfer function of every window).
    pub observations: Vec<Observation>,
    /// Signals per window (same index as `conditions`).
    pub signals: Vec<WindowSignals>,
    /// What could not be used, each naming the file and window.
    pub notes: Vec<String>,
    /// Transfer functions the data supports.
    pub supported: Vec<Tf>,
    /// Sources read.
    pub sources: Vec<String>,
    /// Per window, the noise power of one bin of `τ_c`'s residual spectrum
    /// and the phasors of the fundamental, 2nd and 3rd harmonics of `θ_e`
    /// and of `τ_c` ([`crate::signatures::window_harmonics`]): they depend
    /// on the data only, so they are computed once, when first needed.
    pub(crate) sh_harmonics: std::sync::OnceLock<Vec<Option<ShHarmonics>>>,
    /// The same for `τ_s − τ_gravity` (`S_h-e`'s output) in place of `τ_c`.
    pub(crate) she_harmonics: std::sync::OnceLock<Vec<Option<ShHarmonics>>>,
}

/// One window's `θ_e` and `τ_c` harmonics (see [`Dataset::sh_harmonics`]):
/// `(noise power of τ_c per bin, θ_e phasors, τ_c phasors)`.
pub(crate) type ShHarmonics = (f64, [Complex64; 3], [Complex64; 3]);

impl Dataset {
    /// The experiments present, sorted.
    pub fn experiments(&self) -> Vec<u32> {
        sorted_unique(self.conditions.iter().map(|c| c.experiment))
    }

    /// The experiments with a human impedance observation (`S_h` or
    /// `S_h-e`): only their `K_h`, `H_h` can be fitted.
    pub fn impedance_experiments(&self) -> Vec<u32> {
        sorted_unique(
            self.observations
                .iter()
                .filter(|o| matches!(o.tf, Tf::Sh | Tf::She))
                .map(|o| self.conditions[o.window].experiment),
        )
    }

    /// The same data with every dynamic value held to at least `accuracy`
    /// (fraction of `|value|`) and to its line's own σ: what a model whose forward model is a
    /// describing function ([`crate::terms::Term::describing_function`]) is
    /// fitted and tested on.
    pub fn held_to(&self, accuracy: f64) -> Dataset {
        let mut d = self.clone();
        for o in d.observations.iter_mut().filter(|o| o.tf.is_dynamic()) {
            o.sigma = o.line_sigma;
            o.accuracy = o.accuracy.max(accuracy);
        }
        d
    }

    /// Observations of one transfer function.
    pub fn of(&self, tf: Tf) -> impl Iterator<Item = &Observation> {
        self.observations.iter().filter(move |o| o.tf == tf)
    }
}

fn sorted_unique(it: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut e: Vec<u32> = it.collect();
    e.sort_unstable();
    e.dedup();
    e
}

/// Settings of the data reduction.
#[derive(Debug, Clone, Copy)]
pub struct Reduction {
    /// Smallest coherence (fraction of variance at ω) of θ_e and the output kept.
    pub min_coherence: f64,
    /// Welch segment for broadband windows (samples, power of two).
    pub welch_segment: usize,
    /// Bands a broadband window is summarised into.
    pub broadband_points: usize,
    /// Band (rad/s) of broadband estimates.
    pub broadband_band_rad_s: [f64; 2],
}

impl Default for Reduction {
    fn default() -> Self {
        Self {
            min_coherence: 0.5,
            // As the identifier's defaults, so `exo fit` and `exo diagnose`
            // see the same broadband points.
            welch_segment: 4096,
            broadband_points: 20,
            broadband_band_rad_s: [1.0, 100.0],
        }
    }
}

/// An analysis window found in the protocol topic.
struct Span {
    experiment: u32,
    period: u32,
    start_ns: u64,
    end_ns: u64,
    omega: f64,
    load_kg: f64,
    bias_nm: f64,
    alpha: f64,
    amplitude: f64,
}

fn spans(r: &Recording) -> Vec<Span> {
    let stream_end = r.sensor.last().map(|s| s.stamp_ns + 1);
    exo_analysis::analysis_windows(&r.protocol)
        .into_iter()
        .filter_map(|w| {
            let p = w.state;
            Some(Span {
                experiment: p.experiment,
                period: p.period,
                start_ns: w.start_ns,
                end_ns: w.end_ns.or(stream_end)?,
                omega: p.omega,
                load_kg: p.load_kg,
                bias_nm: p.bias_nm,
                alpha: p.alpha,
                amplitude: p.amplitude,
            })
        })
        .collect()
}

/// Reduces recordings to observations. Never fails on user data: what
/// cannot be used is named in [`Dataset::notes`].
pub fn reduce(recordings: &[Recording], s: &Reduction) -> Dataset {
    let mut d = Dataset::default();
    // Recordings of different subjects keep their experiments apart: the
    // i-th subject's experiment n becomes 100·i + n (i from 1).
    let mut subjects: Vec<String> = Vec::new();
    for r in recordings {
        let s = r.meta("subject").unwrap_or(&r.source).to_string();
        if !subjects.contains(&s) {
            subjects.push(s);
        }
    }
    if subjects.len() > 1 {
        d.notes.push(format!(
            "{} subjects: experiment n of subject i is numbered 100·i + n ({})",
            subjects.len(),
            subjects
                .iter()
                .enumerate()
                .map(|(i, s)| format!("{}: {s}", i + 1))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    for r in recordings {
        let subject = r.meta("subject").unwrap_or(&r.source);
        let key_offset = if subjects.len() > 1 {
            100 * (1 + subjects.iter().position(|s| s == subject).unwrap_or(0) as u32)
        } else {
            0
        };
        d.sources.push(r.source.clone());
        for w in &r.warnings {
            d.notes.push(w.clone());
        }
        if r.protocol.is_empty() {
            d.notes.push(format!(
                "{}: topic exo/protocol is missing or empty: no analysis windows",
                r.source
            ));
        }
        if r.sensor.is_empty() {
            d.notes.push(format!(
                "{}: topic exo/sensor is missing or empty",
                r.source
            ));
            continue;
        }
        let human_only = r.meta("fit_target") == Some("human");
        // Commands by the sample they answer.
        let mut answer: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
        for c in &r.command {
            answer.insert(c.sensor_seq, (c.tau_d, c.tau_gravity));
        }
        if r.command.is_empty() && !human_only {
            d.notes.push(format!(
                "{}: topic exo/command is missing: only S_h (τ_c/θ_e) is compared",
                r.source
            ));
        }
        let spans = spans(r);
        if spans.is_empty() && !r.protocol.is_empty() {
            d.notes.push(format!(
                "{}: the protocol has no analysis phase (phase 3): no windows",
                r.source
            ));
        }
        for sp in &spans {
            let what = format!(
                "{}: experiment {} period {}",
                r.source, sp.experiment, sp.period
            );
            let lo = r.sensor.partition_point(|x| x.stamp_ns < sp.start_ns);
            let hi = r.sensor.partition_point(|x| x.stamp_ns < sp.end_ns);
            let samples = &r.sensor[lo..hi];
            if samples.len() < 16 {
                d.notes
                    .push(format!("{what}: {} samples, window skipped", samples.len()));
                continue;
            }
            let t0 = samples[0].stamp_ns;
            let mut sig = WindowSignals {
                omega_rad_s: sp.omega,
                ..Default::default()
            };
            let mut tau_d = Vec::with_capacity(samples.len());
            let mut tau_s_raw = Vec::with_capacity(samples.len());
            let mut tau_g = Vec::with_capacity(samples.len());
            let mut answered = 0usize;
            let mut bad = 0usize;
            for x in samples {
                if !(x.theta_e.is_finite() && x.tau_c.is_finite() && x.tau_s.is_finite()) {
                    bad += 1;
                    continue;
                }
                let (td, tg) = match answer.get(&x.seq) {
                    Some(&(td, tg)) if td.is_finite() && tg.is_finite() => {
                        answered += 1;
                        (td, tg)
                    }
                    _ => (f64::NAN, 0.0),
                };
                sig.t_s.push((x.stamp_ns - t0) as f64 * 1e-9);
                sig.theta_rad.push(x.theta_e);
                sig.tau_c_nm.push(x.tau_c);
                sig.tau_s_net_nm.push(x.tau_s - tg);
                tau_s_raw.push(x.tau_s);
                tau_d.push(td);
                sig.tau_s_nm.push(x.tau_s);
                sig.tau_d_nm.push(td);
                tau_g.push(tg);
            }
            if bad > 0 {
                d.notes.push(format!(
                    "{what}: {bad} samples with non-finite values left out"
                ));
            }
            let n = sig.t_s.len();
            if n < 16 {
                continue;
            }
            let span_s = sig.t_s[n - 1];
            let dt = if span_s > 0.0 {
                span_s / (n - 1) as f64
            } else {
                1e-3
            };
            let has_command = answered * 10 >= n * 9 && !human_only;
            // The window's whole cycles (all of a broadband window): the
            // means the plant is linearised about. A partial cycle's mean is
            // biased by the sine it holds (at 2 rad/s a 5 s window is one
            // cycle and 0.6 of another: with experiment 1's 0.1 rad that
            // is about 1°, which moves gravity's slope `m g l cos θ₀`).
            let whole = if sp.omega > 0.0 {
                exo_impedance::frf::whole_cycles(&sig.t_s, sp.omega).unwrap_or(n)
            } else {
                n
            }
            .max(1);
            let theta0 = sig.theta_rad[..whole].iter().sum::<f64>() / whole as f64;
            let cond_index = d.conditions.len();
            let mut cond = Condition {
                experiment: sp.experiment + key_offset,
                period: sp.period,
                load_kg: sp.load_kg,
                bias_nm: sp.bias_nm,
                alpha: sp.alpha,
                amplitude_nm: sp.amplitude,
                theta0_rad: theta0,
                theta_amp_rad: 0.0,
                sin_theta_mean: theta0.sin(),
                tau_s_mean_nm: f64::NAN,
                tau_c_mean_nm: sig.tau_c_nm[..whole].iter().sum::<f64>() / whole as f64,
                command: None,
                gravity: None,
                sample_period_s: dt,
                start_s: t0.saturating_sub(r.sensor[0].stamp_ns) as f64 * 1e-9,
                elapsed_s: 0.0,
            };
            let before = d.observations.len();
            if sp.omega > 0.0 {
                single_sine(
                    &what,
                    &sig,
                    &tau_d,
                    &tau_s_raw,
                    &tau_g,
                    has_command,
                    cond_index,
                    s,
                    &mut cond,
                    &mut d,
                );
            } else {
                broadband(
                    &what,
                    &sig,
                    &tau_d,
                    &tau_s_raw,
                    &tau_g,
                    has_command,
                    cond_index,
                    s,
                    &mut cond,
                    &mut d,
                );
            }
            if d.observations.len() > before {
                d.conditions.push(cond);
                d.signals.push(sig);
            }
        }
    }
    // Each window's time within its experiment (from the experiment's
    // first window; a recording's experiments keep their own clocks).
    let mut first: BTreeMap<u32, f64> = BTreeMap::new();
    for c in &d.conditions {
        let f = first.entry(c.experiment).or_insert(c.start_s);
        *f = f.min(c.start_s);
    }
    for c in &mut d.conditions {
        c.elapsed_s = c.start_s - first[&c.experiment];
    }
    pool_transients(&mut d);
    let mut sup: Vec<Tf> = d.observations.iter().map(|o| o.tf).collect();
    sup.sort_unstable();
    sup.dedup();
    d.supported = sup;
    d
}

/// Whether what the neighbouring frequencies hold is a linear transient:
/// smooth in frequency, so that the local polynomials leave only the white
/// noise (their residual's variance within the 99th percentile of
/// `χ²_{2ν}/2ν` over the white σ's, ν the fit's complex degrees of
/// freedom). A nonlinearity's non-periodic response (the impacts of a
/// backlash, ringing the arm's mode) or coloured noise is not, and the
/// polynomials would carry it into the line: no transient-free value then.
/// A fit with no degree of freedom cannot be checked and is not taken.
pub fn smooth_transient(l: &LocalPolynomialPoint, line_sigma: [f64; 2]) -> bool {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    if l.dof == 0 || !l.residual_sigma.is_finite() {
        return false;
    }
    let dof = 2.0 * l.dof as f64;
    let Ok(chi) = ChiSquared::new(dof) else {
        return false;
    };
    let white = 0.5 * (line_sigma[0].powi(2) + line_sigma[1].powi(2)) * l.leverage.max(1.0);
    white > 0.0 && l.residual_sigma.powi(2) / white <= chi.inverse_cdf(0.99) / dof
}

/// The smallest share of a line's white variance taken as noise
/// ([`pool_transients`]). On null recordings of both generators the share
/// measured beside the lines is 0.8–0.95 on average (docs/diagnose.md,
/// "The static balance by its own noise"); a relation with no noise at all
/// (a signal written as another's copy) measures 0, and its σ would vanish
/// against any imperfection of the forward model. An assumption: the white
/// σ is never taken below √0.5 of itself.
const MIN_NOISE_SHARE: f64 = 0.5;

/// A line's own transient beyond which it keeps its own estimate rather
/// than its experiment's pooled one: its squared leak over the estimate's
/// own noise beyond χ²₁'s 99th percentile (a window that clearly rang
/// more than the others of its experiment).
const OWN_TRANSIENT_CHI2: f64 = 6.635;

/// Whether a line's component keeps its own transient `d² − v` (its
/// squared leak `d2` beyond [`OWN_TRANSIENT_CHI2`] times the estimate's
/// own noise `v`) rather than its experiment's pooled one.
fn keeps_own_transient(d2: f64, v: f64) -> bool {
    d2 > OWN_TRANSIENT_CHI2 * v
}

/// Each single-sine line's σ (per component) with its window's transient
/// added as a variance (issue 30 item 3, stop 35). The transient at a line
/// is `d`, the line less its transient-free value (the local polynomials'
/// estimate, where its neighbours hold a smooth transient), whose own
/// noise is `v = σ²(leverage − 1)`; its variance is estimated by
/// `d² − v`, relative to the line's white `σ²`, **pooled** over the lines
/// of one experiment and transfer function and then clipped at zero. A
/// line-by-line clip (stop 34) is biased up: under pure noise
/// `E[max(d² − v, 0)] ≈ 0.48 v`, which left the nulls' χ²/dof at 0.65–0.79.
/// A line whose own `d²` exceeds [`OWN_TRANSIENT_CHI2`]·`v` keeps its own
/// `d² − v` when that is larger, and is left out of the pool (stop 37:
/// counted in both, one ringing window raised every quiet line's σ of its
/// experiment, and the nulls' χ²/dof sat at 0.6 where a few windows rang,
/// the rig's `S_h-e` at 1 kHz most). The line stays the value (a nonlinear
/// form's describing function); the transient is its uncertainty.
fn pool_transients(d: &mut Dataset) {
    // The white σ's share that is noise, pooled per experiment and
    // transfer function: the local polynomials' residual over the white
    // σ, weighted by its degrees of freedom, within [MIN_NOISE_SHARE, 1].
    let mut noise: BTreeMap<(u32, Tf), (f64, f64)> = BTreeMap::new();
    for o in &d.observations {
        let Some(l) = o.transient_free.and_then(|t| t.local_noise) else {
            continue;
        };
        // (Only single-sine lines carry one; a line with no degree of
        // freedom weighs nothing.)
        if l.ratio.is_finite() {
            let g = noise
                .entry((d.conditions[o.window].experiment, o.tf))
                .or_default();
            g.0 += l.dof as f64 * l.ratio;
            g.1 += l.dof as f64;
        }
    }
    let share = |e: u32, tf: Tf| {
        noise
            .get(&(e, tf))
            .filter(|g| g.1 > 0.0)
            .map_or(1.0, |g| (g.0 / g.1).clamp(MIN_NOISE_SHARE, 1.0))
    };
    // Per component: the line's noise variance, the estimate's own noise,
    // the leak.
    let parts = |o: &Observation, q: f64| -> Option<[(f64, f64, f64); 2]> {
        let t = o.transient_free.as_ref().filter(|_| o.tf.is_dynamic())?;
        let leak = o.value - t.value;
        let part = |k: usize, dk: f64| {
            let s2 = o.line_sigma[k].powi(2);
            (q * s2, q * (t.sigma[k].powi(2) - s2).max(0.0), dk * dk)
        };
        Some([part(0, leak.re), part(1, leak.im)])
    };
    let mut pooled: BTreeMap<(u32, Tf), (f64, usize)> = BTreeMap::new();
    for o in &d.observations {
        let e = d.conditions[o.window].experiment;
        let Some(ps) = parts(o, share(e, o.tf)) else {
            continue;
        };
        let g = pooled.entry((e, o.tf)).or_default();
        // A component that keeps its own transient is not pooled: counted
        // in both, its ring would be charged again to every quiet line.
        for (s2, v, d2) in ps
            .into_iter()
            .filter(|&(s2, v, d2)| s2 > 0.0 && !keeps_own_transient(d2, v))
        {
            g.0 += (d2 - v) / s2;
            g.1 += 1;
        }
    }
    for i in 0..d.observations.len() {
        let o = &d.observations[i];
        let e = d.conditions[o.window].experiment;
        let Some(ps) = parts(o, share(e, o.tf)) else {
            continue;
        };
        let (sum, n) = pooled[&(e, o.tf)];
        let r = if n > 0 {
            (sum / n as f64).max(0.0)
        } else {
            0.0
        };
        let sigma = ps.map(|(s2, v, d2)| {
            let own = if keeps_own_transient(d2, v) {
                d2 - v
            } else {
                0.0
            };
            (s2 + (r * s2).max(own)).sqrt()
        });
        d.observations[i].sigma = sigma;
    }
}

fn sigma_of(cov: &[[f64; 2]; 2]) -> [f64; 2] {
    [cov[0][0].max(0.0).sqrt(), cov[1][1].max(0.0).sqrt()]
}

#[allow(clippy::too_many_arguments)]
fn single_sine(
    what: &str,
    sig: &WindowSignals,
    tau_d: &[f64],
    tau_s_raw: &[f64],
    tau_g: &[f64],
    has_command: bool,
    window: usize,
    s: &Reduction,
    cond: &mut Condition,
    d: &mut Dataset,
) {
    let w = sig.omega_rad_s;
    let Ok(corr) = SineCorrelator::<6>::new(w, 0.0, true) else {
        d.notes.push(format!("{what}: ω = {w} is not usable"));
        return;
    };
    let mut corr = corr.with_names(["theta_e", "tau_c", "tau_s_net", "tau_s", "tau_d", "tau_g"]);
    for i in 0..sig.t_s.len() {
        let td = if tau_d[i].is_finite() { tau_d[i] } else { 0.0 };
        if corr
            .push(
                sig.t_s[i],
                &[
                    sig.theta_rad[i],
                    sig.tau_c_nm[i],
                    sig.tau_s_net_nm[i],
                    tau_s_raw[i],
                    td,
                    tau_g[i],
                ],
            )
            .is_err()
        {
            d.notes
                .push(format!("{what}: samples out of order, window skipped"));
            return;
        }
    }
    let end = sig.t_s.last().copied().unwrap_or(0.0) + cond.sample_period_s;
    let amps = match corr.finish(Some(end)) {
        Ok(a) => a,
        Err(e) => {
            d.notes.push(format!("{what}: {e}; window skipped"));
            return;
        }
    };
    let [a_th, a_tc, a_tsn, a_ts, a_td, a_tg] = amps;
    cond.theta_amp_rad = a_th.amplitude.norm();
    let theta_amp_rad = cond.theta_amp_rad;
    let encoder_step_rad = exo_impedance::quantiser::quantum(&sig.theta_rad).unwrap_or(0.0);
    let gravity_comp = if has_command {
        sine_ratio(&a_th, &a_tg).map_or(Complex64::new(0.0, 0.0), |p| p.ratio)
    } else {
        Complex64::new(0.0, 0.0)
    };
    let whole = exo_impedance::frf::whole_cycles(&sig.t_s, w);
    let td_filled: Vec<f64> = tau_d
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    let mut push = |tf: Tf,
                    x: &exo_impedance::frf::SineAmplitude,
                    y: &exo_impedance::frf::SineAmplitude,
                    xs: &[f64],
                    ys: &[f64]| {
        match sine_ratio(x, y) {
            Ok(p)
                if p.coherence >= s.min_coherence
                    && p.ratio.re.is_finite()
                    && p.ratio.im.is_finite() =>
            {
                let line_sigma = sigma_of(&p.cov);
                // The window's transient out of the line; its price (the
                // leverage) on the white noise's σ, which stays the
                // judgement's (docs/diagnose.md, "The noise model").
                let lpm = whole
                    .and_then(|n| local_polynomial_ratio(&sig.t_s[..n], &xs[..n], &ys[..n], w));
                let smooth = lpm.filter(|l| smooth_transient(l, line_sigma));
                let transient_free = smooth.map(|l| {
                    let inflate = l.leverage.max(1.0).sqrt();
                    let white = 0.5 * (line_sigma[0].powi(2) + line_sigma[1].powi(2));
                    TransientFree {
                        value: l.ratio,
                        sigma: [line_sigma[0] * inflate, line_sigma[1] * inflate],
                        local_noise: (white > 0.0).then(|| LocalNoise {
                            ratio: l.residual_sigma.powi(2) / (white * l.leverage.max(1.0)),
                            dof: l.dof,
                        }),
                    }
                });
                // The encoder's quantiser at this amplitude, for the
                // values divided by the angle.
                let quantiser = if tf == Tf::Sea {
                    0.0
                } else {
                    exo_impedance::quantiser::sine_gain_sd(encoder_step_rad, theta_amp_rad)
                };
                // Judged: the line with its white σ, held to the forward
                // model's accuracy (its window's transient may reach it)
                // and the quantiser (docs/diagnose.md, "The judgement by
                // the measured noise").
                // Where the transient was estimated, its variance is added
                // to `sigma` once every window is in (`pool_transients`).
                let floor = match smooth {
                    Some(_) => 0.0,
                    None => crate::fit::MODEL_ACCURACY,
                };
                let sigma = line_sigma;
                d.observations.push(Observation {
                    tf,
                    omega_rad_s: w,
                    value: p.ratio,
                    sigma,
                    line_sigma,
                    transient_free,
                    accuracy: floor.hypot(quantiser),
                    window,
                    gravity_comp,
                    statics: [0.0; 2],
                    sigma_dof: None,
                })
            }
            Ok(p) => d.notes.push(format!(
                "{what}: {} left out: coherence {:.2} below {:.2}",
                tf.signals(),
                p.coherence,
                s.min_coherence
            )),
            Err(e) => d.notes.push(format!("{what}: {}: {e}", tf.signals())),
        }
    };
    push(Tf::Sh, &a_th, &a_tc, &sig.theta_rad, &sig.tau_c_nm);
    if has_command {
        push(Tf::She, &a_th, &a_tsn, &sig.theta_rad, &sig.tau_s_net_nm);
        if a_ts.amplitude.norm() > 0.0 {
            push(Tf::Sea, &a_td, &a_ts, &td_filled, tau_s_raw);
        }
        if let Some(n) = exo_impedance::frf::whole_cycles(&sig.t_s, w) {
            cond.gravity = GravityFundamentals::new(&sig.t_s[..n], &sig.theta_rad[..n], w);
            cond.command =
                CommandPeaks::new(&sig.t_s[..n], &tau_d[..n], w).map(std::sync::Arc::new);
        }
        balance(what, sig, tau_g, window, cond, d);
    }
}

/// The static balance over the window's whole cycles. Where the window
/// allows the noise of its mean to be measured near zero frequency
/// (`exo_impedance::frf::mean_standard_error_beside`: two cycles or more,
/// less what follows sin θ at those bins) every
/// mean of the balance is the Hann-tapered one
/// (`exo_impedance::frf::hann_mean`: the line and a ringing mode's
/// boundary term `M_e Δθ̇/T` left out), judged by that noise times the
/// taper's gain with its few degrees of freedom
/// ([`Observation::sigma_dof`]). A shorter window keeps plain means and the
/// residual's standard error with each cycle counted as one sample
/// (conservative).
fn balance(
    what: &str,
    sig: &WindowSignals,
    tau_g: &[f64],
    window: usize,
    cond: &mut Condition,
    d: &mut Dataset,
) {
    use exo_impedance::frf::{hann_mean, mean_standard_error_beside, HANN_MEAN_NOISE_GAIN};
    let w = sig.omega_rad_s;
    let Some(n) = exo_impedance::frf::whole_cycles(&sig.t_s, w) else {
        d.notes
            .push(format!("{what}: static balance: less than one cycle"));
        return;
    };
    let y: Vec<f64> = (0..n)
        .map(|i| sig.tau_s_net_nm[i] - sig.tau_c_nm[i])
        .collect();
    let sin_theta: Vec<f64> = sig.theta_rad[..n].iter().map(|t| t.sin()).collect();
    let (t_s, tau_c) = (&sig.t_s[..n], &sig.tau_c_nm[..n]);
    let plain = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    // τ_s = its net part + the controller's gravity compensation.
    cond.tau_s_mean_nm = plain(&sig.tau_s_net_nm[..n]) + plain(&tau_g[..n]);
    let Ok(a) = exo_impedance::frf::sine_amplitude(t_s, &y, w, true) else {
        cond.sin_theta_mean = plain(&sin_theta);
        return;
    };
    // Its noise less what follows the posture at those bins: the model
    // takes gravity's moment at the window's own mean sin θ, so a slow
    // wander of the angle is no noise of the residual (stop 37).
    let measured = mean_standard_error_beside(t_s, &y, &sin_theta, w).filter(|(se, _)| *se > 0.0);
    let mean: &dyn Fn(&[f64]) -> f64 = if measured.is_some() {
        &hann_mean
    } else {
        &plain
    };
    let value = mean(&y);
    cond.sin_theta_mean = mean(&sin_theta);
    let statics = [mean(&tau_g[..n]), mean(tau_c)];
    let (se, sigma_dof) = match measured {
        Some((se, dof)) => (se * HANN_MEAN_NOISE_GAIN, Some(dof)),
        None => (
            (a.residual_var.max(0.0) / a.cycles.max(1) as f64).sqrt(),
            None,
        ),
    };
    let transient_free = measured.map(|_| TransientFree {
        value: Complex64::new(value, 0.0),
        sigma: [se, se],
        local_noise: None,
    });
    d.observations.push(Observation {
        tf: Tf::Balance,
        omega_rad_s: 0.0,
        value: Complex64::new(value, 0.0),
        sigma: [se, se],
        line_sigma: [se, se],
        transient_free,
        accuracy: 0.0,
        window,
        gravity_comp: Complex64::new(0.0, 0.0),
        statics,
        sigma_dof,
    });
}

#[allow(clippy::too_many_arguments)]
fn broadband(
    what: &str,
    sig: &WindowSignals,
    tau_d: &[f64],
    tau_s_raw: &[f64],
    tau_g: &[f64],
    has_command: bool,
    window: usize,
    s: &Reduction,
    cond: &mut Condition,
    d: &mut Dataset,
) {
    let n = sig.t_s.len();
    let rate = 1.0 / cond.sample_period_s;
    let seg = s.welch_segment.min(n.next_power_of_two() / 2).max(16);
    let h_c = match welch_h1(&sig.theta_rad, &sig.tau_c_nm, rate, seg) {
        Ok(h) => h,
        Err(e) => {
            d.notes.push(format!("{what}: broadband estimate: {e}"));
            return;
        }
    };
    let mean = sig.theta_rad.iter().sum::<f64>() / n as f64;
    let var = sig
        .theta_rad
        .iter()
        .map(|x| (x - mean).powi(2))
        .sum::<f64>()
        / n as f64;
    cond.theta_amp_rad = (2.0 * var).sqrt();
    let [lo, hi] = s.broadband_band_rad_s;
    let groups = band_groups(&h_c, s.min_coherence, 1e-3, lo, hi, s.broadband_points);
    if groups.is_empty() {
        d.notes.push(format!(
            "{what}: no band of {lo}–{hi} rad/s with coherence ≥ {}",
            s.min_coherence
        ));
        return;
    }
    let extra = if has_command {
        let td: Vec<f64> = tau_d
            .iter()
            .map(|v| if v.is_finite() { *v } else { 0.0 })
            .collect();
        match (
            welch_h1(&sig.theta_rad, &sig.tau_s_net_nm, rate, seg),
            welch_h1(&td, tau_s_raw, rate, seg),
            welch_h1(&sig.theta_rad, tau_g, rate, seg),
        ) {
            (Ok(a), Ok(b), Ok(c)) => Some((a, b, c)),
            _ => None,
        }
    } else {
        None
    };
    let zero = Complex64::new(0.0, 0.0);
    for g in &groups {
        let Some(b) = average_bins(&h_c, g) else {
            continue;
        };
        let sd = |bin: &exo_impedance::frf::H1Bin| {
            let e = bin.noise_rel() * bin.h.norm() / std::f64::consts::SQRT_2;
            [e, e]
        };
        d.observations.push(Observation {
            tf: Tf::Sh,
            omega_rad_s: b.omega_rad_s,
            value: b.h,
            sigma: sd(&b),
            line_sigma: sd(&b),
            transient_free: None,
            accuracy: crate::fit::MODEL_ACCURACY,
            window,
            gravity_comp: zero,
            statics: [0.0; 2],
            sigma_dof: None,
        });
        if let Some((h_s, h_sea, h_g)) = &extra {
            let gravity_comp = average_bins(h_g, g).map_or(zero, |b| b.h);
            for (tf, h) in [(Tf::She, h_s), (Tf::Sea, h_sea)] {
                if let Some(bb) = average_bins(h, g) {
                    if bb.coherence >= s.min_coherence {
                        d.observations.push(Observation {
                            tf,
                            omega_rad_s: bb.omega_rad_s,
                            value: bb.h,
                            sigma: sd(&bb),
                            line_sigma: sd(&bb),
                            transient_free: None,
                            accuracy: crate::fit::MODEL_ACCURACY,
                            window,
                            gravity_comp,
                            statics: [0.0; 2],
                            sigma_dof: None,
                        });
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An empty dataset with one window in experiment 1 (index 0) and one
    /// in experiment 2 (index 1).
    fn two_experiments() -> Dataset {
        let mut second = Condition::test_window(0.0, 0.1, 1e-3);
        second.experiment = 2;
        Dataset {
            conditions: vec![Condition::test_window(0.0, 0.1, 1e-3), second],
            ..Dataset::default()
        }
    }

    /// A line of white σ `s`, whose transient-free value lies `leak` from
    /// it with σ `s·√leverage`, in experiment `experiment`'s window.
    fn line(tf: Tf, window: usize, s: f64, leak: Complex64, leverage: f64) -> Observation {
        let value = Complex64::new(100.0, 10.0);
        Observation {
            tf,
            omega_rad_s: 2.0,
            value,
            sigma: [s, s],
            line_sigma: [s, s],
            transient_free: Some(TransientFree {
                value: value - leak,
                sigma: [s * leverage.sqrt(); 2],
                local_noise: None,
            }),
            accuracy: 0.0,
            window,
            gravity_comp: Complex64::new(0.0, 0.0),
            statics: [0.0; 2],
            sigma_dof: None,
        }
    }

    /// By hand: the transient's relative variance `(d² − σ²(lev − 1))/σ²`
    /// is averaged over an experiment's lines of one transfer function
    /// (both components), clipped at zero, and added as `r σ²`; a line
    /// whose own `d²` exceeds 6.635 times its estimate's noise keeps its
    /// own excess when larger and is not pooled; other experiments and transfer functions
    /// are pooled apart, and a line without a transient-free value is
    /// left alone.
    #[test]
    fn a_lines_transient_is_pooled_over_its_experiment_less_the_estimates_own() {
        let mut d = two_experiments();
        let c = |re: f64, im: f64| Complex64::new(re, im);
        // Experiment 1, S_h, σ 2, leverage 2 (estimate noise 4): parts
        // (16 − 4)/4, (0 − 4)/4 and (8 − 4)/4, (4 − 4)/4: sum 3 − 1 + 1 + 0
        // = 3 over 4, r = 0.75: σ² = 4 + 0.75·4 = 7. No d² above 6.635·4.
        d.observations.push(line(Tf::Sh, 0, 2.0, c(4.0, 0.0), 2.0));
        d.observations
            .push(line(Tf::Sh, 0, 2.0, c(8f64.sqrt(), 2.0), 2.0));
        // Experiment 1, S_h-e, σ 2, leverage 3 (estimate noise 8): parts
        // (0 − 8)/4 twice and (4 − 8)/4, (0 − 8)/4: sum −7, r clipped to
        // 0: the white σ alone.
        d.observations.push(line(Tf::She, 0, 2.0, c(0.0, 0.0), 3.0));
        d.observations.push(line(Tf::She, 0, 2.0, c(2.0, 0.0), 3.0));
        // Experiment 2, S_h: one line's real part rang clearly, d² = 25 >
        // 6.635·1: its own excess 24 kept, and that component left out of
        // the pool; two lines at d² = 4 in both parts (below 6.635: pooled,
        // +3 each) and nine quiet components (−1 each): the pool is
        // 12 − 9 = 3 over 13 components.
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(5.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(2.0, 2.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(2.0, 2.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        let mut alone = line(Tf::Sh, 1, 3.0, c(9.0, 9.0), 2.0);
        alone.transient_free = None;
        d.observations.push(alone);
        // A line of σ 0 adds nothing to its pool (its parts would divide
        // by zero) and keeps σ 0.
        d.observations.push(line(Tf::Sh, 1, 0.0, c(0.0, 0.0), 2.0));
        // Experiment 2, S_h-e, σ 2, leverage 2 (estimate noise 4): one real
        // part at d² = 20, between 6.635 + 4 and 6.635·4 = 26.5: not its
        // own; the pool (20 − 4)/4 − 1 − 6·1 = −3 is clipped: σ 2 for all.
        d.observations
            .push(line(Tf::She, 1, 2.0, c(20f64.sqrt(), 0.0), 2.0));
        for _ in 0..3 {
            d.observations.push(line(Tf::She, 1, 2.0, c(0.0, 0.0), 2.0));
        }
        pool_transients(&mut d);
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        let s = |i: usize| d.observations[i].sigma;
        assert!(close(s(0), [7f64.sqrt(); 2]), "{:?}", s(0));
        assert!(close(s(1), [7f64.sqrt(); 2]), "{:?}", s(1));
        assert!(close(s(2), [2.0; 2]), "{:?}", s(2));
        assert!(close(s(3), [2.0; 2]), "{:?}", s(3));
        let r: f64 = 3.0 / 13.0; // 12 − 9 over 13 components
        assert!(close(s(4), [(1.0 + r).sqrt(); 2]), "{:?}", s(4));
        assert!(close(s(5), [25f64.sqrt(), (1.0 + r).sqrt()]), "{:?}", s(5));
        assert!(close(s(6), [(1.0 + r).sqrt(); 2]), "{:?}", s(6));
        assert!(close(s(7), [(1.0 + r).sqrt(); 2]), "{:?}", s(7));
        assert_eq!(s(11), [3.0, 3.0], "no transient-free value: untouched");
        assert_eq!(s(12), [0.0, 0.0]);
        for i in 13..17 {
            assert!(close(s(i), [2.0, 2.0]), "{i}: {:?}", s(i));
        }
    }

    /// "Beyond" is strict: a leak exactly at 6.635 times its estimate's
    /// noise stays in the pool.
    #[test]
    fn a_leak_keeps_its_own_transient_only_beyond_the_threshold() {
        assert!(!keeps_own_transient(6.635 * 4.0, 4.0));
        assert!(keeps_own_transient(6.635 * 4.0 + 1e-9, 4.0));
        assert!(!keeps_own_transient(1.0, 4.0));
    }

    /// By hand: the white σ's share that is noise is the local noise ratio
    /// pooled over an experiment's lines of one transfer function, weighted
    /// by degrees of freedom ((4·0.5 + 6·0.8)/10 = 0.68), within [0.5, 1]; it
    /// scales the line's noise and its estimate's before the transient is
    /// pooled, also for a line of the experiment without its own measure.
    #[test]
    fn the_white_sigma_is_scaled_by_the_noise_measured_beside_its_lines() {
        let mut d = two_experiments();
        let c = |re: f64| Complex64::new(re, 0.0);
        let with = |mut o: Observation, ratio: f64, dof: usize| {
            if let Some(t) = o.transient_free.as_mut() {
                t.local_noise = Some(LocalNoise { ratio, dof });
            }
            o
        };
        // Experiment 1, σ 2, leverage 3: q = 0.68, noise 2.72, the
        // estimate's 5.44; parts (4 − 5.44)/2.72, −2, (16 − 5.44)/2.72, −2,
        // −2, −2: negative, r = 0: every σ² is 2.72 (without the share it
        // would be 4).
        d.observations
            .push(with(line(Tf::Sh, 0, 2.0, c(2.0), 3.0), 0.5, 4));
        d.observations
            .push(with(line(Tf::Sh, 0, 2.0, c(4.0), 3.0), 0.8, 6));
        d.observations.push(line(Tf::Sh, 0, 2.0, c(0.0), 3.0));
        // Experiment 2: a ratio above 1 pools to 1, the white σ kept.
        d.observations
            .push(with(line(Tf::Sh, 1, 2.0, c(0.0), 2.0), 1.5, 5));
        // Another transfer function of experiment 1: its own pool (none).
        d.observations.push(line(Tf::She, 0, 2.0, c(0.0), 2.0));
        // τ_s/τ_d of experiment 1 measured noiseless beside its line (a
        // copied signal): the share is held at 0.5, σ² = 0.5·4.
        d.observations
            .push(with(line(Tf::Sea, 0, 2.0, c(0.0), 2.0), 0.0, 3));
        // S_h-e of experiment 2 measured with no degree of freedom: it
        // weighs nothing, the share stays 1.
        d.observations
            .push(with(line(Tf::She, 1, 2.0, c(0.0), 2.0), 0.1, 0));
        pool_transients(&mut d);
        let s = |i: usize| d.observations[i].sigma;
        for i in 0..3 {
            assert!((s(i)[0] - 2.72f64.sqrt()).abs() < 1e-12, "{i}: {:?}", s(i));
            assert!((s(i)[1] - 2.72f64.sqrt()).abs() < 1e-12, "{i}: {:?}", s(i));
        }
        assert_eq!(s(3), [2.0, 2.0]);
        assert_eq!(s(4), [2.0, 2.0]);
        assert!((s(5)[0] - 2f64.sqrt()).abs() < 1e-12, "{:?}", s(5));
        assert_eq!(s(6), [2.0, 2.0]);
    }

    /// Held to an accuracy: every dynamic value to its line's own σ and at
    /// least that accuracy (a coarser one of its own kept), the static
    /// balance as it was; the values themselves unchanged.
    #[test]
    fn data_held_to_an_accuracy_take_their_lines_own_sigma_and_the_floor() {
        let o = |tf: Tf, accuracy: f64| Observation {
            tf,
            omega_rad_s: 3.0,
            value: Complex64::new(10.0, 1.0),
            sigma: [2.0, 3.0],
            line_sigma: [0.5, 0.7],
            transient_free: None,
            accuracy,
            window: 0,
            gravity_comp: Complex64::new(0.0, 0.0),
            statics: [0.0; 2],
            sigma_dof: None,
        };
        let d = Dataset {
            observations: vec![o(Tf::Sh, 0.0), o(Tf::Sea, 0.02), o(Tf::Balance, 0.0)],
            ..Dataset::default()
        };
        let h = d.held_to(0.005);
        assert_eq!(h.observations.len(), 3);
        assert_eq!(h.observations[0].sigma, [0.5, 0.7]);
        assert_eq!(h.observations[0].accuracy, 0.005);
        assert_eq!(h.observations[1].sigma, [0.5, 0.7]);
        assert_eq!(h.observations[1].accuracy, 0.02);
        assert_eq!(h.observations[2], d.observations[2]);
        for (a, b) in h.observations.iter().zip(&d.observations) {
            assert_eq!(a.value, b.value);
        }
    }
}
