//! The run file: what `exo run` starts and how every process is set up;
//! its key ranges and checks are in `run/check.rs`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{read_toml, Check, ExperimentSpec, ExperimentTable, ProtocolTiming, Result, Subject};

mod check;
mod services;

pub use check::RUN_RANGES;
pub use services::{LiveSettings, PlayerSettings, ServiceSet, TunnelSettings};

/// How simulated time advances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimingMode {
    /// The plant advances one control period only when the controller's
    /// answer to the current tick has arrived: deterministic and fast.
    Lockstep,
    /// The plant advances on the wall clock at `rate_hz` with absolute deadlines.
    Realtime,
}

/// `[run]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSettings {
    /// Timing mode.
    pub timing: TimingMode,
    /// Control rate (Hz): one sensor sample and one command per tick.
    /// Range [1, 100 000].
    pub rate_hz: f64,
    /// Seed of every random source (sensor noise); same seed ⇒ same run in
    /// lockstep. Any unsigned 64-bit integer.
    pub seed: u64,
    /// Prefix of this run's iceoryx2 service names, so runs do not collide:
    /// 1 to 64 letters, digits, `-` or `_`.
    #[serde(default = "default_instance")]
    pub instance: String,
    /// Stop after this much simulated time (s), if set; otherwise at
    /// protocol end. Range (0, 86 400] (a day).
    #[serde(default)]
    pub max_sim_time_s: Option<f64>,
    /// Directory for recordings and reports (relative to the working
    /// directory). Must not be, or lie under, an existing file; `exo run`
    /// creates it, and refuses to start when it cannot, before any process.
    #[serde(default = "default_output_dir")]
    pub output_dir: PathBuf,
    /// In lockstep, how long (µs) a process polls for the next message,
    /// yielding the CPU between polls, before it sleeps in the kernel; a
    /// kernel wake-up costs tens of µs per hand-over, four per tick.
    /// Default 0: never polls, every wait sleeps on the iceoryx2 event (no
    /// busy loop by default); 200 makes lockstep about three times faster on
    /// two cores (BENCHMARKS.md). Ignored in real time (which always sleeps).
    /// Range [0, 100 000].
    #[serde(default = "default_lockstep_spin_us")]
    pub lockstep_spin_us: f64,
}

fn default_lockstep_spin_us() -> f64 {
    0.0
}

fn default_instance() -> String {
    "exo".into()
}
fn default_output_dir() -> PathBuf {
    PathBuf::from("out/runs")
}

/// `[realtime]`: operating-system real-time settings of the real-time path
/// (plant simulator, sensor driver, controller), applied only in real-time
/// timing. Each is asked for and, where the system refuses (no
/// `CAP_SYS_NICE`, `RLIMIT_MEMLOCK`, a missing CPU), the process warns and
/// runs on with normal scheduling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RealtimeSettings {
    /// Ask for `SCHED_FIFO` at this priority (1–99); none when absent.
    #[serde(default)]
    pub sched_fifo_priority: Option<i32>,
    /// Lock memory (`mlockall`): what is mapped at start at once, what is
    /// mapped later (a peer's shared memory) page by page as it is touched,
    /// so no page of the loop is paged out and a peer's restart does not
    /// populate its segments inside a tick (BENCHMARKS.md, "Restarts").
    #[serde(default)]
    pub lock_memory: bool,
    /// Pin the controller to this CPU (0–1023; a CPU the machine lacks is
    /// warned about at start).
    #[serde(default)]
    pub controller_cpu: Option<usize>,
    /// Pin the sensor driver to this CPU (0–1023).
    #[serde(default)]
    pub sensor_driver_cpu: Option<usize>,
    /// Pin the plant simulator to this CPU (0–1023).
    #[serde(default)]
    pub plant_sim_cpu: Option<usize>,
}

/// Which hardware-bus backend the sensor driver talks to (`[bus] backend`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BusBackend {
    /// The plant simulator's bus: iceoryx2 channels to `exo-plant-sim`.
    #[default]
    Simulator,
    /// A CiA 402 servo drive on EtherCAT (`[bus.ethercat]`), in real time only.
    Ethercat,
}

/// `[bus]`: the sensor driver's hardware bus. Swapping the simulator for
/// hardware is this setting plus `services.plant_sim = false`; see
/// ARCHITECTURE.md for where a new backend plugs in.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSettings {
    /// The backend.
    pub backend: BusBackend,
    /// The EtherCAT drive, with `backend = "ethercat"`.
    #[serde(default)]
    pub ethercat: Option<crate::EthercatSettings>,
}

