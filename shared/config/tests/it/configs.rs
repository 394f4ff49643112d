//! The shipped configuration files load, and bad ones are refused naming the key.

use exo_config::*;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `exo-config-{tag}-{pid}`, removed when the test passes.
fn temp_dir(tag: &str) -> exo_test_support::ScratchDir {
    exo_test_support::ScratchDir::new(&format!("config-{tag}"))
}

#[test]
fn table_i_is_the_papers() {
    let t = ExperimentTable::from_file(&configs_dir().join("experiments.toml")).unwrap();
    assert_eq!(t.periods, 10);
    assert_eq!(t.experiment.len(), 9);
    assert_eq!(t.timing.period_s(), 60.0);
    for e in &t.experiment {
        let group = (e.number - 1) / 3;
        assert_eq!(e.alpha, [1.0, 2.0, 4.0][((e.number - 1) % 3) as usize]);
        assert_eq!(e.grip_kg, [10.0, 14.0, 27.0][group as usize]);
        assert_eq!(e.bias_nm, [0.0, 4.0, 8.0][group as usize]);
        assert_eq!(e.load_kg, 4.5);
        // Frequency range start·10^0 to start·10^0.9.
        let last = t.omega_rad_s(e, 10);
        assert!((last / e.start_omega_rad_s - 10f64.powf(0.9)).abs() < 1e-12);
        assert_eq!(t.amplitude_nm(e, 7), 2.0);
        assert!((t.amplitude_nm(e, 8) - 2.0 * 10f64.powf(0.2)).abs() < 1e-12);
    }
}

#[test]
fn ten_subjects_with_nine_experiments_each() {
    for name in ["A", "B", "C", "D", "E", "F", "G", "H", "I", "J"] {
        let s = Subject::from_file(&configs_dir().join(format!("subjects/{name}.toml"))).unwrap();
        assert_eq!(s.name, name);
        assert_eq!(s.experiment.len(), 9);
        assert_eq!(s.inertia_kg_m2, 0.11);
    }
}

#[test]
fn default_run_loads_with_its_files() {
    let cfg = RunConfig::from_file(&configs_dir().join("default.toml")).unwrap();
    assert_eq!(cfg.run.timing, TimingMode::Lockstep);
    assert_eq!(cfg.subject().name, "B");
    assert_eq!(cfg.experiment_table().timing.rest_s, 1.0);
    assert!((cfg.exo_inertia_kg_m2(4.5) - 1.01125).abs() < 1e-12);
}

#[test]
fn unknown_key_is_named_with_the_file() {
    let d = temp_dir("unknown");
    let text = std::fs::read_to_string(configs_dir().join("default.toml"))
        .unwrap()
        .replace("seed = 1", "seed = 1\nsped = 2");
    let f = write(&d, "run.toml", &text);
    let err = RunConfig::from_file(&f).unwrap_err().to_string();
    assert!(err.contains("run.toml") && err.contains("sped"), "{err}");
}

#[test]
fn impossible_values_are_named_with_the_key() {
    let base = std::fs::read_to_string(configs_dir().join("default.toml")).unwrap();
    let d = temp_dir("values");
    // Copy the referenced files' directory layout by pointing back at configs/.
    let base = base
        .replace(
            "\"plants/",
            &format!("\"{}/plants/", configs_dir().display()),
        )
        .replace(
            "\"subjects/",
            &format!("\"{}/subjects/", configs_dir().display()),
        )
        .replace(
            "\"experiments.toml\"",
            &format!("\"{}/experiments.toml\"", configs_dir().display()),
        );
    for (from, to, key) in [
        ("rate_hz = 1000.0", "rate_hz = -5.0", "run.rate_hz"),
        (
            "command_deadline_ms = 5.0",
            "command_deadline_ms = 0.1",
            "safety.command_deadline_ms",
        ),
        (
            "torque_nm = 40.0",
            "torque_nm = nan",
            "controller.limits.torque_nm",
        ),
        ("arm_mass_kg = 1.5", "arm_mass_kg = -1.5", "rig.arm_mass_kg"),
        (
            "experiments = [1, 7]",
            "experiments = [12]",
            "protocol.experiments[0]",
        ),
        (
            "periods = [1, 4, 7]",
            "periods = [0]",
            "protocol.periods[0]",
        ),
        (
            "f_bounds = [0.0, 0.9]",
            "f_bounds = [0.0, 0.9]\nf = 1.5",
            "controller.f",
        ),
        (
            "[safety]\n",
            "[realtime]\nsched_fifo_priority = 120\n\n[safety]\n",
            "realtime.sched_fifo_priority",
        ),
        ("mode = \"identification\"", "mode = \"release\"", "release"),
    ] {
        assert!(base.contains(from), "{from}");
        let f = write(&d, "run.toml", &base.replace(from, to));
        let err = RunConfig::from_file(&f).unwrap_err().to_string();
        assert!(err.contains("run.toml") && err.contains(key), "{to}: {err}");
    }
    let f = write(
        &d,
        "run.toml",
        &base.replace("[safety]\n", "[safety]\nsafe_state2 = 1\n"),
    );
    let err = RunConfig::from_file(&f).unwrap_err().to_string();
    assert!(err.contains("safe_state2"), "{err}");
    let missing = base.replace("seed = 1\n", "");
    let err = RunConfig::from_file(&write(&d, "run.toml", &missing))
        .unwrap_err()
        .to_string();
    assert!(err.contains("seed"), "missing field not named: {err}");
}

