//! The EtherCAT backend: one CiA 402 servo drive in cyclic synchronous
//! torque mode, through `ethercrab` (the pure-Rust EtherCAT master), chosen
//! by `[bus] backend = "ethercat"` with its settings in `[bus.ethercat]`.
//!
//! - **Bring-up** ([`EthercatBus::open`]): the interface is opened, the bus
//!   scanned (INIT → PRE-OP), the drive at `position` checked against the
//!   run file's identity (the SII's, which is what ethercrab reads), the
//!   run file's PDO mapping written in PRE-OP, the drive taken to OP and its
//!   process image checked against the mapping's size. Every refusal names
//!   the run-file key, and comes before the motor can be enabled.
//! - **Each cycle** ([`HardwareBus::read`] then [`HardwareBus::write`]): at
//!   the cycle's absolute deadline one LRW exchanges the outputs staged by
//!   the last `write` for the drive's inputs; the statusword goes through
//!   the CiA 402 state machine ([`Cia402`]), whose controlword is staged
//!   with the torque set-point of the next `write`.
//! - **Late and lost cycles** are tolerated as real drives and masters do
//!   (issue 33): a cycle the master wakes for more than a period late
//!   (each whole period skipped counts one missed cycle) or whose reply
//!   does not come back within the PDU time-out is counted and flagged
//!   (`bus_status::LATE`, `bus_status::STALE`: the last values repeated),
//!   and the drive holds its last set-point meanwhile, as a CST drive
//!   does. `bus.ethercat.max_missed_cycles` missed cycles in a row latch
//!   ([`BusFault::MissedCycles`]); a cycle on time with its reply back
//!   and its command in time ends the run. A command that does not come
//!   within the deadline is a missed cycle too
//!   ([`HardwareBus::hold_missed_command`]): the drive holds the staged
//!   set-point, and the one that reaches the limit latches
//!   `CommandDeadlineMissed` in the driver. A drive that stops answering altogether is caught
//!   this way too, within that many cycles.
//! - **The drive's own watchdog**: in the first cycle the master arms the
//!   drive's sync-manager watchdog (`bus.ethercat.drive_watchdog_cycles`)
//!   and reads it back; a drive that refuses it latches
//!   ([`BusFault::WatchdogRefused`]) before it is ever enabled.
//! - **Faults** latch within the cycle they are seen in: a frame that
//!   cannot be sent (a lost link), a working counter short of the expected
//!   one, a device that no longer answers (working counter 0), the drive's
//!   AL state other than OP, the drive in Fault, or any other departure
//!   from Operation Enabled. The drive is then powered down
//!   (quick stop, then disable voltage), the frame carries `FRAME_ERROR` on
//!   the cycle of the fault and `DRIVE_FAULT` until the operator's reset,
//!   and [`HardwareBus::take_fault`] names the fault for the driver's latch.
//!   The motor is enabled again only by the operator's reset (the driver's
//!   disable-then-enable pair, `DriverNode::motor_enable`), which is also
//!   the only time a drive fault is reset.
//!
//! Our own TX/RX loop: the backend drives ethercrab's futures by hand on
//! the driver's thread (no executor, no second thread) and moves the frames
//! itself over a raw socket ([`socket::RawSocket`]): a failed send is a lost
//! frame of that cycle, not the end of the master (ethercrab's own
//! `tx_rx_task` stops for good at the first failed send, so a master on it
//! cannot survive a pulled cable).
//!
//! Here the cyclic exchange; the bring-up in `bringup.rs`, the mapping
//! resolved to offsets in `map.rs`, the hand-driven TX/RX loop in
//! `pump.rs`, the raw socket in [`socket`], the errors ([`EthercatError`])
//! in `error.rs`.

mod bringup;
mod error;
mod map;
mod pump;
pub mod socket;

use std::time::{Duration, Instant};

use ethercrab::subdevice_group::Op;
use ethercrab::{MainDevice, PduStorage, SubDeviceGroup, SubDeviceState};
use exo_messages::bus_status;
use exo_service_kit::{monotonic_ns, sleep_then_spin_until_ns};
use tracing::{error, info, warn};

pub use error::EthercatError;
use map::Map;
use pump::Pump;

use crate::cia402::{self, Cia402, Departure, Phase};
use crate::{BusFault, HardwareBus, RawFrame, RoundTrip, RoundTripReport};

/// Seconds of cycles left out of the timing statistics (bring-up, caches).
const TIMING_WARMUP_S: f64 = 1.0;

