//! # exo-identifier (logic)
//!
//! The online complex-stiffness estimator, as a state machine fed the
//! run's streams in any interleaving (the process feeds it from iceoryx2,
//! `exo fit` from a recording). No IPC here.
//!
//! - Every sample and command goes into preallocated rings sized at
//!   construction from the sample rate and the longest window
//!   ([`IdentifierSettings::max_window_s`]); [`Identifier::on_sample`],
//!   [`Identifier::on_command`] and [`Identifier::on_protocol`] do not
//!   allocate, except at the end of an analysis window.
//! - The protocol's analysis phase ([`exo_messages::ProtocolPhase::Analysis`]) marks a
//!   window by time stamps: from the first state in the phase to the first
//!   state after it in another phase (the one cutter,
//!   `exo_analysis::windows::WindowCutter`, with `Closing::Phase`; an
//!   analysis state of another period right after one continues the
//!   window. The controller stamps states with the sample's stamp,
//!   and may send them every tick or only on change.) Once a sample at or
//!   past the window's end has arrived, the window is analysed; states
//!   arriving a little after their samples do not matter.
//!   - A sine period (`omega > 0`): single-frequency correlation over whole
//!     cycles ([`exo_impedance::frf::SineCorrelator`]) gives one
//!     [`FrfPoint`]: `S_h = τ_c/θ_e` with its coherence and relative noise;
//!     the actuator side `S_h-e = τ̃_s/θ_e = S_h + M_e s²` (gravity removed
//!     from `τ_s` with the controller's `tau_gravity`) with its own noise;
//!     `S_{h-e/α} = S_h + (M_e/α) s²` re-created from `S_h` (text after
//!     eq. Sh3); and `τ_s/τ_d`.
//!   - Broadband (`omega = 0`): Welch H1 with coherence over the excited
//!     band, summarised in up to [`IdentifierSettings::broadband_points`]
//!     log-spaced points; or, in a run whose excitation is a designed
//!     periodic multisine ([`Identifier::with_periodic_lines`]), one point
//!     per excited line from the window's whole periods, its noise from the
//!     spread between them (`exo_impedance::frf::periodic_frf`).
//!
//!   A sample with a fault bit ([`status::FAULT_MASK`]) or the safe state
//!   ([`status::SAFE_STATE`]) anywhere in the window discards the window
//!   (a warning, no point); samples outside analysis windows are not checked.
//! - After each window the experiment's points are refitted with M1, M2 and
//!   M3 ([`FitSource`]: `S_h`, as the paper estimates its parameters, or
//!   the actuator side with the whole `M_e` removed), each point weighted by
//!   its measured noise, and one [`ImpedanceEstimate`] per model
//!   is produced, with `F_{M1−M3}`, `F_{M2−M3}` and the critical value at
//!   [`F_TEST_LEVEL`]. A model with too few points for a residual degree of
//!   freedom is skipped with a warning. Across experiments, M2's `(K, H)`
//!   give the subject's power law (eq. ch) and eq. f's recommended
//!   fractional order, clamped to [`IdentifierSettings::f_bounds`].
//!
//! Heavy work (fits, spectra) happens only at window ends, never per sample.
//!
//! `exo fit` runs the same identifier over recordings and CSVs and
//! analyses them as the paper does (`exo_experiments::offline`, a tool's).

use std::collections::BTreeMap;

use exo_impedance::frf::{average_bins, band_groups, sine_ratio, welch_h1, SineCorrelator};
use exo_impedance::{
    exo_inertia_kg_m2, fit_power_law, fractional_order, paper_f_tests, recreate_coupled, Complex64,
    ImpedanceModel, ModelComparison, ModelFit, PowerLawFit, StiffnessRange,
};
use exo_messages::{
    status, ActuatorCommand, ControlMode, FitModel, FrfPoint, ImpedanceEstimate, ProtocolState,
    SensorSample,
};

mod event;
pub mod process;
mod ring;
mod settings;
pub mod taken;

pub use event::Event;
use ring::{CommandCursor, Ring};
pub use settings::{IdentifierSettings, KRangeSource, SettingsError};

pub use exo_analysis::refit::{effective_alpha, fit_models, FitSource, ModelFitError};
use exo_analysis::windows::{AnalysisWindow, Closing, WindowCutter};

/// False-rejection probability of the F-tests (the paper's 5 %; the level
/// [`ImpedanceEstimate::f_critical`] is documented at).
pub const F_TEST_LEVEL: f64 = 0.05;

/// Samples an analysis window needs at the least.
pub const MIN_WINDOW_SAMPLES: usize = 16;

/// Status bits that discard an analysis window.
pub const REJECT_BITS: u32 = status::FAULT_MASK | status::SAFE_STATE;

/// The command ring's flag for a command in a latched safe state
/// ([`ControlMode::is_safe_state`]): it discards its analysis window (no
/// excitation, no amplification), whatever the samples' status says. `Idle`
/// is not one: writers that leave `mode` unset write 0.
const COMMAND_IN_SAFE_STATE: u32 = 1;

/// Channels of the sample correlator.
const CHANNELS: [&str; 4] = ["theta_e", "tau_c", "tau_s - tau_gravity", "tau_s"];