/// What the protocol does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProtocolMode {
    /// Table I: bias ramps and sine perturbation, constant α per experiment
    /// unless a fractional-order controller is configured.
    Identification,
    /// The paper's amplification experiments: the subject moves voluntarily
    /// (sinusoid), the fractional-order controller amplifies; no perturbation.
    Voluntary,
    /// The paper's post-tuning test (section "Tuning Results"): springs
    /// attached to the exoskeleton arm's tip pull on it while the subject
    /// holds a stiffness; they are detached at once and the response shows
    /// whether the amplification loop is stable. Needs `[release]`.
    Release,
    /// A designed periodic multisine per experiment instead of the sine
    /// steps (issue 34; `[protocol.multisine]`, defaults when absent): each
    /// experiment is one period of the protocol whose settling holds
    /// `settling_periods` and whose analysis window `periods` whole periods
    /// of the multisine.
    Multisine,
}

impl ProtocolMode {
    /// Whether the mode excites the subject for identification (the sine
    /// steps or the multisine): its experiments are the run's list, its
    /// recording is fitted and reported after the run.
    pub fn identifies(self) -> bool {
        matches!(self, ProtocolMode::Identification | ProtocolMode::Multisine)
    }
}

/// `[protocol.multisine]`: the designed excitation of `mode = "multisine"`
/// (issue 34 item 1; `exo_impedance::multisine`). One design serves every
/// experiment of the run, scaled to each experiment's peak torque.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MultisineSettings {
    /// Band (rad/s) the lines are log-spaced over, `[low, high]`: each edge
    /// in (0, 10 000], the high edge below the Nyquist frequency
    /// π·`run.rate_hz`. Default: the sine-step protocol's 2–32 rad/s.
    #[serde(default = "MultisineSettings::default_band")]
    pub band_rad_s: [f64; 2],
    /// Number of excited lines. Range [1, 1000]; the band must hold at
    /// least as many frequencies the period resolves. Default 12.
    #[serde(default = "MultisineSettings::default_lines")]
    pub lines: u32,
    /// Length of one multisine period (s); `period_s · run.rate_hz` must be
    /// a whole number of samples. Range (0, 3600]. Default 10 (lines
    /// 0.63 rad/s apart at the finest).
    #[serde(default = "MultisineSettings::default_period_s")]
    pub period_s: f64,
    /// Whole periods of settling before the analysis window (the first
    /// half of the first one fades the multisine in). Range [1, 1000].
    /// Default 1.
    #[serde(default = "MultisineSettings::default_settling_periods")]
    pub settling_periods: u32,
    /// Whole periods in the analysis window: at least 2 (the noise is
    /// estimated from the spread between periods). Range [2, 1000].
    /// Default 3.
    #[serde(default = "MultisineSettings::default_periods")]
    pub periods: u32,
    /// Peak excitation torque (Nm); when absent, each experiment's largest
    /// sine amplitude of the experiment table (the sine-step protocol's
    /// peak). Range (0, 1000]; with the experiment's bias at most
    /// `controller.limits.torque_nm`.
    #[serde(default)]
    pub peak_nm: Option<f64>,
}

impl MultisineSettings {
    fn default_band() -> [f64; 2] {
        [2.0, 32.0]
    }
    fn default_lines() -> u32 {
        12
    }
    fn default_period_s() -> f64 {
        10.0
    }
    fn default_settling_periods() -> u32 {
        1
    }
    fn default_periods() -> u32 {
        3
    }

    /// Rounds of clipping after Schroeder's phases, each at
    /// [`MultisineSettings::CLIP`] of the current peak
    /// (`exo_impedance::Multisine::clipped`).
    pub const CLIP_ITERATIONS: usize = 100;
    /// The clipping level of each round, as a fraction of the peak.
    pub const CLIP: f64 = 0.8;

    /// Samples in one period at `rate_hz`, if `period_s · rate_hz` is a
    /// whole number (within 1e-6 of a sample).
    pub fn period_samples(&self, rate_hz: f64) -> Option<usize> {
        let n = self.period_s * rate_hz;
        let whole = n.round();
        (n.is_finite() && whole >= 1.0 && (n - whole).abs() <= 1e-6).then_some(whole as usize)
    }

    /// The period's length in samples and its excited bins at `rate_hz`:
    /// the lines log-spaced over the band on the period's grid
    /// (`exo_impedance::multisine::log_spaced_bins`). Cheap: what the run
    /// file's check needs.
    pub fn bins(&self, rate_hz: f64) -> std::result::Result<(usize, Vec<usize>), MultisineError> {
        let n = self.period_samples(rate_hz).ok_or_else(|| MultisineError {
            key: "protocol.multisine.period_s",
            why: format!(
                "{} s at run.rate_hz = {rate_hz} Hz is not a whole number of samples",
                self.period_s
            ),
        })?;
        let bins = exo_impedance::multisine::log_spaced_bins(
            rate_hz,
            n,
            self.band_rad_s,
            self.lines as usize,
        )
        .map_err(|e| MultisineError {
            key: "protocol.multisine.band_rad_s",
            why: e.to_string(),
        })?;
        Ok((n, bins))
    }

