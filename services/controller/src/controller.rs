//! One controller tick: validate the sample, advance the protocol clock,
//! compose and limit the desired torque, latch faults into the safe state.

use exo_config::{
    ExperimentSpec, ExperimentTable, ProtocolMode, ProtocolTiming, RigSettings, RunConfig,
    SafeState,
};
use exo_impedance::{nominal_crossover, proportional_gain, StiffnessRange};
use thiserror::Error;

use crate::amplification::Amplifier;
use crate::protocol::{Protocol, ProtocolPoint};
use crate::safety::{Fault, FaultLatch, Limits};

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

/// What the controller is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Normal operation.
    Run,
    /// Latched fault: gravity compensation only.
    SafeGravityOnly,
    /// Latched fault: zero torque.
    SafeZeroTorque,
    /// Protocol finished: gravity compensation only, no amplification.
    Done,
}

/// One sensor sample, in physical units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TickInput {
    /// Sample sequence number; time is `(seq − first seq)/rate`.
    pub seq: u64,
    /// θ_e (rad).
    pub theta_e_rad: f64,
    /// ω_e (rad/s).
    pub omega_e_rad_s: f64,
    /// τ_c (Nm), the torque the cuff applies to the human.
    pub tau_c_nm: f64,
    /// τ_s (Nm), the SEA spring torque.
    pub tau_s_nm: f64,
    /// Whether the driver flagged a sensor fault.
    pub sensor_fault: bool,
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
    /// Mode.
    pub mode: Mode,
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
        self.protocol.done && self.mode != Mode::Run
    }
}

/// The controller.
#[derive(Debug, Clone)]
pub struct Controller {
    protocol: Protocol,
    amplifier: Amplifier,
    limits: Limits,
    latch: FaultLatch,
    rig: RigSettings,
    safe_state: SafeState,
    rate_hz: f64,
    first_seq: Option<u64>,
    previous_tau_d_nm: f64,
    f_bounds: [f64; 2],
    design: FractionalDesign,
    gravity_compensation: bool,
}

/// What is needed to rebuild the fractional amplifier with a new f.
#[derive(Debug, Clone, Copy)]
struct FractionalDesign {
    kp: f64,
    omega_gc_hat_rad_s: f64,
    filters: usize,
    p1_rad_s: f64,
    r_pp: f64,
}

