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
//! - **Faults** latch within the cycle they are seen in: a frame that does
//!   not come back within the PDU time-out or cannot be sent (a lost link),
//!   a working counter short of the expected one, a device that no longer
//!   answers (working counter 0), a cycle started more than one period late,
//!   the drive's AL state other than OP, the drive in Fault, or any other
//!   departure from Operation Enabled. The drive is then powered down
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

pub mod socket;

use std::future::Future;
use std::pin::pin;
use std::task::{Context, Poll, Waker};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context as _, Result};
use ethercrab::subdevice_group::Op;
use ethercrab::{
    std::ethercat_now, MainDevice, MainDeviceConfig, PduRx, PduStorage, PduTx, SubDeviceGroup,
    SubDeviceState, Timeouts,
};
use exo_config::{EthercatSettings, PdoEntry, PdoRole, PdoSettings};
use exo_messages::bus_status;
use exo_service_kit::{monotonic_ns, sleep_until_ns};
use tracing::{error, info, warn};

use crate::cia402::{self, Cia402, Departure, Phase};
use crate::{BusFault, HardwareBus, RawFrame, RoundTrip, RoundTripReport};

/// Seconds of cycles left out of the timing statistics (bring-up, caches).
const TIMING_WARMUP_S: f64 = 1.0;
use socket::RawSocket;

/// Devices on one bus this master handles.
const MAX_SUBDEVICES: usize = 16;
/// Process image of the whole bus (bytes).
const PDI_BYTES: usize = 1024;
/// Frames in flight at once.
const MAX_FRAMES: usize = 16;

static PDU_STORAGE: PduStorage<MAX_FRAMES, { PduStorage::element_size(1100) }> = PduStorage::new();

type OpGroup = SubDeviceGroup<MAX_SUBDEVICES, PDI_BYTES, ethercrab::DefaultLock, Op>;

/// Errors of the cyclic exchange (the bring-up reports `anyhow` errors
/// naming the run-file key).
#[derive(Debug, thiserror::Error)]
pub enum EthercatError {
    /// ethercrab reported an error outside the cyclic exchange.
    #[error("EtherCAT: {0}")]
    Master(String),
}

/// One mapped value: where it sits in the process image, its width, its scale.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Field {
    offset: usize,
    bits: u8,
    scale: f64,
}

impl Field {
    fn of(pdo: &PdoSettings, role: PdoRole) -> Option<Field> {
        pdo.find(role).map(|(offset, e): (usize, PdoEntry)| Field {
            offset,
            bits: e.bits,
            scale: e.scale.unwrap_or(1.0),
        })
    }

    /// The value as a signed integer of its width (little-endian).
    fn read(&self, image: &[u8]) -> i64 {
        let b = |i: usize| image.get(self.offset + i).copied().unwrap_or(0);
        match self.bits {
            8 => i64::from(b(0) as i8),
            16 => i64::from(i16::from_le_bytes([b(0), b(1)])),
            _ => i64::from(i32::from_le_bytes([b(0), b(1), b(2), b(3)])),
        }
    }

    /// Writes `value`, saturated to the width's range.
    fn write(&self, image: &mut [u8], value: i64) {
        let n = usize::from(self.bits / 8);
        let (lo, hi) = self.range();
        let bytes = value.clamp(lo, hi).to_le_bytes();
        if let Some(dst) = image.get_mut(self.offset..self.offset + n) {
            dst.copy_from_slice(&bytes[..n]);
        }
    }

    fn range(&self) -> (i64, i64) {
        match self.bits {
            8 => (i64::from(i8::MIN), i64::from(i8::MAX)),
            16 => (i64::from(i16::MIN), i64::from(i16::MAX)),
            _ => (i64::from(i32::MIN), i64::from(i32::MAX)),
        }
    }
}

/// The run file's mapping resolved to offsets.
#[derive(Debug, Clone, Copy)]
struct Map {
    controlword: Field,
    mode: Option<Field>,
    torque: Field,
    statusword: Field,
    position: Field,
    velocity: Option<Field>,
    torque_actual: Option<Field>,
    error_code: Option<Field>,
    sea: Option<Field>,
    cuff: [Option<Field>; 6],
    in_bytes: usize,
    out_bytes: usize,
}