/// Devices on one bus this master handles.
const MAX_SUBDEVICES: usize = 16;
/// Process image of the whole bus (bytes).
const PDI_BYTES: usize = 1024;
/// Frames in flight at once.
const MAX_FRAMES: usize = 16;
/// ESC register: the watchdog divider (ETG.1000.4).
const WATCHDOG_DIVIDER: u16 = 0x0400;
/// ESC register: the sync managers' (process data) watchdog time.
const SM_WATCHDOG_TIME: u16 = 0x0420;

static PDU_STORAGE: PduStorage<MAX_FRAMES, { PduStorage::element_size(1100) }> = PduStorage::new();

type OpGroup = SubDeviceGroup<MAX_SUBDEVICES, PDI_BYTES, ethercrab::DefaultLock, Op>;

/// What the drive reported last, beyond the raw frame (for logs and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DriveReadings {
    /// Statusword (0x6041).
    pub statusword: u16,
    /// Controlword last staged (0x6040).
    pub controlword: u16,
    /// Velocity actual value (0x606C) × its scale, if mapped.
    pub velocity: f64,
    /// Torque actual value (0x6077) × its scale (Nm), if mapped.
    pub torque_nm: f64,
    /// Target torque last staged (drive units).
    pub target_torque_units: i64,
    /// Error code (0x603F), if mapped.
    pub error_code: u16,
    /// Working counter of the last exchange.
    pub working_counter: u16,
}

/// Counts since the bus opened.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EthercatCounters {
    /// Cycles run.
    pub cycles: u64,
    /// Frames lost (not sent, or their reply not back within the PDU
    /// time-out).
    pub frames_lost: u64,
    /// Cycles with a working counter other than expected.
    pub wkc_errors: u64,
    /// Cycles the master woke for more than one period late.
    pub cycles_late: u64,
    /// Missed cycles: the periods skipped by late wake-ups plus the lost
    /// replies.
    pub cycles_missed: u64,
    /// Cycles whose command did not come within the deadline (held).
    pub commands_missed: u64,
    /// The longest run of missed cycles in a row.
    pub longest_miss_run: u64,
    /// Replies that came back after their cycle had given up on them
    /// (ethercrab could not claim them); ignored.
    pub late_replies: u64,
}

/// The EtherCAT backend of the sensor driver.
pub struct EthercatBus {
    md: &'static MainDevice<'static>,
    group: OpGroup,
    pump: Pump,
    position: usize,
    map: Map,
    cia: Cia402,
    torque_scale: f64,
    period_ns: u64,
    /// The end of each wait for the deadline spent polling the clock
    /// (`bus.ethercat.wake_spin_us`), ns.
    wake_spin_ns: u64,
    pdu_timeout: Duration,
    max_missed_cycles: u64,
    /// The drive's sync-manager watchdog: (divider, time) for ESC
    /// registers 0x0400 and 0x0420, armed in the first cycle.
    watchdog: (u16, u16),
    watchdog_cycles: u32,
    watchdog_armed: bool,
    /// Missed cycles in a row up to now.
    miss_run: u64,
    /// Whether the cycle read last missed nothing so far.
    cycle_clean: bool,
    /// When the late replies were last summarised in the log (ns).
    late_replies_logged_ns: u64,
    late_replies_logged: u64,
    expected_wkc: u16,
    next_ns: u64,
    seq: u64,
    last: RawFrame,
    readings: DriveReadings,
    latched: Option<BusFault>,
    new_fault: Option<BusFault>,
    saw_disable: bool,
    counters: EthercatCounters,
    last_master_error: Option<ethercrab::error::Error>,
    announced_enabled: bool,
    exchange_time: RoundTrip,
    wake_lateness: RoundTrip,
    /// The driver's own part of each cycle: from the frame handed over to
    /// the next `read` (publish, the controller's command, the write).
    driver_part: RoundTrip,
    handed_over_ns: u64,
}

impl EthercatBus {
    /// What the drive reported last.
    pub fn readings(&self) -> DriveReadings {
        self.readings
    }

    /// Counts since the bus opened.
    pub fn counters(&self) -> EthercatCounters {
        self.counters
    }

    /// The last error ethercrab returned from a cyclic exchange (a time-out
    /// of its own, a frame it could not place), if any.
    pub fn last_master_error(&self) -> Option<ethercrab::error::Error> {
        self.last_master_error
    }

