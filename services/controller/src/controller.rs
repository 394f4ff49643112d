//! One controller tick: validate the sample, advance the protocol clock,
//! compose and limit the desired torque, latch faults into the safe state.
//!
//! The operator's commands and the protocol's position they move are in
//! `controller/operator.rs` (a child module: it reads the controller's
//! fields), with their tests in `controller/operator/tests.rs`.

use exo_config::{
    ExperimentSpec, ExperimentTable, ProtocolMode, ProtocolTiming, RigSettings, RunConfig,
    SafeState,
};
use exo_impedance::loop_shaping::FractionalLayout;
use exo_messages::operator::SeenSeqs;
use exo_messages::ControlMode;
use thiserror::Error;

use crate::amplification::Amplifier;
use crate::protocol::{Protocol, ProtocolPoint};
use crate::safety::{Fault, FaultLatch, Limits};

mod operator;
mod stop_when;

pub use operator::{OperatorOutcome, OperatorRefusal, ProtocolRun};
pub use stop_when::StopNews;

/// Errors building a controller from a configuration.
#[derive(Debug, Error)]
pub enum ControllerError {
    /// The science core refused a design parameter.
    #[error("controller design: {0}")]
    Design(#[from] exo_impedance::ScienceError),
    /// A value the configuration must provide is missing.
    #[error("{0}")]
    Config(String),
}

/// One sensor sample, in physical units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TickInput {
    /// Sample sequence number; time is `(seq − first seq)/rate`.
    pub seq: u64,
    /// The sample's time stamp (ns): when it was taken, on the clock the
    /// identifier's estimates are stamped with (`protocol.stop_when`
    /// compares the two).
    pub stamp_ns: u64,
    /// θ_e (rad).
    pub theta_e_rad: f64,
    /// ω_e (rad/s).
    pub omega_e_rad_s: f64,
    /// τ_c (Nm), the torque the cuff applies to the human.
    pub tau_c_nm: f64,
    /// τ_s (Nm), the SEA spring torque.
    pub tau_s_nm: f64,
    /// The sample's status bits (`exo_messages::status`): a fault bit
    /// ([`status::FAULT_MASK`](exo_messages::status::FAULT_MASK)) or the
    /// driver's `SAFE_STATE` latches the controller's safe state, so the
    /// two never disagree.
    pub status: u32,
}

/// The controller's answer to one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// The sample answered.
    pub sensor_seq: u64,
    /// Protocol time (s).
    pub t_s: f64,
    /// Desired actuator torque after limits (Nm).
    pub tau_d_nm: f64,
    /// Gravity compensation part (Nm).
    pub tau_gravity_nm: f64,
    /// Amplification part (Nm).
    pub tau_amplification_nm: f64,
    /// Bias part (Nm).
    pub tau_bias_nm: f64,
    /// Excitation part (Nm).
    pub tau_excitation_nm: f64,
    /// What the controller is doing: `Run`, `SafeGravityOnly`,
    /// `SafeZeroTorque` or `Done` (it never answers a sample in `Idle` or
    /// `FaultLatched`); the wire's `ActuatorCommand::mode` as is.
    pub mode: ControlMode,
    /// The latched fault, if any.
    pub fault: Option<Fault>,
    /// Protocol state.
    pub protocol: ProtocolPoint,
}

impl Tick {
    /// Whether the protocol's time is over: in `Done`, or past its end with
    /// a fault latched (which holds the safe state instead of `Done`, and
    /// would otherwise keep the run going with nothing left to do; the
    /// driver holds its own safe state once the controller stops).
    pub fn protocol_over(&self) -> bool {
        self.protocol.done && self.mode != ControlMode::Run
    }
}

