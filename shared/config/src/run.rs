//! The run file: what `exo run` starts and how every process is set up.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{read_toml, Check, ExperimentTable, ProtocolTiming, Result, Subject};

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
    pub rate_hz: f64,
    /// Seed of every random source (sensor noise); same seed ⇒ same run in lockstep.
    pub seed: u64,
    /// Prefix of this run's iceoryx2 service names, so runs do not collide.
    #[serde(default = "default_instance")]
    pub instance: String,
    /// Stop after this much simulated time (s), if set; otherwise at protocol end.
    #[serde(default)]
    pub max_sim_time_s: Option<f64>,
    /// Directory for recordings and reports (relative to the working directory).
    #[serde(default = "default_output_dir")]
    pub output_dir: PathBuf,
    /// In lockstep, how long (µs) a process polls for the next message,
    /// yielding the CPU between polls, before it sleeps in the kernel; a
    /// kernel wake-up costs tens of µs per hand-over, four per tick.
    /// Default 0: never polls, every wait sleeps on the iceoryx2 event (no
    /// busy loop by default); 200 makes lockstep about three times faster on
    /// two cores (BENCHMARKS.md). Ignored in real time (which always sleeps).
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
    /// Lock all current and future memory (`mlockall`), so no page fault stalls a tick.
    #[serde(default)]
    pub lock_memory: bool,
    /// Pin the controller to this CPU.
    #[serde(default)]
    pub controller_cpu: Option<usize>,
    /// Pin the sensor driver to this CPU.
    #[serde(default)]
    pub sensor_driver_cpu: Option<usize>,
    /// Pin the plant simulator to this CPU.
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
    /// A recording played back (`bus.replay_file`): re-run the identifier
    /// and the recorder on old data; no controller, nothing actuated.
    Replay,
}

/// `[bus]`: the sensor driver's hardware bus. Swapping the simulator for
/// hardware is this setting plus `services.plant_sim = false`; see
/// ARCHITECTURE.md for where a new backend plugs in.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusSettings {
    /// The backend.
    pub backend: BusBackend,
    /// The recording to play back (`backend = "replay"`; relative to the run file).
    #[serde(default)]
    pub replay_file: Option<PathBuf>,
    /// Frames per second of wall time a replay delivers (default 5000).
    #[serde(default)]
    pub replay_pace_hz: Option<f64>,
}

/// `[services]`: which processes `exo run` starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceSet {
    /// The plant simulator (the physical world).
    pub plant_sim: bool,
    /// The sensor driver (owns the actuator).
    pub sensor_driver: bool,
    /// The controller.
    pub controller: bool,
    /// The online identifier.
    #[serde(default)]
    pub identifier: bool,
    /// The MCAP recorder.
    #[serde(default)]
    pub recorder: bool,
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
}

/// `[protocol]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolSettings {
    /// Mode.
    pub mode: ProtocolMode,
    /// Experiment table (relative to the run file).
    pub experiments_file: PathBuf,
    /// Which experiments to run, in order.
    pub experiments: Vec<u32>,
    /// Which periods of each (1-based); all when absent.
    #[serde(default)]
    pub periods: Option<Vec<u32>>,
    /// Override of the rest between periods (s), so simulations need not wait 40 s.
    #[serde(default)]
    pub rest_s: Option<f64>,
    /// Override of the bias ramp-in (s); the paper: 5.
    #[serde(default)]
    pub ramp_in_s: Option<f64>,
    /// Override of the settling part of the sine (s); the paper: 5.
    #[serde(default)]
    pub settling_s: Option<f64>,
    /// Override of the analysis window (s); the paper: 5.
    #[serde(default)]
    pub analysis_s: Option<f64>,
    /// Override of the bias ramp-out (s); the paper: 5.
    #[serde(default)]
    pub ramp_out_s: Option<f64>,
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

    /// Applies the overrides to the experiment table's timing.
    pub fn apply_timing(&self, timing: &mut ProtocolTiming) {
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
    /// Target angle amplitude (rad).
    pub amplitude_rad: f64,
    /// Target frequency (rad/s).
    pub omega_rad_s: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// Grip (kg) and bias (Nm) held meanwhile (the paper: 14 kg, 4 Nm).
    pub grip_kg: f64,
    /// Bias torque (Nm).
    pub bias_nm: f64,
    /// Experiment whose stiffness the subject holds.
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
    /// Experiment of Table I whose stiffness, grip, bias and load the subject holds.
    pub experiment: u32,
    /// Torque (Nm) the attached springs exert on the exoskeleton joint (positive = raising).
    pub spring_torque_nm: f64,
    /// Time (s) the spring stays attached after the bias has ramped in.
    pub hold_s: f64,
    /// Time (s) observed after the release.
    pub observe_s: f64,
}