    /// Percentiles of the exchange (cycle start → the drive's inputs back:
    /// the LRW's round trip through the master, the wire and the drive), of
    /// the cycle's wake-up lateness (deadline → cycle start) and of the
    /// driver's own part of the cycle (frame handed over → next read), after
    /// the first second.
    pub fn timing(&self) -> [Option<RoundTripReport>; 3] {
        [
            self.exchange_time.report(),
            self.wake_lateness.report(),
            self.driver_part.report(),
        ]
    }

    /// Missed cycles in a row that latch (`bus.ethercat.max_missed_cycles`).
    pub fn max_missed_cycles(&self) -> u64 {
        self.max_missed_cycles
    }

    /// Missed cycles in a row up to the last cycle (0 after one on time,
    /// with its reply back and its command in time).
    pub fn misses_in_a_row(&self) -> u64 {
        self.miss_run
    }

    /// The CiA 402 phase the master is in.
    pub fn phase(&self) -> Phase {
        self.cia.phase()
    }

    /// The fault the backend is latched on (powered down), if any.
    pub fn latched(&self) -> Option<BusFault> {
        self.latched
    }

    /// Powers the drive down at the end of a run (quick stop, then disable
    /// voltage), cycling on until the drive reports it is off or the
    /// quick-stop time and a few cycles more have passed; the statusword
    /// it ended with.
    pub fn power_down(&mut self) -> u16 {
        self.cia.power_down();
        let cycles = self.cia.quick_stop_cycles() + 10;
        for _ in 0..cycles {
            if self.read(Duration::ZERO).is_err() {
                break;
            }
            let off = self.cia.phase() == Phase::Off
                && !cia402::DriveState::from_statusword(self.readings.statusword).is_powered();
            if off {
                break;
            }
        }
        self.readings.statusword
    }

    /// One LRW of the process image, bounded by the PDU time-out.
    fn exchange(&mut self) -> Result<(), BusFault> {
        let deadline = Instant::now() + self.pdu_timeout;
        let (md, group, pump) = (self.md, &self.group, &mut self.pump);
        let response = match pump.drive(group.tx_rx(md), deadline) {
            Err(l) => {
                return Err(BusFault::FrameLost {
                    os_error: l.os_error,
                })
            }
            Ok(Err(e)) => {
                // ethercrab gave up on the frame itself (its own time-out):
                // the send went out (a failed one ends `drive` above).
                self.last_master_error = Some(e);
                return Err(BusFault::FrameLost { os_error: 0 });
            }
            Ok(Ok(r)) => r,
        };
        let wkc = response.working_counter;
        self.readings.working_counter = wkc;
        if wkc == 0 {
            return Err(BusFault::DeviceVanished);
        }
        if wkc != self.expected_wkc {
            return Err(BusFault::WorkingCounter {
                expected: self.expected_wkc,
                received: wkc,
            });
        }
        match response.subdevice_states.get(self.position) {
            Some(SubDeviceState::Op) => Ok(()),
            Some(s) => Err(BusFault::AlState { state: al_code(*s) }),
            None => Err(BusFault::DeviceVanished),
        }
    }

    /// Adds `missed` cycles to the run and the counts.
    fn count_missed(&mut self, missed: u64) {
        self.counters.cycles_missed += missed;
        self.miss_run += missed;
        self.counters.longest_miss_run = self.counters.longest_miss_run.max(self.miss_run);
    }

    /// Logs the replies that came back too late since the last summary,
    /// at most once a second (ethercrab's own line for each is silenced:
    /// `exo_service_kit::init_logging`).
    fn summarise_late_replies(&mut self, now_ns: u64) {
        self.counters.late_replies = self.pump.late_replies;
        let new = self.counters.late_replies - self.late_replies_logged;
        if new > 0 && now_ns.saturating_sub(self.late_replies_logged_ns) >= 1_000_000_000 {
            warn!(
                "sensor-driver: EtherCAT {new} replies came back after their cycle gave up on them ({} in all); ignored",
                self.counters.late_replies
            );
            self.late_replies_logged = self.counters.late_replies;
            self.late_replies_logged_ns = now_ns;
        }
    }