    /// The design at `rate_hz`, with a peak of 1 (scale it by each
    /// experiment's peak torque): [`MultisineSettings::bins`], flat
    /// amplitudes (flat in torque), Schroeder's phases, then
    /// [`MultisineSettings::CLIP_ITERATIONS`] rounds of clipping.
    /// Deterministic: every process of a run (and the fit of its recording,
    /// from the configuration the recording holds) builds the same one.
    pub fn design(
        &self,
        rate_hz: f64,
    ) -> std::result::Result<exo_impedance::multisine::Multisine, MultisineError> {
        let (n, bins) = self.bins(rate_hz)?;
        let amplitudes = vec![1.0; bins.len()];
        exo_impedance::multisine::Multisine::schroeder(rate_hz, n, &bins, &amplitudes)
            .and_then(|m| m.clipped(Self::CLIP_ITERATIONS, Self::CLIP))
            .and_then(|m| m.scaled_to_peak(1.0))
            .map_err(|e| MultisineError {
                key: "protocol.multisine",
                why: e.to_string(),
            })
    }

    /// The peak excitation torque (Nm) of experiment `e` of `table`:
    /// `peak_nm`, or the experiment's largest sine amplitude.
    pub fn peak_nm_of(&self, table: &ExperimentTable, e: &ExperimentSpec) -> f64 {
        self.peak_nm.unwrap_or_else(|| {
            (1..=table.periods.max(1))
                .map(|p| table.amplitude_nm(e, p))
                .fold(0.0, f64::max)
        })
    }
}

/// Why a multisine cannot be designed from `[protocol.multisine]`, naming the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {why}")]
pub struct MultisineError {
    /// The run file's key at fault.
    pub key: &'static str,
    /// What is wrong.
    pub why: String,
}

impl Default for MultisineSettings {
    fn default() -> Self {
        MultisineSettings {
            band_rad_s: Self::default_band(),
            lines: Self::default_lines(),
            period_s: Self::default_period_s(),
            settling_periods: Self::default_settling_periods(),
            periods: Self::default_periods(),
            peak_nm: None,
        }
    }
}

/// `[protocol]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolSettings {
    /// Mode.
    pub mode: ProtocolMode,
    /// Experiment table (relative to the run file).
    pub experiments_file: PathBuf,
    /// Which experiments to run, in order: at least one, each in the
    /// experiment table and the subject file (1 to 9).
    pub experiments: Vec<u32>,
    /// Which periods of each (1-based, each at most the table's `periods`);
    /// all when absent; when present, at least one.
    #[serde(default)]
    pub periods: Option<Vec<u32>>,
    /// Override of the rest between periods (s), so simulations need not
    /// wait 40 s. Range [0, 3600].
    #[serde(default)]
    pub rest_s: Option<f64>,
    /// Override of the bias ramp-in (s); the paper: 5. Range [0, 3600].
    #[serde(default)]
    pub ramp_in_s: Option<f64>,
    /// Override of the settling part of the sine (s); the paper: 5. Range [0, 3600].
    #[serde(default)]
    pub settling_s: Option<f64>,
    /// Override of the analysis window (s); the paper: 5. Range [0.01, 3600].
    #[serde(default)]
    pub analysis_s: Option<f64>,
    /// Override of the bias ramp-out (s); the paper: 5. Range [0, 3600].
    /// The whole protocol (experiments × periods × period) lasts at most a day.
    #[serde(default)]
    pub ramp_out_s: Option<f64>,
    /// `[protocol.multisine]`: the design of `mode = "multisine"` (its
    /// defaults when absent); refused in the other modes.
    #[serde(default)]
    pub multisine: Option<MultisineSettings>,
    /// `[protocol.stop_when]`: in multisine mode, end each experiment's
    /// analysis as soon as its M2 K and H are known well enough (issue 34
    /// item 3); every analysis window runs its whole `periods` when absent.
    #[serde(default)]
    pub stop_when: Option<StopWhen>,
}

/// `[protocol.stop_when]` (issue 34 item 3): an experiment of a multisine
/// run has been measured enough once the identifier's M2 fit of its lines
/// gives K and H with 95 % intervals (Student's t at the fit's degrees of
/// freedom times the standard error, `exo_impedance::fit`) no wider than
/// these fractions of K and H; its analysis window then ends at the next
/// whole period of the multisine, but never before `min_periods` periods
/// and never after `[protocol.multisine] periods` (the most).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StopWhen {
    /// The largest 95 % half-width of K over K (dimensionless, (0, 1]).
    pub k_rel_ci: f64,
    /// The largest 95 % half-width of H over H (dimensionless, (0, 1]).
    pub h_rel_ci: f64,
    /// Whole periods analysed before the window may end (at least 2: the
    /// noise comes from their spread; at most the multisine's `periods`).
    #[serde(default = "default_stop_min_periods")]
    pub min_periods: u32,
}

fn default_stop_min_periods() -> u32 {
    2
}

