//! `[bus.ethercat]`: a CiA 402 servo drive on EtherCAT, driven in cyclic
//! synchronous torque mode (CST) by the sensor driver's EtherCAT backend.
//!
//! Everything that differs from one drive to another is here, not in code:
//! the interface, the drive's place on the bus and identity, the PDO
//! mapping (object index, sub-index, width and what each entry means) and
//! the scalings from drive units to physical ones. The cycle is the run's
//! (`run.rate_hz`); positions are encoder counts converted with `[rig]`.

use serde::{Deserialize, Serialize};

use crate::Check;

/// Largest process image (bytes) of one direction this backend accepts.
/// ethercrab's process image is sized at compile time in the driver
/// (`PDI_BYTES` there); a mapping larger than this "does not fit".
pub const MAX_PDO_BYTES: usize = 64;

/// Most entries in one PDO (CiA 301 allows 64; drives typically 8–16).
pub const MAX_PDO_ENTRIES: usize = 16;

/// `[bus.ethercat]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EthercatSettings {
    /// The network interface the EtherCAT segment hangs on (e.g. `eth1`).
    /// It must exist and be openable as a raw socket (`CAP_NET_RAW`).
    pub interface: String,
    /// The drive's place on the bus, counting from 0 at the master. Range
    /// [0, 255].
    #[serde(default)]
    pub position: u16,
    /// The identity the drive must report in its SII EEPROM (what the
    /// master reads at discovery; it can differ from object 0x1018):
    /// CiA vendor ID.
    pub vendor_id: u32,
    /// SII product code.
    pub product_code: u32,
    /// SII revision number; not checked when absent.
    #[serde(default)]
    pub revision: Option<u32>,
    /// How long (ms) one exchange of process data may take before the
    /// frame counts as lost. Default: one control period. Range (0, 1000],
    /// and at most one control period (a longer wait would miss the next
    /// cycle on a broken link).
    #[serde(default)]
    pub pdu_timeout_ms: Option<f64>,
    /// After a fault the motor is powered down in two steps: quick stop
    /// (controlword 0x0002) for this long (ms), or until the drive reports
    /// quick stop active, then disable voltage (0x0000). Range [0, 1000].
    #[serde(default = "default_quick_stop_ms")]
    pub quick_stop_ms: f64,
    /// Missed cycles in a row after which the safe state latches. A cycle
    /// is missed when the master wakes for it more than a period late
    /// (each period skipped counts one) or its reply does not come back
    /// within the PDU time-out; the drive holds its last set-point
    /// meanwhile (CST) and the sample is flagged `LATE` or `STALE`. A
    /// cycle on time with its reply back ends the run. Range [1, 1000],
    /// and at most [`MAX_MISSED_SPAN_MS`] of cycles. Default: the cycles
    /// in [`DEFAULT_MISSED_SPAN_MS`] (50 at 1 kHz, 5 at 100 Hz;
    /// docs/hardware.md says why), [`EthercatSettings::max_missed_cycles`].
    #[serde(default)]
    pub max_missed_cycles: Option<u32>,
    /// The drive's own sync-manager watchdog, in cycles: the drive takes
    /// its outputs (the torque) away by itself when no process data has
    /// reached it for this long, whatever the master does. The master
    /// arms it in its first cycle (ESC registers 0x0400, a 100 µs unit,
    /// and 0x0420) and reads it back: a drive that refuses it is named
    /// before Operation Enabled. At least `max_missed_cycles` (a shorter
    /// one would stop the drive while the master still rides a run of
    /// misses through), at most 100 ms of cycles. Default: the cycles in
    /// 100 ms, a real ESC's power-on setting (KickCAT's emulated one
    /// starts with it off) ([`EthercatSettings::drive_watchdog_cycles`]).
    #[serde(default)]
    pub drive_watchdog_cycles: Option<u32>,
    /// The last part (µs) of each wait for the cycle's deadline that the
    /// master spends polling the clock instead of asleep in the kernel
    /// (`exo_service_kit::sleep_then_spin_until_ns`): the kernel's wake-up
    /// latency then falls before the deadline, at the cost of that much of
    /// one core per cycle. 0 sleeps to the deadline. Range [0, 1000], and
    /// less than one control period. Default 0 (docs/hardware.md, "Less
    /// lateness", gives the measurements).
    #[serde(default)]
    pub wake_spin_us: f64,
    /// Write the PDO mapping below into the drive in PRE-OP (CiA 301:
    /// 0x1C1x:0 = 0, the PDO's entries and count, 0x1C1x:1, 0x1C1x:0 = 1).
    /// `false`: the drive's own mapping is used and only its size is
    /// checked against the one below. Default `true`.
    #[serde(default = "default_true")]
    pub write_mapping: bool,
    /// Outputs, master → drive (RxPDO).
    pub rx_pdo: PdoSettings,
    /// Inputs, drive → master (TxPDO).
    pub tx_pdo: PdoSettings,
}