    /// Arms the drive's sync-manager watchdog (ESC registers 0x0400 and
    /// 0x0420, ETG.1000.4) and reads both back: the drive takes the torque
    /// away by itself when no process data reaches it for that long. Done
    /// in the first cycle, after its exchange, so the watchdog starts from
    /// a write of the process data (an emulated ESC times it from the last
    /// one).
    fn arm_watchdog(&mut self) -> Result<(), BusFault> {
        let (divider, time) = self.watchdog;
        let (md, group, pump) = (self.md, &self.group, &mut self.pump);
        let sd = group
            .subdevice(md, self.position)
            .map_err(|_| BusFault::DeviceVanished)?;
        let arm = async {
            sd.register_write(WATCHDOG_DIVIDER, divider).await?;
            sd.register_write(SM_WATCHDOG_TIME, time).await?;
            let d: u16 = sd.register_read(WATCHDOG_DIVIDER).await?;
            let t: u16 = sd.register_read(SM_WATCHDOG_TIME).await?;
            Ok::<_, ethercrab::error::Error>((d, t))
        };
        let deadline = Instant::now() + 4 * self.pdu_timeout;
        let back = match pump.drive(arm, deadline) {
            Ok(Ok(back)) => Some(back),
            _ => None,
        };
        watchdog_verdict(self.watchdog, back)?;
        info!(
            "sensor-driver: EtherCAT drive's sync-manager watchdog armed: {time} × {:.1} µs (read back)",
            f64::from(divider + 2) * 0.04
        );
        Ok(())
    }

    /// The drive's sync-manager watchdog registers as it reports them now
    /// (divider 0x0400, time 0x0420).
    pub fn drive_watchdog(&mut self) -> Result<(u16, u16), EthercatError> {
        let (md, group, pump) = (self.md, &self.group, &mut self.pump);
        let sd = group
            .subdevice(md, self.position)
            .map_err(|e| EthercatError::Master(e.to_string()))?;
        let read = async {
            let d: u16 = sd.register_read(WATCHDOG_DIVIDER).await?;
            let t: u16 = sd.register_read(SM_WATCHDOG_TIME).await?;
            Ok::<_, ethercrab::error::Error>((d, t))
        };
        match pump.drive(read, Instant::now() + 4 * self.pdu_timeout) {
            Ok(Ok(back)) => Ok(back),
            Ok(Err(e)) => Err(EthercatError::Master(e.to_string())),
            Err(_) => Err(EthercatError::Master(
                "no answer reading the watchdog registers".into(),
            )),
        }
    }

    fn fault(&mut self, f: BusFault) {
        self.cia.power_down();
        if self.latched.is_none() {
            self.latched = Some(f);
            self.new_fault = Some(f);
        }
    }
}

/// The AL state's code (ETG.1000.6: 1 INIT, 2 PRE-OP, 3 BOOT, 4 SAFE-OP, 8 OP).
fn al_code(s: SubDeviceState) -> u8 {
    match s {
        SubDeviceState::Init => 1,
        SubDeviceState::PreOp => 2,
        SubDeviceState::Bootstrap => 3,
        SubDeviceState::SafeOp => 4,
        SubDeviceState::Op => 8,
        SubDeviceState::Other(x) => x,
        SubDeviceState::None => 0,
    }
}

impl HardwareBus for EthercatBus {
    type Error = EthercatError;