impl StopWhen {
    /// Whether an M2 fit with stiffness `k` and hysteretic damping `h`
    /// (Nm/rad) and 95 % half-widths `k_ci95`, `h_ci95` (Nm/rad) is known
    /// well enough: both positive and finite, each interval within its
    /// fraction.
    pub fn met(&self, k: f64, k_ci95: f64, h: f64, h_ci95: f64) -> bool {
        let within = |x: f64, ci: f64, rel: f64| x > 0.0 && ci.is_finite() && ci <= rel * x;
        within(k, k_ci95, self.k_rel_ci) && within(h, h_ci95, self.h_rel_ci)
    }
}

impl ProtocolSettings {
    /// The timing overrides with their keys, for validation and application.
    fn timing_overrides(&self) -> [(&'static str, Option<f64>); 5] {
        [
            ("protocol.ramp_in_s", self.ramp_in_s),
            ("protocol.settling_s", self.settling_s),
            ("protocol.analysis_s", self.analysis_s),
            ("protocol.ramp_out_s", self.ramp_out_s),
            ("protocol.rest_s", self.rest_s),
        ]
    }

    /// The multisine design's settings in `mode = "multisine"` (the
    /// defaults when `[protocol.multisine]` is absent); `None` in the other
    /// modes.
    pub fn multisine(&self) -> Option<MultisineSettings> {
        (self.mode == ProtocolMode::Multisine).then(|| self.multisine.unwrap_or_default())
    }

    /// Applies the overrides to the experiment table's timing; in
    /// multisine mode the settling and analysis windows are then
    /// `settling_periods` and `periods` whole periods of the multisine.
    pub fn apply_timing(&self, timing: &mut ProtocolTiming) {
        if let Some(m) = self.multisine() {
            timing.settling_s = f64::from(m.settling_periods) * m.period_s;
            timing.analysis_s = f64::from(m.periods) * m.period_s;
        }
        let fields = [
            &mut timing.ramp_in_s,
            &mut timing.settling_s,
            &mut timing.analysis_s,
            &mut timing.ramp_out_s,
            &mut timing.rest_s,
        ];
        for (field, (_, v)) in fields.into_iter().zip(self.timing_overrides()) {
            if let Some(v) = v {
                *field = v;
            }
        }
    }
}

/// `[protocol.voluntary]`: the subject's voluntary motion for `mode = "voluntary"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoluntarySettings {
    /// Target angle amplitude (rad). Range [0, 1.5].
    pub amplitude_rad: f64,
    /// Target frequency (rad/s). Range (0, 10 000], and below the Nyquist
    /// frequency π·`run.rate_hz`.
    pub omega_rad_s: f64,
    /// Duration (s). Range (0, 3600].
    pub duration_s: f64,
    /// Grip (kg) and bias (Nm) held meanwhile (the paper: 14 kg, 4 Nm).
    /// Range [0, 100].
    pub grip_kg: f64,
    /// Bias torque (Nm). Range [−100, 100].
    pub bias_nm: f64,
    /// Experiment whose stiffness the subject holds (1 to 9, in the
    /// experiment table and the subject file).
    pub experiment: u32,
}

/// `[release]`: the spring-release perturbation of `mode = "release"`.
///
/// The protocol is one period: the experiment's bias ramps in over 1 s with
/// the spring attached, the spring stays attached for `hold_s` (phase
/// *settling*), is released at the start of the *analysis* phase, and the
/// response is observed for `observe_s`; then the bias ramps out over 1 s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReleaseSettings {
    /// Experiment of Table I whose stiffness, grip, bias and load the
    /// subject holds (1 to 9, in the experiment table and the subject file).
    pub experiment: u32,
    /// Torque (Nm) the attached springs exert on the exoskeleton joint
    /// (positive = raising). Range [−100, 100].
    pub spring_torque_nm: f64,
    /// Time (s) the spring stays attached after the bias has ramped in.
    /// Range (0, 3600].
    pub hold_s: f64,
    /// Time (s) observed after the release. Range (0, 3600].
    pub observe_s: f64,
}