fn default_quick_stop_ms() -> f64 {
    20.0
}

/// The span (ms) of missed cycles in a row that latches by default
/// (docs/hardware.md, "Late and lost cycles": the stalls measured on an
/// ordinary 2-core Linux computer, against how long a held set-point is
/// harmless).
pub const DEFAULT_MISSED_SPAN_MS: f64 = 50.0;

/// The longest span (ms) of missed cycles `bus.ethercat.max_missed_cycles`
/// may allow: the EtherCAT slave controller's own default sync-manager
/// watchdog (100 ms, ETG.1000.4), the longest a drive holds a set-point
/// by itself.
pub const MAX_MISSED_SPAN_MS: f64 = 100.0;

/// The ESC watchdog divider (register 0x0400) for a 100 µs unit:
/// `(2498 + 2) × 40 ns` (ETG.1000.4; also the ESC's power-on value).
pub const WATCHDOG_DIVIDER_100_US: u16 = 2498;

fn default_true() -> bool {
    true
}

/// One PDO and its entries, in the order they sit in the process image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdoSettings {
    /// The PDO's mapping object: 0x1600–0x17FF (RxPDO) or 0x1A00–0x1BFF
    /// (TxPDO).
    pub index: u16,
    /// Its entries, first byte first.
    pub entries: Vec<PdoEntry>,
}

/// One mapped object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdoEntry {
    /// Object index, e.g. 0x6071.
    pub index: u16,
    /// Object sub-index (default 0).
    #[serde(default)]
    pub subindex: u8,
    /// Width in bits: 8, 16 or 32 (the entries are byte-aligned).
    pub bits: u8,
    /// What the entry means.
    pub role: PdoRole,
    /// Physical units per drive unit, for the roles that carry a torque or
    /// a force: `target_torque`, `torque_actual` (Nm per unit; CiA 402:
    /// rated torque 0x6076 / 1000), `velocity_actual` (rad/s per unit),
    /// `cuff_*` (N or Nm per unit). Finite and non-zero. Counts
    /// (`position_actual`, `sea_deflection`) use `[rig]`; words take none.
    #[serde(default)]
    pub scale: Option<f64>,
}

/// What a PDO entry means to the driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PdoRole {
    /// 0x6040 controlword (RxPDO, 16 bits).
    Controlword,
    /// 0x6060 modes of operation (RxPDO, 8 bits): written as CST (10)
    /// every cycle. When not mapped, it is written once by SDO.
    ModeOfOperation,
    /// 0x6071 target torque (RxPDO).
    TargetTorque,
    /// 0x6041 statusword (TxPDO, 16 bits).
    Statusword,
    /// 0x6061 modes of operation display (TxPDO, 8 bits): must read CST.
    ModeDisplay,
    /// 0x6064 position actual value (TxPDO): joint encoder counts
    /// (`rig.encoder_counts_per_rev`).
    PositionActual,
    /// 0x606C velocity actual value (TxPDO), kept for logs; the driver
    /// filters its own velocity from the angle.
    VelocityActual,
    /// 0x6077 torque actual value (TxPDO), kept for logs.
    TorqueActual,
    /// 0x603F error code (TxPDO, 16 bits), logged with a drive fault.
    ErrorCode,
    /// SEA spring-deflection encoder counts (`rig.sea_counts_per_rev`),
    /// e.g. a second encoder's position.
    SeaDeflection,
    /// Cuff force along x (N).
    CuffFx,
    /// Cuff force along y (N).
    CuffFy,
    /// Cuff force along z (N).
    CuffFz,
    /// Cuff torque about x (Nm).
    CuffTx,
    /// Cuff torque about y (Nm).
    CuffTy,
    /// Cuff torque about z (Nm).
    CuffTz,
}

