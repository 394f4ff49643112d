//! The protocol clock: what the excitation, bias and settings are at a given
//! time (Table I and section "Experimental Protocol for Modeling").
//!
//! Every period is `ramp-in → settling → analysis → ramp-out → rest`. The bias
//! ramps with a raised cosine (smooth start and end) during ramp-in and
//! ramp-out; the sine `A sin(ω (t − t_sine))` runs through settling and
//! analysis, starting at zero phase. [`Protocol::at`] is a pure function of
//! time, so a run is reproducible and the identifier can rebuild the windows
//! from the recorded protocol state alone.

use exo_config::{ExperimentSpec, ExperimentTable, ProtocolTiming};
use exo_messages::ProtocolPhase;

/// The protocol's state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProtocolPoint {
    /// Experiment number (0 when idle).
    pub experiment: u32,
    /// Period number, 1-based (0 when idle).
    pub period: u32,
    /// Phase (the wire's `ProtocolState::phase`, encoded by `ProtocolPhase::as_u32`).
    pub phase: ProtocolPhase,
    /// Sine frequency of this period (rad/s).
    pub omega_rad_s: f64,
    /// Sine amplitude of this period (Nm).
    pub amplitude_nm: f64,
    /// Constant amplification α of the experiment.
    pub alpha: f64,
    /// Load (kg).
    pub load_kg: f64,
    /// Grip (kg).
    pub grip_kg: f64,
    /// The experiment's bias torque (Nm), the plateau value.
    pub bias_nm: f64,
    /// Bias torque commanded now (Nm), ramped.
    pub tau_bias_nm: f64,
    /// Excitation torque commanded now (Nm).
    pub tau_excitation_nm: f64,
    /// Whether the protocol has finished.
    pub done: bool,
}

/// The sequence of (experiment, period) the run goes through.
#[derive(Debug, Clone)]
pub struct Protocol {
    steps: Vec<(ExperimentSpec, u32)>,
    table: ExperimentTable,
    timing: ProtocolTiming,
    excitation: Excitation,
}

/// What each period excites with.
#[derive(Debug, Clone)]
enum Excitation {
    /// The experiment table's sine of each period (Table I).
    Sine,
    /// A designed periodic multisine (`mode = "multisine"`): one period of
    /// it at unit peak, sampled at the control rate, scaled per step.
    Multisine {
        /// One period's samples, peak 1.
        unit_period: Vec<f64>,
        /// The control rate (Hz) the period is sampled at.
        rate_hz: f64,
        /// Peak torque (Nm) of each step.
        peak_nm: Vec<f64>,
    },
}

impl Protocol {
    /// A protocol over `experiments` (numbers in `table`), each over `periods`
    /// (1-based; all of the table's when `None`). Unknown numbers are skipped
    /// by the caller's validation (see `exo_config::RunConfig`).
    pub fn new(table: &ExperimentTable, experiments: &[u32], periods: Option<&[u32]>) -> Self {
        let all: Vec<u32> = (1..=table.periods).collect();
        let periods = periods.unwrap_or(&all);
        let steps = experiments
            .iter()
            .filter_map(|n| table.get(*n))
            .flat_map(|e| periods.iter().map(move |p| (*e, *p)))
            .collect();
        Protocol {
            steps,
            table: table.clone(),
            timing: table.timing,
            excitation: Excitation::Sine,
        }
    }

    /// The same steps excited by a periodic multisine instead of the
    /// table's sines: `design` (sampled at its own rate, the control rate)
    /// scaled in each step to `peak_nm_of` its experiment (Nm). The
    /// multisine starts at sample 0 of its period when the settling window
    /// opens, so the analysis window (whole periods after whole periods of
    /// settling) holds whole periods.
    pub fn with_multisine(
        mut self,
        design: &exo_impedance::multisine::Multisine,
        peak_nm_of: impl Fn(&ExperimentSpec) -> f64,
    ) -> Self {
        let peak = design.peak();
        let unit_period = design.period().iter().map(|x| x / peak).collect();
        self.excitation = Excitation::Multisine {
            unit_period,
            rate_hz: design.rate_hz(),
            peak_nm: self.steps.iter().map(|(e, _)| peak_nm_of(e)).collect(),
        };
        self
    }