/// `[controller]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSettings {
    /// Proportional gain k_p; eq. kp from the rig and subject inertias when
    /// absent. Range (0, 20] (the paper's is 3.2; eq. kp gives about 3 for
    /// its rig); `exo run` also refuses a k_p and f whose model loop is
    /// clearly unstable (see `controller.f`).
    #[serde(default)]
    pub kp: Option<f64>,
    /// Fractional order f in [0, 1); when absent, α is the experiment's
    /// constant. `exo run` computes the loop's phase margin (the science
    /// core's model, with the plant's SEA) at the stiffness the subject
    /// holds in each experiment of the run and at both bounds of
    /// `k_range_nm_per_rad`: it refuses the run, naming the margin, when one
    /// is below −15°, and warns when one is negative.
    #[serde(default)]
    pub f: Option<f64>,
    /// Stiffness range (Nm/rad) for k_f (eq. kf): [min, max], each in
    /// (0, 5000], min ≤ max.
    pub k_range_nm_per_rad: [f64; 2],
    /// Number of lag filters, 1 to 16.
    pub filters: usize,
    /// First pole (rad/s). Range (0, 10 000].
    pub p1_rad_s: f64,
    /// Pole spacing. Range (1, 100].
    pub r_pp: f64,
    /// Adopt the identifier's recommended f when it is published.
    #[serde(default)]
    pub adopt_recommended_f: bool,
    /// Bounds within which a recommended f may be adopted: [min, max], each
    /// in [0, 0.999], min ≤ max.
    #[serde(default = "default_f_bounds")]
    pub f_bounds: [f64; 2],
    /// Torque and rate limits.
    pub limits: LimitSettings,
    /// Compensate gravity with the rig model (off for a rig moving in a horizontal plane).
    #[serde(default = "default_true")]
    pub gravity_compensation: bool,
}

/// Why a controller's lag-filter layout could not be designed: the run
/// file's key and the science core's reason.
#[derive(Debug, thiserror::Error)]
#[error("{key}: {source}")]
pub struct LayoutError {
    /// The `[controller]` key, e.g. `"controller.kp"`.
    pub key: &'static str,
    /// The science core's reason.
    #[source]
    pub source: exo_impedance::ScienceError,
}

impl ControllerSettings {
    /// The fractional amplifier's layout for an arm of inertia `m_e` and a
    /// subject of inertia `m_h` (kg·m²): `k_p` as set or from the inertias
    /// (eq. kp), the nominal crossover `ω̂_gc` of `k_range_nm_per_rad` that
    /// sets `k_f` (eq. kf), and the lag cascade's `n`, `p_1`, `r_pp`. The one
    /// place the controller, `exo run`'s preflight and `exo tune` design it.
    pub fn layout(
        &self,
        m_e_kg_m2: f64,
        m_h_kg_m2: f64,
    ) -> Result<exo_impedance::loop_shaping::FractionalLayout, LayoutError> {
        let kp = match self.kp {
            Some(kp) => kp,
            None => exo_impedance::proportional_gain(m_e_kg_m2, m_h_kg_m2).map_err(|source| {
                LayoutError {
                    key: "controller.kp",
                    source,
                }
            })?,
        };
        let [k_lo, k_hi] = self.k_range_nm_per_rad;
        let crossover = |source| LayoutError {
            key: "controller.k_range_nm_per_rad",
            source,
        };
        let range = exo_impedance::StiffnessRange::new(k_lo, k_hi).map_err(crossover)?;
        Ok(exo_impedance::loop_shaping::FractionalLayout {
            kp,
            omega_gc_hat_rad_s: exo_impedance::nominal_crossover(range, m_e_kg_m2, m_h_kg_m2)
                .map_err(crossover)?,
            filters: self.filters,
            p1_rad_s: self.p1_rad_s,
            r_pp: self.r_pp,
        })
    }
}

fn default_true() -> bool {
    true
}

fn default_f_bounds() -> [f64; 2] {
    [0.0, 0.9]
}

/// `[controller.limits]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitSettings {
    /// |τ_d| limit (Nm); every command is clamped to it. Range (0, 1000].
    pub torque_nm: f64,
    /// |dτ_d/dt| limit (Nm/s). Range (0, 1 000 000].
    pub torque_rate_nm_per_s: f64,
    /// Allowed joint angle range (rad); outside it the controller faults.
    /// [min, max], each in [−2π, 2π], min < max.
    pub theta_rad: [f64; 2],
    /// |τ_c| above this (Nm) is a sensor fault. Range (0, 1000].
    pub tau_c_nm: f64,
}

/// What the safe state commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SafeState {
    /// Gravity compensation only.
    GravityOnly,
    /// Zero torque.
    ZeroTorque,
}

/// `[safety]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafetySettings {
    /// The driver drops to the safe state when no fresh command arrives
    /// within this (ms). Range (0, 1000], and at least one control period.
    pub command_deadline_ms: f64,
    /// The controller faults when no sample arrives within this (ms).
    /// Range (0, 1000], and at least one control period.
    pub sample_deadline_ms: f64,
    /// What the safe state commands.
    pub safe_state: SafeState,
    /// In lockstep, simulated time stands still while a process waits, so
    /// deadlines are counted in ticks: after this much wall time (ms)
    /// without the controller's command the sensor driver declares it if
    /// the controller's process is gone, or waits on (up to 15 s) if it
    /// lives, since a loaded machine can hold a process this long; the safe
    /// state then takes effect at the same simulated tick. Range (0, 60 000]
    /// (a minute).
    #[serde(default = "default_lockstep_timeout_ms")]
    pub lockstep_timeout_ms: f64,
    /// The drive's watchdog (as an EtherCAT drive's sync-manager watchdog):
    /// in real time, with no motor command for this long (ms) the drive
    /// applies zero torque and reports `DRIVE_FAULT` until it is re-enabled.
    /// The simulated drive (plant-sim) implements it; the EtherCAT backend
    /// does not write a drive's watchdog (set it in the drive,
    /// docs/hardware.md) and detects a silent bus itself. Range (0, 1000], and at
    /// least one control period.
    #[serde(default = "default_drive_watchdog_ms")]
    pub drive_watchdog_ms: f64,
    /// In real time, with no bus frame for this long (ms) the sensor driver
    /// publishes a sample flagged `BUS_FAULT | SAFE_STATE` from its own
    /// timer, latches its safe state and commands it. Range (0, 1000], and
    /// at least one control period.
    #[serde(default = "default_bus_deadline_ms")]
    pub bus_deadline_ms: f64,
}