    fn name(&self) -> &'static str {
        "ethercat"
    }

    /// Waits for the cycle's absolute deadline (not `timeout`: the cycle
    /// is the run's), exchanges the process image and returns the drive's
    /// inputs. Always a frame: a lost exchange gives the last values
    /// flagged `FRAME_ERROR`, so the driver latches in this cycle.
    fn read(&mut self, _timeout: Duration) -> Result<Option<RawFrame>, EthercatError> {
        let now = monotonic_ns();
        if self.handed_over_ns != 0 {
            self.driver_part.record(self.handed_over_ns, now);
        }
        if self.next_ns == 0 {
            self.next_ns = now;
            // One warm-up for the three, from the first cycle: the first
            // cycle is the longest (the watchdog is armed in it).
            for t in [
                &mut self.exchange_time,
                &mut self.wake_lateness,
                &mut self.driver_part,
            ] {
                t.start_warmup_at(now);
            }
        } else {
            // Returns at once when the deadline has already passed.
            sleep_then_spin_until_ns(self.next_ns, self.wake_spin_ns);
        }
        let start = monotonic_ns();
        let late_ns = start.saturating_sub(self.next_ns);
        // Each whole period a late wake-up skipped is a missed cycle.
        let skipped = if self.counters.cycles > 0 && late_ns > self.period_ns {
            late_ns / self.period_ns
        } else {
            0
        };
        self.next_ns = if late_ns > self.period_ns {
            start + self.period_ns
        } else {
            self.next_ns + self.period_ns
        };
        self.counters.cycles += 1;
        let mut status = 0;
        let mut cycle_fault = None;
        if skipped > 0 {
            self.counters.cycles_late += 1;
            status |= bus_status::LATE;
        }
        let scheduled_ns = start - late_ns;
        let exchanged = self.exchange();
        if exchanged.is_ok() {
            self.exchange_time.record(start, monotonic_ns());
        }
        self.wake_lateness.record(scheduled_ns, start);
        self.summarise_late_replies(start);
        // A reply not back within the PDU time-out is a missed cycle; a
        // frame that could not be sent (the link) and every other fault
        // latch now.
        let reply_lost = matches!(exchanged, Err(BusFault::FrameLost { os_error: 0 }));
        match exchanged {
            Err(BusFault::FrameLost { .. }) => self.counters.frames_lost += 1,
            Err(BusFault::WorkingCounter { .. } | BusFault::DeviceVanished) => {
                self.counters.wkc_errors += 1
            }
            _ => {}
        }
        if reply_lost {
            status |= bus_status::STALE;
        } else if let Err(f) = exchanged {
            cycle_fault = Some(f);
        }
        if exchanged.is_ok() && !self.watchdog_armed {
            self.watchdog_armed = true;
            if let Err(f) = self.arm_watchdog() {
                cycle_fault = cycle_fault.or(Some(f));
            }
        }
        let missed = skipped + u64::from(reply_lost);
        // The run ends at the write of a cycle that missed nothing (its
        // command came in time too).
        self.cycle_clean = missed == 0;
        self.count_missed(missed);
        if self.miss_run >= self.max_missed_cycles {
            cycle_fault = cycle_fault.or(Some(BusFault::MissedCycles {
                in_a_row: self.miss_run.min(u64::from(u32::MAX)) as u32,
                reply_lost,
            }));
        }
        if exchanged.is_ok() {
            let sd = self
                .group
                .subdevice(self.md, self.position)
                .map_err(|e| EthercatError::Master(e.to_string()))?;
            let inputs = sd.inputs_raw();
            let m = &self.map;
            let r = &mut self.readings;
            r.statusword = m.statusword.read(&inputs) as u16;
            r.velocity = m.velocity.map_or(0.0, |f| f.read(&inputs) as f64 * f.scale);
            r.torque_nm = m
                .torque_actual
                .map_or(0.0, |f| f.read(&inputs) as f64 * f.scale);
            r.error_code = m.error_code.map_or(0, |f| f.read(&inputs) as u16);
            self.last.encoder_counts = m.position.read(&inputs);
            self.last.sea_deflection_counts = m.sea.map_or(0, |f| f.read(&inputs));
            for (w, f) in self.last.cuff_wrench.iter_mut().zip(m.cuff) {
                *w = f.map_or(0.0, |f| f.read(&inputs) as f64 * f.scale);
            }
        }
        if let Some(f) = cycle_fault {
            status |= bus_status::FRAME_ERROR;
            self.fault(f);
        }
        let (controlword, departure) = self.cia.step(self.readings.statusword);
        if let Some(d) = departure {
            let f = match d {
                Departure::Fault { statusword } => BusFault::DriveFault {
                    statusword,
                    error_code: self.readings.error_code,
                },
                Departure::UnexpectedState { statusword } => {
                    BusFault::UnexpectedState { statusword }
                }
            };
            status |= bus_status::DRIVE_FAULT;
            self.fault(f);
        }
        if self.latched.is_some() {
            status |= bus_status::DRIVE_FAULT;
        }
        self.readings.controlword = controlword;
        let enabled = self.cia.phase() == Phase::Enabled;
        if enabled && !self.announced_enabled {
            info!(
                "sensor-driver: EtherCAT drive in Operation Enabled (statusword {:#06x}), cyclic synchronous torque",
                self.readings.statusword
            );
        }
        self.announced_enabled = enabled;
        {
            let sd = self
                .group
                .subdevice(self.md, self.position)
                .map_err(|e| EthercatError::Master(e.to_string()))?;
            let mut out = sd.outputs_raw_mut();
            self.map.controlword.write(&mut out, i64::from(controlword));
            if let Some(m) = self.map.mode {
                m.write(&mut out, i64::from(cia402::MODE_CST));
            }
            if self.cia.phase() != Phase::Enabled {
                self.map.torque.write(&mut out, 0);
                self.readings.target_torque_units = 0;
            }
        }
        self.last.seq = self.seq;
        self.last.stamp_ns = start;
        self.last.status = status;
        self.seq += 1;
        self.handed_over_ns = monotonic_ns();
        Ok(Some(self.last))
    }

    /// Stages the torque set-point (and the controlword decided in `read`)
    /// for the next exchange. Torque reaches the drive only in Operation
    /// Enabled with no fault latched; a non-finite one is refused (zero,
    /// and a fault). `enable = false` then `true` is the operator's reset:
    /// the latch is cleared and the drive walked back up, resetting its
    /// fault if it has one.
    fn write(
        &mut self,
        _frame_seq: u64,
        _stamp_ns: u64,
        tau_motor_nm: f64,
        enable: bool,
    ) -> Result<(), EthercatError> {
        if !enable {
            self.saw_disable = true;
            self.cia.power_down();
        } else if self.saw_disable {
            self.saw_disable = false;
            if let Some(f) = self.latched.take() {
                info!("sensor-driver: EtherCAT fault {f:?} reset by the operator; enabling the drive again");
            }
            self.new_fault = None;
            self.cia.enable(true);
        }
        let units = if !tau_motor_nm.is_finite() {
            self.fault(BusFault::NonFiniteTorque);
            0
        } else if self.cia.phase() == Phase::Enabled && self.latched.is_none() {
            (tau_motor_nm / self.torque_scale).round() as i64
        } else {
            0
        };
        if self.cycle_clean {
            self.miss_run = 0;
        }
        let sd = self
            .group
            .subdevice(self.md, self.position)
            .map_err(|e| EthercatError::Master(e.to_string()))?;
        let mut out = sd.outputs_raw_mut();
        self.map.torque.write(&mut out, units);
        let (lo, hi) = self.map.torque.range();
        self.readings.target_torque_units = units.clamp(lo, hi);
        Ok(())
    }

    /// A command that did not come in time is a missed cycle: the staged
    /// set-point stays (the drive holds it) while the run of misses stays
    /// below `max_missed_cycles`.
    fn hold_missed_command(&mut self) -> bool {
        self.counters.commands_missed += 1;
        self.cycle_clean = false;
        self.count_missed(1);
        self.latched.is_none() && self.miss_run < self.max_missed_cycles
    }

    fn take_fault(&mut self) -> Option<BusFault> {
        let f = self.new_fault.take();
        if let Some(f) = f {
            match f {
                BusFault::DriveFault { error_code, .. } => error!(
                    "sensor-driver: EtherCAT drive fault {f:?}, error code {error_code:#06x}; powering down"
                ),
                BusFault::WatchdogRefused { .. } => error!(
                    "sensor-driver: EtherCAT drive refused its sync-manager watchdog (bus.ethercat.drive_watchdog_cycles = {} cycles: divider {:#06x}, time {}): {f:?}; not enabling it",
                    self.watchdog_cycles, self.watchdog.0, self.watchdog.1
                ),
                _ => warn!("sensor-driver: EtherCAT fault {f:?}; powering the drive down"),
            }
        }
        f
    }
}