/// The controller.
#[derive(Debug, Clone)]
pub struct Controller {
    protocol: Protocol,
    run: ProtocolRun,
    operator_seqs: SeenSeqs,
    amplifier: Amplifier,
    limits: Limits,
    latch: FaultLatch,
    /// Whether the last sample carried the driver's `SAFE_STATE`.
    driver_was_safe: bool,
    rig: RigSettings,
    safe_state: SafeState,
    rate_hz: f64,
    first_seq: Option<u64>,
    /// Ticks (samples since the first) of the last tick answered.
    last_tick: Option<u64>,
    previous_tau_d_nm: f64,
    f_bounds: [f64; 2],
    /// What is needed to rebuild the fractional amplifier with a new f.
    design: FractionalLayout,
    gravity_compensation: bool,
    /// `protocol.stop_when` in ticks, when the run has it.
    stop_rule: Option<stop_when::StopRule>,
    /// The experiment whose K and H the latest estimate found known, and
    /// where that estimate's data end (its `stamp_ns`).
    known: Option<(u32, u64)>,
}

impl Controller {
    /// Builds the controller of a run configuration.
    pub fn from_config(cfg: &RunConfig) -> Result<Self, ControllerError> {
        let subject = cfg.subject();
        let (protocol, load_kg) = match cfg.protocol.mode {
            ProtocolMode::Identification | ProtocolMode::Multisine => {
                let table = cfg.experiment_table();
                let load = cfg
                    .protocol
                    .experiments
                    .first()
                    .and_then(|n| table.get(*n))
                    .map_or(0.0, |e| e.load_kg);
                let periods = cfg.periods_run(table);
                let protocol = Protocol::new(table, &cfg.protocol.experiments, Some(&periods));
                let protocol = match cfg.protocol.multisine() {
                    None => protocol,
                    Some(m) => {
                        let design = m
                            .design(cfg.run.rate_hz)
                            .map_err(|e| ControllerError::Config(e.to_string()))?;
                        protocol.with_multisine(&design, |e| m.peak_nm_of(table, e))
                    }
                };
                (protocol, load)
            }
            ProtocolMode::Voluntary => {
                let v = cfg.voluntary.ok_or_else(|| {
                    ControllerError::Config("voluntary mode needs [voluntary]".into())
                })?;
                let load = cfg
                    .experiment_table()
                    .get(v.experiment)
                    .map_or(4.5, |e| e.load_kg);
                let table = one_period_table(
                    v.duration_s / 2.0,
                    v.duration_s / 2.0,
                    v.grip_kg,
                    v.bias_nm,
                    load,
                    v.experiment,
                );
                (Protocol::new(&table, &[v.experiment], None), load)
            }
            ProtocolMode::Release => {
                let r = cfg.release.ok_or_else(|| {
                    ControllerError::Config("release mode needs [release]".into())
                })?;
                let spec = cfg
                    .experiment_table()
                    .get(r.experiment)
                    .copied()
                    .ok_or_else(|| {
                        ControllerError::Config(format!(
                            "release.experiment {} is not in the experiment table",
                            r.experiment
                        ))
                    })?;
                let table = one_period_table(
                    r.hold_s,
                    r.observe_s,
                    spec.grip_kg,
                    spec.bias_nm,
                    spec.load_kg,
                    r.experiment,
                );
                (Protocol::new(&table, &[r.experiment], None), spec.load_kg)
            }
        };
        let m_e = cfg.exo_inertia_kg_m2(load_kg);
        let design = cfg
            .controller
            .layout(m_e, subject.inertia_kg_m2)
            .map_err(|e| ControllerError::Design(e.source))?;
        let kp = design.kp;
        let amplifier = match cfg.controller.f {
            Some(f) => Amplifier::fractional(
                kp,
                f,
                design.omega_gc_hat_rad_s,
                design.filters,
                design.p1_rad_s,
                design.r_pp,
                cfg.run.rate_hz,
            )?,
            None => Amplifier::Constant { alpha: 1.0 },
        };
        Ok(Controller {
            protocol,
            run: ProtocolRun::Running {
                from_step: 0,
                since_tick: 0,
                skipped_ticks: 0,
            },
            operator_seqs: SeenSeqs::default(),
            amplifier,
            limits: Limits::new(&cfg.controller.limits, cfg.run.rate_hz),
            latch: FaultLatch::default(),
            driver_was_safe: false,
            rig: cfg.rig,
            safe_state: cfg.safety.safe_state,
            rate_hz: cfg.run.rate_hz,
            first_seq: None,
            last_tick: None,
            previous_tau_d_nm: 0.0,
            f_bounds: cfg.controller.f_bounds,
            design,
            gravity_compensation: cfg.controller.gravity_compensation,
            stop_rule: stop_when::StopRule::of_run(cfg),
            known: None,
        })
    }

