//! The driver's cycle and its safety latch.

use exo_config::{RigSettings, SafeState};

use crate::calibration::{Calibration, VelocityFilter};

/// Status bits of a calibrated sample: the message's own (`SensorSample.status`).
pub use exo_messages::status;

/// One raw frame from the hardware bus.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawFrame {
    /// Frame sequence number.
    pub seq: u64,
    /// Monotonic time stamp (ns).
    pub stamp_ns: u64,
    /// Joint encoder counts.
    pub encoder_counts: i64,
    /// Cuff 6-axis reading `[f_x, f_y, f_z, t_x, t_y, t_z]` (N, Nm), sensor frame.
    pub cuff_wrench: [f64; 6],
    /// SEA spring-deflection encoder counts.
    pub sea_deflection_counts: i64,
    /// Bus status (non-zero: the bus reports a fault).
    pub status: u32,
}

/// A calibrated sample, ready to publish as `SensorSample`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CalibratedSample {
    /// Frame sequence number.
    pub seq: u64,
    /// Monotonic time stamp (ns).
    pub stamp_ns: u64,
    /// θ_e (rad).
    pub theta_e: f64,
    /// ω_e (rad/s), filtered.
    pub omega_e: f64,
    /// τ_c (Nm), the torque the cuff applies to the human.
    pub tau_c: f64,
    /// τ_s (Nm), the SEA spring torque.
    pub tau_s: f64,
    /// Status bits ([`status`]).
    pub status: u32,
}

/// Where the torque written to the bus came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandSource {
    /// The controller's command for the current frame.
    Controller,
    /// Safe state: gravity compensation only.
    SafeGravityOnly,
    /// Safe state: zero torque.
    SafeZeroTorque,
}

/// Why the driver entered its safe state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SafetyEvent {
    /// No fresh command for frame `frame_seq` within the deadline.
    CommandDeadlineMissed {
        /// The frame left unanswered.
        frame_seq: u64,
    },
    /// The controller sent a non-finite torque.
    NonFiniteCommand {
        /// The frame it answered.
        frame_seq: u64,
    },
    /// No bus frame arrived within the bus deadline (a silent bus, a
    /// stalled drive or plant).
    BusSilent {
        /// The last frame received.
        last_frame_seq: u64,
    },
    /// The hardware bus found a fault of its own (EtherCAT: frame,
    /// working counter, cycle, drive state); the drive is powered down.
    Bus {
        /// The frame it was found in.
        frame_seq: u64,
        /// What it was.
        fault: BusFault,
    },
}

/// A fault a hardware bus finds itself ([`HardwareBus::take_fault`](crate::HardwareBus::take_fault)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusFault {
    /// The cycle's frame could not be sent (`os_error`, e.g. ENETDOWN on
    /// a link taken down): latched in its cycle. A frame that did not come
    /// back within the PDU time-out (`os_error` 0) is a missed cycle,
    /// latched only as [`BusFault::MissedCycles`].
    FrameLost {
        /// The OS error of the failed send, 0 for a time-out.
        os_error: i32,
    },
    /// The frame came back with a working counter short of the expected
    /// one: some device did not process it.
    WorkingCounter {
        /// Expected working counter.
        expected: u16,
        /// The one received.
        received: u16,
    },
    /// The frame came back unprocessed (working counter 0): the device is gone.
    DeviceVanished,
    /// `bus.ethercat.max_missed_cycles` cycles in a row were missed: the
    /// master woke more than a period late for them (each period skipped
    /// counts one), or their replies did not come back within the PDU
    /// time-out (a drive that stopped answering too).
    MissedCycles {
        /// Missed cycles in a row.
        in_a_row: u32,
        /// Whether the last of them lost its reply (else it woke late).
        reply_lost: bool,
    },
    /// The drive's EtherCAT (AL) state is no longer OP.
    AlState {
        /// The AL state it reports (1 INIT, 2 PRE-OP, 4 SAFE-OP).
        state: u8,
    },
    /// The drive reports Fault (CiA 402).
    DriveFault {
        /// Its statusword.
        statusword: u16,
        /// Its error code (0x603F), 0 when not mapped.
        error_code: u16,
    },
    /// The drive left Operation Enabled on its own (CiA 402).
    UnexpectedState {
        /// Its statusword.
        statusword: u16,
    },
    /// A non-finite torque reached the backend (never sent).
    NonFiniteTorque,
    /// The drive did not take the sync-manager watchdog the master armed
    /// in its first cycle (`bus.ethercat.drive_watchdog_cycles`): the
    /// divider (0x0400) and time (0x0420) read back, 0 when the write or
    /// the read got no answer.
    WatchdogRefused {
        /// The divider read back.
        divider: u16,
        /// The time read back (units of the divider).
        time: u16,
    },
}