/// The identifier.
#[derive(Debug, Clone)]
pub struct Identifier {
    s: IdentifierSettings,
    sensor: Ring<3>,
    command: Ring<2>,
    /// The analysis window being delimited or waiting for its last samples.
    window: Option<AnalysisWindow>,
    /// Where windows open and close: the one cutter, with the phase as the
    /// closing rule ([`Closing::Phase`]).
    cutter: WindowCutter,
    frf_seq: u64,
    estimate_seq: u64,
    /// Points per experiment.
    points: BTreeMap<u32, Vec<FrfPoint>>,
    /// Latest M2 (K, H) per experiment (Nm/rad).
    m2: BTreeMap<u32, (f64, f64)>,
    /// α and load (kg) per experiment.
    settings_of: BTreeMap<u32, (f64, f64)>,
    power_law: Option<PowerLawFit>,
    recommended_f: Option<f64>,
    /// A periodic excitation's period (samples) and excited bins
    /// ([`Identifier::with_periodic_lines`]).
    periodic: Option<(usize, Vec<usize>)>,
    /// Samples taken so far in the open analysis window (a multisine's
    /// interim fits fall due at whole periods of them).
    window_samples: usize,
    /// The experiment whose points are an interim fit's (replaced by the
    /// window's own when it closes, or dropped if it is discarded).
    interim_of: Option<u32>,
}

/// Degree of the slow trend removed from a periodic window's signals
/// beside its lines ([`exo_impedance::frf::remove_slow_trend`]): a cubic
/// follows a creep whose time constant is a third of the window or more.
const TREND_DEGREE: usize = 3;

/// A window's point stamped at its `end` (ns) with `S_h-e/α` re-created
/// from its `S_h` (`M_e` kg·m², effective α), as published.
fn completed(mut pt: FrfPoint, end: u64, m_e: f64, alpha: f64) -> FrfPoint {
    pt.stamp_ns = end;
    let s_hea = recreate_coupled(Complex64::new(pt.s_h_re, pt.s_h_im), pt.omega, m_e, alpha);
    (pt.s_hea_re, pt.s_hea_im) = (s_hea.re, s_hea.im);
    pt
}

/// One broadband window's signals, sample by sample, and how many samples
/// had their own command.
struct WindowSignals {
    /// `θ_e` (rad).
    theta_rad: Vec<f64>,
    /// `τ_c` (Nm).
    tau_c_nm: Vec<f64>,
    /// `τ_s − τ_gravity` (Nm).
    tau_s_less_gravity_nm: Vec<f64>,
    /// `τ_s` as measured (Nm).
    tau_s_nm: Vec<f64>,
    /// `τ_d` (Nm).
    tau_d_nm: Vec<f64>,
    /// Samples whose command was found at their own stamp.
    exact: usize,
    /// The rate of the window's own stamps (Hz).
    rate_hz: f64,
}

impl WindowSignals {
    /// Whether (nearly) every sample had its own command: at least 90 %,
    /// and one at all. Only then is `τ_s/τ_d` estimated.
    fn commands_cover_it(&self) -> bool {
        let n = self.theta_rad.len();
        self.exact >= n * 9 / 10 && self.exact > 0
    }
}

impl Identifier {
    /// An identifier with rings of `rate_hz · max_window_s` samples and
    /// commands (allocated now, once). Trusts its settings: use
    /// [`try_new`](Self::try_new) for settings from a file.
    pub fn new(s: IdentifierSettings) -> Self {
        let cap = (s.rate_hz * s.max_window_s).ceil();
        let cap = if cap.is_finite() && cap > 16.0 {
            cap as usize
        } else {
            16
        };
        Identifier {
            s,
            sensor: Ring::new(cap),
            command: Ring::new(cap),
            window: None,
            cutter: WindowCutter::new(Closing::Phase),
            frf_seq: 0,
            estimate_seq: 0,
            points: BTreeMap::new(),
            m2: BTreeMap::new(),
            settings_of: BTreeMap::new(),
            power_law: None,
            recommended_f: None,
            periodic: None,
            window_samples: 0,
            interim_of: None,
        }
    }

    /// [`new`](Self::new) after [`IdentifierSettings::validate`].
    pub fn try_new(s: IdentifierSettings) -> Result<Self, SettingsError> {
        s.validate()?;
        Ok(Identifier::new(s))
    }

    /// The identifier of run `cfg` (loaded by `RunConfig::from_file`): its
    /// settings ([`IdentifierSettings::of_run`]) and, in multisine mode, the
    /// design's lines ([`with_periodic_lines`](Self::with_periodic_lines)),
    /// as the identifier process and `exo sim` both build it. The error
    /// says why the run's multisine has no lines (a run file that was
    /// checked always has them).
    pub fn of_run(cfg: &exo_config::RunConfig) -> Result<Self, String> {
        let id = Identifier::new(IdentifierSettings::of_run(cfg));
        let Some(m) = cfg.protocol.multisine() else {
            return Ok(id);
        };
        let (period_samples, bins) = m.bins(cfg.run.rate_hz).map_err(|e| e.to_string())?;
        id.with_periodic_lines(period_samples, bins)
            .map_err(|e| e.to_string())
    }

