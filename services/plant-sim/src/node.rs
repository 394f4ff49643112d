//! The plant simulator as a node: a plain type stepped tick by tick, with
//! no IPC inside. The process (`main.rs`) and the in-process simulation
//! (`exo-sim`) both drive it the same way, once per control period:
//!
//! 1. [`PlantNode::on_protocol`] for every protocol state that has arrived
//!    (the subject's impedance, the running sine, the load follow it);
//! 2. [`PlantNode::frame`]: the raw bus frame of this tick;
//! 3. [`PlantNode::on_motor`] with the motor command answering it, then
//!    [`PlantNode::advance`] one control period.
//!
//! In lockstep the frame's time stamp is the tick times the period
//! ([`PlantNode::lockstep_stamp_ns`]), so a run is a function of its
//! configuration and seed.

use exo_config::{ProtocolMode, ReleaseSettings, RunConfig, Subject, TimingMode};
use exo_messages::bus_status::DRIVE_FAULT;
use exo_messages::{BusMotorCommand, BusSensorFrame, ProtocolPhase, ProtocolState};
use tracing::{info, warn};

use crate::model::PostureReference;
use crate::{Plant, PlantModel, PlantTruth, PostureDrive};

/// Why a plant node cannot be built from a run configuration.
#[derive(Debug, thiserror::Error)]
#[error("{model}: integration.step_s = {step_s} does not divide the control period {period_s} s")]
pub struct StepMismatch {
    /// The plant model file.
    pub model: String,
    /// Its integration step (s).
    pub step_s: f64,
    /// The run's control period (s).
    pub period_s: f64,
}

/// The simulated hardware, one control period per tick.
pub struct PlantNode {
    plant: Plant,
    drive: PostureDrive,
    subject: Subject,
    release: Option<ReleaseSettings>,
    released: bool,
    protocol: ProtocolState,
    /// `protocol`'s phase, decoded once on arrival; an unknown code counts
    /// as [`ProtocolPhase::Idle`].
    phase: ProtocolPhase,
    period_s: f64,
    period_ns: u64,
    tick: u64,
    max_ticks: Option<u64>,
    tau_motor_nm: f64,
    inject_fault_at: Option<u64>,
    watchdog: DriveWatchdog,
    /// What the subject's reference does, with what a subject that holds
    /// its goal needs: the goal, the plant's default stiffness, and the
    /// controller's gravity compensation (`None` when off).
    posture: PostureGoal,
}

/// What a subject that holds its goal ([`PostureReference::HoldsGoal`])
/// knows: the goal, its default stiffness and what the controller
/// compensates of gravity.
struct PostureGoal {
    reference: PostureReference,
    goal_rad: f64,
    default_stiffness_nm_per_rad: f64,
    compensation: Option<exo_config::RigSettings>,
}

/// The simulated drive's watchdog (as an EtherCAT drive's sync-manager
/// watchdog, `safety.drive_watchdog_ms`): in real time, a drive that gets no
/// motor command for longer than its limit applies zero torque and reports
/// `DRIVE_FAULT` in every frame until it is disabled and enabled again
/// (a command with `enable = 0`, then one with `enable = 1`; the sensor
/// driver sends that pair on an operator reset). In lockstep the plant
/// waits for every answer, so there is no watchdog.
#[derive(Debug, Clone, Copy, PartialEq)]
struct DriveWatchdog {
    /// Ticks without a command allowed (`None`: lockstep, no watchdog).
    limit_ticks: Option<u64>,
    ticks_without_command: u64,
    fault: bool,
    disabled_since_fault: bool,
}