/// What to write to the bus for the current frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriverOutput {
    /// Motor torque (Nm), clamped.
    pub tau_motor_nm: f64,
    /// Its source.
    pub source: CommandSource,
}

/// The driver's state.
#[derive(Debug, Clone)]
pub struct Driver {
    calibration: Calibration,
    velocity: VelocityFilter,
    rig: RigSettings,
    safe_state: SafeState,
    torque_limit_nm: f64,
    load_kg: f64,
    current_frame: Option<u64>,
    answered: bool,
    last_good: CalibratedSample,
    latched: Option<SafetyEvent>,
}

impl Driver {
    /// A driver for the rig, at `rate_hz`, with the given safe state and torque limit.
    pub fn new(
        rig: &RigSettings,
        rate_hz: f64,
        safe_state: SafeState,
        torque_limit_nm: f64,
        load_kg: f64,
    ) -> Self {
        Driver {
            calibration: Calibration::new(rig),
            velocity: VelocityFilter::new(rig.velocity_cutoff_hz, rate_hz),
            rig: *rig,
            safe_state,
            torque_limit_nm,
            load_kg,
            current_frame: None,
            answered: true,
            last_good: CalibratedSample::default(),
            latched: None,
        }
    }

    /// Sets the load (kg) the gravity-only safe state compensates.
    pub fn set_load_kg(&mut self, load_kg: f64) {
        if load_kg.is_finite() && load_kg >= 0.0 {
            self.load_kg = load_kg;
        }
    }

    /// The latched safety event, if any.
    pub fn latched(&self) -> Option<SafetyEvent> {
        self.latched
    }

    /// Clears the latch (operator command).
    pub fn reset(&mut self) {
        self.latched = None;
    }

    /// Converts a raw frame. Non-finite readings never leave the driver: the
    /// last good value is kept and a fault bit is set instead.
    pub fn on_frame(&mut self, f: &RawFrame) -> CalibratedSample {
        let mut st = 0;
        if self.current_frame.is_some_and(|last| f.seq > last + 1) {
            st |= status::FRAMES_SKIPPED;
        }
        self.current_frame = Some(f.seq);
        self.answered = false;
        // A late frame (bus_status::LATE) is counted by `exo run`, not a
        // fault of the devices.
        if f.status & exo_messages::bus_status::FAULTS != 0 {
            st |= status::BUS_FAULT;
        }
        if f.status & exo_messages::bus_status::LATE != 0 {
            st |= status::LATE;
        }
        // A lost reply: the bus repeated the last values.
        if f.status & exo_messages::bus_status::STALE != 0 {
            st |= status::STALE;
        }
        let theta = self.calibration.theta_rad(f.encoder_counts);
        let tau_c = self.calibration.tau_c_nm(&f.cuff_wrench);
        let tau_c = if f.cuff_wrench.iter().all(|v| v.is_finite()) && tau_c.is_finite() {
            tau_c
        } else {
            st |= status::FT_FAULT;
            self.last_good.tau_c
        };
        let tau_s = self.calibration.tau_s_nm(f.sea_deflection_counts);
        let omega = self.velocity.update(theta);
        if self.latched.is_some() {
            st |= status::SAFE_STATE;
        }
        let s = CalibratedSample {
            seq: f.seq,
            stamp_ns: f.stamp_ns,
            theta_e: theta,
            omega_e: omega,
            tau_c,
            tau_s,
            status: st,
        };
        self.last_good = s;
        s
    }