impl PdoRole {
    /// Whether the entry is an output (RxPDO, master → drive).
    pub fn is_output(self) -> bool {
        matches!(
            self,
            PdoRole::Controlword | PdoRole::ModeOfOperation | PdoRole::TargetTorque
        )
    }

    /// The width this role must have, if fixed by CiA 402.
    pub fn fixed_bits(self) -> Option<u8> {
        match self {
            PdoRole::Controlword | PdoRole::Statusword | PdoRole::ErrorCode => Some(16),
            PdoRole::ModeOfOperation | PdoRole::ModeDisplay => Some(8),
            _ => None,
        }
    }

    /// Whether the role takes a `scale`.
    pub fn is_scaled(self) -> bool {
        matches!(
            self,
            PdoRole::TargetTorque
                | PdoRole::TorqueActual
                | PdoRole::VelocityActual
                | PdoRole::CuffFx
                | PdoRole::CuffFy
                | PdoRole::CuffFz
                | PdoRole::CuffTx
                | PdoRole::CuffTy
                | PdoRole::CuffTz
        )
    }
}

impl PdoSettings {
    /// Size of the PDO's process image (bytes).
    pub fn bytes(&self) -> usize {
        self.entries.iter().map(|e| usize::from(e.bits / 8)).sum()
    }

    /// Byte offset of the entry with `role`, and the entry.
    pub fn find(&self, role: PdoRole) -> Option<(usize, PdoEntry)> {
        let mut offset = 0;
        for e in &self.entries {
            if e.role == role {
                return Some((offset, *e));
            }
            offset += usize::from(e.bits / 8);
        }
        None
    }
}

impl EthercatSettings {
    /// The PDU time-out (ms): `pdu_timeout_ms`, or one period at `rate_hz`.
    pub fn pdu_timeout_ms(&self, rate_hz: f64) -> f64 {
        self.pdu_timeout_ms.unwrap_or(1000.0 / rate_hz)
    }

    /// The last part of each wait spent polling the clock, in ns
    /// (`wake_spin_us` × 1000, rounded).
    pub fn wake_spin_ns(&self) -> u64 {
        (self.wake_spin_us * 1e3).round() as u64
    }

    /// Missed cycles in a row that latch at `rate_hz`: `max_missed_cycles`,
    /// or the cycles in [`DEFAULT_MISSED_SPAN_MS`] (at least 1).
    pub fn max_missed_cycles(&self, rate_hz: f64) -> u32 {
        self.max_missed_cycles
            .unwrap_or_else(|| ((DEFAULT_MISSED_SPAN_MS * rate_hz / 1000.0).floor() as u32).max(1))
    }

    /// The drive's sync-manager watchdog at `rate_hz` (cycles):
    /// `drive_watchdog_cycles`, or the cycles in [`MAX_MISSED_SPAN_MS`]
    /// (at least 1).
    pub fn drive_watchdog_cycles(&self, rate_hz: f64) -> u32 {
        self.drive_watchdog_cycles
            .unwrap_or_else(|| ((MAX_MISSED_SPAN_MS * rate_hz / 1000.0).floor() as u32).max(1))
    }

    /// The ESC's watchdog registers for [`Self::drive_watchdog_cycles`]:
    /// the divider (0x0400) that makes its unit 100 µs, `(divider + 2) ×
    /// 40 ns` (ETG.1000.4), and the process-data watchdog time (0x0420) in
    /// that unit, rounded up, at least 1.
    pub fn drive_watchdog_registers(&self, rate_hz: f64) -> (u16, u16) {
        let units = (f64::from(self.drive_watchdog_cycles(rate_hz)) * 1e4 / rate_hz).ceil();
        (
            WATCHDOG_DIVIDER_100_US,
            units.clamp(1.0, f64::from(u16::MAX)) as u16,
        )
    }