    /// Broadband windows of a periodic excitation (issue 34: a designed
    /// multisine) are estimated line by line at `bins` (cycles per period)
    /// from the window's whole periods of `period_samples` samples at
    /// [`IdentifierSettings::rate_hz`], the noise from the spread between
    /// periods, instead of by Welch's method. Refused: a period of fewer
    /// than 4 samples, no bin, a bin at 0 or not below Nyquist, a bin twice.
    pub fn with_periodic_lines(
        mut self,
        period_samples: usize,
        bins: Vec<usize>,
    ) -> Result<Self, SettingsError> {
        let err = |value: f64, why| {
            Err(SettingsError {
                field: "periodic_lines",
                value,
                why,
            })
        };
        if period_samples < 4 {
            return err(period_samples as f64, "a period needs at least 4 samples");
        }
        if bins.is_empty() {
            return err(0.0, "name at least one excited bin");
        }
        if exo_impedance::multisine::check_bins(period_samples, &bins).is_err() {
            return err(
                period_samples as f64,
                "each bin must lie between 1 and Nyquist (period_samples / 2), each once",
            );
        }
        self.periodic = Some((period_samples, bins));
        Ok(self)
    }

    /// The settings.
    pub fn settings(&self) -> &IdentifierSettings {
        &self.s
    }

    /// The points so far, by experiment.
    pub fn points(&self) -> &BTreeMap<u32, Vec<FrfPoint>> {
        &self.points
    }

    /// The latest M2 `(K_h, H_h)` (Nm/rad) per experiment (those with both positive).
    pub fn m2_by_experiment(&self) -> &BTreeMap<u32, (f64, f64)> {
        &self.m2
    }

    /// The subject's power law over the experiments so far, once there is one.
    pub fn power_law(&self) -> Option<&PowerLawFit> {
        self.power_law.as_ref()
    }

    /// Eq. f's fractional order (clamped to the bounds), once known.
    pub fn recommended_f(&self) -> Option<f64> {
        self.recommended_f
    }

    /// A calibrated sample. Allocation-free, except when it completes an
    /// analysis window (then the window is analysed and events pushed).
    pub fn on_sample(&mut self, s: &SensorSample, out: &mut Vec<Event>) {
        self.sensor
            .push(s.stamp_ns, [s.theta_e, s.tau_c, s.tau_s], s.status);
        if self
            .window
            .is_some_and(|w| w.end_ns.is_none() && w.contains(s.stamp_ns))
        {
            self.window_samples += 1;
            self.try_interim(out);
        }
        self.try_finish(out);
    }

    /// A multisine's fits as its periods accrue (issue 34 item 2): at each
    /// whole period from the second on, the open window's lines so far are
    /// estimated and M1–M3 refitted for its experiment, and the estimates
    /// published, without FRF points (the window's own, when it closes,
    /// replace them). The interim lines' warnings are not repeated: the
    /// window's own analysis names them. Allocates: at whole periods only.
    fn try_interim(&mut self, out: &mut Vec<Event>) {
        let (Some(w), Some((period_samples, bins))) = (self.window, self.periodic.as_ref()) else {
            return;
        };
        // At whole periods (after one, `periodic_points` refuses: no
        // spread between periods yet).
        let (n, k) = (*period_samples, self.window_samples / *period_samples);
        let p = w.state;
        if !(self.window_samples.is_multiple_of(n) && p.omega == 0.0 && p.amplitude > 0.0) {
            return;
        }
        let Some(latest) = self.sensor.latest() else {
            return;
        };
        let end = latest.saturating_add(1);
        let Some((origin, _, _)) = self.sensor.window(w.start_ns, end).next() else {
            return;
        };
        let bins = bins.clone();
        let what = format!(
            "experiment {} period {} (interim, {k} periods)",
            p.experiment, p.period
        );
        let mut quiet = Vec::new();
        let Some(lines) = self.periodic_points(&p, origin, end, (n, &bins), &what, &mut quiet)
        else {
            return;
        };
        let (m_e, alpha) = (self.m_e(p.load_kg), effective_alpha(p.alpha));
        let lines: Vec<FrfPoint> = lines
            .into_iter()
            .map(|pt| completed(pt, end, m_e, alpha))
            .filter(|pt| pt.validate().is_ok())
            .collect();
        if lines.is_empty() {
            return;
        }
        self.settings_of.insert(p.experiment, (p.alpha, p.load_kg));
        self.points.insert(p.experiment, lines);
        self.interim_of = Some(p.experiment);
        self.refit(p.experiment, p.period, end, out);
    }

    /// A controller command (`τ_d` for `τ_s/τ_d`, `τ_gravity` to remove
    /// gravity from `τ_s`). Allocation-free.
    pub fn on_command(&mut self, c: &ActuatorCommand) {
        let safe = ControlMode::from_u32(c.mode).is_some_and(ControlMode::is_safe_state);
        let flags = if safe { COMMAND_IN_SAFE_STATE } else { 0 };
        self.command
            .push(c.stamp_ns, [c.tau_d, c.tau_gravity], flags);
    }

    /// A protocol state (every tick or only on change). Allocation-free,
    /// except at the end of an analysis window or for a warning.
    pub fn on_protocol(&mut self, p: &ProtocolState, out: &mut Vec<Event>) {
        let cut = self.cutter.next(p);
        if let Some(end) = cut.closes_at {
            if let Some(w) = self.window.as_mut() {
                w.end_ns = Some(end);
            }
        }
        if cut.opens {
            if self.window.is_some_and(|w| w.end_ns.is_some()) {
                // A previous window still waits for its last samples: analyse what is there.
                self.finish(out);
            }
            self.window_samples = 0;
            match p.validate() {
                Ok(()) => self.window = Some(AnalysisWindow::opened_by(p)),
                Err(e) => out.push(Event::Warning(format!(
                    "experiment {} period {}: analysis window not analysed: {e}",
                    p.experiment, p.period
                ))),
            }
        }
        self.try_finish(out);
    }