fn default_lockstep_timeout_ms() -> f64 {
    1000.0
}

fn default_drive_watchdog_ms() -> f64 {
    10.0
}

fn default_bus_deadline_ms() -> f64 {
    5.0
}

/// `[rig]`: what the software believes about the hardware (calibration and
/// gravity model). The plant model holds the truth; they may differ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSettings {
    /// Exoskeleton arm inertia without load (kg·m²); the paper: 0.1. Range (0, 10].
    pub arm_inertia_kg_m2: f64,
    /// Arm mass (kg) and centre-of-mass distance (m) for gravity
    /// compensation. Range [0, 50].
    pub arm_mass_kg: f64,
    /// Arm centre of mass from the joint (m). Range [0, 2].
    pub arm_com_m: f64,
    /// Where the load hangs (m); the paper: 0.45. Range [0, 2].
    pub load_lever_arm_m: f64,
    /// Encoder counts per revolution. Range [1, 10¹²].
    pub encoder_counts_per_rev: f64,
    /// Cuff F/T sensor distance from the joint (m): τ_c = r·f_y + t_z. Range (0, 2].
    pub cuff_lever_arm_m: f64,
    /// SEA spring stiffness (Nm/rad) and its deflection encoder resolution.
    /// Range (0, 10⁶].
    pub sea_stiffness_nm_per_rad: f64,
    /// SEA deflection encoder counts per revolution. Range [1, 10¹²].
    pub sea_counts_per_rev: f64,
    /// Velocity filter cut-off (Hz) of the driver's angle differentiator.
    /// Range (0, 50 000], and below half of `run.rate_hz`.
    pub velocity_cutoff_hz: f64,
    /// Gravity in the arm's plane of motion (m/s²) for the compensation and
    /// the gravity-only safe state: standard gravity for a joint whose axis
    /// is horizontal (the arm swings in a vertical plane, as the paper's),
    /// 0 for a horizontal rig (axis vertical: gravity does not turn the
    /// joint). Default (the key absent) [`GRAVITY_M_S2`]. Range [0, 20].
    #[serde(default = "standard_gravity")]
    pub gravity_m_s2: f64,
}

fn standard_gravity() -> f64 {
    GRAVITY_M_S2
}

/// Standard gravity (m/s²).
pub const GRAVITY_M_S2: f64 = 9.80665;

/// The gravity moment of the exoskeleton arm and its load about the joint
/// (Nm): `g (m_a l_a + m_L l_L)`, the amplitude of the gravity torque
/// `τ_gravity = g (m_a l_a + m_L l_L) sin θ` at joint angle θ (0 = hanging
/// straight down), which the controller compensates (the paper's
/// τ_gravity, removed from τ_s on the actuator side `(τ_s − τ_gravity)/θ_e`).
///
/// `g_m_s2`: gravity in the arm's plane of motion (m/s²); `arm_mass_kg`:
/// the arm's mass `m_a` (kg); `arm_com_m`: its centre of mass from the
/// joint `l_a` (m); `load_kg`: the load `m_L` (kg); `load_lever_arm_m`:
/// where the load hangs, `l_L` (m).
///
/// The one place the moment is written: what the software believes
/// ([`RigSettings::gravity_moment_nm`], `rig.*`) and the simulated truth
/// (`exo_plant_model::PlantModel::gravity_moment_nm`, `[gravity]` and
/// `exo.load_lever_arm_m`) both call it.
pub fn gravity_moment_nm(
    g_m_s2: f64,
    arm_mass_kg: f64,
    arm_com_m: f64,
    load_kg: f64,
    load_lever_arm_m: f64,
) -> f64 {
    g_m_s2 * (arm_mass_kg * arm_com_m + load_kg * load_lever_arm_m)
}