    /// Records every value at fault, naming its key under `bus.ethercat`.
    pub(crate) fn check(&self, c: &Check<'_>, rate_hz: f64) {
        let iface = &self.interface;
        if iface.is_empty() || iface.len() >= 16 || iface.contains(['/', ' ', '\0']) {
            c.note(
                "bus.ethercat.interface",
                format!("must be a network interface name (1 to 15 characters, no '/' or space), got {iface:?}"),
            );
        }
        c.key("bus.ethercat.position", f64::from(self.position));
        if let Some(t) = self.pdu_timeout_ms {
            let period_ms = 1000.0 / rate_hz;
            if c.key("bus.ethercat.pdu_timeout_ms", t) && t > period_ms {
                c.note(
                    "bus.ethercat.pdu_timeout_ms",
                    format!("{t} ms is longer than one control period ({period_ms} ms): a lost frame would miss the next cycle"),
                );
            }
        }
        c.key("bus.ethercat.quick_stop_ms", self.quick_stop_ms);
        let period_us = 1e6 / rate_hz;
        if c.key("bus.ethercat.wake_spin_us", self.wake_spin_us) && self.wake_spin_us >= period_us {
            c.note(
                "bus.ethercat.wake_spin_us",
                format!(
                    "{} µs is not less than one control period ({period_us} µs): the master would never sleep",
                    self.wake_spin_us
                ),
            );
        }
        if let Some(n) = self.drive_watchdog_cycles {
            let span_ms = f64::from(n) * 1000.0 / rate_hz;
            let missed = self.max_missed_cycles(rate_hz);
            if c.key("bus.ethercat.drive_watchdog_cycles", f64::from(n)) {
                if span_ms > MAX_MISSED_SPAN_MS {
                    c.note(
                        "bus.ethercat.drive_watchdog_cycles",
                        format!("{n} cycles at {rate_hz} Hz are {span_ms} ms, longer than {MAX_MISSED_SPAN_MS} ms"),
                    );
                } else if n < missed {
                    c.note(
                        "bus.ethercat.drive_watchdog_cycles",
                        format!("{n} cycles is shorter than the {missed} missed cycles in a row the master rides through (bus.ethercat.max_missed_cycles): the drive would stop first"),
                    );
                }
            }
        }
        if let Some(n) = self.max_missed_cycles {
            let span_ms = f64::from(n) * 1000.0 / rate_hz;
            if c.key("bus.ethercat.max_missed_cycles", f64::from(n)) && span_ms > MAX_MISSED_SPAN_MS
            {
                c.note(
                    "bus.ethercat.max_missed_cycles",
                    format!("{n} cycles at {rate_hz} Hz are {span_ms} ms, longer than {MAX_MISSED_SPAN_MS} ms without a fresh exchange"),
                );
            }
        }
        self.rx_pdo.check(c, "bus.ethercat.rx_pdo", true);
        self.tx_pdo.check(c, "bus.ethercat.tx_pdo", false);
        for (pdo, key, role) in [
            (&self.rx_pdo, "bus.ethercat.rx_pdo", PdoRole::Controlword),
            (&self.rx_pdo, "bus.ethercat.rx_pdo", PdoRole::TargetTorque),
            (&self.tx_pdo, "bus.ethercat.tx_pdo", PdoRole::Statusword),
            (&self.tx_pdo, "bus.ethercat.tx_pdo", PdoRole::PositionActual),
        ] {
            if pdo.find(role).is_none() {
                c.note(
                    &format!("{key}.entries"),
                    format!(
                        "a CST drive needs an entry with role = \"{}\"",
                        role_name(role)
                    ),
                );
            }
        }
    }
}