    /// Analyses a delimited window once a sample at or past its end has arrived.
    fn try_finish(&mut self, out: &mut Vec<Event>) {
        let ready = matches!(
            (self.window, self.sensor.latest()),
            (Some(AnalysisWindow { end_ns: Some(end), .. }), Some(latest)) if latest >= end
        );
        if ready {
            self.finish(out);
        }
    }

    /// Analyses the current window if it has an end (call at the end of a recording).
    pub fn flush(&mut self, out: &mut Vec<Event>) {
        if self.window.is_some_and(|w| w.end_ns.is_some()) {
            self.finish(out);
        }
    }

    /// `M_e` with `load_kg` on the arm (kg·m²).
    fn m_e(&self, load_kg: f64) -> f64 {
        exo_inertia_kg_m2(self.s.arm_inertia_kg_m2, load_kg, self.s.load_lever_arm_m)
    }

    fn finish(&mut self, out: &mut Vec<Event>) {
        // An interim fit's points give way to the window's own (or to none,
        // when the window is discarded below).
        if let Some(e) = self.interim_of.take() {
            self.points.remove(&e);
            self.m2.remove(&e);
            // Nor does the power law (and eq. f's order) keep the interim
            // M2; the window's own refit, if any, says its notes.
            self.update_power_law(&mut Vec::new());
        }
        let Some(w) = self.window.take() else { return };
        let Some(end) = w.end_ns else { return };
        let p = w.state;
        let what = format!(
            "experiment {} period {} (ω = {:.3} rad/s)",
            p.experiment, p.period, p.omega
        );
        if p.amplitude <= 0.0 {
            out.push(Event::Warning(format!(
                "{what}: no excitation (amplitude 0: voluntary motion or a release test); no FRF point"
            )));
            return;
        }
        let (mut count, mut first, mut rejected) = (0usize, None, None);
        for (stamp, _, flags) in self.sensor.window(w.start_ns, end) {
            count += 1;
            first.get_or_insert(stamp);
            if flags & REJECT_BITS != 0 && rejected.is_none() {
                rejected = Some((stamp, flags));
            }
        }
        let Some(origin) = first.filter(|_| count >= MIN_WINDOW_SAMPLES) else {
            out.push(Event::Warning(format!(
                "{what}: only {count} samples in the analysis window; no FRF point"
            )));
            return;
        };
        if let Some((stamp, flags)) = rejected {
            out.push(Event::Warning(format!(
                "{what}: sample at {stamp} ns has status {flags:#x} (fault or safe state); window discarded"
            )));
            return;
        }
        if let Some((stamp, _, _)) = self
            .command
            .window(w.start_ns, end)
            .find(|(_, _, flags)| flags & COMMAND_IN_SAFE_STATE != 0)
        {
            out.push(Event::Warning(format!(
                "{what}: the controller was in a latched safe state at {stamp} ns (no excitation); window discarded"
            )));
            return;
        }
        // More than ten sample periods missing at the start.
        let slack_ns = (10.0e9 / self.s.rate_hz).min(1e12) as u64;
        if origin > w.start_ns.saturating_add(slack_ns) {
            out.push(Event::Warning(format!(
                "{what}: the window's first {:.3} s are missing (longer than max_window_s or lost); the rest is analysed",
                (origin - w.start_ns) as f64 * 1e-9
            )));
        }
        let new_points = if p.omega > 0.0 {
            self.sine_point(&p, origin, end, &what, out)
                .map(|pt| vec![pt])
        } else if let Some((period_samples, bins)) = &self.periodic {
            self.periodic_points(&p, origin, end, (*period_samples, bins), &what, out)
        } else {
            self.broadband_points(&p, origin, end, &what, out)
        };
        let Some(new_points) = new_points else { return };
        self.settings_of.insert(p.experiment, (p.alpha, p.load_kg));
        let (m_e, alpha) = (self.m_e(p.load_kg), effective_alpha(p.alpha));
        for pt in new_points {
            let mut pt = completed(pt, end, m_e, alpha);
            pt.seq = self.frf_seq;
            if let Err(e) = pt.validate() {
                out.push(Event::Warning(format!(
                    "{what}: FRF point at {:.3} rad/s not published: {e}",
                    pt.omega
                )));
                continue;
            }
            self.frf_seq += 1;
            out.push(Event::Frf(pt));
            self.points.entry(p.experiment).or_default().push(pt);
        }
        self.refit(p.experiment, p.period, end, out);
    }

    /// Warns about samples without their own command, when the fit uses the
    /// actuator side (the cuff's `S_h` needs no command).
    fn command_coverage(&self, what: &str, exact: usize, count: usize, out: &mut Vec<Event>) {
        if self.s.fit_source != FitSource::ActuatorTorque {
            return;
        }
        if exact == 0 {
            out.push(Event::Warning(format!(
                "{what}: no command answers the window's samples: the actuator side (τ_s − τ_gravity)/θ_e keeps τ_s's gravity part"
            )));
        } else if exact < count * 9 / 10 {
            out.push(Event::Warning(format!(
                "{what}: only {exact} of {count} samples have their command; the latest earlier command's gravity is used for the others"
            )));
        }
    }