    /// Frequency (rad/s; 0 for a multisine, the wire's "broadband"), peak
    /// amplitude (Nm) and the excitation's value at unit amplitude
    /// `since_start_s` after it started in step `index` (which exists).
    /// Allocation-free.
    fn excite(&self, index: usize, since_start_s: f64) -> (f64, f64, f64) {
        let (e, period) = &self.steps[index];
        match &self.excitation {
            Excitation::Sine => {
                let omega = self.table.omega_rad_s(e, *period);
                (
                    omega,
                    self.table.amplitude_nm(e, *period),
                    (omega * since_start_s).sin(),
                )
            }
            Excitation::Multisine {
                unit_period,
                rate_hz,
                peak_nm,
            } => {
                let n = (since_start_s * rate_hz).round();
                let value = if n >= 0.0 && !unit_period.is_empty() {
                    unit_period[(n as u64 % unit_period.len() as u64) as usize]
                } else {
                    0.0
                };
                (0.0, peak_nm[index], value)
            }
        }
    }

    /// Total duration (s).
    pub fn duration_s(&self) -> f64 {
        self.steps.len() as f64 * self.timing.period_s()
    }

    /// Number of (experiment, period) steps.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    /// Whether the protocol has no step.
    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// The state at time `t_s` since the protocol started. Allocation-free.
    pub fn at(&self, t_s: f64) -> ProtocolPoint {
        self.at_from(0, t_s)
    }

    /// The state `rel_s` after the protocol was (re)started at the
    /// beginning of step `from_step` (an operator start): the steps from
    /// there on follow each other as they do from the beginning, so
    /// `at_from(0, t)` is [`Protocol::at`]. Allocation-free.
    pub fn at_from(&self, from_step: usize, rel_s: f64) -> ProtocolPoint {
        let idle = self.idle(self.steps.last().map_or(0.0, |(e, _)| e.load_kg));
        if rel_s.is_nan() || rel_s < 0.0 || self.timing.period_s() <= 0.0 {
            return ProtocolPoint {
                done: false,
                ..idle
            };
        }
        match self.locate_from(from_step, rel_s) {
            Some((index, tau)) => self.point(index, tau),
            None => idle,
        }
    }

    /// The step (index into the run's sequence of experiment and period)
    /// `rel_s` after a start at step `from_step`, and the time into its
    /// period (s); `None` past the last step.
    pub fn locate_from(&self, from_step: usize, rel_s: f64) -> Option<(usize, f64)> {
        let period_s = self.timing.period_s();
        if rel_s.is_nan() || rel_s < 0.0 || period_s <= 0.0 {
            return None;
        }
        let k = (rel_s / period_s).floor();
        let index = from_step.checked_add(k as usize)?;
        (index < self.steps.len()).then_some((index, rel_s - k * period_s))
    }

    /// Duration of one period (s).
    pub fn period_s(&self) -> f64 {
        self.timing.period_s()
    }

    /// Duration of a period's ramp-out (s), also the ramp-out after an
    /// operator stop.
    pub fn ramp_out_s(&self) -> f64 {
        self.timing.ramp_out_s
    }

    /// Experiment and period of step `index`.
    pub fn step(&self, index: usize) -> Option<(u32, u32)> {
        self.steps.get(index).map(|(e, p)| (e.number, *p))
    }

    /// The first step of experiment `number`, if the run has it.
    pub fn first_step_of(&self, number: u32) -> Option<usize> {
        self.steps.iter().position(|(e, _)| e.number == number)
    }

    /// The run's experiments as a bit set (bit `n` = experiment `n`), for
    /// messages that must not allocate.
    pub fn experiment_set(&self) -> u32 {
        self.steps
            .iter()
            .filter(|(e, _)| e.number < 32)
            .fold(0, |set, (e, _)| set | (1 << e.number))
    }

    /// Whether `tau_s` into a period is before the end of its analysis
    /// window (a period stopped there has not been measured completely).
    pub fn before_analysis_end(&self, tau_s: f64) -> bool {
        let t = &self.timing;
        tau_s < t.ramp_in_s + t.settling_s + t.analysis_s
    }