    /// A command from the controller for frame `sensor_seq`. Returns what to
    /// write, or `None` if the command is stale (answers another frame) or the
    /// frame was already answered.
    pub fn on_command(&mut self, sensor_seq: u64, tau_d_nm: f64) -> Option<DriverOutput> {
        if self.current_frame != Some(sensor_seq) || self.answered {
            return None;
        }
        self.answered = true;
        if !tau_d_nm.is_finite() {
            self.latch(SafetyEvent::NonFiniteCommand {
                frame_seq: sensor_seq,
            });
        }
        if self.latched.is_some() {
            return Some(self.safe_output());
        }
        Some(DriverOutput {
            tau_motor_nm: tau_d_nm.clamp(-self.torque_limit_nm, self.torque_limit_nm),
            source: CommandSource::Controller,
        })
    }

    /// No bus frame within the bus deadline: latches the safe state and
    /// returns the sample to publish in place of the missing frame: the
    /// last one's values, stamped `stamp_ns`, numbered after it, flagged
    /// `BUS_FAULT | STALE | SAFE_STATE`.
    pub fn on_bus_silent(&mut self, stamp_ns: u64) -> CalibratedSample {
        let last_frame_seq = self.current_frame.unwrap_or(0);
        self.latch(SafetyEvent::BusSilent { last_frame_seq });
        CalibratedSample {
            seq: self.current_frame.map_or(0, |s| s + 1),
            stamp_ns,
            status: status::BUS_FAULT | status::STALE | status::SAFE_STATE,
            ..self.last_good
        }
    }

    /// The bus found a fault of its own in the current frame: latches the
    /// safe state (call before [`Driver::on_frame`] so the frame's sample
    /// carries `SAFE_STATE`).
    pub fn on_bus_fault(&mut self, frame_seq: u64, fault: BusFault) {
        self.latch(SafetyEvent::Bus { frame_seq, fault });
    }

    /// The deadline for the current frame passed without a fresh command:
    /// latches the safe state and returns its torque (`None` if the frame was answered).
    pub fn on_deadline(&mut self) -> Option<DriverOutput> {
        if self.answered {
            return None;
        }
        let frame_seq = self.current_frame.unwrap_or(0);
        self.answered = true;
        self.latch(SafetyEvent::CommandDeadlineMissed { frame_seq });
        Some(self.safe_output())
    }

    fn latch(&mut self, e: SafetyEvent) {
        if self.latched.is_none() {
            self.latched = Some(e);
        }
    }

