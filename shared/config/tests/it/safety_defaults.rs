//! Every default of the run file's `[safety]`, `[controller.limits]`, `[bus]`
//! and `[bus.ethercat]` sections, pinned to a literal (issue 35, item 3): a
//! changed default fails here. Each value is read from a run file in which
//! the key is absent (the shipped `configs/default.toml` writes
//! `drive_watchdog_ms` and `bus_deadline_ms` out, so loading it as it is
//! never reaches their defaults: how `default_drive_watchdog_ms -> 1.0`
//! survived). Each assertion says where its value comes from, or that no
//! source is recorded. A key without a default is pinned as required: a
//! default added to it fails here too.
//!
//! docs/testing.md, "Safety defaults pinned (issue 35, item 3)", lists them.

use crate::common::{accepted, refused_naming};
use exo_config::{BusBackend, BusSettings, PdoRole};

/// `[safety]` written with only its required keys: the other three take
/// their defaults.
#[test]
fn safety_defaults() {
    let c = accepted(
        "safety-min",
        &[
            // The trailing comments of these lines stay, as comments.
            ("drive_watchdog_ms = 10.0", ""),
            ("bus_deadline_ms = 5.0", ""),
        ],
    );
    let s = c.safety;
    // No source recorded; chosen in 68691cf (the processes over iceoryx2):
    // a wall-clock second before a missing lockstep answer is declared.
    // It is no real-time figure (lockstep stops simulated time meanwhile);
    // `exo run` holds the plant at most half of it across a recorder
    // restart (docs/faults.md).
    assert_eq!(s.lockstep_timeout_ms, 1000.0);
    // Issue 22 asked for it ("`drive_watchdog_ms`, default 10"), as an
    // EtherCAT drive's sync-manager watchdog, against its criterion
    // DRIVE_FAULT within 20 ms of the last motor command; BENCHMARKS.md
    // ("Detection latencies") measured 11.05 ms p50/p99 11.09 ms over 20
    // runs at this value (10 ms plus the tick it counts in). Ten cycles at
    // 1 kHz: docs/hardware.md step 5 sets a real drive's watchdog to "a few
    // cycles". Not the ESC's power-on default (ETG/Beckhoff ESC: watchdog
    // divider 2498 → 100 µs × WD_PD 1000 = 100 ms), ten times longer.
    assert_eq!(s.drive_watchdog_ms, 10.0);
    // No source recorded for the value itself; chosen in 95d6e6c (issue 22,
    // which sets only its criterion: BUS_FAULT within 15 ms of the last
    // frame). BENCHMARKS.md ("Detection latencies") measured 5.09 ms p50,
    // 5.14 ms p99 over 20 runs at this value. It equals the shipped
    // command and sample deadlines (configs/default.toml, 5 ms).
    assert_eq!(s.bus_deadline_ms, 5.0);

    // The rest of `[safety]` has no default: each is the rig's to set.
    for (tag, line, key) in [
        ("cmd", "command_deadline_ms = 5.0", "command_deadline_ms"),
        ("smp", "sample_deadline_ms = 5.0", "sample_deadline_ms"),
        ("safe", "safe_state = \"gravity_only\"", "safe_state"),
    ] {
        refused_naming(&format!("safety-no-{tag}"), &[(line, "")], key);
    }
}

/// `[controller]` without `gravity_compensation` compensates gravity: on a
/// vertical rig a controller that silently stopped would let the arm's
/// weight (about 16 Nm at 45° for the default plant) fall on the wearer.
/// Off only when a run file says so (a horizontal rig). The shipped
/// `configs/default.toml` leaves the key out, so it loads the default.
#[test]
fn the_controller_compensates_gravity_unless_told_not_to() {
    let c = accepted("gravity-default", &[]);
    assert!(c.controller.gravity_compensation);
}

/// `[controller.limits]` has no default at all: every limit is the rig's,
/// and a run file that leaves one out is refused naming it (a default
/// added to any of them fails here).
#[test]
fn controller_limits_have_no_defaults() {
    for (tag, line, key) in [
        ("torque", "torque_nm = 40.0", "torque_nm"),
        (
            "rate",
            "torque_rate_nm_per_s = 4000.0",
            "torque_rate_nm_per_s",
        ),
        ("theta", "theta_rad = [-0.6, 2.6]", "theta_rad"),
        ("tauc", "tau_c_nm = 60.0", "tau_c_nm"),
    ] {
        refused_naming(&format!("limits-no-{tag}"), &[(line, "")], key);
    }
}

/// `[bus]`: a run file without the table is on the simulator's bus, the
/// `Default` of `BusSettings`; a `[bus]` table must name its backend.
#[test]
fn bus_defaults() {
    // configs/default.toml has no `[bus]` table.
    let c = accepted("bus-absent", &[]);
    assert_eq!(c.bus, BusSettings::default());
    // No external source: a design choice of a599c24 (the `[bus]` table
    // came with the HardwareBus trait): a run file that names no bus never
    // drives hardware (run.rs: "`[bus]` (default: the simulator's)";
    // ARCHITECTURE.md: hardware is this setting plus
    // `services.plant_sim = false`).
    assert_eq!(c.bus.backend, BusBackend::Simulator);
    // No EtherCAT table unless one is written (75b6a48); `backend =
    // "ethercat"` without it is refused (configs.rs).
    assert_eq!(c.bus.ethercat, None);
    // An empty `[bus]` is not the simulator's: `backend` is required once
    // the table is written, so a `[bus.ethercat]` table without a backend
    // is refused rather than silently run on the simulator.
    refused_naming(
        "bus-empty",
        &[("[safety]\n", "[bus]\n\n[safety]\n")],
        "backend",
    );
    refused_naming(
        "bus-no-backend",
        &[(
            "[safety]\n",
            "[bus.ethercat]\ninterface = \"ecm0\"\n\n[safety]\n",
        )],
        "backend",
    );
}