impl RigSettings {
    /// The rig's gravity moment with `load_kg` (kg) on the arm (Nm):
    /// [`gravity_moment_nm`] of `rig.gravity_m_s2`, `rig.arm_mass_kg`,
    /// `rig.arm_com_m` and `rig.load_lever_arm_m`.
    pub fn gravity_moment_nm(&self, load_kg: f64) -> f64 {
        gravity_moment_nm(
            self.gravity_m_s2,
            self.arm_mass_kg,
            self.arm_com_m,
            load_kg,
            self.load_lever_arm_m,
        )
    }

    /// Gravity torque (Nm) on the exoskeleton arm and its load at joint angle
    /// `theta_rad` (0 = hanging straight down): `g (m_a l_a + m_L l_L) sin θ`
    /// ([`RigSettings::gravity_moment_nm`] times `sin θ`), `g` =
    /// `rig.gravity_m_s2`.
    /// The controller adds it to cancel gravity; the driver uses it for the
    /// gravity-only safe state.
    pub fn gravity_torque_nm(&self, theta_rad: f64, load_kg: f64) -> f64 {
        self.gravity_moment_nm(load_kg) * theta_rad.sin()
    }
}

/// A whole run file with the files it refers to loaded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// `[run]`.
    pub run: RunSettings,
    /// `[services]`.
    pub services: ServiceSet,
    /// `[bus]` (default: the simulator's).
    #[serde(default)]
    pub bus: BusSettings,
    /// `[player]` (with `services.player`).
    #[serde(default)]
    pub player: Option<PlayerSettings>,
    /// `[live]` (with `services.live`; default: loopback, port 8765).
    #[serde(default)]
    pub live: Option<LiveSettings>,
    /// `[tunnel]` (with `services.tunnel`; default: loopback, port 7447).
    #[serde(default)]
    pub tunnel: Option<TunnelSettings>,
    /// `[realtime]` (default: nothing asked for).
    #[serde(default)]
    pub realtime: Option<RealtimeSettings>,
    /// Plant model path (relative to the run file).
    pub plant_model: PathBuf,
    /// Subject file path (relative to the run file).
    pub subject_file: PathBuf,
    /// `[protocol]`.
    pub protocol: ProtocolSettings,
    /// `[protocol.voluntary]`, needed when `protocol.mode = "voluntary"`.
    #[serde(default)]
    pub voluntary: Option<VoluntarySettings>,
    /// `[release]`, needed when `protocol.mode = "release"`.
    #[serde(default)]
    pub release: Option<ReleaseSettings>,
    /// `[controller]`.
    pub controller: ControllerSettings,
    /// `[safety]`.
    pub safety: SafetySettings,
    /// `[rig]`.
    pub rig: RigSettings,
    /// Where this configuration was read from (set on load).
    #[serde(skip)]
    pub source: PathBuf,
    /// The experiment table (loaded from `protocol.experiments_file`).
    #[serde(skip)]
    pub experiments: Option<ExperimentTable>,
    /// The subject (loaded from `subject_file`).
    #[serde(skip)]
    pub subject: Option<Subject>,
}

/// Why `dir` cannot be a run's output directory, as far as can be told
/// without writing: it is empty, or it or a directory above it exists and
/// is not a directory. `None` when nothing is wrong so far (whether it can
/// be created and written is for `exo run` to find out before it starts).
pub fn output_dir_problem(dir: &Path) -> Option<String> {
    if dir.as_os_str().is_empty() {
        return Some("must not be empty (use \".\" for the working directory)".into());
    }
    let mut at = Some(dir);
    while let Some(p) = at {
        if p.as_os_str().is_empty() {
            break;
        }
        match std::fs::metadata(p) {
            Ok(m) if m.is_dir() => return None,
            Ok(_) => return Some(format!("{} exists and is not a directory", p.display())),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                at = p.parent();
            }
            Err(e) => return Some(format!("{}: {e}", p.display())),
        }
    }
    None
}