    /// The protocol this controller runs.
    pub fn protocol(&self) -> &Protocol {
        &self.protocol
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.latch.fault()
    }

    /// Latches a fault detected outside a tick (e.g. a sample timeout).
    pub fn raise(&mut self, fault: Fault) {
        self.latch.raise(fault);
    }

    /// Clears a latched fault (operator command); the amplifier restarts from rest.
    pub fn reset_fault(&mut self) {
        self.latch.reset();
        self.amplifier.reset();
    }

    /// Switches to the fractional amplifier with order `f`, if within the
    /// configured bounds; returns whether it was adopted. Allocation-free.
    pub fn adopt_fractional_order(&mut self, f: f64) -> bool {
        if !(f.is_finite() && f >= self.f_bounds[0] && f <= self.f_bounds[1]) {
            return false;
        }
        let d = self.design;
        match Amplifier::fractional(
            d.kp,
            f,
            d.omega_gc_hat_rad_s,
            d.filters,
            d.p1_rad_s,
            d.r_pp,
            self.rate_hz,
        ) {
            Ok(a) => {
                self.amplifier = a;
                true
            }
            Err(_) => false,
        }
    }

    /// The amplifier in use (constant α, or the fractional order adopted).
    pub fn amplifier(&self) -> &Amplifier {
        &self.amplifier
    }

    /// Where the protocol is, as the operator left it.
    pub fn protocol_run(&self) -> ProtocolRun {
        self.run
    }
    /// Answers one sample. Allocation-free; the returned torque is always
    /// finite and within the torque and rate limits.
    pub fn tick(&mut self, s: &TickInput) -> Tick {
        let first = *self.first_seq.get_or_insert(s.seq);
        let tick = s.seq.saturating_sub(first);
        let t_s = tick as f64 / self.rate_hz;
        self.last_tick = Some(tick);
        self.validate(s);
        let (p, held) = self.protocol_at(tick, s.stamp_ns);
        let theta_for_gravity = if s.theta_e_rad.is_finite() {
            s.theta_e_rad
        } else {
            0.0
        };
        let gravity = if self.gravity_compensation {
            self.rig.gravity_torque_nm(theta_for_gravity, p.load_kg)
        } else {
            0.0
        };
        // The driver's latched safe state is followed, not latched here:
        // it lasts exactly as long as the driver's (an operator reset clears
        // both), so the two never disagree whichever hears the reset first.
        let driver_safe = s.status & exo_messages::status::SAFE_STATE != 0;
        if self.driver_was_safe && !driver_safe {
            self.amplifier.reset();
        }
        self.driver_was_safe = driver_safe;
        let (mode, tau_g, tau_a, tau_b, tau_x) = if self.latch.is_latched() || driver_safe {
            match self.safe_state {
                SafeState::GravityOnly => (ControlMode::SafeGravityOnly, gravity, 0.0, 0.0, 0.0),
                SafeState::ZeroTorque => (ControlMode::SafeZeroTorque, 0.0, 0.0, 0.0, 0.0),
            }
        } else if p.done {
            (ControlMode::Done, gravity, 0.0, 0.0, 0.0)
        } else if held {
            // Stopped by the operator: gravity compensation alone, no fault.
            (ControlMode::Run, gravity, 0.0, 0.0, 0.0)
        } else {
            self.amplifier.set_constant_alpha(p.alpha);
            let tau_a = self.amplifier.step(s.tau_c_nm);
            (
                ControlMode::Run,
                gravity,
                tau_a,
                p.tau_bias_nm,
                p.tau_excitation_nm,
            )
        };
        let tau_d = self
            .limits
            .clamp(tau_g + tau_a + tau_b + tau_x, self.previous_tau_d_nm);
        self.previous_tau_d_nm = tau_d;
        Tick {
            sensor_seq: s.seq,
            t_s,
            tau_d_nm: tau_d,
            tau_gravity_nm: tau_g,
            tau_amplification_nm: tau_a,
            tau_bias_nm: tau_b,
            tau_excitation_nm: tau_x,
            mode,
            fault: self
                .latch
                .fault()
                .or(driver_safe.then_some(Fault::DriverSafeState)),
            protocol: p,
        }
    }