    /// One point from single-frequency correlation over whole cycles from
    /// `origin` (ns) to `end` (ns, exclusive). No heap allocation but for
    /// warnings (the correlators live on the stack).
    fn sine_point(
        &self,
        p: &ProtocolState,
        origin: u64,
        end: u64,
        what: &str,
        out: &mut Vec<Event>,
    ) -> Option<FrfPoint> {
        let warn = |out: &mut Vec<Event>, e: &dyn std::fmt::Display| {
            out.push(Event::Warning(format!("{what}: {e}; no FRF point")));
        };
        let secs = |stamp: u64| (stamp - origin) as f64 * 1e-9;
        let correlators = SineCorrelator::<4>::new(p.omega, 0.0, self.s.detrend)
            .and_then(|s| SineCorrelator::<1>::new(p.omega, 0.0, self.s.detrend).map(|c| (s, c)));
        let (mut sine, mut sine_command) = match correlators {
            Ok((s, c)) => (s.with_names(CHANNELS), c.with_names(["tau_d"])),
            Err(e) => {
                warn(out, &e);
                return None;
            }
        };
        let mut cursor = CommandCursor::new(&self.command);
        let (mut count, mut exact) = (0, 0);
        for (stamp, [theta, tau_c, tau_s], _) in self.sensor.window(origin, end) {
            let gravity = match cursor.at(stamp) {
                Some(([_, g], hit)) => {
                    exact += usize::from(hit);
                    g
                }
                None => 0.0,
            };
            if let Err(e) = sine.push(secs(stamp), &[theta, tau_c, tau_s - gravity, tau_s]) {
                warn(out, &format_args!("sample at {stamp} ns: {e}"));
                return None;
            }
            count += 1;
        }
        self.command_coverage(what, exact, count, out);
        let t_end = secs(end);
        let [a_theta, a_tau_c, a_tau_s, a_tau_s_raw] = match sine.finish(Some(t_end)) {
            Ok(a) => a,
            Err(e) => {
                warn(out, &e);
                return None;
            }
        };
        let (s_h, s_he) = match (
            sine_ratio(&a_theta, &a_tau_c),
            sine_ratio(&a_theta, &a_tau_s),
        ) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => {
                warn(out, &e);
                return None;
            }
        };
        let mut commands_ok = true;
        for (stamp, [tau_d, _], _) in self.command.window(origin, end) {
            if sine_command.push(secs(stamp), &[tau_d]).is_err() {
                commands_ok = false;
                break;
            }
        }
        let sea = if exact > 0 && commands_ok {
            match sine_command
                .finish(Some(t_end))
                .and_then(|[a_tau_d]| sine_ratio(&a_tau_d, &a_tau_s_raw))
            {
                Ok(r) => r.ratio,
                Err(e) => {
                    out.push(Event::Warning(format!(
                        "{what}: τ_s/τ_d not estimated: {e}"
                    )));
                    Complex64::new(0.0, 0.0)
                }
            }
        } else {
            Complex64::new(0.0, 0.0)
        };
        Some(FrfPoint {
            experiment: p.experiment,
            period: p.period,
            omega: p.omega,
            s_h_re: s_h.ratio.re,
            s_h_im: s_h.ratio.im,
            s_he_re: s_he.ratio.re,
            s_he_im: s_he.ratio.im,
            s_he_noise_rel: s_he.noise_rel,
            sea_re: sea.re,
            sea_im: sea.im,
            coherence: s_h.coherence,
            noise_rel: s_h.noise_rel,
            ..Default::default()
        })
    }

    /// The window's signals (allocates: window ends only).
    fn window_signals(
        &self,
        origin: u64,
        end: u64,
        what: &str,
        out: &mut Vec<Event>,
    ) -> WindowSignals {
        let n = self.sensor.window(origin, end).count();
        let mut w = WindowSignals {
            theta_rad: Vec::with_capacity(n),
            tau_c_nm: Vec::with_capacity(n),
            tau_s_less_gravity_nm: Vec::with_capacity(n),
            tau_s_nm: Vec::with_capacity(n),
            tau_d_nm: Vec::with_capacity(n),
            exact: 0,
            rate_hz: self.s.rate_hz,
        };
        let mut cursor = CommandCursor::new(&self.command);
        let mut last = origin;
        for (stamp, [theta, tau_c, tau_s], _) in self.sensor.window(origin, end) {
            let (tau_d, gravity) = match cursor.at(stamp) {
                Some(([d, g], hit)) => {
                    w.exact += usize::from(hit);
                    (d, g)
                }
                None => (0.0, 0.0),
            };
            w.theta_rad.push(theta);
            w.tau_c_nm.push(tau_c);
            w.tau_s_less_gravity_nm.push(tau_s - gravity);
            w.tau_s_nm.push(tau_s);
            w.tau_d_nm.push(tau_d);
            last = stamp;
        }
        self.command_coverage(what, w.exact, n, out);
        // The rate of the window's own stamps (a recording may not say its rate).
        let span_s = (last - origin) as f64 * 1e-9;
        // A positive span holds two samples at least.
        if span_s > 0.0 {
            w.rate_hz = (n - 1) as f64 / span_s;
        }
        w
    }

    /// Points at a multisine's excited lines from the window's whole
    /// periods (issue 34 item 2; `exo_impedance::frf::periodic_frf`): each
    /// line's `S_h`, `S_h-e` and `τ_s/τ_d` with its noise from the spread
    /// between the periods; no leakage, no taper. The window's first whole
    /// periods are used (any `period_samples` consecutive samples of a
    /// periodic steady state are a whole period). At the control rate
    /// (the design's grid). Allocates: window ends only.
    fn periodic_points(
        &self,
        p: &ProtocolState,
        origin: u64,
        end: u64,
        (period_samples, bins): (usize, &[usize]),
        what: &str,
        out: &mut Vec<Event>,
    ) -> Option<Vec<FrfPoint>> {
        let mut w = self.window_signals(origin, end, what, out);
        let n = w.theta_rad.len();
        let periods = n / period_samples;
        let whole = periods * period_samples;
        let commands_cover_it = w.commands_cover_it();
        if periods < 2 {
            out.push(Event::Warning(format!(
                "{what}: {n} samples hold fewer than two whole multisine periods of {period_samples}; no FRF point"
            )));
            return None;
        }
        // A creep of the operating point across the window (a viscoelastic
        // joint relaxing under the bias) is not periodic: removed with the
        // sine windows' `detrend`, a cubic fitted beside the lines.
        let mut channels = [
            &mut w.theta_rad[..whole],
            &mut w.tau_c_nm[..whole],
            &mut w.tau_s_less_gravity_nm[..whole],
            &mut w.tau_s_nm[..whole],
            &mut w.tau_d_nm[..whole],
        ];
        if self.s.detrend {
            if let Err(e) = exo_impedance::frf::remove_slow_trend(
                &mut channels,
                period_samples,
                bins,
                TREND_DEGREE,
            ) {
                out.push(Event::Warning(format!("{what}: {e}; no FRF point")));
                return None;
            }
        }
        let [theta, tau_c, tau_s_less_gravity, tau_s, tau_d] = channels;
        let rate = self.s.rate_hz;
        let line = |x: &[f64], y: &[f64]| {
            exo_impedance::frf::periodic_frf_each(x, y, rate, period_samples, bins)
        };
        let (s_h, s_he) = match (line(theta, tau_c), line(theta, tau_s_less_gravity)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => {
                out.push(Event::Warning(format!("{what}: {e}; no FRF point")));
                return None;
            }
        };
        // τ_s/τ_d only when (nearly) every sample has its own command.
        let sea = if commands_cover_it {
            line(tau_d, tau_s).ok()
        } else {
            None
        };
        // A line the angle does not carry beyond its noise is left out by
        // name; the window's other lines stand.
        let mut points = Vec::with_capacity(bins.len());
        for (i, (c, a)) in s_h.iter().zip(&s_he).enumerate() {
            let (c, a) = match (c, a) {
                (Ok(c), Ok(a)) => (c, a),
                (Err(e), _) | (_, Err(e)) => {
                    out.push(Event::Warning(format!(
                        "{what}: line at bin {} left out: {e}",
                        bins[i]
                    )));
                    continue;
                }
            };
            let sea = sea
                .as_ref()
                .and_then(|s| s[i].as_ref().ok())
                .map_or(Complex64::new(0.0, 0.0), |s| s.ratio);
            points.push(FrfPoint {
                experiment: p.experiment,
                period: p.period,
                omega: c.omega_rad_s,
                s_h_re: c.ratio.re,
                s_h_im: c.ratio.im,
                s_he_re: a.ratio.re,
                s_he_im: a.ratio.im,
                s_he_noise_rel: a.noise_rel,
                sea_re: sea.re,
                sea_im: sea.im,
                // The coherence its noise implies over `periods`
                // averaged periods: a period's SNR is
                // 1/(P·noise_rel²), γ² = SNR/(1 + SNR).
                coherence: 1.0 / (1.0 + periods as f64 * c.noise_rel * c.noise_rel),
                noise_rel: c.noise_rel,
                ..Default::default()
            });
        }
        if points.is_empty() {
            out.push(Event::Warning(format!(
                "{what}: no line above its noise; no FRF point"
            )));
            return None;
        }
        Some(points)
    }

    /// Points from Welch H1 over the excited band (allocates: window ends only).
    fn broadband_points(
        &self,
        p: &ProtocolState,
        origin: u64,
        end: u64,
        what: &str,
        out: &mut Vec<Event>,
    ) -> Option<Vec<FrfPoint>> {
        let w = self.window_signals(origin, end, what, out);
        let (th, tc, ts, ts_raw, td) = (
            &w.theta_rad,
            &w.tau_c_nm,
            &w.tau_s_less_gravity_nm,
            &w.tau_s_nm,
            &w.tau_d_nm,
        );
        let (n, rate) = (th.len(), w.rate_hz);
        let seg = self.s.welch_segment.min(n.next_power_of_two() / 2).max(16);
        let [lo, hi] = self.s.broadband_band_rad_s;
        let spectra =
            welch_h1(th, tc, rate, seg).and_then(|c| welch_h1(th, ts, rate, seg).map(|s| (c, s)));
        let (h_c, h_s) = match spectra {
            Ok(v) => v,
            Err(e) => {
                out.push(Event::Warning(format!("{what}: {e}; no FRF point")));
                return None;
            }
        };
        // τ_s/τ_d only when (nearly) every sample has its own command.
        let sea = if w.commands_cover_it() {
            welch_h1(td, ts_raw, rate, seg).ok()
        } else {
            None
        };
        let groups = band_groups(
            &h_c,
            self.s.min_coherence,
            self.s.min_rel_power,
            lo,
            hi,
            self.s.broadband_points,
        );
        let zero = Complex64::new(0.0, 0.0);
        let points: Vec<FrfPoint> = groups
            .iter()
            .filter_map(|g| {
                let b = average_bins(&h_c, g)?;
                // τ_s/θ_e and τ_s/τ_d averaged over the same bins as τ_c/θ_e.
                let s_he = average_bins(&h_s, g);
                let sea = sea
                    .as_deref()
                    .and_then(|s| average_bins(s, g))
                    .map_or(zero, |b| b.h);
                Some(FrfPoint {
                    experiment: p.experiment,
                    period: p.period,
                    omega: b.omega_rad_s,
                    s_h_re: b.h.re,
                    s_h_im: b.h.im,
                    s_he_re: s_he.map_or(0.0, |b| b.h.re),
                    s_he_im: s_he.map_or(0.0, |b| b.h.im),
                    s_he_noise_rel: s_he.map_or(0.0, |b| b.noise_rel()),
                    sea_re: sea.re,
                    sea_im: sea.im,
                    coherence: b.coherence,
                    // Per-bin error at the group's mean coherence: averaging
                    // neighbouring bins is not credited (conservative).
                    noise_rel: b.noise_rel(),
                    ..Default::default()
                })
            })
            .collect();
        if points.is_empty() {
            out.push(Event::Warning(format!(
                "{what}: broadband window has no coherent excited band (coherence ≥ {}, input power ≥ {} of its peak, {lo}–{hi} rad/s)",
                self.s.min_coherence, self.s.min_rel_power
            )));
            return None;
        }
        Some(points)
    }

    /// Refits M1–M3 to the experiment's points, then the power law and eq. f.
    fn refit(&mut self, experiment: u32, period: u32, stamp_ns: u64, out: &mut Vec<Event>) {
        let Some(points) = self.points.get(&experiment) else {
            return;
        };
        let (_, load) = self
            .settings_of
            .get(&experiment)
            .copied()
            .unwrap_or((1.0, 0.0));
        let pts = self.s.fit_source.fit_points(points);
        let target = self.s.fit_source.target(self.m_e(load));
        let n = pts.len();
        let head = format!("experiment {experiment} after {n} FRF point(s)");
        let mut fits: [Option<ModelFit>; 3] = [None; 3];
        let mut skipped = Vec::new();
        for ((slot, model), fit) in
            fits.iter_mut()
                .zip(ImpedanceModel::ALL)
                .zip(fit_models(&pts, target, self.s.damping))
        {
            match fit {
                Ok(f) => *slot = Some(f),
                Err(ModelFitError::TooFewPoints { needed }) => skipped.push(format!(
                    "{} ({} parameters) needs {needed} points",
                    model.name(),
                    model.n_params()
                )),
                Err(ModelFitError::Science(e)) => out.push(Event::RefitNote(format!(
                    "{head}: {} not fitted: {e}",
                    model.name()
                ))),
            }
        }
        if !skipped.is_empty() {
            out.push(Event::RefitNote(format!(
                "{head}: not fitted yet: {} (two real equations per point, one left for the residual)",
                skipped.join(", ")
            )));
        }
        let (f13, f23, fcrit) = match fits {
            [Some(m1), Some(m2), Some(m3)] => {
                match paper_f_tests(&[ModelComparison { m1, m2, m3 }], F_TEST_LEVEL) {
                    Ok(t) => (
                        t.m1_vs_m3.statistic,
                        t.m2_vs_m3.statistic,
                        t.m1_vs_m3.critical,
                    ),
                    Err(e) => {
                        out.push(Event::RefitNote(format!("{head}: no F-tests: {e}")));
                        (0.0, 0.0, 0.0)
                    }
                }
            }
            _ => (0.0, 0.0, 0.0),
        };
        if let Some(m2) = fits[1] {
            let (k, h) = (m2.params.k_nm_per_rad, m2.params.h_nm_per_rad);
            if k > 0.0 && h > 0.0 {
                self.m2.insert(experiment, (k, h));
            } else {
                self.m2.remove(&experiment);
                out.push(Event::RefitNote(format!(
                    "{head}: M2 gives K = {k:.3}, H = {h:.3} Nm/rad; not used for the power law"
                )));
            }
        }
        self.update_power_law(out);
        let (beta0, beta1, pl_r2) = self
            .power_law
            .map_or((0.0, 0.0, 0.0), |pl| (pl.law.beta0, pl.law.beta1, pl.r2));
        let f_rec = self.recommended_f.unwrap_or(0.0);
        for (fit, model) in fits.iter().zip(ImpedanceModel::ALL) {
            let Some(fit) = fit else { continue };
            let par = fit.params;
            let se = fit.std_errors.unwrap_or_default();
            let (k, h) = (par.k_nm_per_rad, par.h_nm_per_rad);
            let c = if k != 0.0 { h / k } else { 0.0 };
            // se of H/K by first-order propagation (K and H taken as independent).
            let c_se = if k != 0.0 {
                ((se.h_nm_per_rad / k).powi(2) + (h * se.k_nm_per_rad / (k * k)).powi(2)).sqrt()
            } else {
                0.0
            };
            let e = ImpedanceEstimate {
                seq: self.estimate_seq,
                stamp_ns,
                experiment,
                period,
                n_points: n as u32,
                model: match model {
                    ImpedanceModel::M1 => FitModel::M1,
                    ImpedanceModel::M2 => FitModel::M2,
                    ImpedanceModel::M3 => FitModel::M3,
                }
                .as_u32(),
                k_h: k,
                k_h_se: se.k_nm_per_rad.abs(),
                h_h: h,
                h_h_se: se.h_nm_per_rad.abs(),
                b_h: par.b_nm_s_per_rad,
                b_h_se: se.b_nm_s_per_rad.abs(),
                m_h: par.m_kg_m2,
                m_h_se: se.m_kg_m2.abs(),
                c_h: c,
                c_h_se: c_se,
                r2: fit.r2.min(1.0),
                f_m1_m3: f13,
                f_m2_m3: f23,
                f_critical: fcrit,
                beta0,
                beta1,
                power_law_r2: pl_r2,
                recommended_f: f_rec,
            };
            match e.validate() {
                Ok(()) => {
                    self.estimate_seq += 1;
                    out.push(Event::Estimate(e));
                }
                Err(err) => out.push(Event::RefitNote(format!(
                    "{head}: {} estimate not published: {err}",
                    model.name()
                ))),
            }
        }
    }

    /// The power law over the experiments' M2 `(K, H)` (two or more with
    /// distinct K) and eq. f's fractional order from it.
    fn update_power_law(&mut self, out: &mut Vec<Event>) {
        self.power_law = None;
        self.recommended_f = None;
        if self.m2.len() < 2 {
            return;
        }
        let (ks, hs): (Vec<f64>, Vec<f64>) = self.m2.values().copied().unzip();
        let pl = match fit_power_law(&ks, &hs) {
            Ok(pl) => pl,
            Err(e) => {
                out.push(Event::RefitNote(format!(
                    "power law over {} experiments not fitted: {e}",
                    ks.len()
                )));
                return;
            }
        };
        self.power_law = Some(pl);
        let [k_lo, k_hi] = match self.s.k_range_source {
            KRangeSource::Settings => self.s.k_range_nm_per_rad,
            KRangeSource::Experiments => [
                ks.iter().copied().fold(f64::INFINITY, f64::min),
                ks.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ],
        };
        match StiffnessRange::new(k_lo, k_hi)
            .and_then(|r| fractional_order(pl.law, r, self.s.phase_margin_deg))
        {
            Ok(f) => self.recommended_f = Some(f.clamp(self.s.f_bounds[0], self.s.f_bounds[1])),
            Err(e) => out.push(Event::RefitNote(format!(
                "power law β0 = {:.3}, β1 = {:.3}: no recommended f: {e}",
                pl.law.beta0, pl.law.beta1
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fewer_than_nine_in_ten_commands_are_warned_about() {
        let id = Identifier::new(IdentifierSettings {
            fit_source: FitSource::ActuatorTorque,
            ..IdentifierSettings::default()
        });
        let warned = |exact, count| {
            let mut out = Vec::new();
            id.command_coverage("w", exact, count, &mut out);
            out.len()
        };
        assert_eq!(warned(10, 10), 0);
        assert_eq!(warned(9, 10), 0, "nine in ten is enough");
        assert_eq!(warned(8, 10), 1);
        assert_eq!(warned(0, 10), 1);
        // The cuff's S_h needs no command.
        let cuff = Identifier::new(IdentifierSettings::default());
        let mut out = Vec::new();
        cuff.command_coverage("w", 0, 10, &mut out);
        assert!(out.is_empty());
    }

    /// `τ_s/τ_d` is estimated when nine in ten samples or more had their
    /// own command, and never from none (a one-sample window included).
    #[test]
    fn the_sea_is_tracked_from_nine_in_ten_commands_and_never_from_none() {
        let signals = |n: usize, exact: usize| WindowSignals {
            theta_rad: vec![0.0; n],
            tau_c_nm: vec![],
            tau_s_less_gravity_nm: vec![],
            tau_s_nm: vec![],
            tau_d_nm: vec![],
            exact,
            rate_hz: 1000.0,
        };
        assert!(signals(10, 10).commands_cover_it());
        assert!(signals(10, 9).commands_cover_it());
        assert!(!signals(10, 8).commands_cover_it());
        assert!(!signals(100, 89).commands_cover_it());
        assert!(signals(100, 90).commands_cover_it());
        assert!(!signals(10, 0).commands_cover_it());
        assert!(!signals(1, 0).commands_cover_it());
        assert!(signals(1, 1).commands_cover_it());
    }

    /// A window's rate is its own stamps' (a recording at 500 Hz read with
    /// the default 1 kHz settings): n − 1 intervals over the span; a window
    /// of one sample keeps the settings' rate.
    #[test]
    fn a_windows_rate_is_read_from_its_own_stamps() {
        let mut id = Identifier::new(IdentifierSettings::default());
        let mut out = Vec::new();
        let origin = 7_000_000_000u64;
        for k in 0..101u64 {
            id.on_sample(
                &SensorSample {
                    seq: k,
                    stamp_ns: origin + k * 2_000_000,
                    ..Default::default()
                },
                &mut out,
            );
        }
        let w = id.window_signals(origin, origin + 200_000_001, "w", &mut out);
        assert_eq!(w.theta_rad.len(), 101);
        assert!((w.rate_hz - 500.0).abs() < 1e-9, "{}", w.rate_hz);
        let one = id.window_signals(origin, origin + 1, "w", &mut out);
        assert_eq!((one.theta_rad.len(), one.rate_hz), (1, 1000.0));
    }
}
