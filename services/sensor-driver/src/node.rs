//! The sensor driver as a node: a plain type stepped frame by frame, with
//! no IPC inside (ros2_control's read → update → write, with the bus and
//! the channels left to the caller). The process (`main.rs`, any
//! [`HardwareBus`](crate::HardwareBus)) and the in-process simulation
//! (`exo-sim`) drive it the same way, once per frame:
//!
//! 1. [`DriverNode::on_protocol`] and [`DriverNode::on_operator`] for what
//!    has arrived;
//! 2. [`DriverNode::on_frame`]: the calibrated sample to publish;
//! 3. [`DriverNode::answer`] with the controller's command (or
//!    [`DriverNode::on_deadline`] when none came in time): the torque to
//!    write to the bus.

use exo_config::RunConfig;
use exo_messages::operator::{KnownKinds, SeenSeqs};
use exo_messages::{
    ActuatorCommand, BusSensorFrame, OperatorCommand, OperatorCommandKind, ProtocolState,
    SensorSample,
};
use tracing::{debug, error, info, warn};

use crate::{CalibratedSample, Driver, DriverOutput, RawFrame};

/// The driver with its operator bookkeeping, one frame per step.
pub struct DriverNode {
    driver: Driver,
    operator_seqs: SeenSeqs,
    reported_latch: bool,
    frame_seq: u64,
    drive_faulted: bool,
    drive_reset_pending: bool,
}

impl DriverNode {
    /// The driver of run `cfg`; the gravity-only safe state starts with the
    /// first experiment's load.
    pub fn new(cfg: &RunConfig) -> Self {
        let load_kg = cfg
            .protocol
            .experiments
            .first()
            .and_then(|n| cfg.experiment_table().get(*n))
            .map_or(0.0, |e| e.load_kg);
        DriverNode {
            driver: Driver::new(
                &cfg.rig,
                cfg.run.rate_hz,
                cfg.safety.safe_state,
                cfg.controller.limits.torque_nm,
                load_kg,
            ),
            operator_seqs: SeenSeqs::default(),
            reported_latch: false,
            frame_seq: 0,
            drive_faulted: false,
            drive_reset_pending: false,
        }
    }

    /// The driver itself (calibration, latch).
    pub fn driver(&self) -> &Driver {
        &self.driver
    }

    /// Takes a protocol state: the load the gravity-only safe state holds.
    pub fn on_protocol(&mut self, p: &ProtocolState) {
        self.driver.set_load_kg(p.load_kg);
    }

    /// Takes an operator command: acts on `ResetFault` (clears the latched
    /// safe state), each `seq` once; the other kinds are the controller's;
    /// an unknown kind or a non-finite value is refused with a warning.
    pub fn on_operator(&mut self, op: &OperatorCommand) {
        if !self.operator_seqs.first_time(op.seq) {
            info!(
                "sensor-driver: operator command seq {}: already handled; ignored",
                op.seq
            );
            return;
        }
        match OperatorCommandKind::from_u32(op.kind) {
            Some(kind @ OperatorCommandKind::ResetFault) if op.validate().is_err() => warn!(
                "sensor-driver: operator command seq {}: {kind} refused: value {} is not finite; nothing changed",
                op.seq, op.value
            ),
            Some(OperatorCommandKind::ResetFault) => {
                match self.driver.latched() {
                    Some(event) => info!(
                        "sensor-driver: operator command seq {}: safe state reset (was: {event:?}); commands are applied again",
                        op.seq
                    ),
                    None => info!(
                        "sensor-driver: operator command seq {}: reset (no safe state was latched)",
                        op.seq
                    ),
                }
                self.driver.reset();
                self.reported_latch = false;
                // A faulted drive (its watchdog tripped) is reset too.
                self.drive_reset_pending = self.drive_faulted;
            }
            Some(kind) => debug!(
                "sensor-driver: operator command seq {}: {kind} is the controller's",
                op.seq
            ),
            None => warn!(
                "sensor-driver: operator command seq {}: unknown operator command kind {} refused (known kinds: {KnownKinds}); nothing changed",
                op.seq, op.kind
            ),
        }
    }

    /// Calibrates one raw frame into the sample to publish; `extra_status`
    /// is or-ed into its status (e.g. `REPLAY`).
    pub fn on_frame(&mut self, frame: &RawFrame, extra_status: u32) -> SensorSample {
        self.frame_seq = frame.seq;
        self.drive_faulted = frame.status & exo_messages::bus_status::DRIVE_FAULT != 0;
        let s = self.driver.on_frame(frame);
        message(&s, extra_status)
    }