    /// Whether step `index` applies neither bias nor excitation `tau_s`
    /// into its period (in its rest, or the ramp-in of an experiment
    /// without bias): an operator stop or start then has nothing to ramp out.
    pub fn quiet(&self, index: usize, tau_s: f64) -> bool {
        let Some((e, _)) = self.steps.get(index) else {
            return true;
        };
        let (_, bias_fraction, envelope) = self.shape(tau_s);
        bias_fraction * e.bias_nm == 0.0 && (envelope == 0.0 || self.excite(index, 0.0).1 == 0.0)
    }

    /// The state `elapsed_s` after an operator stop `tau_stop_s` into step
    /// `index`: the bias and the excitation envelope keep the values they
    /// had at the stop (the sine keeps its phase and frequency) and fade to
    /// zero with the ramp-out's raised cosine over [`Protocol::ramp_out_s`];
    /// reported as [`ProtocolPhase::RampOut`] of that experiment and period (so the
    /// identifier ends an analysis window there). Continuous with
    /// [`Protocol::at_from`] at the stop. Allocation-free.
    pub fn stopping(&self, index: usize, tau_stop_s: f64, elapsed_s: f64) -> ProtocolPoint {
        let Some((e, period)) = self.steps.get(index) else {
            return self.idle(0.0);
        };
        let t = &self.timing;
        let (_, bias_fraction, envelope) = self.shape(tau_stop_s);
        let fade = 1.0 - smooth_step(elapsed_s / t.ramp_out_s);
        let (omega, amplitude, wave) = self.excite(index, tau_stop_s + elapsed_s - t.ramp_in_s);
        let excitation = if tau_stop_s >= t.ramp_in_s {
            fade * envelope * amplitude * wave
        } else {
            0.0
        };
        ProtocolPoint {
            experiment: e.number,
            period: *period,
            phase: ProtocolPhase::RampOut,
            omega_rad_s: omega,
            amplitude_nm: amplitude,
            alpha: e.alpha,
            load_kg: e.load_kg,
            grip_kg: e.grip_kg,
            bias_nm: e.bias_nm,
            tau_bias_nm: fade * bias_fraction * e.bias_nm,
            tau_excitation_nm: excitation,
            done: false,
        }
    }

    /// The state while stopped by the operator after step `index`: no
    /// experiment ([`ProtocolPhase::Idle`], experiment and period 0), no bias or
    /// excitation, α = 1, that step's load (still on the arm), not done.
    pub fn held(&self, index: usize) -> ProtocolPoint {
        let load = self
            .steps
            .get(index)
            .or(self.steps.last())
            .map_or(0.0, |(e, _)| e.load_kg);
        ProtocolPoint {
            done: false,
            ..self.idle(load)
        }
    }

    /// Before the first or after the last step, with `load_kg` on the arm.
    fn idle(&self, load_kg: f64) -> ProtocolPoint {
        ProtocolPoint {
            experiment: 0,
            period: 0,
            phase: ProtocolPhase::Idle,
            omega_rad_s: 0.0,
            amplitude_nm: 0.0,
            alpha: 1.0,
            load_kg,
            grip_kg: 0.0,
            bias_nm: 0.0,
            tau_bias_nm: 0.0,
            tau_excitation_nm: 0.0,
            done: true,
        }
    }

    /// Phase, bias fraction and excitation envelope `tau_s` into a period.
    fn shape(&self, tau_s: f64) -> (ProtocolPhase, f64, f64) {
        let t = &self.timing;
        let sine_start = t.ramp_in_s;
        let analysis_start = sine_start + t.settling_s;
        let ramp_out_start = analysis_start + t.analysis_s;
        let rest_start = ramp_out_start + t.ramp_out_s;
        let (phase, bias_fraction) = if tau_s < sine_start {
            (ProtocolPhase::RampIn, smooth_step(tau_s / t.ramp_in_s))
        } else if tau_s < analysis_start {
            (ProtocolPhase::Settling, 1.0)
        } else if tau_s < ramp_out_start {
            (ProtocolPhase::Analysis, 1.0)
        } else if tau_s < rest_start {
            (
                ProtocolPhase::RampOut,
                1.0 - smooth_step((tau_s - ramp_out_start) / t.ramp_out_s),
            )
        } else {
            (ProtocolPhase::Rest, 0.0)
        };
        // The sine fades in over the first half of the settling window and
        // out over the ramp-out (raised cosine): an abrupt start or stop
        // excites the arm's natural mode, which a lightly damped subject
        // carries for many seconds into the analysis window and the next
        // period. The analysis window always sees the full amplitude.
        let envelope = match phase {
            ProtocolPhase::Settling => smooth_step((tau_s - sine_start) / (0.5 * t.settling_s)),
            ProtocolPhase::Analysis => 1.0,
            ProtocolPhase::RampOut => 1.0 - smooth_step((tau_s - ramp_out_start) / t.ramp_out_s),
            _ => 0.0,
        };
        (phase, bias_fraction, envelope)
    }