/// The `[bus.ethercat]` table with only its required keys (interface,
/// identity and the four entries a CST drive needs), inserted before
/// `[safety]`.
const MINIMAL_ETHERCAT: &str = "[bus]
backend = \"ethercat\"

[bus.ethercat]
interface = \"ecm0\"
vendor_id = 0x29c
product_code = 0x03b11002

[bus.ethercat.rx_pdo]
index = 0x1600
entries = [
  { index = 0x6040, bits = 16, role = \"controlword\" },
  { index = 0x6071, bits = 16, role = \"target_torque\", scale = 0.001 },
]

[bus.ethercat.tx_pdo]
index = 0x1A00
entries = [
  { index = 0x6041, bits = 16, role = \"statusword\" },
  { index = 0x6064, bits = 32, role = \"position_actual\" },
]

[safety]
";

/// `[bus.ethercat]` written with only its required keys (interface,
/// identity and the four entries a CST drive needs): the rest take their
/// defaults.
#[test]
fn bus_ethercat_defaults() {
    let minimal = MINIMAL_ETHERCAT;
    let c = accepted(
        "ecat-min",
        &[
            // EtherCAT runs on the wall clock only.
            ("timing = \"lockstep\"", "timing = \"realtime\""),
            ("[safety]\n", minimal),
            // At least the 50 ms of missed cycles the bus rides through.
            ("sample_deadline_ms = 5.0", "sample_deadline_ms = 50.0"),
        ],
    );
    assert_eq!(c.bus.backend, BusBackend::Ethercat);
    let e = c.bus.ethercat.expect("the [bus.ethercat] table");
    // ETG.1000.4 position (auto-increment) addressing counts from 0 at the
    // first device after the master: the default is the first drive on the
    // segment (the key's doc: "counting from 0 at the master").
    assert_eq!(e.position, 0);
    // No source recorded; chosen in 75b6a48: absent, the SII revision is
    // not checked (vendor ID and product code always are).
    assert_eq!(e.revision, None);
    // docs/hardware.md ("Each exchange is bounded by the PDU time-out ...
    // default one period"): absent, one control period, the longest the
    // key accepts (a longer wait would miss the next cycle).
    assert_eq!(e.pdu_timeout_ms, None);
    assert_eq!(e.pdu_timeout_ms(c.run.rate_hz), 1.0); // 1000 Hz → 1 ms
    assert_eq!(e.pdu_timeout_ms(250.0), 4.0); // 250 Hz → 4 ms
                                              // No source recorded; chosen in 75b6a48. CiA 402 fixes no quick-stop
                                              // time (the drive's quick-stop option code 0x605A decides what it does
                                              // meanwhile, docs/hardware.md); KickCAT's emulated drive ignores quick
                                              // stop, so no measurement holds it either.
    assert_eq!(e.quick_stop_ms, 20.0);
    // docs/hardware.md step 3: "Most drives' default PDOs are for CSP, so
    // keep write_mapping = true" (the emulated drive's hold no 0x6071 or
    // 0x6077: configs/ethercat-kickcat.toml).
    assert!(e.write_mapping);
    // docs/hardware.md ("Less lateness"): spinning before the deadline took
    // the typical wake-up latency but not the millisecond tail that late
    // cycles come from, at up to that much of a core: off unless asked.
    assert_eq!(e.wake_spin_us, 0.0);
    // CiA 301: a VAR object's value sits at sub-index 0, and every CiA 402
    // object mapped here (0x6040, 0x6071, 0x6041, 0x6064) is a VAR.
    for entry in e.rx_pdo.entries.iter().chain(&e.tx_pdo.entries) {
        assert_eq!(entry.subindex, 0, "{:?}", entry.role);
    }
    // No scale unless written: words and counts take none, and a torque
    // without one is refused (ethercat.rs tests), never a guessed 1:1.
    for role in [
        PdoRole::Controlword,
        PdoRole::Statusword,
        PdoRole::PositionActual,
    ] {
        let pdo = if role.is_output() {
            &e.rx_pdo
        } else {
            &e.tx_pdo
        };
        assert_eq!(pdo.find(role).map(|(_, p)| p.scale), Some(None), "{role:?}");
    }
}

/// The controller's sample deadline spans the missed cycles the EtherCAT
/// bus rides through (`bus.ethercat.max_missed_cycles`, 50 at 1 kHz by
/// default): a shorter one would latch the controller on a stall the
/// driver holds through, so it is refused naming the key; the span itself
/// is accepted, and a shorter span lets a shorter deadline through.
#[test]
fn an_ethercat_sample_deadline_within_the_buses_ride_through_is_refused() {
    let ecat = [
        ("timing = \"lockstep\"", "timing = \"realtime\""),
        ("[safety]\n", MINIMAL_ETHERCAT),
    ];
    let with = |deadline: &'static str| {
        let mut e = ecat.to_vec();
        e.push(("sample_deadline_ms = 5.0", deadline));
        e
    };
    refused_naming(
        "ecat-smp-49",
        &with("sample_deadline_ms = 49.0"),
        "safety.sample_deadline_ms",
    );
    refused_naming("ecat-smp-5", &ecat, "safety.sample_deadline_ms");
    accepted("ecat-smp-50", &with("sample_deadline_ms = 50.0"));
    let mut five = ecat.to_vec();
    five.push((
        "interface = \"ecm0\"",
        "interface = \"ecm0\"\nmax_missed_cycles = 5",
    ));
    accepted("ecat-smp-5-missed-5", &five);
}