impl Controller {
    /// Builds the controller of a run configuration.
    pub fn from_config(cfg: &RunConfig) -> Result<Self, ControllerError> {
        let subject = cfg.subject();
        let (protocol, load_kg) = match cfg.protocol.mode {
            ProtocolMode::Identification => {
                let table = cfg.experiment_table();
                let load = cfg
                    .protocol
                    .experiments
                    .first()
                    .and_then(|n| table.get(*n))
                    .map_or(0.0, |e| e.load_kg);
                (
                    Protocol::new(
                        table,
                        &cfg.protocol.experiments,
                        cfg.protocol.periods.as_deref(),
                    ),
                    load,
                )
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
        let kp = match cfg.controller.kp {
            Some(kp) => kp,
            None => proportional_gain(m_e, subject.inertia_kg_m2)?,
        };
        let [k_lo, k_hi] = cfg.controller.k_range_nm_per_rad;
        let design = FractionalDesign {
            kp,
            omega_gc_hat_rad_s: nominal_crossover(
                StiffnessRange::new(k_lo, k_hi)?,
                m_e,
                subject.inertia_kg_m2,
            )?,
            filters: cfg.controller.filters,
            p1_rad_s: cfg.controller.p1_rad_s,
            r_pp: cfg.controller.r_pp,
        };
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
            amplifier,
            limits: Limits::new(&cfg.controller.limits, cfg.run.rate_hz),
            latch: FaultLatch::default(),
            rig: cfg.rig,
            safe_state: cfg.safety.safe_state,
            rate_hz: cfg.run.rate_hz,
            first_seq: None,
            previous_tau_d_nm: 0.0,
            f_bounds: cfg.controller.f_bounds,
            design,
            gravity_compensation: cfg.controller.gravity_compensation,
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

    /// Answers one sample. Allocation-free; the returned torque is always
    /// finite and within the torque and rate limits.
    pub fn tick(&mut self, s: &TickInput) -> Tick {
        let first = *self.first_seq.get_or_insert(s.seq);
        let t_s = s.seq.saturating_sub(first) as f64 / self.rate_hz;
        self.validate(s);
        let p = self.protocol.at(t_s);
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
        let (mode, tau_g, tau_a, tau_b, tau_x) = if self.latch.is_latched() {
            match self.safe_state {
                SafeState::GravityOnly => (Mode::SafeGravityOnly, gravity, 0.0, 0.0, 0.0),
                SafeState::ZeroTorque => (Mode::SafeZeroTorque, 0.0, 0.0, 0.0, 0.0),
            }
        } else if p.done {
            (Mode::Done, gravity, 0.0, 0.0, 0.0)
        } else {
            self.amplifier.set_constant_alpha(p.alpha);
            let tau_a = self.amplifier.step(s.tau_c_nm);
            (
                Mode::Run,
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
            fault: self.latch.fault(),
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
        if s.sensor_fault {
            self.latch.raise(Fault::SensorStatus { status: 1 });
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

    fn cfg() -> RunConfig {
        RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap()
    }

    fn sample(seq: u64, theta: f64, tau_c: f64) -> TickInput {
        TickInput {
            seq,
            theta_e_rad: theta,
            omega_e_rad_s: 0.0,
            tau_c_nm: tau_c,
            tau_s_nm: 0.0,
            sensor_fault: false,
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
        assert_eq!(t.mode, Mode::Run);
    }

    #[test]
    fn nan_sample_latches_the_safe_state_and_torque_stays_finite() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        for seq in 0..10 {
            k.tick(&sample(seq, 0.3, 1.0));
        }
        let t = k.tick(&sample(10, 0.3, f64::NAN));
        assert_eq!(t.mode, Mode::SafeGravityOnly);
        assert_eq!(t.fault, Some(Fault::NonFiniteSample { field: "tau_c" }));
        assert!(t.tau_d_nm.is_finite());
        // Latched: a good sample does not clear it.
        let t = k.tick(&sample(11, 0.3, 1.0));
        assert_eq!(t.mode, Mode::SafeGravityOnly);
        assert_eq!(t.tau_amplification_nm, 0.0);
        k.reset_fault();
        assert_eq!(k.tick(&sample(12, 0.3, 1.0)).mode, Mode::Run);
    }

    #[test]
    fn a_latched_run_is_over_when_the_protocol_is() {
        let c = cfg();
        let mut k = Controller::from_config(&c).unwrap();
        let end = (k.protocol().duration_s() * c.run.rate_hz).ceil() as u64;
        k.tick(&sample(0, 0.3, 0.0));
        let t = k.tick(&sample(1, 0.3, f64::NAN));
        assert_eq!(t.mode, Mode::SafeGravityOnly);
        assert!(!t.protocol_over());
        let t = k.tick(&sample(end - 10, 0.3, 0.0));
        assert!(!t.protocol_over(), "before the end");
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, Mode::SafeGravityOnly, "still latched");
        assert!(t.protocol_over());
        // Unlatched, the end is `Done`.
        let mut k = Controller::from_config(&c).unwrap();
        assert!(!k.tick(&sample(0, 0.3, 0.0)).protocol_over());
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, Mode::Done);
        assert!(t.protocol_over());
    }

    #[test]
    fn out_of_range_angle_and_interaction_torque_fault() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert_eq!(k.tick(&sample(0, 3.0, 0.0)).mode, Mode::SafeGravityOnly);
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(matches!(
            k.tick(&sample(0, 0.3, 500.0)).fault,
            Some(Fault::InteractionTorqueOutOfRange { .. })
        ));
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

    #[test]
    fn adopting_f_respects_bounds() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(!k.adopt_fractional_order(0.95));
        assert!(!k.adopt_fractional_order(f64::NAN));
        assert!(k.adopt_fractional_order(0.4));
    }
}