    /// The state `tau_s` into step `index` (which exists).
    fn point(&self, index: usize, tau_s: f64) -> ProtocolPoint {
        let (e, period) = &self.steps[index];
        let (phase, bias_fraction, envelope) = self.shape(tau_s);
        let (omega, amplitude, wave) = self.excite(index, tau_s - self.timing.ramp_in_s);
        let excitation = envelope * amplitude * wave;
        ProtocolPoint {
            experiment: e.number,
            period: *period,
            phase,
            omega_rad_s: omega,
            amplitude_nm: amplitude,
            alpha: e.alpha,
            load_kg: e.load_kg,
            grip_kg: e.grip_kg,
            bias_nm: e.bias_nm,
            tau_bias_nm: e.bias_nm * bias_fraction,
            tau_excitation_nm: excitation,
            done: false,
        }
    }
}

/// Raised-cosine step from 0 at `x ≤ 0` to 1 at `x ≥ 1` (smooth at both ends).
fn smooth_step(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        0.0
    } else if x >= 1.0 {
        1.0
    } else {
        0.5 - 0.5 * (std::f64::consts::PI * x).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The raised-cosine step by hand: 0 before its start (and for NaN, a
    /// zero-length ramp's 0/0), ½ − ½ cos(π x) within, 1 after.
    #[test]
    fn the_smooth_step_is_zero_before_a_raised_cosine_within_and_one_after() {
        assert_eq!(smooth_step(-0.5), 0.0);
        assert_eq!(smooth_step(-2.0), 0.0);
        assert_eq!(smooth_step(0.0), 0.0);
        assert_eq!(smooth_step(f64::NAN), 0.0);
        assert!((smooth_step(0.5) - 0.5).abs() < 1e-15);
        assert!(
            (smooth_step(0.25) - (0.5 - 0.5 * (std::f64::consts::FRAC_PI_4).cos())).abs() < 1e-15
        );
        assert_eq!(smooth_step(1.0), 1.0);
        assert_eq!(smooth_step(3.0), 1.0);
    }

    fn table() -> ExperimentTable {
        ExperimentTable::from_file(&exo_config::configs_dir().join("experiments.toml")).unwrap()
    }

    #[test]
    fn nine_experiments_of_ten_sixty_second_periods() {
        let t = table();
        let p = Protocol::new(&t, &[1, 2, 3, 4, 5, 6, 7, 8, 9], None);
        assert_eq!(p.len(), 90);
        assert_eq!(p.duration_s(), 90.0 * 60.0);
        // Period 1 of experiment 4: ramp-in to 5 s, sine 5–15 s, ramp-out 15–20 s, rest to 60 s.
        let base = 30.0 * 60.0;
        let phases = [
            (2.0, ProtocolPhase::RampIn),
            (7.0, ProtocolPhase::Settling),
            (12.0, ProtocolPhase::Analysis),
            (17.0, ProtocolPhase::RampOut),
            (40.0, ProtocolPhase::Rest),
        ];
        for (dt, phase) in phases {
            let s = p.at(base + dt);
            assert_eq!(
                (s.experiment, s.period, s.phase),
                (4, 1, phase),
                "at +{dt} s"
            );
        }
        assert_eq!(p.at(base + 12.0).omega_rad_s, 3.0);
        assert_eq!(p.at(base + 12.0).tau_bias_nm, 4.0);
        assert_eq!(p.at(base + 40.0).tau_bias_nm, 0.0);
        assert!(p.at(90.0 * 60.0 + 1.0).done);
    }

    #[test]
    fn frequencies_step_by_ten_to_the_tenth_and_amplitude_rises_from_period_8() {
        let t = table();
        let p = Protocol::new(&t, &[7], None);
        for period in 1..=10u32 {
            let s = p.at((period - 1) as f64 * 60.0 + 10.0);
            assert_eq!(s.period, period);
            let expected = 4.0 * 10f64.powf(0.1 * (period - 1) as f64);
            assert!((s.omega_rad_s - expected).abs() < 1e-9 * expected);
            let amp = if period >= 8 {
                2.0 * 10f64.powf(0.2)
            } else {
                2.0
            };
            assert!((s.amplitude_nm - amp).abs() < 1e-12);
        }
    }

    #[test]
    fn excitation_is_the_sine_and_bias_ramps_smoothly() {
        let t = table();
        let p = Protocol::new(&t, &[4], Some(&[3]));
        let w = 3.0 * 10f64.powf(0.2);
        // Full amplitude from half-way through settling to the end of the analysis window.
        for tau in [2.5, 3.456, 7.0, 9.999] {
            let s = p.at(5.0 + tau);
            assert!((s.tau_excitation_nm - 2.0 * (w * tau).sin()).abs() < 1e-12);
        }
        // Faded in: raised cosine over the first 2.5 s of the sine.
        let fade = 0.5 - 0.5 * (std::f64::consts::PI * 1.234 / 2.5).cos();
        let s = p.at(5.0 + 1.234);
        assert!((s.tau_excitation_nm - fade * 2.0 * (w * 1.234).sin()).abs() < 1e-12);
        // Faded out over the ramp-out, nothing before the sine or in the rest.
        let s = p.at(15.0 + 1.7);
        let fade = 0.5 + 0.5 * (std::f64::consts::PI * 1.7 / 5.0).cos();
        assert!((s.tau_excitation_nm - fade * 2.0 * (w * 11.7).sin()).abs() < 1e-12);
        assert_eq!(p.at(4.0).tau_excitation_nm, 0.0);
        assert_eq!(p.at(20.5).tau_excitation_nm, 0.0);
        // Continuous: no step anywhere in the excitation.
        let mut prev = 0.0;
        for i in 0..=2500 {
            let x = p.at(i as f64 * 0.01).tau_excitation_nm;
            assert!((x - prev).abs() < 2.0 * w * 0.01 + 1e-9, "step at {i}");
            prev = x;
        }
        assert_eq!(p.at(0.0).tau_bias_nm, 0.0);
        assert!((p.at(2.5).tau_bias_nm - 2.0).abs() < 1e-12);
        let mut prev = 0.0;
        for i in 0..=500 {
            let b = p.at(i as f64 * 0.01).tau_bias_nm;
            assert!(b >= prev - 1e-12 && (b - prev).abs() < 0.02);
            prev = b;
        }
        // The bias ramps out over the ramp-out (15–20 s) as the excitation
        // does: a raised cosine of the time since the ramp-out began.
        let full = p.at(12.0).tau_bias_nm;
        assert!(full > 0.0);
        for tau in [0.3, 1.7, 2.5, 4.2] {
            let fade = 0.5 + 0.5 * (std::f64::consts::PI * tau / 5.0).cos();
            let b = p.at(15.0 + tau).tau_bias_nm;
            assert!((b - full * fade).abs() < 1e-12, "at 15 + {tau} s: {b}");
        }
    }

    /// A multisine protocol (issue 34 item 1): from the settling window's
    /// start, sample `n` of the period (100 Hz, 200 samples: lines at bins
    /// 3, 5 and 11 written out by hand in the test) scaled to each
    /// experiment's peak; whole periods in the analysis window; the wire's
    /// "broadband" ω = 0 and the peak as the amplitude; faded in and out
    /// as the sine is; an operator stop continuous with the running
    /// protocol.
    #[test]
    fn a_multisine_protocol_plays_the_design_scaled_to_each_experiments_peak() {
        let mut t = table();
        t.timing = ProtocolTiming {
            ramp_in_s: 1.0,
            settling_s: 2.0,
            analysis_s: 4.0,
            ramp_out_s: 1.0,
            rest_s: 0.5,
        };
        let (rate, n_period) = (100.0, 200usize);
        let design = exo_impedance::multisine::Multisine::schroeder(
            rate,
            n_period,
            &[3, 5, 11],
            &[1.0, 0.5, 0.25],
        )
        .unwrap();
        let by_hand = |n: usize| -> f64 {
            design
                .lines()
                .iter()
                .map(|l| {
                    let arg = std::f64::consts::TAU * (l.bin * n) as f64 / n_period as f64;
                    l.amplitude * (arg + l.phase_rad).cos()
                })
                .sum()
        };
        let peak = (0..n_period).map(|n| by_hand(n).abs()).fold(0.0, f64::max);
        let p = Protocol::new(&t, &[1, 7], Some(&[1])).with_multisine(&design, |e| {
            if e.number == 1 {
                3.0
            } else {
                1.5
            }
        });
        assert_eq!(p.len(), 2);
        let step_s = p.period_s();
        assert_eq!(step_s, 8.5);
        for (step, scale) in [(0usize, 3.0), (1, 1.5)] {
            // Every tick of the analysis window (3 s to 7 s into the step:
            // samples 200..600 of the multisine, two whole periods).
            for k in 200..600usize {
                let s = p.at(step as f64 * step_s + 1.0 + k as f64 / rate);
                assert_eq!(s.phase, ProtocolPhase::Analysis, "{step} {k}");
                assert_eq!(s.omega_rad_s, 0.0);
                assert_eq!(s.amplitude_nm, scale);
                let want = scale * by_hand(k % n_period) / peak;
                assert!((s.tau_excitation_nm - want).abs() < 1e-9, "{step} {k}");
                assert!(s.tau_excitation_nm.abs() <= scale + 1e-9);
            }
        }
        // Faded in over the first half of the settling window (1 s).
        let k = 37usize;
        let fade = 0.5 - 0.5 * (std::f64::consts::PI * k as f64 / rate).cos();
        let s = p.at(1.0 + k as f64 / rate);
        assert_eq!(s.phase, ProtocolPhase::Settling);
        assert!((s.tau_excitation_nm - fade * 3.0 * by_hand(k) / peak).abs() < 1e-9);
        assert_eq!(p.at(0.5).tau_excitation_nm, 0.0);
        assert_eq!(p.at(8.2).tau_excitation_nm, 0.0);
        // An operator stop 0.25 s into the analysis window holds the
        // multisine on, faded out over the ramp-out.
        let tau_stop = 3.25;
        let s = p.stopping(0, tau_stop, 0.0);
        assert!((s.tau_excitation_nm - p.at(tau_stop).tau_excitation_nm).abs() < 1e-12);
        let elapsed = 0.4;
        let fade = 0.5 + 0.5 * (std::f64::consts::PI * elapsed).cos();
        let n = ((tau_stop + elapsed - 1.0) * rate).round() as usize;
        let s = p.stopping(0, tau_stop, elapsed);
        assert!((s.tau_excitation_nm - fade * 3.0 * by_hand(n % n_period) / peak).abs() < 1e-9);
        // A stop in the fade-in keeps the envelope it had (0.3 s into the
        // settling window: ½ − ½ cos(0.3π)) under the ramp-out's fade.
        let (tau_stop, elapsed) = (1.3, 0.25);
        let envelope = 0.5 - 0.5 * (std::f64::consts::PI * 0.3).cos();
        let fade = 0.5 + 0.5 * (std::f64::consts::PI * elapsed).cos();
        let n = ((tau_stop + elapsed - 1.0) * rate).round() as usize;
        let s = p.stopping(0, tau_stop, elapsed);
        let want = fade * envelope * 3.0 * by_hand(n % n_period) / peak;
        assert!(
            (s.tau_excitation_nm - want).abs() < 1e-9,
            "{} vs {want}",
            s.tau_excitation_nm
        );
        assert!(!p.quiet(0, 4.0));
        // Before the multisine starts (during the ramp-in) it has no value:
        // nothing is played, whatever multiplies it.
        for before_s in [-0.005, -0.5, -1.0] {
            assert_eq!(p.excite(0, before_s), (0.0, 3.0, 0.0), "{before_s}");
        }
        assert_eq!(p.excite(1, 0.0).2, by_hand(0) / peak);
    }

    #[test]
    fn before_the_start_the_protocol_is_idle_not_done() {
        let t = table();
        let p = Protocol::new(&t, &[1], None);
        for t_s in [-1.0, f64::NAN] {
            let s = p.at(t_s);
            assert!(!s.done, "at {t_s}: {s:?}");
            assert_eq!(s.experiment, 0);
        }
        // After its end it is done.
        assert!(p.at(p.duration_s() + 1.0).done);
    }

    /// `locate_from` on its own (the operator's restart calls it without
    /// `at`'s guard): no step before the start or at a NaN time, from any
    /// step; the step and the time into it otherwise, by hand.
    #[test]
    fn locating_a_time_before_the_start_or_at_nan_finds_no_step() {
        let t = table();
        let p = Protocol::new(&t, &[1, 4], Some(&[1, 4]));
        let period = p.period_s();
        for from in [0, 1, 2] {
            for rel_s in [-1e-9, -0.5 * period, -3.0 * period, f64::NAN] {
                assert_eq!(p.locate_from(from, rel_s), None, "{from}, {rel_s}");
            }
        }
        assert_eq!(p.locate_from(1, 0.0), Some((1, 0.0)));
        assert_eq!(p.locate_from(1, period + 2.5), Some((2, 2.5)));
        assert_eq!(p.locate_from(2, 2.0 * period), None);
    }

    #[test]
    fn a_restart_and_an_operator_stop_follow_the_same_periods() {
        let t = table();
        let p = Protocol::new(&t, &[1, 4], Some(&[1, 4]));
        let period = p.period_s();
        // `at` is `at_from` the first step.
        for x in [0.0, 3.3, 12.0, 30.0, 70.0, 4.0 * period + 1.0] {
            assert_eq!(p.at(x), p.at_from(0, x));
        }
        // Restarted at step 2 (experiment 4, period 1): the same states as
        // two periods into the protocol.
        for x in [0.0, 6.0, 12.5, period - 0.5, period + 7.0] {
            assert_eq!(p.at_from(2, x), p.at(2.0 * period + x));
        }
        assert!(p.at_from(3, period + 0.1).done);
        assert_eq!(p.first_step_of(4), Some(2));
        assert_eq!(p.first_step_of(7), None);
        assert_eq!(p.experiment_set(), (1 << 1) | (1 << 4));
        // A stop 8 s into experiment 4's period 1 (sine fading in, bias 4 Nm):
        // continuous at the stop, then faded to zero over the ramp-out.
        let tau = 8.0;
        let at_stop = p.at_from(2, tau);
        let s0 = p.stopping(2, tau, 0.0);
        assert_eq!(s0.tau_bias_nm, at_stop.tau_bias_nm);
        assert!((s0.tau_excitation_nm - at_stop.tau_excitation_nm).abs() < 1e-12);
        assert_eq!(
            (s0.experiment, s0.period, s0.phase),
            (4, 1, ProtocolPhase::RampOut)
        );
        let mut prev = s0;
        for i in 1..=500 {
            let s = p.stopping(2, tau, i as f64 * 0.01);
            assert!(s.tau_bias_nm <= prev.tau_bias_nm);
            assert!((s.tau_excitation_nm - prev.tau_excitation_nm).abs() < 2.0 * 3.0 * 0.01 + 1e-3);
            prev = s;
        }
        assert_eq!((prev.tau_bias_nm, prev.tau_excitation_nm), (0.0, 0.0));
        assert!(p.quiet(2, period - 0.1), "rest");
        assert!(p.quiet(0, 2.0), "experiment 1's ramp-in has no bias");
        assert!(!p.quiet(2, 2.0), "experiment 4's has");
        let held = p.held(2);
        assert_eq!(
            (held.experiment, held.phase, held.done),
            (0, ProtocolPhase::Idle, false)
        );
        assert_eq!(held.load_kg, 4.5);
    }
}