/// Whether the drive took its sync-manager watchdog: the registers read
/// back after the write (`back`, divider 0x0400 and time 0x0420; `None`
/// when the exchange failed) must be those written (`set`). Anything else
/// is [`BusFault::WatchdogRefused`] with what was read (0, 0 when nothing
/// was), before the drive is enabled.
fn watchdog_verdict(set: (u16, u16), back: Option<(u16, u16)>) -> Result<(), BusFault> {
    match back {
        Some(b) if b == set => Ok(()),
        Some((divider, time)) => Err(BusFault::WatchdogRefused { divider, time }),
        None => Err(BusFault::WatchdogRefused {
            divider: 0,
            time: 0,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// KickCAT's emulated ESC always takes the registers, so the refusal
    /// is tested here on its verdict: a drive that keeps its own divider or
    /// time (an ESC whose watchdog is fixed in its EEPROM), or that does
    /// not answer the read-back, is refused with what it reported.
    #[test]
    fn a_watchdog_read_back_other_than_written_is_refused_with_what_was_read() {
        let set = (2498, 100);
        assert_eq!(watchdog_verdict(set, Some(set)), Ok(()));
        assert_eq!(
            watchdog_verdict(set, Some((2498, 1000))),
            Err(BusFault::WatchdogRefused {
                divider: 2498,
                time: 1000
            })
        );
        assert_eq!(
            watchdog_verdict(set, Some((0, 100))),
            Err(BusFault::WatchdogRefused {
                divider: 0,
                time: 100
            })
        );
        assert_eq!(
            watchdog_verdict(set, None),
            Err(BusFault::WatchdogRefused {
                divider: 0,
                time: 0
            })
        );
    }
}