    /// Whether the motor is enabled in the command written for the current
    /// frame: after an operator reset while the drive reports
    /// `DRIVE_FAULT`, one command disables the drive, which resets the
    /// fault (a tripped watchdog) when the next enables it again.
    pub fn motor_enable(&mut self) -> bool {
        !std::mem::take(&mut self.drive_reset_pending)
    }

    /// No bus frame within `safety.bus_deadline_ms`: latches the safe state
    /// and returns the flagged sample to publish
    /// ([`Driver::on_bus_silent`](crate::Driver::on_bus_silent)).
    pub fn on_bus_silent(&mut self, stamp_ns: u64) -> SensorSample {
        let s = self.driver.on_bus_silent(stamp_ns);
        self.frame_seq = s.seq;
        message(&s, 0)
    }

    /// The bus found a fault of its own in frame `frame_seq` (before
    /// [`DriverNode::on_frame`] of that frame): latches the safe state.
    pub fn on_bus_fault(&mut self, frame_seq: u64, fault: crate::BusFault) {
        self.driver.on_bus_fault(frame_seq, fault);
    }

    /// The torque for the current frame when the safe state is latched: no
    /// need to wait for the controller.
    pub fn latched_output(&mut self) -> Option<DriverOutput> {
        self.driver.latched().map(|_| self.on_deadline())
    }

    /// Takes the controller's command; the torque to write when it answers
    /// the current frame (a stale or repeated one gives `None`: keep
    /// waiting until the deadline).
    pub fn answer(&mut self, cmd: &ActuatorCommand) -> Option<DriverOutput> {
        if cmd.sensor_seq != self.frame_seq {
            return None;
        }
        self.driver.on_command(cmd.sensor_seq, cmd.tau_d)
    }

    /// No command for the current frame within the deadline: the latched
    /// safe-state torque.
    pub fn on_deadline(&mut self) -> DriverOutput {
        self.driver
            .on_deadline()
            .unwrap_or_else(|| self.driver.safe_output())
    }

    /// The safe-state torque without latching (start-up, shutdown).
    pub fn safe_output(&self) -> DriverOutput {
        self.driver.safe_output()
    }

    /// Logs a newly latched safe state once (at the frame it latched at);
    /// returns whether it did now.
    pub fn report_latch(&mut self, out: &DriverOutput) -> bool {
        if let (Some(event), false) = (self.driver.latched(), self.reported_latch) {
            error!(
                "sensor-driver: safe state latched at frame {}: {event:?} → {:?}",
                self.frame_seq, out.source
            );
            self.reported_latch = true;
            return true;
        }
        false
    }
}

/// The message of a calibrated sample, with `extra_status` or-ed in.
fn message(s: &CalibratedSample, extra_status: u32) -> SensorSample {
    SensorSample {
        seq: s.seq,
        stamp_ns: s.stamp_ns,
        theta_e: s.theta_e,
        omega_e: s.omega_e,
        tau_c: s.tau_c,
        tau_s: s.tau_s,
        status: s.status | extra_status,
        _pad: 0,
    }
}