    fn validate(&mut self, s: &TickInput) {
        for (field, v) in [
            ("theta_e", s.theta_e_rad),
            ("omega_e", s.omega_e_rad_s),
            ("tau_c", s.tau_c_nm),
            ("tau_s", s.tau_s_nm),
        ] {
            if !v.is_finite() {
                self.latch.raise(Fault::NonFiniteSample { field });
                return;
            }
        }
        if s.status & exo_messages::status::FAULT_MASK != 0 {
            self.latch.raise(Fault::SensorStatus { status: s.status });
        }
        let [lo, hi] = self.limits.theta_rad;
        if s.theta_e_rad < lo || s.theta_e_rad > hi {
            self.latch.raise(Fault::AngleOutOfRange {
                theta_rad: s.theta_e_rad,
            });
        }
        if s.tau_c_nm.abs() > self.limits.tau_c_nm {
            self.latch.raise(Fault::InteractionTorqueOutOfRange {
                tau_c_nm: s.tau_c_nm,
            });
        }
    }
}

/// A one-period protocol without perturbation (amplitude 0), for the
/// voluntary-motion experiments and the spring-release test: the bias ramps
/// in over 1 s, `settling_s` follow (the motion settles, or the spring stays
/// attached), then the `analysis_s` window (the second half of the motion,
/// or the response after the release), and the bias ramps out over 1 s.
fn one_period_table(
    settling_s: f64,
    analysis_s: f64,
    grip_kg: f64,
    bias_nm: f64,
    load_kg: f64,
    number: u32,
) -> ExperimentTable {
    ExperimentTable {
        periods: 1,
        amplitude_boost_from_period: 2,
        amplitude_boost: 1.0,
        frequency_step: 1.0,
        timing: ProtocolTiming {
            ramp_in_s: 1.0,
            settling_s,
            analysis_s,
            ramp_out_s: 1.0,
            rest_s: 0.0,
        },
        experiment: vec![ExperimentSpec {
            number,
            alpha: 1.0,
            load_kg,
            grip_kg,
            bias_nm,
            amplitude_nm: 0.0,
            start_omega_rad_s: 1.0,
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped default run (also the operator tests').
    pub(in crate::controller) fn cfg() -> RunConfig {
        RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap()
    }

    /// Sample `seq` at angle `theta` (rad) with `tau_c` (Nm) (also the operator tests').
    pub(in crate::controller) fn sample(seq: u64, theta: f64, tau_c: f64) -> TickInput {
        TickInput {
            seq,
            theta_e_rad: theta,
            omega_e_rad_s: 0.0,
            tau_c_nm: tau_c,
            tau_s_nm: 0.0,
            status: 0,
            ..Default::default()
        }
    }

    #[test]
    fn gravity_compensation_cancels_the_rig_model() {
        let c = cfg();
        let mut k = Controller::from_config(&c).unwrap();
        // Run long enough for the rate limiter to reach the target.
        let mut t = None;
        for seq in 0..200 {
            t = Some(k.tick(&sample(seq, 0.5, 0.0)));
        }
        let t = t.unwrap();
        let expected = c.rig.gravity_torque_nm(0.5, 4.5);
        assert!((t.tau_gravity_nm - expected).abs() < 1e-12);
        assert_eq!(t.mode, ControlMode::Run);
    }

    #[test]
    fn nan_sample_latches_the_safe_state_and_torque_stays_finite() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        for seq in 0..10 {
            k.tick(&sample(seq, 0.3, 1.0));
        }
        let t = k.tick(&sample(10, 0.3, f64::NAN));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert_eq!(t.fault, Some(Fault::NonFiniteSample { field: "tau_c" }));
        assert!(t.tau_d_nm.is_finite());
        // Latched: a good sample does not clear it.
        let t = k.tick(&sample(11, 0.3, 1.0));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert_eq!(t.tau_amplification_nm, 0.0);
        k.reset_fault();
        assert_eq!(k.tick(&sample(12, 0.3, 1.0)).mode, ControlMode::Run);
    }

    #[test]
    fn a_latched_run_is_over_when_the_protocol_is() {
        let c = cfg();
        let mut k = Controller::from_config(&c).unwrap();
        let end = (k.protocol().duration_s() * c.run.rate_hz).ceil() as u64;
        k.tick(&sample(0, 0.3, 0.0));
        let t = k.tick(&sample(1, 0.3, f64::NAN));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert!(!t.protocol_over());
        let t = k.tick(&sample(end - 10, 0.3, 0.0));
        assert!(!t.protocol_over(), "before the end");
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly, "still latched");
        assert!(t.protocol_over());
        // Unlatched, the end is `Done`.
        let mut k = Controller::from_config(&c).unwrap();
        assert!(!k.tick(&sample(0, 0.3, 0.0)).protocol_over());
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, ControlMode::Done);
        assert!(t.protocol_over());
    }

    #[test]
    fn the_controller_follows_a_fault_bit_and_the_drivers_safe_state() {
        use exo_messages::status;
        // Bits that are not faults (a replayed, stale or skipped-after sample) change nothing.
        let mut k = Controller::from_config(&cfg()).unwrap();
        for (seq, bits) in [status::REPLAY, status::STALE, status::FRAMES_SKIPPED]
            .into_iter()
            .enumerate()
        {
            let mut s = sample(seq as u64, 0.3, 0.0);
            s.status = bits;
            assert_eq!(k.tick(&s).mode, ControlMode::Run, "{bits:#x}");
        }
        for bits in [
            status::ENCODER_FAULT,
            status::FT_FAULT,
            status::SEA_FAULT,
            status::BUS_FAULT,
        ] {
            let mut k = Controller::from_config(&cfg()).unwrap();
            let mut s = sample(0, 0.3, 0.0);
            s.status = bits;
            let t = k.tick(&s);
            assert_eq!(t.fault, Some(Fault::SensorStatus { status: bits }));
            assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        }
        // The driver latched: the controller follows it for as long as its
        // samples say so (an operator reset clears both), never in Run.
        let mut k = Controller::from_config(&cfg()).unwrap();
        k.tick(&sample(0, 0.3, 0.0));
        for seq in 1..50 {
            let mut s = sample(seq, 0.3, 1.0);
            s.status = status::SAFE_STATE;
            let t = k.tick(&s);
            assert_eq!(t.fault, Some(Fault::DriverSafeState));
            assert_eq!(t.mode, ControlMode::SafeGravityOnly);
            assert_eq!(t.tau_amplification_nm, 0.0);
        }
        assert_eq!(k.fault(), None, "followed, not latched here");
        let t = k.tick(&sample(50, 0.3, 0.0));
        assert_eq!((t.mode, t.fault), (ControlMode::Run, None));
    }

    #[test]
    fn the_amplifier_restarts_from_rest_when_the_drivers_safe_state_ends() {
        let fractional = || {
            let mut k = Controller::from_config(&cfg()).unwrap();
            assert!(k.adopt_fractional_order(0.5));
            k
        };
        // A safe state of one sample or of ten.
        for safe_ticks in [1, 10] {
            let mut k = fractional();
            for seq in 0..100 {
                k.tick(&sample(seq, 0.3, 1.0));
            }
            for seq in 100..100 + safe_ticks {
                let mut s = sample(seq, 0.3, 1.0);
                s.status = exo_messages::status::SAFE_STATE;
                k.tick(&s);
            }
            // After the safe state the amplifier answers as a fresh one
            // does, and keeps its state from then on.
            let mut fresh = fractional();
            for i in 0..3 {
                let after = k
                    .tick(&sample(100 + safe_ticks + i, 0.3, 1.0))
                    .tau_amplification_nm;
                let expected = fresh.tick(&sample(i, 0.3, 1.0)).tau_amplification_nm;
                assert_eq!(after, expected, "tick {i} after {safe_ticks} safe");
            }
        }
        let mut once = fractional();
        let first = once.tick(&sample(0, 0.3, 1.0)).tau_amplification_nm;
        let second = once.tick(&sample(1, 0.3, 1.0)).tau_amplification_nm;
        assert_ne!(first, second, "the filter has a state to restart");
    }

    #[test]
    fn out_of_range_angle_and_interaction_torque_fault() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert_eq!(
            k.tick(&sample(0, 3.0, 0.0)).mode,
            ControlMode::SafeGravityOnly
        );
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(matches!(
            k.tick(&sample(0, 0.3, 500.0)).fault,
            Some(Fault::InteractionTorqueOutOfRange { .. })
        ));
    }

    /// A limit is the largest value tolerated, not the first refused: a
    /// sample exactly at the run file's angle range or interaction-torque
    /// limit runs on; one a nanoradian or a nano-newton-metre beyond latches
    /// the fault (docs/faults.md).
    #[test]
    fn a_sample_at_a_limit_runs_on_and_just_beyond_faults() {
        let k0 = Controller::from_config(&cfg()).unwrap();
        let [lo, hi] = k0.limits.theta_rad;
        let tc = k0.limits.tau_c_nm;
        for (theta, tau) in [(lo, 0.0), (hi, 0.0), (0.3, tc), (0.3, -tc)] {
            let mut k = Controller::from_config(&cfg()).unwrap();
            assert_eq!(
                k.tick(&sample(0, theta, tau)).fault,
                None,
                "θ {theta}, τ_c {tau}"
            );
        }
        for (theta, tau) in [
            (lo - 1e-9, 0.0),
            (hi + 1e-9, 0.0),
            (0.3, tc + 1e-9),
            (0.3, -tc - 1e-9),
        ] {
            let mut k = Controller::from_config(&cfg()).unwrap();
            assert!(
                k.tick(&sample(0, theta, tau)).fault.is_some(),
                "θ {theta}, τ_c {tau}"
            );
        }
    }

    #[test]
    fn constant_alpha_amplifies_per_experiment() {
        let mut c = cfg();
        c.protocol.experiments = vec![3];
        let mut k = Controller::from_config(&c).unwrap();
        // Experiment 3 has α = 4: τ_a = −3 τ_c.
        let t = k.tick(&sample(0, 0.0, 0.1));
        assert!((t.tau_amplification_nm + 0.3).abs() < 1e-12, "{t:?}");
    }

    /// The command is gravity compensation + amplification + bias +
    /// excitation, each as published, while neither limit binds; with
    /// gravity and amplification both non-zero (a product or a difference of
    /// two of them would pass a test where one is 0). Issue 23: the
    /// cargo-mutants sample left `τ_g + τ_a` → `τ_g · τ_a` alive.
    #[test]
    fn the_command_is_the_sum_of_its_published_parts() {
        let mut c = cfg();
        c.protocol.experiments = vec![3];
        let mut k = Controller::from_config(&c).unwrap();
        let (step, max) = (k.limits.torque_step_nm, k.limits.torque_nm);
        let mut checked = 0;
        let mut previous = 0.0;
        for seq in 0..2000 {
            let t = k.tick(&sample(seq, 0.5, 0.1));
            // α = 4 in experiment 3: τ_a = −3 τ_c; gravity of the rig at 0.5 rad.
            assert!((t.tau_amplification_nm + 0.3).abs() < 1e-12, "{t:?}");
            assert!(t.tau_gravity_nm.abs() > 0.1, "{t:?}");
            let sum =
                t.tau_gravity_nm + t.tau_amplification_nm + t.tau_bias_nm + t.tau_excitation_nm;
            let within = (sum - previous).abs() < step && sum.abs() < max;
            if within {
                assert!((t.tau_d_nm - sum).abs() < 1e-12, "seq {seq}: {t:?}");
                checked += 1;
            }
            previous = t.tau_d_nm;
        }
        assert!(checked > 1000, "only {checked} ticks within the limits");
    }

    #[test]
    fn adopting_f_respects_bounds() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(!k.adopt_fractional_order(0.95));
        assert!(!k.adopt_fractional_order(f64::NAN));
        assert!(k.adopt_fractional_order(0.4));
    }
}