impl PdoSettings {
    fn check(&self, c: &Check<'_>, key: &str, outputs: bool) {
        let (lo, hi, what) = if outputs {
            (0x1600, 0x17FF, "an RxPDO mapping object, 0x1600 to 0x17FF")
        } else {
            (0x1A00, 0x1BFF, "a TxPDO mapping object, 0x1A00 to 0x1BFF")
        };
        if !(lo..=hi).contains(&self.index) {
            c.note(
                &format!("{key}.index"),
                format!("must be {what}, got {:#06x}", self.index),
            );
        }
        if self.entries.is_empty() || self.entries.len() > MAX_PDO_ENTRIES {
            c.note(
                &format!("{key}.entries"),
                format!(
                    "must hold 1 to {MAX_PDO_ENTRIES} entries, got {}",
                    self.entries.len()
                ),
            );
        }
        if self.bytes() > MAX_PDO_BYTES {
            c.note(
                &format!("{key}.entries"),
                format!(
                    "{} bytes do not fit the {MAX_PDO_BYTES}-byte process image",
                    self.bytes()
                ),
            );
        }
        for (i, e) in self.entries.iter().enumerate() {
            let k = format!("{key}.entries[{i}]");
            if e.role.is_output() != outputs {
                c.note(
                    &format!("{k}.role"),
                    format!(
                        "\"{}\" is an {}, not allowed in the {}",
                        role_name(e.role),
                        if outputs { "input" } else { "output" },
                        if outputs {
                            "RxPDO (outputs)"
                        } else {
                            "TxPDO (inputs)"
                        }
                    ),
                );
            }
            if self.entries[..i].iter().any(|p| p.role == e.role) {
                c.note(
                    &format!("{k}.role"),
                    format!("\"{}\" is mapped twice", role_name(e.role)),
                );
            }
            if !matches!(e.bits, 8 | 16 | 32) {
                c.note(
                    &format!("{k}.bits"),
                    format!("must be 8, 16 or 32, got {}", e.bits),
                );
            } else if let Some(b) = e.role.fixed_bits().filter(|b| *b != e.bits) {
                c.note(
                    &format!("{k}.bits"),
                    format!(
                        "\"{}\" is {b} bits in CiA 402, got {}",
                        role_name(e.role),
                        e.bits
                    ),
                );
            }
            match (e.role.is_scaled(), e.scale) {
                (true, None) => c.note(
                    &format!("{k}.scale"),
                    format!(
                        "\"{}\" needs a scale (physical units per drive unit)",
                        role_name(e.role)
                    ),
                ),
                (true, Some(s)) => {
                    if c.key(&format!("{k}.scale"), s) && s == 0.0 {
                        c.note(&format!("{k}.scale"), "must not be 0");
                    }
                }
                (false, Some(_)) => c.note(
                    &format!("{k}.scale"),
                    format!(
                        "\"{}\" takes no scale (counts are converted with [rig])",
                        role_name(e.role)
                    ),
                ),
                (false, None) => {}
            }
        }
    }
}