/// `[controller]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSettings {
    /// Proportional gain k_p; eq. kp from the rig and subject inertias when absent.
    #[serde(default)]
    pub kp: Option<f64>,
    /// Fractional order f in [0, 1); when absent, α is the experiment's constant.
    #[serde(default)]
    pub f: Option<f64>,
    /// Stiffness range (Nm/rad) for k_f (eq. kf).
    pub k_range_nm_per_rad: [f64; 2],
    /// Number of lag filters.
    pub filters: usize,
    /// First pole (rad/s).
    pub p1_rad_s: f64,
    /// Pole spacing.
    pub r_pp: f64,
    /// Adopt the identifier's recommended f when it is published.
    #[serde(default)]
    pub adopt_recommended_f: bool,
    /// Bounds within which a recommended f may be adopted.
    #[serde(default = "default_f_bounds")]
    pub f_bounds: [f64; 2],
    /// Torque and rate limits.
    pub limits: LimitSettings,
    /// Compensate gravity with the rig model (off for a rig moving in a horizontal plane).
    #[serde(default = "default_true")]
    pub gravity_compensation: bool,
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
    /// |τ_d| limit (Nm); every command is clamped to it.
    pub torque_nm: f64,
    /// |dτ_d/dt| limit (Nm/s).
    pub torque_rate_nm_per_s: f64,
    /// Allowed joint angle range (rad); outside it the controller faults.
    pub theta_rad: [f64; 2],
    /// |τ_c| above this (Nm) is a sensor fault.
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
    /// The driver drops to the safe state when no fresh command arrives within this (ms).
    pub command_deadline_ms: f64,
    /// The controller faults when no sample arrives within this (ms).
    pub sample_deadline_ms: f64,
    /// What the safe state commands.
    pub safe_state: SafeState,
    /// In lockstep, simulated time stands still while a process waits, so
    /// deadlines are counted in ticks: a missing answer is declared after
    /// this much wall time (ms), and the safe state then takes effect at the
    /// same simulated tick.
    #[serde(default = "default_lockstep_timeout_ms")]
    pub lockstep_timeout_ms: f64,
}

fn default_lockstep_timeout_ms() -> f64 {
    1000.0
}

/// `[rig]`: what the software believes about the hardware (calibration and
/// gravity model). The plant model holds the truth; they may differ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigSettings {
    /// Exoskeleton arm inertia without load (kg·m²); the paper: 0.1.
    pub arm_inertia_kg_m2: f64,
    /// Arm mass (kg) and centre-of-mass distance (m) for gravity compensation.
    pub arm_mass_kg: f64,
    /// Arm centre of mass from the joint (m).
    pub arm_com_m: f64,
    /// Where the load hangs (m); the paper: 0.45.
    pub load_lever_arm_m: f64,
    /// Encoder counts per revolution.
    pub encoder_counts_per_rev: f64,
    /// Cuff F/T sensor distance from the joint (m): τ_c = r·f_y + t_z.
    pub cuff_lever_arm_m: f64,
    /// SEA spring stiffness (Nm/rad) and its deflection encoder resolution.
    pub sea_stiffness_nm_per_rad: f64,
    /// SEA deflection encoder counts per revolution.
    pub sea_counts_per_rev: f64,
    /// Velocity filter cut-off (Hz) of the driver's angle differentiator.
    pub velocity_cutoff_hz: f64,
}

/// Standard gravity (m/s²).
pub const GRAVITY_M_S2: f64 = 9.80665;