    /// The safe-state torque for the latest angle.
    pub fn safe_output(&self) -> DriverOutput {
        match self.safe_state {
            SafeState::GravityOnly => DriverOutput {
                tau_motor_nm: self
                    .rig
                    .gravity_torque_nm(self.last_good.theta_e, self.load_kg)
                    .clamp(-self.torque_limit_nm, self.torque_limit_nm),
                source: CommandSource::SafeGravityOnly,
            },
            SafeState::ZeroTorque => DriverOutput {
                tau_motor_nm: 0.0,
                source: CommandSource::SafeZeroTorque,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> RigSettings {
        crate::calibration::test_rig()
    }

    fn frame(seq: u64) -> RawFrame {
        RawFrame {
            seq,
            encoder_counts: 512,
            cuff_wrench: [0.0, 4.0, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        }
    }

    #[test]
    fn fresh_command_is_clamped_and_stale_one_ignored() {
        let mut d = Driver::new(&rig(), 1000.0, SafeState::GravityOnly, 10.0, 4.5);
        d.on_frame(&frame(1));
        assert_eq!(d.on_command(0, 3.0), None, "stale");
        let out = d.on_command(1, 30.0).unwrap();
        assert_eq!(
            (out.tau_motor_nm, out.source),
            (10.0, CommandSource::Controller)
        );
        assert_eq!(d.on_command(1, 1.0), None, "already answered");
        assert_eq!(d.on_deadline(), None);
    }

    #[test]
    fn a_gap_in_the_frames_is_flagged_on_the_sample_after_it() {
        let mut d = Driver::new(&rig(), 1000.0, SafeState::GravityOnly, 10.0, 4.5);
        let flags: Vec<u32> = [1, 2, 5, 6]
            .iter()
            .map(|&k| d.on_frame(&frame(k)).status & status::FRAMES_SKIPPED)
            .collect();
        assert_eq!(flags, [0, 0, status::FRAMES_SKIPPED, 0]);
    }

    #[test]
    fn missed_deadline_latches_gravity_only_until_reset() {
        let r = rig();
        let mut d = Driver::new(&r, 1000.0, SafeState::GravityOnly, 40.0, 4.5);
        let s = d.on_frame(&frame(7));
        let out = d.on_deadline().unwrap();
        assert_eq!(out.source, CommandSource::SafeGravityOnly);
        assert!((out.tau_motor_nm - r.gravity_torque_nm(s.theta_e, 4.5)).abs() < 1e-12);
        assert_eq!(
            d.latched(),
            Some(SafetyEvent::CommandDeadlineMissed { frame_seq: 7 })
        );
        // Later commands do not leave the safe state.
        let s8 = d.on_frame(&frame(8));
        assert_ne!(s8.status & status::SAFE_STATE, 0);
        assert_eq!(
            d.on_command(8, 5.0).unwrap().source,
            CommandSource::SafeGravityOnly
        );
        d.reset();
        d.on_frame(&frame(9));
        assert_eq!(
            d.on_command(9, 5.0).unwrap().source,
            CommandSource::Controller
        );
    }

    #[test]
    fn nan_reading_never_leaves_the_driver() {
        let mut d = Driver::new(&rig(), 1000.0, SafeState::ZeroTorque, 40.0, 4.5);
        let good = d.on_frame(&frame(1));
        let mut f = frame(2);
        f.cuff_wrench[1] = f64::NAN;
        let s = d.on_frame(&f);
        assert!(s.tau_c.is_finite());
        assert_eq!(s.tau_c, good.tau_c);
        assert_ne!(s.status & status::FT_FAULT, 0);
        assert_eq!(
            d.on_command(2, f64::INFINITY).unwrap().source,
            CommandSource::SafeZeroTorque
        );
    }

    #[test]
    fn a_late_frame_is_no_bus_fault_and_a_device_fault_is() {
        use exo_messages::bus_status;
        let mut d = Driver::new(&rig(), 1000.0, SafeState::ZeroTorque, 40.0, 4.5);
        let late = RawFrame {
            status: bus_status::LATE,
            ..frame(1)
        };
        assert_eq!(d.on_frame(&late).status, status::LATE, "late, no fault");
        // A lost reply (the bus repeats the last values): stale, no fault.
        let stale = RawFrame {
            status: bus_status::STALE,
            ..frame(2)
        };
        assert_eq!(d.on_frame(&stale).status, status::STALE);
        assert_eq!(
            d.on_command(2, 5.0).unwrap().source,
            CommandSource::Controller,
            "a stale frame is answered"
        );
        for (k, bit) in [
            bus_status::FRAME_ERROR,
            bus_status::ENCODER_ERROR,
            bus_status::FT_ERROR,
            bus_status::SEA_ENCODER_ERROR,
            bus_status::DRIVE_FAULT,
        ]
        .into_iter()
        .enumerate()
        {
            let f = RawFrame {
                status: bit | bus_status::LATE,
                ..frame(2 + k as u64)
            };
            assert_ne!(d.on_frame(&f).status & status::BUS_FAULT, 0, "bit {bit}");
        }
    }
}