#[test]
fn the_bus_backend_is_configuration_and_an_unknown_one_names_the_choices() {
    let base = std::fs::read_to_string(configs_dir().join("default.toml")).unwrap();
    let cfg = RunConfig::from_file(&configs_dir().join("default.toml")).unwrap();
    assert_eq!(cfg.bus.backend, BusBackend::Simulator, "the default bus");
    let d = temp_dir("bus");
    let text = base.replace("[safety]\n", "[bus]\nbackend = \"canopen\"\n\n[safety]\n");
    let err = RunConfig::from_file(&write(&d, "run.toml", &text))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("run.toml") && err.contains("ethercat") && err.contains("simulator"),
        "{err}"
    );
    // EtherCAT needs its table, and the wall clock.
    let text = base.replace("[safety]\n", "[bus]\nbackend = \"ethercat\"\n\n[safety]\n");
    let err = RunConfig::from_file(&write(&d, "run.toml", &text))
        .unwrap_err()
        .to_string();
    assert!(err.contains("bus.ethercat"), "{err}");
    let cfg = RunConfig::from_file(&configs_dir().join("ethercat-kickcat.toml")).unwrap();
    assert_eq!(cfg.bus.backend, BusBackend::Ethercat);
    let e = cfg.bus.ethercat.as_ref().unwrap();
    assert_eq!((e.vendor_id, e.product_code), (0x29c, 0x03b1_1002));
    let mut lockstep = cfg.clone();
    lockstep.run.timing = TimingMode::Lockstep;
    let err = lockstep
        .validate(Path::new("run.toml"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("run.timing"), "{err}");
    let _ = std::fs::remove_dir_all(&d);
}

/// The controller's layout by hand: without `kp`, eq. kp's
/// `√((M_e + M_h)/M_h)` (0.3 and 0.1 kg·m²: 2); with it, as set; a stiffness
/// range upside down and a subject without inertia name their keys.
#[test]
fn the_controllers_layout_is_eq_kp_or_the_set_gain_and_names_a_bad_key() {
    let cfg =
        exo_config::RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    let mut c = cfg.controller.clone();
    c.kp = None;
    let l = c.layout(0.3, 0.1).unwrap();
    assert!((l.kp - 2.0).abs() < 1e-12, "{}", l.kp);
    assert_eq!(
        (l.filters, l.p1_rad_s, l.r_pp),
        (c.filters, c.p1_rad_s, c.r_pp)
    );
    assert!(l.omega_gc_hat_rad_s > 0.0);
    c.kp = Some(3.2);
    assert_eq!(c.layout(0.3, 0.1).unwrap().kp, 3.2);
    c.k_range_nm_per_rad = [100.0, 10.0];
    assert_eq!(
        c.layout(0.3, 0.1).unwrap_err().key,
        "controller.k_range_nm_per_rad"
    );
    c.kp = None;
    assert_eq!(c.layout(0.3, 0.0).unwrap_err().key, "controller.kp");
}

/// CiA 402 fixes the width of the state machine's objects (controlword,
/// statusword and error code 16 bits; modes of operation and its display,
/// 0x6060/0x6061, 8 bits: CiA 402-2 object dictionary): an entry of another
/// width is refused naming its `bits` key and the width, in either PDO;
/// a role the standard leaves free (torque actual at 32 bits) is taken.
#[test]
fn cia_402_objects_of_the_wrong_width_are_refused_naming_the_entry() {
    let cfg = RunConfig::from_file(&configs_dir().join("ethercat-kickcat.toml")).unwrap();
    let e = cfg.bus.ethercat.as_ref().unwrap();
    let find = |entries: &[exo_config::PdoEntry], role| {
        entries.iter().position(|p| p.role == role).unwrap()
    };
    use exo_config::PdoRole;
    for (role, wrong, fixed) in [
        (PdoRole::ModeOfOperation, 16u8, 8u8),
        (PdoRole::ModeDisplay, 16, 8),
        (PdoRole::Controlword, 8, 16),
        (PdoRole::Statusword, 32, 16),
    ] {
        let mut c = cfg.clone();
        let b = c.bus.ethercat.as_mut().unwrap();
        let (pdo, entries) = if role.is_output() {
            ("rx_pdo", &mut b.rx_pdo.entries)
        } else {
            ("tx_pdo", &mut b.tx_pdo.entries)
        };
        let i = find(entries, role);
        entries[i].bits = wrong;
        let err = c.validate(Path::new("run.toml")).unwrap_err().to_string();
        let key = format!("bus.ethercat.{pdo}.entries[{i}].bits");
        assert!(
            err.contains(&key) && err.contains(&format!("is {fixed} bits in CiA 402")),
            "{role:?} at {wrong} bits: {err}"
        );
    }
    let mut c = cfg.clone();
    let b = c.bus.ethercat.as_mut().unwrap();
    let i = find(&b.tx_pdo.entries, PdoRole::TorqueActual);
    b.tx_pdo.entries[i].bits = 32;
    assert!(c.validate(Path::new("run.toml")).is_ok());
    assert_eq!(e.rx_pdo.entries.len(), 3);
}