impl Map {
    fn new(s: &EthercatSettings) -> Result<Map> {
        let need = |pdo: &PdoSettings, role, key: &str| {
            Field::of(pdo, role).ok_or_else(|| {
                anyhow!(
                    "{key}.entries: no entry with role = \"{}\"",
                    exo_config::role_name(role)
                )
            })
        };
        let (rx, tx) = (&s.rx_pdo, &s.tx_pdo);
        let rxk = "bus.ethercat.rx_pdo";
        let txk = "bus.ethercat.tx_pdo";
        Ok(Map {
            controlword: need(rx, PdoRole::Controlword, rxk)?,
            mode: Field::of(rx, PdoRole::ModeOfOperation),
            torque: need(rx, PdoRole::TargetTorque, rxk)?,
            statusword: need(tx, PdoRole::Statusword, txk)?,
            position: need(tx, PdoRole::PositionActual, txk)?,
            velocity: Field::of(tx, PdoRole::VelocityActual),
            torque_actual: Field::of(tx, PdoRole::TorqueActual),
            error_code: Field::of(tx, PdoRole::ErrorCode),
            sea: Field::of(tx, PdoRole::SeaDeflection),
            cuff: [
                PdoRole::CuffFx,
                PdoRole::CuffFy,
                PdoRole::CuffFz,
                PdoRole::CuffTx,
                PdoRole::CuffTy,
                PdoRole::CuffTz,
            ]
            .map(|r| Field::of(tx, r)),
            in_bytes: tx.bytes(),
            out_bytes: rx.bytes(),
        })
    }
}

/// Our TX/RX loop: ethercrab's frames over the raw socket.
struct Pump {
    socket: RawSocket,
    tx: PduTx<'static>,
    rx: PduRx<'static>,
    buf: Box<[u8; 2048]>,
    last_os_error: i32,
}

/// A frame that did not come back: the OS error of a failed send, if any.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Lost {
    os_error: i32,
}

impl Pump {
    /// Sends every frame ethercrab has queued, then receives what comes
    /// back within `wait`. `Err` when a send failed (link down).
    fn pump(&mut self, wait: Duration) -> Result<(), Lost> {
        while let Some(frame) = self.tx.next_sendable_frame() {
            let socket = &self.socket;
            let mut os_error = 0;
            let sent = frame.send_blocking(|data| {
                socket.send(data).map_err(|e| {
                    os_error = e.raw_os_error().unwrap_or(-1);
                    ethercrab::error::Error::SendFrame
                })
            });
            if sent.is_err() {
                self.last_os_error = os_error;
                return Err(Lost { os_error });
            }
        }
        let mut wait = wait;
        while let Ok(Some(n)) = self.socket.recv(&mut self.buf[..], wait) {
            // A frame that is not ours, or answers a frame given up on, is ignored.
            let _ = self.rx.receive_frame(&self.buf[..n]);
            wait = Duration::ZERO;
        }
        Ok(())
    }