impl RunConfig {
    /// Reads, validates and resolves a run file and the files it names (the
    /// experiment table and the subject; the plant model is the plant
    /// simulator's). The error names the file and the key of every value at
    /// fault that could be found, one per line: a run file that does not
    /// parse stops there, otherwise its own values, the experiment table,
    /// the subject and the checks across them are all made.
    pub fn from_file(file: &Path) -> Result<Self> {
        let mut cfg: RunConfig = read_toml(file)?;
        cfg.source = file.to_path_buf();
        let c = Check::with_ranges(file, RUN_RANGES);
        cfg.check_values(&c);
        let dir = file.parent().unwrap_or(Path::new("."));
        cfg.plant_model = dir.join(&cfg.plant_model);
        cfg.subject_file = dir.join(&cfg.subject_file);
        cfg.protocol.experiments_file = dir.join(&cfg.protocol.experiments_file);
        if let Some(p) = cfg.player.as_mut() {
            p.file = dir.join(&p.file);
        }
        if let Some(z) = cfg.tunnel.as_mut().and_then(|t| t.zenoh_config.as_mut()) {
            *z = dir.join(&*z);
            if !z.is_file() {
                c.note(
                    "tunnel.zenoh_config",
                    format!("{} does not exist", z.display()),
                );
            }
        }
        if cfg.services.player {
            match &cfg.player {
                None => c.note(
                    "services.player",
                    "the player needs a [player] table naming the recording to play (file = …)",
                ),
                Some(p) if !p.file.is_file() => c.note(
                    "player.file",
                    format!("{} does not exist", p.file.display()),
                ),
                Some(_) => {}
            }
            let s = cfg.services;
            for (on, key) in [
                (s.plant_sim, "services.plant_sim"),
                (s.sensor_driver, "services.sensor_driver"),
                (s.controller, "services.controller"),
            ] {
                if on {
                    c.note(
                        key,
                        "must be false with services.player: the player publishes the samples, commands and protocol states itself",
                    );
                }
            }
        }
        let table = c
            .take(ExperimentTable::from_file(&cfg.protocol.experiments_file))
            .map(|mut t| {
                cfg.protocol.apply_timing(&mut t.timing);
                t
            });
        let subject = c.take(Subject::from_file(&cfg.subject_file));
        if let Some(t) = &table {
            cfg.check_against_table(&c, t);
        }
        if let Some(s) = &subject {
            for (i, n) in cfg.protocol.experiments.iter().enumerate() {
                if s.get(*n).is_none() {
                    c.note(
                        "subject_file",
                        format!(
                            "{} has no impedance for experiment {n} (protocol.experiments[{i}])",
                            cfg.subject_file.display()
                        ),
                    );
                }
            }
        }
        if let Some((key, n)) = cfg.held_experiment() {
            let in_table = table.as_ref().is_none_or(|t| t.get(n).is_some());
            let in_subject = subject.as_ref().is_none_or(|s| s.get(n).is_some());
            if !(in_table && in_subject) {
                c.note(
                    key,
                    format!(
                        "experiment {n} must be in both {} and {}",
                        cfg.protocol.experiments_file.display(),
                        cfg.subject_file.display()
                    ),
                );
            }
        }
        c.finish()?;
        cfg.experiments = table;
        cfg.subject = subject;
        Ok(cfg)
    }

    /// The experiment whose stiffness the subject holds throughout, with its
    /// key: `voluntary.experiment` or `release.experiment` in those modes.
    fn held_experiment(&self) -> Option<(&'static str, u32)> {
        match self.protocol.mode {
            ProtocolMode::Voluntary => self
                .voluntary
                .map(|v| ("voluntary.experiment", v.experiment)),
            ProtocolMode::Release => self.release.map(|r| ("release.experiment", r.experiment)),
            ProtocolMode::Identification | ProtocolMode::Multisine => None,
        }
    }

    /// Whether the controller listens to the identifier's estimates: to
    /// adopt its recommended f (`controller.adopt_recommended_f`) or to end
    /// an analysis window once K and H are known (`protocol.stop_when`). In
    /// lockstep the plant then paces itself to the identifier as to the
    /// recorder, so the estimates reach the controller at the same tick in
    /// every run.
    pub fn controller_hears_identifier(&self) -> bool {
        self.controller.adopt_recommended_f || self.protocol.stop_when.is_some()
    }

    /// The periods (1-based) each experiment of the run goes through.
    /// In multisine mode, one: the experiment's multisine periods all lie
    /// in its one protocol period.
    pub fn periods_run(&self, table: &ExperimentTable) -> Vec<u32> {
        if self.protocol.mode == ProtocolMode::Multisine {
            return vec![1];
        }
        match &self.protocol.periods {
            Some(p) => p.clone(),
            None => (1..=table.periods).collect(),
        }
    }

    /// The experiment table (always present after [`RunConfig::from_file`]).
    pub fn experiment_table(&self) -> &ExperimentTable {
        self.experiments
            .as_ref()
            .expect("RunConfig::from_file loads the experiment table")
    }

    /// The subject (always present after [`RunConfig::from_file`]).
    pub fn subject(&self) -> &Subject {
        self.subject
            .as_ref()
            .expect("RunConfig::from_file loads the subject")
    }

    /// How long a lockstep process polls before sleeping (`run.lockstep_spin_us`);
    /// zero in real time.
    pub fn lockstep_spin(&self) -> std::time::Duration {
        match self.run.timing {
            TimingMode::Lockstep => {
                std::time::Duration::from_secs_f64(self.run.lockstep_spin_us.max(0.0) * 1e-6)
            }
            TimingMode::Realtime => std::time::Duration::ZERO,
        }
    }

    /// Exoskeleton inertia with `load_kg` at the load lever arm (kg·m²): `M_e`.
    pub fn exo_inertia_kg_m2(&self, load_kg: f64) -> f64 {
        exo_impedance::exo_inertia_kg_m2(
            self.rig.arm_inertia_kg_m2,
            load_kg,
            self.rig.load_lever_arm_m,
        )
    }
}