/// A role as written in the run file.
pub fn role_name(role: PdoRole) -> String {
    toml::Value::try_from(role)
        .ok()
        .and_then(|v| v.as_str().map(str::to_owned))
        .unwrap_or_else(|| format!("{role:?}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn settings() -> EthercatSettings {
        toml::from_str(
            r#"
            interface = "ecm0"
            vendor_id = 0x29c
            product_code = 0x03b11002
            [rx_pdo]
            index = 0x1600
            entries = [
              { index = 0x6040, bits = 16, role = "controlword" },
              { index = 0x6071, bits = 16, role = "target_torque", scale = 0.001 },
              { index = 0x6060, bits = 8, role = "mode_of_operation" },
            ]
            [tx_pdo]
            index = 0x1A00
            entries = [
              { index = 0x6041, bits = 16, role = "statusword" },
              { index = 0x6064, bits = 32, role = "position_actual" },
              { index = 0x6077, bits = 16, role = "torque_actual", scale = 0.001 },
            ]
            "#,
        )
        .unwrap()
    }

    fn errors(s: &EthercatSettings) -> String {
        let c = Check::with_ranges(Path::new("run.toml"), crate::RUN_RANGES);
        s.check(&c, 1000.0);
        match c.finish() {
            Ok(()) => String::new(),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_good_mapping_passes_and_its_offsets_follow_the_entries() {
        let s = settings();
        assert_eq!(errors(&s), "");
        assert_eq!(s.rx_pdo.bytes(), 5);
        assert_eq!(s.tx_pdo.bytes(), 8);
        assert_eq!(s.rx_pdo.find(PdoRole::ModeOfOperation).unwrap().0, 4);
        assert_eq!(s.tx_pdo.find(PdoRole::TorqueActual).unwrap().0, 6);
        assert!(s.tx_pdo.find(PdoRole::ErrorCode).is_none());
        assert_eq!(s.pdu_timeout_ms(1000.0), 1.0);
        // The default: the cycles in 50 ms, whatever the rate.
        assert_eq!(s.max_missed_cycles, None);
        assert_eq!(s.max_missed_cycles(1000.0), 50);
        assert_eq!(s.max_missed_cycles(100.0), 5);
        assert_eq!(s.max_missed_cycles(10.0), 1);
        // The wake-up spin: off by default; just under a period is allowed.
        assert_eq!(s.wake_spin_us, 0.0);
        assert_eq!(s.wake_spin_ns(), 0);
        let mut spin = settings();
        spin.wake_spin_us = 999.0;
        assert_eq!(errors(&spin), "");
        assert_eq!(spin.wake_spin_ns(), 999_000);
        spin.wake_spin_us = 150.0004; // rounded to the nanosecond
        assert_eq!(spin.wake_spin_ns(), 150_000);
        let mut edge = settings();
        edge.max_missed_cycles = Some(100); // 100 ms at 1 kHz: the limit itself
        assert_eq!(errors(&edge), "");
        assert_eq!(edge.max_missed_cycles(1000.0), 100);
        // The drive's watchdog: 100 ms of cycles by default (100 at
        // 1 kHz, 10 at 100 Hz: 1000 units of 100 µs either way); a given
        // one in units rounded up (7 cycles at 300 Hz: 23.33 ms → 234).
        assert_eq!(s.drive_watchdog_cycles(1000.0), 100);
        assert_eq!(s.drive_watchdog_registers(1000.0), (2498, 1000));
        assert_eq!(s.drive_watchdog_cycles(100.0), 10);
        assert_eq!(s.drive_watchdog_registers(100.0), (2498, 1000));
        let mut given = settings();
        given.drive_watchdog_cycles = Some(7);
        assert_eq!(given.drive_watchdog_registers(300.0), (2498, 234));
        assert_eq!(role_name(PdoRole::TargetTorque), "target_torque");
    }

    #[test]
    fn each_bad_mapping_is_refused_naming_its_key() {
        type Spoil = fn(&mut EthercatSettings);
        let cases: [(&str, Spoil); 18] = [
            ("bus.ethercat.rx_pdo.entries[1].scale", |s| {
                s.rx_pdo.entries[1].scale = None
            }),
            ("bus.ethercat.rx_pdo.entries[1].scale", |s| {
                s.rx_pdo.entries[1].scale = Some(f64::NAN)
            }),
            ("bus.ethercat.tx_pdo.entries[1].scale", |s| {
                s.tx_pdo.entries[1].scale = Some(2.0)
            }),
            ("bus.ethercat.rx_pdo.entries[0].bits", |s| {
                s.rx_pdo.entries[0].bits = 32
            }),
            ("bus.ethercat.tx_pdo.entries[1].bits", |s| {
                s.tx_pdo.entries[1].bits = 24
            }),
            ("bus.ethercat.tx_pdo.entries[2].role", |s| {
                s.tx_pdo.entries[2].role = PdoRole::TargetTorque
            }),
            ("bus.ethercat.tx_pdo.entries", |s| {
                s.tx_pdo.entries.remove(0);
            }),
            ("bus.ethercat.rx_pdo.index", |s| s.rx_pdo.index = 0x1A00),
            ("bus.ethercat.pdu_timeout_ms", |s| {
                s.pdu_timeout_ms = Some(2.0)
            }),
            ("bus.ethercat.interface", |s| s.interface.clear()),
            ("bus.ethercat.wake_spin_us", |s| s.wake_spin_us = f64::NAN),
            ("bus.ethercat.wake_spin_us", |s| s.wake_spin_us = -1.0),
            // One period at 1 kHz: never asleep.
            ("bus.ethercat.wake_spin_us", |s| s.wake_spin_us = 1000.0),
            ("bus.ethercat.max_missed_cycles", |s| {
                s.max_missed_cycles = Some(0)
            }),
            // 101 cycles at 1 kHz: 101 ms, beyond the slave controller's 100 ms.
            ("bus.ethercat.max_missed_cycles", |s| {
                s.max_missed_cycles = Some(101)
            }),
            ("bus.ethercat.drive_watchdog_cycles", |s| {
                s.drive_watchdog_cycles = Some(0)
            }),
            // 101 ms at 1 kHz.
            ("bus.ethercat.drive_watchdog_cycles", |s| {
                s.drive_watchdog_cycles = Some(101)
            }),
            // Shorter than the default 50 missed cycles at 1 kHz.
            ("bus.ethercat.drive_watchdog_cycles", |s| {
                s.drive_watchdog_cycles = Some(49)
            }),
        ];
        for (key, spoil) in cases {
            let mut s = settings();
            spoil(&mut s);
            let e = errors(&s);
            assert!(e.contains(key), "{key}: {e}");
        }
        let mut s = settings();
        for _ in 0..16 {
            s.tx_pdo.entries.push(PdoEntry {
                index: 0x2000,
                subindex: 0,
                bits: 32,
                role: PdoRole::SeaDeflection,
                scale: None,
            });
        }
        let e = errors(&s);
        assert!(e.contains("do not fit"), "{e}");
        assert!(e.contains("mapped twice"), "{e}");
    }
}