    /// Drives `fut` to completion by hand, moving its frames, until
    /// `deadline`; `Err` when it is not done by then or a send failed.
    /// Dropping an unfinished ethercrab future releases its frame.
    fn drive<F: Future>(&mut self, fut: F, deadline: Instant) -> Result<F::Output, Lost> {
        let mut fut = pin!(fut);
        let mut cx = Context::from_waker(Waker::noop());
        loop {
            if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                return Ok(v);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(Lost { os_error: 0 });
            }
            self.pump((deadline - now).min(Duration::from_micros(500)))?;
        }
    }
}

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
    /// Frames lost (not sent or not back in time).
    pub frames_lost: u64,
    /// Cycles with a working counter other than expected.
    pub wkc_errors: u64,
    /// Cycles started more than one period late.
    pub cycles_missed: u64,
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
    pdu_timeout: Duration,
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
    /// Brings the bus up and the drive to OP (not yet enabled: that
    /// happens in the first cycles). Refuses, naming the run-file key, an
    /// interface that cannot be opened, a bus without the device, a device
    /// with another identity and a mapping the drive refuses or that does
    /// not match its process image. Once per process (ethercrab's frame
    /// storage is static).
    pub fn open(s: &EthercatSettings, rate_hz: f64) -> Result<Self> {
        let map = Map::new(s)?;
        let socket = RawSocket::open(&s.interface)
            .with_context(|| format!("bus.ethercat.interface = {:?}", s.interface))?;
        let (tx, rx, pdu_loop) = PDU_STORAGE
            .try_split()
            .map_err(|()| anyhow!("the EtherCAT backend can be opened once per process"))?;
        let md: &'static MainDevice<'static> = Box::leak(Box::new(MainDevice::new(
            pdu_loop,
            Timeouts {
                pdu: Duration::from_millis(50),
                state_transition: Duration::from_secs(5),
                mailbox_response: Duration::from_secs(1),
                ..Default::default()
            },
            MainDeviceConfig::default(),
        )));
        let mut pump = Pump {
            socket,
            tx,
            rx,
            buf: Box::new([0; 2048]),
            last_os_error: 0,
        };
        let iface = &s.interface;
        let soon = |secs| Instant::now() + Duration::from_secs(secs);
        let group = pump
            .drive(
                md.init_single_group::<MAX_SUBDEVICES, PDI_BYTES>(ethercat_now),
                soon(20),
            )
            .map_err(|l| lost_at_start(iface, l))?
            .map_err(|e| {
                anyhow!("bus.ethercat.interface = {iface:?}: no EtherCAT bus answered ({e})")
            })?;
        let position = usize::from(s.position);
        if position >= group.len() {
            bail!(
                "bus.ethercat.position = {position}: the bus on {iface:?} has {} device(s)",
                group.len()
            );
        }
        {
            let sd = group
                .subdevice(md, position)
                .map_err(|e| anyhow!("bus.ethercat.position = {position}: {e}"))?;
            let id = sd.identity();
            let name = sd.name();
            for (key, want, got) in [
                ("bus.ethercat.vendor_id", Some(s.vendor_id), id.vendor_id),
                (
                    "bus.ethercat.product_code",
                    Some(s.product_code),
                    id.product_id,
                ),
                ("bus.ethercat.revision", s.revision, id.revision),
            ] {
                if let Some(want) = want.filter(|w| *w != got) {
                    bail!(
                        "{key} = {want:#x}: the device at position {position} ({name:?}) reports {got:#x} in its SII \
                         (vendor {:#x}, product {:#x}, revision {:#x}): not the drive this run file names",
                        id.vendor_id,
                        id.product_id,
                        id.revision
                    );
                }
            }
            info!(
                "sensor-driver: EtherCAT device {position} on {iface}: {name:?}, vendor {:#x}, product {:#x}, revision {:#x}",
                id.vendor_id, id.product_id, id.revision
            );
            for (pdo, key) in [
                (&s.rx_pdo, "bus.ethercat.rx_pdo"),
                (&s.tx_pdo, "bus.ethercat.tx_pdo"),
            ] {
                check_objects(&mut pump, &sd, pdo, key)?;
            }
            if s.write_mapping {
                for (pdo, assign, key) in [
                    (&s.rx_pdo, 0x1C12u16, "bus.ethercat.rx_pdo"),
                    (&s.tx_pdo, 0x1C13u16, "bus.ethercat.tx_pdo"),
                ] {
                    write_mapping(&mut pump, &sd, pdo, assign, key)?;
                }
            }
            if map.mode.is_none() {
                let sdo = sd.sdo_write(0x6060, 0, cia402::MODE_CST);
                pump.drive(sdo, soon(2))
                    .map_err(|l| lost_at_start(iface, l))?
                    .map_err(|e| anyhow!("bus.ethercat.rx_pdo.entries: 0x6060 is not mapped and writing CST to it by SDO failed: {e}"))?;
            }
        }
        let group = pump
            .drive(group.into_op(md), soon(20))
            .map_err(|l| lost_at_start(iface, l))?
            .map_err(|e| {
                anyhow!(
                    "bus.ethercat.rx_pdo, bus.ethercat.tx_pdo: the drive did not reach OP with this mapping ({e})"
                )
            })?;
        let mut expected_wkc = 0u16;
        for sd in group.iter(md) {
            let io = sd.io_raw();
            expected_wkc +=
                u16::from(!io.inputs().is_empty()) + 2 * u16::from(!io.outputs().is_empty());
        }
        {
            let sd = group
                .subdevice(md, position)
                .map_err(|e| anyhow!("bus.ethercat.position = {position}: {e}"))?;
            let io = sd.io_raw();
            for (key, what, got, want) in [
                (
                    "bus.ethercat.tx_pdo.entries",
                    "input",
                    io.inputs().len(),
                    map.in_bytes,
                ),
                (
                    "bus.ethercat.rx_pdo.entries",
                    "output",
                    io.outputs().len(),
                    map.out_bytes,
                ),
            ] {
                if got != want {
                    bail!("{key}: the mapping is {want} {what} bytes, the drive's process image {got}: the mapping does not fit this drive");
                }
            }
        }
        let pdu_timeout = Duration::from_secs_f64(s.pdu_timeout_ms(rate_hz) / 1000.0);
        let quick_stop_cycles = (s.quick_stop_ms * rate_hz / 1000.0).ceil() as u32;
        let mut cia = Cia402::new(quick_stop_cycles);
        cia.enable(false);
        info!(
            "sensor-driver: EtherCAT drive in OP, {} input and {} output bytes, expected working counter {expected_wkc}, cycle {:.3} ms, PDU time-out {:?}",
            map.in_bytes,
            map.out_bytes,
            1000.0 / rate_hz,
            pdu_timeout
        );
        let torque_scale = map.torque.scale;
        Ok(EthercatBus {
            md,
            group,
            pump,
            position,
            map,
            cia,
            torque_scale,
            period_ns: (1e9 / rate_hz).round() as u64,
            pdu_timeout,
            expected_wkc,
            next_ns: 0,
            seq: 0,
            last: RawFrame::default(),
            readings: DriveReadings::default(),
            latched: None,
            new_fault: None,
            saw_disable: false,
            counters: EthercatCounters::default(),
            last_master_error: None,
            announced_enabled: false,
            exchange_time: RoundTrip::new(TIMING_WARMUP_S),
            wake_lateness: RoundTrip::new(TIMING_WARMUP_S),
            driver_part: RoundTrip::new(TIMING_WARMUP_S),
            handed_over_ns: 0,
        })
    }

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
                self.last_master_error = Some(e);
                return Err(BusFault::FrameLost {
                    os_error: pump.last_os_error,
                });
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

