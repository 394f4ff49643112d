//! Bring-up: the interface opened, the bus scanned, the drive's identity
//! and objects checked, the mapping written in PRE-OP, the drive taken to
//! OP and its process image checked. Every refusal is an
//! [`EthercatError`] naming the run-file key.

use std::time::{Duration, Instant};

use ethercrab::{std::ethercat_now, MainDevice, MainDeviceConfig, Timeouts};
use exo_config::{EthercatSettings, PdoSettings};
use tracing::info;

use super::map::Map;
use super::pump::{Lost, Pump};
use super::socket::RawSocket;
use super::{
    DriveReadings, EthercatBus, EthercatCounters, EthercatError, MAX_SUBDEVICES, PDI_BYTES,
    PDU_STORAGE, TIMING_WARMUP_S,
};
use crate::cia402::{self, Cia402};
use crate::{RawFrame, RoundTrip};

impl EthercatBus {
    /// Brings the bus up and the drive to OP (not yet enabled: that
    /// happens in the first cycles). Refuses, naming the run-file key, an
    /// interface that cannot be opened, a bus without the device, a device
    /// with another identity and a mapping the drive refuses or that does
    /// not match its process image. Once per process (ethercrab's frame
    /// storage is static).
    pub fn open(s: &EthercatSettings, rate_hz: f64) -> Result<Self, EthercatError> {
        let map = Map::new(s)?;
        let socket = RawSocket::open(&s.interface).map_err(|source| EthercatError::Interface {
            interface: s.interface.clone(),
            source,
        })?;
        let (tx, rx, pdu_loop) = PDU_STORAGE
            .try_split()
            .map_err(|()| EthercatError::OpenedTwice)?;
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
            late_replies: 0,
        };
        let iface = &s.interface;
        let soon = |secs| Instant::now() + Duration::from_secs(secs);
        let group = pump
            .drive(
                md.init_single_group::<MAX_SUBDEVICES, PDI_BYTES>(ethercat_now),
                soon(20),
            )
            .map_err(|l| lost_at_start(iface, l))?
            .map_err(|error| EthercatError::NoBus {
                interface: iface.clone(),
                error,
            })?;
        let position = usize::from(s.position);
        if position >= group.len() {
            return Err(EthercatError::PositionPastBus {
                position,
                interface: iface.clone(),
                devices: group.len(),
            });
        }
        {
            let sd = group
                .subdevice(md, position)
                .map_err(|error| EthercatError::Position { position, error })?;
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
                    return Err(EthercatError::Identity {
                        key,
                        want,
                        got,
                        position,
                        name: name.to_owned(),
                        vendor_id: id.vendor_id,
                        product_code: id.product_id,
                        revision: id.revision,
                    });
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
                    .map_err(|error| EthercatError::ModeOfOperation { error })?;
            }
        }
        let group = pump
            .drive(group.into_op(md), soon(20))
            .map_err(|l| lost_at_start(iface, l))?
            .map_err(|error| EthercatError::NotOp { error })?;
        let mut expected_wkc = 0u16;
        for sd in group.iter(md) {
            let io = sd.io_raw();
            expected_wkc +=
                u16::from(!io.inputs().is_empty()) + 2 * u16::from(!io.outputs().is_empty());
        }
        {
            let sd = group
                .subdevice(md, position)
                .map_err(|error| EthercatError::Position { position, error })?;
            let io = sd.io_raw();
            for (key, direction, image, mapped) in [
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
                if image != mapped {
                    return Err(EthercatError::ImageSize {
                        key,
                        direction,
                        mapped,
                        image,
                    });
                }
            }
        }
        let pdu_timeout = Duration::from_secs_f64(s.pdu_timeout_ms(rate_hz) / 1000.0);
        let quick_stop_cycles = (s.quick_stop_ms * rate_hz / 1000.0).ceil() as u32;
        let mut cia = Cia402::new(quick_stop_cycles);
        cia.enable(false);
        info!(
            "sensor-driver: EtherCAT drive in OP, {} input and {} output bytes, expected working counter {expected_wkc}, cycle {:.3} ms (the last {} µs of each wait spun), PDU time-out {:?}, latching after {} missed cycles in a row",
            map.in_bytes,
            map.out_bytes,
            1000.0 / rate_hz,
            s.wake_spin_us,
            pdu_timeout,
            s.max_missed_cycles(rate_hz)
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
            wake_spin_ns: s.wake_spin_ns(),
            pdu_timeout,
            max_missed_cycles: u64::from(s.max_missed_cycles(rate_hz)),
            watchdog: s.drive_watchdog_registers(rate_hz),
            watchdog_cycles: s.drive_watchdog_cycles(rate_hz),
            watchdog_armed: false,
            miss_run: 0,
            cycle_clean: false,
            late_replies_logged_ns: 0,
            late_replies_logged: 0,
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
}

/// Reads every object a PDO maps, by SDO, at the entry's width: an object
/// the drive lacks (or of another width) is refused naming its entry.
fn check_objects<S>(
    pump: &mut Pump,
    sd: &ethercrab::SubDeviceRef<'_, S>,
    pdo: &PdoSettings,
    key: &'static str,
) -> Result<(), EthercatError>
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
            Ok(Err(error)) => {
                return Err(EthercatError::NoObject {
                    pdo: key,
                    entry: i,
                    bits: e.bits,
                    index,
                    subindex: sub,
                    error,
                })
            }
            Err(_) => {
                return Err(EthercatError::SdoReadUnanswered {
                    pdo: key,
                    entry: i,
                    index,
                    subindex: sub,
                })
            }
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
) -> Result<(), EthercatError>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    let soon = || Instant::now() + Duration::from_secs(2);
    let mut sdo = |key: String, index: u16, subindex: u8, value: SdoValue| {
        let done = match value {
            SdoValue::U8(v) => pump.drive(sd.sdo_write(index, subindex, v), soon()),
            SdoValue::U16(v) => pump.drive(sd.sdo_write(index, subindex, v), soon()),
            SdoValue::U32(v) => pump.drive(sd.sdo_write(index, subindex, v), soon()),
        };
        match done {
            Ok(Ok(())) => Ok(()),
            Ok(Err(error)) => Err(EthercatError::SdoWriteRefused {
                key,
                index,
                subindex,
                error,
            }),
            Err(_) => Err(EthercatError::SdoWriteUnanswered {
                key,
                index,
                subindex,
            }),
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

/// A bring-up step's frame lost: not sent (the OS error) or not answered.
fn lost_at_start(iface: &str, l: Lost) -> EthercatError {
    if l.os_error != 0 {
        EthercatError::CannotSend {
            interface: iface.into(),
            os_error: l.os_error,
        }
    } else {
        EthercatError::NoAnswer {
            interface: iface.into(),
        }
    }
}