impl RigSettings {
    /// Gravity torque (Nm) on the exoskeleton arm and its load at joint angle
    /// `theta_rad` (0 = hanging straight down): `g (m_a l_a + m_L l_L) sin θ`.
    /// The controller adds it to cancel gravity; the driver uses it for the
    /// gravity-only safe state.
    pub fn gravity_torque_nm(&self, theta_rad: f64, load_kg: f64) -> f64 {
        GRAVITY_M_S2
            * (self.arm_mass_kg * self.arm_com_m + load_kg * self.load_lever_arm_m)
            * theta_rad.sin()
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

impl RunConfig {
    /// Reads, validates and resolves a run file and the files it names.
    pub fn from_file(file: &Path) -> Result<Self> {
        let mut cfg: RunConfig = read_toml(file)?;
        cfg.source = file.to_path_buf();
        cfg.validate(file)?;
        let dir = file.parent().unwrap_or(Path::new("."));
        cfg.plant_model = dir.join(&cfg.plant_model);
        cfg.subject_file = dir.join(&cfg.subject_file);
        cfg.protocol.experiments_file = dir.join(&cfg.protocol.experiments_file);
        if let Some(f) = cfg.bus.replay_file.as_mut() {
            *f = dir.join(&*f);
        }
        if cfg.bus.backend == BusBackend::Replay {
            let c = Check::new(file);
            match &cfg.bus.replay_file {
                None => {
                    return Err(c.fail(
                        "bus.replay_file",
                        "bus.backend = \"replay\" needs the recording to play back",
                    ))
                }
                Some(f) if !f.is_file() => {
                    return Err(c.fail("bus.replay_file", format!("{} does not exist", f.display())))
                }
                Some(_) => {}
            }
            if let Some(p) = cfg.bus.replay_pace_hz {
                c.within("bus.replay_pace_hz", p, 1.0, 1e6)?;
            }
        }
        let mut table = ExperimentTable::from_file(&cfg.protocol.experiments_file)?;
        cfg.protocol.apply_timing(&mut table.timing);
        let c = Check::new(file);
        for (i, n) in cfg.protocol.experiments.iter().enumerate() {
            if table.get(*n).is_none() {
                return Err(c.fail(
                    &format!("protocol.experiments[{i}]"),
                    format!(
                        "experiment {n} is not in {}; it has {:?}",
                        cfg.protocol.experiments_file.display(),
                        table
                            .experiment
                            .iter()
                            .map(|e| e.number)
                            .collect::<Vec<_>>()
                    ),
                ));
            }
        }
        if let Some(periods) = &cfg.protocol.periods {
            for (i, p) in periods.iter().enumerate() {
                if *p == 0 || *p > table.periods {
                    return Err(c.fail(
                        &format!("protocol.periods[{i}]"),
                        format!("period {p} is outside 1..={}", table.periods),
                    ));
                }
            }
        }
        let subject = Subject::from_file(&cfg.subject_file)?;
        for n in &cfg.protocol.experiments {
            if subject.get(*n).is_none() {
                return Err(c.fail(
                    "subject_file",
                    format!(
                        "{} has no impedance for experiment {n}",
                        cfg.subject_file.display()
                    ),
                ));
            }
        }
        let held = [
            cfg.voluntary
                .filter(|_| cfg.protocol.mode == ProtocolMode::Voluntary)
                .map(|v| ("voluntary.experiment", v.experiment)),
            cfg.release
                .filter(|_| cfg.protocol.mode == ProtocolMode::Release)
                .map(|r| ("release.experiment", r.experiment)),
        ];
        for (key, n) in held.into_iter().flatten() {
            if table.get(n).is_none() || subject.get(n).is_none() {
                return Err(c.fail(
                    key,
                    format!(
                        "experiment {n} must be in both {} and {}",
                        cfg.protocol.experiments_file.display(),
                        cfg.subject_file.display()
                    ),
                ));
            }
        }
        cfg.experiments = Some(table);
        cfg.subject = Some(subject);
        Ok(cfg)
    }

    /// Validates the values of the run file itself, naming the key at fault.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let c = Check::new(file);
        c.within("run.rate_hz", self.run.rate_hz, 1.0, 100_000.0)?;
        c.within(
            "run.lockstep_spin_us",
            self.run.lockstep_spin_us,
            0.0,
            100_000.0,
        )?;
        if let Some(t) = self.run.max_sim_time_s {
            c.positive("run.max_sim_time_s", t)?;
        }
        if self.run.instance.is_empty()
            || !self
                .run
                .instance
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
        {
            return Err(c.fail(
                "run.instance",
                "must be non-empty letters, digits, '-' or '_'",
            ));
        }
        for (key, v) in self.protocol.timing_overrides() {
            if let Some(v) = v {
                if key == "protocol.analysis_s" {
                    c.positive(key, v)?;
                } else {
                    c.non_negative(key, v)?;
                }
            }
        }
        if let Some(p) = self.realtime.and_then(|r| r.sched_fifo_priority) {
            if !(1..=99).contains(&p) {
                return Err(c.fail(
                    "realtime.sched_fifo_priority",
                    format!("must be 1 to 99, got {p}"),
                ));
            }
        }
        if self.protocol.experiments.is_empty() {
            return Err(c.fail("protocol.experiments", "name at least one experiment"));
        }
        if self.protocol.mode == ProtocolMode::Voluntary {
            let v = self.voluntary.ok_or_else(|| {
                c.fail(
                    "voluntary",
                    "protocol.mode = \"voluntary\" needs a [voluntary] table",
                )
            })?;
            c.non_negative("voluntary.amplitude_rad", v.amplitude_rad)?;
            c.positive("voluntary.omega_rad_s", v.omega_rad_s)?;
            c.positive("voluntary.duration_s", v.duration_s)?;
            c.non_negative("voluntary.grip_kg", v.grip_kg)?;
            c.finite("voluntary.bias_nm", v.bias_nm)?;
        }
        if self.protocol.mode == ProtocolMode::Release {
            let r = self.release.ok_or_else(|| {
                c.fail(
                    "release",
                    "protocol.mode = \"release\" needs a [release] table",
                )
            })?;
            c.finite("release.spring_torque_nm", r.spring_torque_nm)?;
            c.positive("release.hold_s", r.hold_s)?;
            c.positive("release.observe_s", r.observe_s)?;
        }
        let k = &self.controller;
        if let Some(kp) = k.kp {
            c.positive("controller.kp", kp)?;
        }
        if let Some(f) = k.f {
            c.finite("controller.f", f)?;
            if !(0.0..1.0).contains(&f) {
                return Err(c.fail("controller.f", format!("must lie in [0, 1), got {f}")));
            }
        }
        c.positive("controller.k_range_nm_per_rad[0]", k.k_range_nm_per_rad[0])?;
        c.positive("controller.k_range_nm_per_rad[1]", k.k_range_nm_per_rad[1])?;
        if k.k_range_nm_per_rad[0] > k.k_range_nm_per_rad[1] {
            return Err(c.fail(
                "controller.k_range_nm_per_rad",
                "the range is reversed (min > max)",
            ));
        }
        if k.filters == 0 || k.filters > 16 {
            return Err(c.fail(
                "controller.filters",
                format!("must be 1 to 16, got {}", k.filters),
            ));
        }
        c.positive("controller.p1_rad_s", k.p1_rad_s)?;
        c.finite("controller.r_pp", k.r_pp)?;
        if k.r_pp <= 1.0 {
            return Err(c.fail(
                "controller.r_pp",
                format!("must be greater than 1, got {}", k.r_pp),
            ));
        }
        c.within("controller.f_bounds[0]", k.f_bounds[0], 0.0, 0.999)?;
        c.within(
            "controller.f_bounds[1]",
            k.f_bounds[1],
            k.f_bounds[0],
            0.999,
        )?;
        c.positive("controller.limits.torque_nm", k.limits.torque_nm)?;
        c.positive(
            "controller.limits.torque_rate_nm_per_s",
            k.limits.torque_rate_nm_per_s,
        )?;
        c.finite("controller.limits.theta_rad[0]", k.limits.theta_rad[0])?;
        c.finite("controller.limits.theta_rad[1]", k.limits.theta_rad[1])?;
        if k.limits.theta_rad[0] >= k.limits.theta_rad[1] {
            return Err(c.fail(
                "controller.limits.theta_rad",
                "must be [min, max] with min < max",
            ));
        }
        c.positive("controller.limits.tau_c_nm", k.limits.tau_c_nm)?;
        let period_ms = 1000.0 / self.run.rate_hz;
        for (key, v) in [
            (
                "safety.command_deadline_ms",
                self.safety.command_deadline_ms,
            ),
            ("safety.sample_deadline_ms", self.safety.sample_deadline_ms),
        ] {
            c.positive(key, v)?;
            if v < period_ms {
                return Err(c.fail(
                    key,
                    format!(
                        "{v} ms is shorter than one control period ({period_ms} ms at {} Hz)",
                        self.run.rate_hz
                    ),
                ));
            }
        }
        c.positive(
            "safety.lockstep_timeout_ms",
            self.safety.lockstep_timeout_ms,
        )?;
        let r = &self.rig;
        c.positive("rig.arm_inertia_kg_m2", r.arm_inertia_kg_m2)?;
        c.non_negative("rig.arm_mass_kg", r.arm_mass_kg)?;
        c.non_negative("rig.arm_com_m", r.arm_com_m)?;
        c.non_negative("rig.load_lever_arm_m", r.load_lever_arm_m)?;
        c.positive("rig.encoder_counts_per_rev", r.encoder_counts_per_rev)?;
        c.positive("rig.cuff_lever_arm_m", r.cuff_lever_arm_m)?;
        c.positive("rig.sea_stiffness_nm_per_rad", r.sea_stiffness_nm_per_rad)?;
        c.positive("rig.sea_counts_per_rev", r.sea_counts_per_rev)?;
        c.positive("rig.velocity_cutoff_hz", r.velocity_cutoff_hz)?;
        if r.velocity_cutoff_hz >= self.run.rate_hz / 2.0 {
            return Err(c.fail(
                "rig.velocity_cutoff_hz",
                "must be below half the control rate",
            ));
        }
        Ok(())
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
        self.rig.arm_inertia_kg_m2 + load_kg * self.rig.load_lever_arm_m * self.rig.load_lever_arm_m
    }
}