impl PlantNode {
    /// The plant of run `cfg` with plant model `model`. `inject_fault_at`
    /// (tests): from that tick on the cuff sensor reads NaN.
    pub fn new(
        cfg: &RunConfig,
        model: &PlantModel,
        inject_fault_at: Option<u64>,
    ) -> Result<Self, StepMismatch> {
        let period_s = 1.0 / cfg.run.rate_hz;
        let steps = period_s / model.integration.step_s;
        if (steps - steps.round()).abs() > 1e-9 {
            return Err(StepMismatch {
                model: cfg.plant_model.display().to_string(),
                step_s: model.integration.step_s,
                period_s,
            });
        }
        let mut plant = Plant::new(model);
        let subject = cfg.subject().clone();
        let voluntary = match (cfg.protocol.mode, cfg.voluntary) {
            (ProtocolMode::Voluntary, Some(v)) => Some(v),
            _ => None,
        };
        let drive = PostureDrive::new(
            model.human.rest_angle_rad,
            model.human.active_angle_rad,
            voluntary.map(|v| (v.amplitude_rad, v.omega_rad_s)),
        );
        let set_impedance = |plant: &mut Plant, experiment: u32| {
            if let Some(e) = subject.get(experiment) {
                plant.set_human_impedance(e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
            }
        };
        if let Some(v) = voluntary {
            set_impedance(&mut plant, v.experiment);
            plant.set_excitation_omega(v.omega_rad_s);
        }
        // Spring-release test: the springs pull until the analysis phase starts.
        let release = cfg
            .release
            .filter(|_| cfg.protocol.mode == ProtocolMode::Release);
        if let Some(r) = release {
            set_impedance(&mut plant, r.experiment);
            plant.set_external_torque_nm(r.spring_torque_nm);
        }
        Ok(PlantNode {
            plant,
            drive,
            subject,
            release,
            released: false,
            protocol: ProtocolState::default(),
            phase: ProtocolPhase::Idle,
            period_s,
            period_ns: (period_s * 1e9).round() as u64,
            tick: 0,
            max_ticks: cfg.run.max_sim_time_s.map(|t| (t / period_s).ceil() as u64),
            tau_motor_nm: 0.0,
            inject_fault_at,
            posture: PostureGoal {
                reference: model.human.posture_reference,
                goal_rad: model.human.active_angle_rad,
                default_stiffness_nm_per_rad: model.human.stiffness_nm_per_rad,
                compensation: cfg.controller.gravity_compensation.then_some(cfg.rig),
            },
            watchdog: DriveWatchdog {
                limit_ticks: (cfg.run.timing == TimingMode::Realtime)
                    .then(|| (cfg.safety.drive_watchdog_ms * 1e-3 / period_s).ceil() as u64),
                ticks_without_command: 0,
                fault: false,
                disabled_since_fault: false,
            },
        })
    }

    /// Takes a protocol state: a new experiment sets the subject's
    /// impedance, a running sine its frequency (B_eq = H/ω follows it;
    /// without one, as in voluntary motion or a spring release, the plant
    /// keeps its setting), a load its mass.
    pub fn on_protocol(&mut self, p: &ProtocolState) {
        let now = (p.experiment, p.omega, p.load_kg);
        let before = (
            self.protocol.experiment,
            self.protocol.omega,
            self.protocol.load_kg,
        );
        if p.experiment != self.protocol.experiment {
            self.plant.start_experiment_clock();
        }
        if now != before {
            if let Some(e) = self.subject.get(p.experiment) {
                self.plant
                    .set_human_impedance(e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
            }
            if p.omega > 0.0 && p.amplitude > 0.0 {
                self.plant.set_excitation_omega(p.omega);
            }
            if p.load_kg > 0.0 {
                self.plant.set_load_kg(p.load_kg);
            }
        }
        if self.posture.reference == PostureReference::HoldsGoal {
            let offset = self.goal_offset_rad(p);
            self.drive.set_goal_offset(offset);
        }
        self.protocol = *p;
        self.phase = p.protocol_phase().unwrap_or(ProtocolPhase::Idle);
    }

    /// The reference offset a subject that holds its goal sets for period
    /// `p` (rad): `−(bias + τ_comp − τ_gravity)/(α K)` at the goal, the
    /// torque its spring must carry there over its stiffness (the
    /// amplifier's static gain taken as `α − 1`; `α ≤ 0` counts as 1).
    fn goal_offset_rad(&self, p: &ProtocolState) -> f64 {
        let goal = self.posture.goal_rad;
        let k = self
            .subject
            .get(p.experiment)
            .map_or(self.posture.default_stiffness_nm_per_rad, |e| {
                e.stiffness_nm_per_rad
            });
        let load = if p.load_kg > 0.0 {
            p.load_kg
        } else {
            self.plant.load_kg()
        };
        let compensated = self
            .posture
            .compensation
            .map_or(0.0, |r| r.gravity_torque_nm(goal, load));
        let alpha = if p.alpha > 0.0 { p.alpha } else { 1.0 };
        let offset = -(p.bias_nm + compensated - self.plant.gravity_torque(goal)) / (alpha * k);
        if offset.is_finite() {
            offset
        } else {
            0.0
        }
    }

    /// The raw bus frame of the current tick, stamped `stamp_ns`. In a
    /// spring-release run the springs come off when the analysis phase
    /// starts.
    pub fn frame(&mut self, stamp_ns: u64) -> BusSensorFrame {
        if self.release.is_some() && !self.released && self.phase == ProtocolPhase::Analysis {
            self.plant.set_external_torque_nm(0.0);
            self.released = true;
            info!(
                "plant-sim: springs released at sim {:.3} s",
                self.plant.truth().t_s
            );
        }
        let raw = self.plant.raw_sensors();
        let mut cuff_wrench = raw.cuff_wrench;
        if self.inject_fault_at.is_some_and(|n| self.tick >= n) {
            cuff_wrench[1] = f64::NAN;
        }
        BusSensorFrame {
            seq: self.tick,
            stamp_ns,
            encoder_counts: raw.encoder_counts,
            cuff_wrench,
            sea_deflection_counts: raw.sea_deflection_counts,
            status: if self.watchdog.fault { DRIVE_FAULT } else { 0 },
            _pad: 0,
        }
    }

    /// Takes a motor command; returns whether it answers the current tick's
    /// frame (an older one is ignored). A disabled motor gives no torque.
    pub fn on_motor(&mut self, cmd: &BusMotorCommand) -> bool {
        let answers = cmd.frame_seq == self.tick;
        if answers {
            self.hold_motor(cmd);
        }
        answers
    }

    /// Takes a motor command whatever frame it answers (real time: the
    /// latest command is held until the next).
    pub fn hold_motor(&mut self, cmd: &BusMotorCommand) {
        let d = &mut self.watchdog;
        d.ticks_without_command = 0;
        if d.fault {
            if cmd.enable == 0 {
                d.disabled_since_fault = true;
            } else if d.disabled_since_fault {
                d.fault = false;
                info!("plant-sim: drive fault reset (disabled, then enabled)");
            }
        }
        self.tau_motor_nm = if cmd.enable != 0 && !d.fault {
            cmd.tau_motor_nm
        } else {
            0.0
        };
    }

    /// The motor torque (Nm) the drive applies now.
    pub fn tau_motor_nm(&self) -> f64 {
        self.tau_motor_nm
    }

    /// Whether the drive's watchdog has tripped (torque off, `DRIVE_FAULT`).
    pub fn drive_fault(&self) -> bool {
        self.watchdog.fault
    }

    /// Advances one control period with the motor torque held, the subject
    /// following the protocol's phase.
    pub fn advance(&mut self) {
        let d = &mut self.watchdog;
        if let Some(limit) = d.limit_ticks {
            d.ticks_without_command += 1;
            if d.ticks_without_command > limit && !d.fault {
                d.fault = true;
                d.disabled_since_fault = false;
                self.tau_motor_nm = 0.0;
                warn!(
                    "plant-sim: drive watchdog: no motor command for {} ticks; torque off, DRIVE_FAULT until the drive is disabled and enabled again",
                    d.ticks_without_command
                );
            }
        }
        self.plant
            .set_drive(self.drive.update(self.period_s, self.phase));
        self.plant.advance(self.period_s, self.tau_motor_nm);
        self.tick += 1;
    }

    /// Ticks advanced so far (the next frame's `seq`).
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// The control period (ns).
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// The time stamp of the current tick in lockstep: tick × period.
    pub fn lockstep_stamp_ns(&self) -> u64 {
        self.tick * self.period_ns
    }

    /// Whether the run's bound (`run.max_sim_time_s`) is reached.
    pub fn finished(&self) -> bool {
        self.max_ticks.is_some_and(|m| self.tick >= m)
    }

    /// The plant (its present settings).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The simulated physical state (ground truth, not a measurement).
    pub fn truth(&self) -> PlantTruth {
        self.plant.truth()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(timing: TimingMode) -> PlantNode {
        let mut cfg =
            RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        cfg.run.timing = timing;
        cfg.safety.drive_watchdog_ms = 10.0;
        let model = PlantModel::from_file(&cfg.plant_model).unwrap();
        PlantNode::new(&cfg, &model, None).unwrap()
    }

    fn motor(node: &PlantNode, tau: f64, enable: u32) -> BusMotorCommand {
        BusMotorCommand {
            frame_seq: node.tick(),
            tau_motor_nm: tau,
            enable,
            ..Default::default()
        }
    }

    #[test]
    fn the_drive_watchdog_zeroes_the_torque_until_the_drive_is_disabled_and_enabled() {
        let mut n = node(TimingMode::Realtime);
        for _ in 0..5 {
            n.frame(0);
            let m = motor(&n, 2.0, 1);
            n.hold_motor(&m);
            n.advance();
        }
        assert_eq!(n.tau_motor_nm(), 2.0);
        // The last command's tick and 9 more (10 ms at 1 kHz since that
        // command) are within the watchdog ...
        for _ in 0..9 {
            assert_eq!(n.frame(0).status, 0);
            n.advance();
        }
        assert!(!n.drive_fault());
        assert_eq!(n.tau_motor_nm(), 2.0);
        // ... an 11th millisecond is not.
        n.advance();
        assert!(n.drive_fault());
        assert_eq!(n.frame(0).status, DRIVE_FAULT);
        assert_eq!(n.tau_motor_nm(), 0.0);
        // Commands alone do not clear it.
        let m = motor(&n, 3.0, 1);
        n.hold_motor(&m);
        assert!(n.drive_fault());
        assert_eq!(n.tau_motor_nm(), 0.0);
        // Disabled, then enabled: cleared, and the torque follows again.
        let m = motor(&n, 3.0, 0);
        n.hold_motor(&m);
        assert!(n.drive_fault());
        let m = motor(&n, 3.0, 1);
        n.hold_motor(&m);
        assert!(!n.drive_fault());
        assert_eq!(n.tau_motor_nm(), 3.0);
        assert_eq!(n.frame(0).status, 0);
    }

    fn state(
        experiment: u32,
        phase: ProtocolPhase,
        omega: f64,
        amplitude: f64,
        load_kg: f64,
    ) -> ProtocolState {
        ProtocolState {
            experiment,
            period: 1,
            phase: phase.as_u32(),
            omega,
            amplitude,
            load_kg,
            ..Default::default()
        }
    }

    #[test]
    fn the_protocol_sets_the_subjects_impedance_the_sine_and_the_load() {
        let mut n = node(TimingMode::Lockstep);
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        let subject = cfg.subject();
        let (e1, e7) = (subject.get(1).unwrap(), subject.get(7).unwrap());
        let before = n.plant().human_impedance();
        assert_ne!(n.plant().load_kg(), 2.5, "the model's own load differs");
        n.on_protocol(&state(1, ProtocolPhase::Analysis, 2.0, 2.0, 2.5));
        assert_ne!(before, n.plant().human_impedance());
        assert_eq!(
            n.plant().human_impedance(),
            (e1.stiffness_nm_per_rad, e1.hysteretic_damping_nm_per_rad)
        );
        assert_eq!(n.plant().excitation_omega_rad_s(), 2.0);
        assert_eq!(n.plant().load_kg(), 2.5);
        // Another experiment without a sine (amplitude 0) and without a
        // load: the impedance follows, the sine and the load are kept.
        n.on_protocol(&state(7, ProtocolPhase::RampIn, 8.0, 0.0, 0.0));
        assert_eq!(
            n.plant().human_impedance(),
            (e7.stiffness_nm_per_rad, e7.hysteretic_damping_nm_per_rad)
        );
        assert_eq!(n.plant().excitation_omega_rad_s(), 2.0);
        assert_eq!(n.plant().load_kg(), 2.5);
        // ω without amplitude or amplitude without ω is no sine either.
        n.on_protocol(&state(7, ProtocolPhase::Settling, 0.0, 2.0, 2.5));
        assert_eq!(n.plant().excitation_omega_rad_s(), 2.0);
        n.on_protocol(&state(7, ProtocolPhase::Analysis, 4.0, 2.0, 2.5));
        assert_eq!(n.plant().excitation_omega_rad_s(), 4.0);
        // The same experiment, sine and load again change nothing, even
        // when the plant was set otherwise meanwhile.
        n.plant.set_human_impedance(99.0, 1.0);
        n.on_protocol(&state(7, ProtocolPhase::RampOut, 4.0, 2.0, 2.5));
        assert_eq!(n.plant().human_impedance(), (99.0, 1.0));
        // An experiment the subject has no row for leaves the impedance.
        n.on_protocol(&state(0, ProtocolPhase::Idle, 4.0, 2.0, 2.5));
        assert_eq!(n.plant().human_impedance(), (99.0, 1.0));
    }

    /// The human's stiffness drift counts from an experiment's start: the
    /// protocol's other states within it (periods, phases) leave its
    /// clock running; a new experiment restarts it.
    #[test]
    fn the_experiment_clock_restarts_only_with_a_new_experiment() {
        let mut n = node(TimingMode::Lockstep);
        n.on_protocol(&state(1, ProtocolPhase::RampIn, 2.0, 2.0, 2.5));
        for _ in 0..100 {
            n.advance();
        }
        let period_s = n.period_ns() as f64 * 1e-9;
        let ran = n.plant().experiment_elapsed_s();
        assert!((ran - 100.0 * period_s).abs() < 1e-9, "{ran} s");
        n.on_protocol(&state(1, ProtocolPhase::Analysis, 4.0, 2.0, 2.5));
        assert_eq!(n.plant().experiment_elapsed_s(), ran);
        n.on_protocol(&state(7, ProtocolPhase::RampIn, 4.0, 2.0, 2.5));
        assert_eq!(n.plant().experiment_elapsed_s(), 0.0);
    }

    #[test]
    fn frames_carry_the_tick_and_the_stamp_and_an_injected_fault_from_its_tick() {
        let mut cfg =
            RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        cfg.run.timing = TimingMode::Lockstep;
        let model = PlantModel::from_file(&cfg.plant_model).unwrap();
        let mut n = PlantNode::new(&cfg, &model, Some(3)).unwrap();
        for k in 0..6u64 {
            let f = n.frame(n.lockstep_stamp_ns());
            assert_eq!((f.seq, f.stamp_ns), (k, k * 1_000_000));
            assert_eq!(f.cuff_wrench[1].is_nan(), k >= 3, "tick {k}");
            let m = motor(&n, 0.0, 1);
            assert!(n.on_motor(&m));
            n.advance();
        }
        assert_eq!(n.frame(42).stamp_ns, 42, "the stamp is the caller's");
    }

    #[test]
    fn only_the_answer_to_the_current_frame_drives_the_motor() {
        let mut n = node(TimingMode::Lockstep);
        n.advance();
        n.advance();
        let stale = BusMotorCommand {
            frame_seq: 1,
            tau_motor_nm: 5.0,
            enable: 1,
            ..Default::default()
        };
        assert!(!n.on_motor(&stale));
        assert_eq!(n.tau_motor_nm(), 0.0);
        let answer = BusMotorCommand {
            frame_seq: 2,
            ..stale
        };
        assert!(n.on_motor(&answer));
        assert_eq!(n.tau_motor_nm(), 5.0);
        let disabled = BusMotorCommand {
            enable: 0,
            ..answer
        };
        assert!(n.on_motor(&disabled));
        assert_eq!(n.tau_motor_nm(), 0.0);
    }

    #[test]
    fn the_springs_pull_until_the_analysis_phase_starts() {
        let mut cfg =
            RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        cfg.protocol.mode = ProtocolMode::Release;
        cfg.release = Some(ReleaseSettings {
            experiment: 7,
            spring_torque_nm: 3.0,
            hold_s: 1.0,
            observe_s: 1.0,
        });
        let model = PlantModel::from_file(&cfg.plant_model).unwrap();
        let mut n = PlantNode::new(&cfg, &model, None).unwrap();
        let e7 = cfg.subject().get(7).unwrap();
        assert_eq!(
            n.plant().human_impedance(),
            (e7.stiffness_nm_per_rad, e7.hysteretic_damping_nm_per_rad)
        );
        for phase in [ProtocolPhase::RampIn, ProtocolPhase::Settling] {
            n.on_protocol(&state(7, phase, 0.0, 0.0, 0.0));
            n.frame(0);
            assert_eq!(n.plant().external_torque_nm(), 3.0, "{phase:?}");
        }
        n.on_protocol(&state(7, ProtocolPhase::Analysis, 0.0, 0.0, 0.0));
        n.frame(0);
        assert_eq!(n.plant().external_torque_nm(), 0.0);
        // Released once: a later analysis phase does not put them back.
        n.on_protocol(&state(7, ProtocolPhase::RampOut, 0.0, 0.0, 0.0));
        n.frame(0);
        assert_eq!(n.plant().external_torque_nm(), 0.0);
        // Without the release protocol, no springs at all.
        let mut plain = node(TimingMode::Lockstep);
        plain.on_protocol(&state(7, ProtocolPhase::Analysis, 0.0, 0.0, 0.0));
        plain.frame(0);
        assert_eq!(plain.plant().external_torque_nm(), 0.0);
    }

    #[test]
    fn a_tick_is_one_control_period_and_the_bound_ends_the_run() {
        let mut cfg =
            RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        cfg.run.max_sim_time_s = Some(0.005);
        let model = PlantModel::from_file(&cfg.plant_model).unwrap();
        let mut n = PlantNode::new(&cfg, &model, None).unwrap();
        assert_eq!(n.period_ns(), 1_000_000, "1 kHz");
        for k in 0..5 {
            assert!(!n.finished(), "tick {k}");
            assert_eq!(n.lockstep_stamp_ns(), k * 1_000_000);
            let t0 = n.truth().t_s;
            n.advance();
            assert!((n.truth().t_s - t0 - 1e-3).abs() < 1e-12);
        }
        assert!(n.finished(), "0.005 s = 5 ticks");
        // Without a bound the run never ends by the plant.
        let mut unbounded = node(TimingMode::Lockstep);
        for _ in 0..10 {
            unbounded.advance();
        }
        assert!(!unbounded.finished());
    }

    #[test]
    fn in_lockstep_there_is_no_watchdog() {
        let mut n = node(TimingMode::Lockstep);
        for _ in 0..1000 {
            n.advance();
        }
        assert!(!n.drive_fault());
        assert_eq!(n.frame(0).status, 0);
    }
}