/// Reads every object a PDO maps, by SDO, at the entry's width: an object
/// the drive lacks (or of another width) is refused naming its entry.
fn check_objects<S>(
    pump: &mut Pump,
    sd: &ethercrab::SubDeviceRef<'_, S>,
    pdo: &PdoSettings,
    key: &str,
) -> Result<()>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    for (i, e) in pdo.entries.iter().enumerate() {
        let soon = Instant::now() + Duration::from_secs(2);
        let (index, sub) = (e.index, e.subindex);
        let read = match e.bits {
            8 => pump
                .drive(sd.sdo_read::<u8>(index, sub), soon)
                .map(|r| r.map(drop)),
            16 => pump
                .drive(sd.sdo_read::<u16>(index, sub), soon)
                .map(|r| r.map(drop)),
            _ => pump
                .drive(sd.sdo_read::<u32>(index, sub), soon)
                .map(|r| r.map(drop)),
        };
        match read {
            Ok(Ok(())) => {}
            Ok(Err(err)) => bail!(
                "{key}.entries[{i}]: the drive has no {}-bit object {index:#06x}:{sub} to map ({err})",
                e.bits
            ),
            Err(_) => bail!("{key}.entries[{i}]: no answer to the SDO read of {index:#06x}:{sub}"),
        }
    }
    Ok(())
}