/// A bus frame of the plant simulator as the driver's raw frame.
pub fn raw_frame(f: &BusSensorFrame) -> RawFrame {
    RawFrame {
        seq: f.seq,
        stamp_ns: f.stamp_ns,
        encoder_counts: f.encoder_counts,
        cuff_wrench: f.cuff_wrench,
        sea_deflection_counts: f.sea_deflection_counts,
        status: f.status,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use exo_messages::status;

    fn node() -> DriverNode {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        DriverNode::new(&cfg)
    }

    fn frame(seq: u64) -> RawFrame {
        RawFrame {
            seq,
            stamp_ns: seq * 1_000_000,
            ..Default::default()
        }
    }

    fn command(sensor_seq: u64, tau_d: f64) -> ActuatorCommand {
        ActuatorCommand {
            sensor_seq,
            tau_d,
            ..Default::default()
        }
    }

    #[test]
    fn a_silent_bus_gives_a_flagged_sample_and_latches_until_a_reset() {
        let mut n = node();
        for k in 0..3 {
            let s = n.on_frame(&frame(k), 0);
            assert_eq!(s.status, 0);
            assert!(n.answer(&command(k, 1.5)).is_some());
        }
        let s = n.on_bus_silent(7_000_000);
        assert_eq!(s.seq, 3, "numbered after the last frame");
        assert_eq!(s.stamp_ns, 7_000_000);
        assert_eq!(
            s.status,
            status::BUS_FAULT | status::STALE | status::SAFE_STATE
        );
        assert_eq!(
            n.driver().latched(),
            Some(crate::SafetyEvent::BusSilent { last_frame_seq: 2 })
        );
        // The bus comes back: still latched, the controller's torque is not applied.
        let s = n.on_frame(&frame(3), 0);
        assert_ne!(s.status & status::SAFE_STATE, 0);
        assert!(n.latched_output().is_some());
        // An operator reset clears it; the next command written disables
        // the drive once (resetting a drive fault), then enables it.
        n.on_operator(&OperatorCommand {
            seq: 1,
            kind: OperatorCommandKind::ResetFault.as_u32(),
            ..Default::default()
        });
        assert!(n.driver().latched().is_none());
        assert!(
            n.motor_enable(),
            "the drive reported no fault: not disabled"
        );
        let s = n.on_frame(&frame(4), 0);
        assert_eq!(s.status & status::SAFE_STATE, 0);
        let out = n.answer(&command(4, 1.5)).unwrap();
        assert_eq!(out.tau_motor_nm, 1.5);
    }

    #[test]
    fn a_reset_disables_a_faulted_drive_once_then_enables_it() {
        let mut n = node();
        let faulted = RawFrame {
            status: exo_messages::bus_status::DRIVE_FAULT,
            ..frame(0)
        };
        let s = n.on_frame(&faulted, 0);
        assert_ne!(s.status & status::BUS_FAULT, 0);
        assert!(n.motor_enable(), "no reset yet");
        n.on_operator(&OperatorCommand {
            seq: 1,
            kind: OperatorCommandKind::ResetFault.as_u32(),
            ..Default::default()
        });
        assert!(!n.motor_enable());
        assert!(n.motor_enable());
    }

    #[test]
    fn a_latch_is_reported_once_until_a_reset_and_a_bad_reset_is_refused() {
        let mut n = node();
        n.on_frame(&frame(0), 0);
        assert!(!n.report_latch(&n.safe_output()), "nothing latched");
        n.on_frame(&frame(1), 0);
        let out = n.on_deadline();
        assert!(n.report_latch(&out));
        assert!(!n.report_latch(&out), "once");
        // A reset with a non-finite value is refused: still latched.
        n.on_operator(&OperatorCommand {
            seq: 1,
            kind: OperatorCommandKind::ResetFault.as_u32(),
            value: f64::NAN,
            ..Default::default()
        });
        assert!(n.driver().latched().is_some());
        n.on_operator(&OperatorCommand {
            seq: 2,
            kind: OperatorCommandKind::ResetFault.as_u32(),
            ..Default::default()
        });
        assert!(n.driver().latched().is_none());
        n.on_frame(&frame(2), 0);
        let out = n.on_deadline();
        assert!(
            n.report_latch(&out),
            "a new latch after the reset is reported"
        );
    }

    #[test]
    fn the_protocols_load_is_what_the_gravity_only_safe_state_holds() {
        let mut n = node();
        let mut f = frame(0);
        f.encoder_counts = 100_000; // an arm raised well off the vertical
        n.on_frame(&f, 0);
        n.on_protocol(&ProtocolState {
            load_kg: 0.0,
            ..Default::default()
        });
        let unloaded = n.safe_output().tau_motor_nm;
        n.on_protocol(&ProtocolState {
            load_kg: 4.5,
            ..Default::default()
        });
        let loaded = n.safe_output().tau_motor_nm;
        assert!(
            loaded.abs() > unloaded.abs() + 1.0,
            "{loaded} vs {unloaded}"
        );
    }

    #[test]
    fn a_bus_frame_becomes_the_drivers_raw_frame_field_for_field() {
        let f = BusSensorFrame {
            seq: 7,
            stamp_ns: 8,
            encoder_counts: 9,
            cuff_wrench: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            sea_deflection_counts: -10,
            status: 4,
            _pad: 0,
        };
        let r = raw_frame(&f);
        assert_eq!(
            (
                r.seq,
                r.stamp_ns,
                r.encoder_counts,
                r.cuff_wrench,
                r.sea_deflection_counts,
                r.status
            ),
            (7, 8, 9, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], -10, 4)
        );
    }

    #[test]
    fn a_command_for_another_frame_is_not_an_answer() {
        let mut n = node();
        n.on_frame(&frame(5), 0);
        assert!(n.answer(&command(4, 1.0)).is_none());
        assert!(n.answer(&command(5, 1.0)).is_some());
        assert!(n.motor_enable(), "no reset: always enabled");
    }
}