/// Writes one PDO's mapping and assignment by SDO in PRE-OP (CiA 301).
fn write_mapping<S>(
    pump: &mut Pump,
    sd: &ethercrab::SubDeviceRef<'_, S>,
    pdo: &PdoSettings,
    assign: u16,
    key: &str,
) -> Result<()>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    let soon = || Instant::now() + Duration::from_secs(2);
    let mut sdo = |what: String, index: u16, sub: u8, value: SdoValue| -> Result<()> {
        let done = match value {
            SdoValue::U8(v) => pump.drive(sd.sdo_write(index, sub, v), soon()),
            SdoValue::U16(v) => pump.drive(sd.sdo_write(index, sub, v), soon()),
            SdoValue::U32(v) => pump.drive(sd.sdo_write(index, sub, v), soon()),
        };
        match done {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => bail!("{what}: the drive refused {index:#06x}:{sub} ({e})"),
            Err(_) => bail!("{what}: no answer to the SDO write of {index:#06x}:{sub}"),
        }
    };
    sdo(format!("{key}.index"), assign, 0, SdoValue::U8(0))?;
    sdo(format!("{key}.index"), pdo.index, 0, SdoValue::U8(0))?;
    for (i, e) in pdo.entries.iter().enumerate() {
        let word = (u32::from(e.index) << 16) | (u32::from(e.subindex) << 8) | u32::from(e.bits);
        sdo(
            format!("{key}.entries[{i}]"),
            pdo.index,
            (i + 1) as u8,
            SdoValue::U32(word),
        )?;
    }
    sdo(
        format!("{key}.entries"),
        pdo.index,
        0,
        SdoValue::U8(pdo.entries.len() as u8),
    )?;
    sdo(format!("{key}.index"), assign, 1, SdoValue::U16(pdo.index))?;
    sdo(format!("{key}.index"), assign, 0, SdoValue::U8(1))?;
    Ok(())
}

enum SdoValue {
    U8(u8),
    U16(u16),
    U32(u32),
}

fn lost_at_start(iface: &str, l: Lost) -> anyhow::Error {
    if l.os_error != 0 {
        anyhow!(
            "bus.ethercat.interface = {iface:?}: cannot send on it ({}); is it up?",
            std::io::Error::from_raw_os_error(l.os_error)
        )
    } else {
        anyhow!("bus.ethercat.interface = {iface:?}: no answer from the bus in time")
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
        } else if now < self.next_ns {
            sleep_until_ns(self.next_ns);
        }
        let start = monotonic_ns();
        let late_ns = start.saturating_sub(self.next_ns);
        let missed = self.counters.cycles > 0 && late_ns > self.period_ns;
        self.next_ns = if late_ns > self.period_ns {
            start + self.period_ns
        } else {
            self.next_ns + self.period_ns
        };
        self.counters.cycles += 1;
        let mut status = 0;
        let mut cycle_fault = None;
        if missed {
            self.counters.cycles_missed += 1;
            cycle_fault = Some(BusFault::CycleMissed {
                late_us: (late_ns / 1000).min(u64::from(u32::MAX)) as u32,
            });
        }
        let scheduled_ns = start - late_ns;
        let exchanged = self.exchange();
        if exchanged.is_ok() {
            self.exchange_time.record(start, monotonic_ns());
        }
        self.wake_lateness.record(scheduled_ns, start);
        match exchanged {
            Err(BusFault::FrameLost { .. }) => self.counters.frames_lost += 1,
            Err(BusFault::WorkingCounter { .. } | BusFault::DeviceVanished) => {
                self.counters.wkc_errors += 1
            }
            _ => {}
        }
        if let Err(f) = exchanged {
            cycle_fault = cycle_fault.or(Some(f));
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

    fn take_fault(&mut self) -> Option<BusFault> {
        let f = self.new_fault.take();
        if let Some(f) = f {
            match f {
                BusFault::DriveFault { error_code, .. } => error!(
                    "sensor-driver: EtherCAT drive fault {f:?}, error code {error_code:#06x}; powering down"
                ),
                _ => warn!("sensor-driver: EtherCAT fault {f:?}; powering the drive down"),
            }
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_read_and_write_little_endian_signed_and_saturate() {
        let mut image = [0u8; 8];
        let f16 = Field {
            offset: 2,
            bits: 16,
            scale: 1.0,
        };
        f16.write(&mut image, -2);
        assert_eq!(image[2..4], [0xFE, 0xFF]);
        assert_eq!(f16.read(&image), -2);
        f16.write(&mut image, 100_000);
        assert_eq!(f16.read(&image), 32767, "saturated, not wrapped");
        let f32_ = Field {
            offset: 4,
            bits: 32,
            scale: 1.0,
        };
        f32_.write(&mut image, 0x0102_0304);
        assert_eq!(image[4..8], [4, 3, 2, 1]);
        let f8 = Field {
            offset: 0,
            bits: 8,
            scale: 1.0,
        };
        f8.write(&mut image, -200);
        assert_eq!(f8.read(&image), -128);
        assert_eq!(image[2..4], [0xFF, 0x7F], "neighbours untouched");
    }
}
