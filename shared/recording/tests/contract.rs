//! The recording contract: CDR bytes, round trips through a file, lenient
//! reading of damaged files, and cross-checks with Python's `mcap` +
//! `mcap-ros2-support` (an independent decoder and an independent writer).

use std::path::{Path, PathBuf};
use std::process::Command;

use exo_messages::*;
use exo_recording::*;

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("exo-recording-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn sample(k: u64) -> SensorSample {
    SensorSample {
        seq: k,
        stamp_ns: 1_000_000 * k + 17,
        theta_e: 0.1 + k as f64 * 1e-3,
        omega_e: -0.25 * k as f64,
        tau_c: 1.0 / (k as f64 + 3.0),
        tau_s: std::f64::consts::PI * k as f64,
        status: (k % 3) as u32,
        _pad: 0,
    }
}

fn protocol(k: u32) -> ProtocolState {
    ProtocolState {
        experiment: 1 + k % 9,
        period: 1 + k % 10,
        phase: k % 6,
        omega: 2.0 * 10f64.powf(0.1 * k as f64),
        amplitude: 2.0,
        alpha: 4.0,
        load_kg: 4.5,
        grip_kg: 27.0,
        bias_nm: 8.0,
        stamp_ns: 5_000_000 * k as u64 + 1,
        ..Default::default()
    }
}

/// A recording with every topic, `n` sensor samples.
fn write_full(path: &Path, n: u64, chunk: u64) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = RecordingWriter::new(std::io::BufWriter::new(f), path, chunk).unwrap();
    w.register_contract().unwrap();
    for k in 0..n {
        w.write(&sample(k)).unwrap();
        w.write(&ActuatorCommand {
            seq: k,
            stamp_ns: 1_000_000 * k + 17,
            sensor_seq: k,
            tau_d: 0.5 * k as f64,
            tau_gravity: 3.0,
            tau_amplification: -1.5,
            tau_bias: 4.0,
            tau_excitation: (k as f64).sin(),
            mode: 1,
            _pad: 0,
        })
        .unwrap();
        if k % 100 == 0 {
            w.write(&protocol(k as u32 / 100)).unwrap();
        }
    }
    w.write(&FrfPoint {
        seq: 0,
        stamp_ns: 99,
        experiment: 2,
        period: 3,
        omega: 3.17,
        s_h_re: 30.0,
        s_h_im: 12.0,
        s_hea_re: 20.0,
        s_hea_im: 12.5,
        sea_re: 0.98,
        sea_im: -0.1,
        coherence: 0.97,
        noise_rel: 0.01,
    })
    .unwrap();
    w.write(&ImpedanceEstimate {
        seq: 1,
        stamp_ns: 100,
        experiment: 2,
        period: 3,
        n_points: 3,
        model: 2,
        k_h: 30.0,
        h_h: 12.0,
        m_h: 0.11,
        r2: 0.99,
        beta0: -0.2,
        beta1: 0.9,
        recommended_f: 0.3,
        ..Default::default()
    })
    .unwrap();
    w.write(&OperatorCommand::new(
        0,
        5,
        OperatorCommandKind::ResetFault,
        0.0,
    ))
    .unwrap();
    w.write(&BusSensorFrame {
        seq: 4,
        stamp_ns: 8,
        encoder_counts: -12345,
        cuff_wrench: [1.0, -2.0, 3.0, 0.1, 0.2, -0.3],
        sea_deflection_counts: 77,
        status: 0,
        _pad: 0,
    })
    .unwrap();
    w.write(&BusMotorCommand {
        seq: 4,
        stamp_ns: 9,
        frame_seq: 4,
        tau_motor_nm: 2.5,
        enable: 1,
        _pad: 0,
    })
    .unwrap();
    let meta = [("subject".to_string(), "B".to_string())]
        .into_iter()
        .collect();
    w.write_metadata("exo", &meta).unwrap();
    w.attach(
        "config.toml",
        "application/toml",
        b"[run]\nrate_hz = 1000.0\n",
        0,
    )
    .unwrap();
    w.finish().unwrap();
}

#[test]
fn protocol_state_cdr_bytes_have_the_padding_after_the_three_uint32() {
    let p = protocol(3);
    let b = p.encode_into(Vec::new());
    assert_eq!(&b[..4], &[0, 1, 0, 0], "CDR_LE encapsulation");
    assert_eq!(&b[4..8], &p.experiment.to_le_bytes());
    assert_eq!(&b[8..12], &p.period.to_le_bytes());
    assert_eq!(&b[12..16], &p.phase.to_le_bytes());
    assert_eq!(
        &b[16..20],
        &[0, 0, 0, 0],
        "padding before the first float64"
    );
    assert_eq!(&b[20..28], &p.omega.to_le_bytes());
    assert_eq!(&b[60..68], &p.bias_nm.to_le_bytes());
    assert_eq!(&b[68..76], &p.stamp_ns.to_le_bytes());
    assert_eq!(b.len(), 76);
    // A writer that stops after bias_nm (the fixed part) is accepted, the
    // stamp taken from the log time.
    let q = ProtocolState::decode(&b[..68], 42).unwrap();
    assert_eq!(q.stamp_ns, 42);
    assert_eq!(q.bias_nm, p.bias_nm);
    // Cut inside a required field: an error naming it.
    let e = ProtocolState::decode(&b[..30], 0).unwrap_err();
    assert!(e.to_string().contains("amplitude"), "{e}");
}

#[test]
fn the_schemas_are_the_contract_text() {
    assert_eq!(
        SensorSample::schema(),
        "uint64 seq\nuint64 stamp_ns\nfloat64 theta_e\nfloat64 omega_e\nfloat64 tau_c\nfloat64 tau_s\nuint32 status\n"
    );
    assert!(ProtocolState::schema().starts_with(
        "uint32 experiment\nuint32 period\nuint32 phase\nfloat64 omega\nfloat64 amplitude\nfloat64 alpha\nfloat64 load_kg\nfloat64 grip_kg\nfloat64 bias_nm\n"
    ));
    assert!(ActuatorCommand::schema().starts_with(
        "uint64 seq\nuint64 stamp_ns\nuint64 sensor_seq\nfloat64 tau_d\nfloat64 tau_gravity\nfloat64 tau_amplification\nfloat64 tau_bias\nfloat64 tau_excitation\nuint32 mode\n"
    ));
    assert!(BusSensorFrame::schema().contains("float64[6] cuff_wrench\n"));
    assert_eq!(contract().len(), 8);
}

#[test]
fn every_message_round_trips_through_a_file() {
    let path = temp("full.mcap");
    write_full(&path, 2500, 4096);
    let r = read_recording(&path).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert!(!r.truncated);
    assert_eq!(r.sensor.len(), 2500);
    for (k, s) in r.sensor.iter().enumerate() {
        assert_eq!(*s, sample(k as u64));
    }
    assert_eq!(r.command.len(), 2500);
    assert_eq!(r.protocol.len(), 25);
    assert_eq!(r.protocol[7], protocol(7));
    assert_eq!(r.frf[0].omega, 3.17);
    assert_eq!(r.estimate[0].recommended_f, 0.3);
    assert_eq!(r.operator.len(), 1);
    assert_eq!(
        r.bus_sensor[0].cuff_wrench,
        [1.0, -2.0, 3.0, 0.1, 0.2, -0.3]
    );
    assert_eq!(r.bus_motor[0].tau_motor_nm, 2.5);
    assert_eq!(r.meta("subject"), Some("B"));
    assert_eq!(r.attachments[0].0, "config.toml");
    assert_eq!(r.topics.len(), 8);
}

#[test]
fn a_file_cut_anywhere_reads_leniently_without_panic() {
    let path = temp("cut.mcap");
    write_full(&path, 3000, 4096);
    let bytes = std::fs::read(&path).unwrap();
    let mut last_count = 0;
    for frac in [0.05, 0.2, 0.33, 0.5, 0.71, 0.9, 0.99] {
        let cut = (bytes.len() as f64 * frac) as usize;
        let r = read_recording_bytes("cut.mcap", &bytes[..cut]).unwrap();
        assert!(r.truncated, "cut at {cut}");
        assert!(
            r.warnings.iter().any(|w| w.contains("cut.mcap")),
            "{:?}",
            r.warnings
        );
        // Complete chunks survive, in order, and more of them the later the cut.
        for (k, s) in r.sensor.iter().enumerate() {
            assert_eq!(*s, sample(k as u64));
        }
        assert!(r.sensor.len() >= last_count);
        last_count = r.sensor.len();
    }
    assert!(last_count > 2000, "most of the file survives a cut at 99 %");
}

#[test]
fn corrupt_bytes_give_errors_or_warnings_never_a_panic() {
    let path = temp("corrupt.mcap");
    write_full(&path, 500, 2048);
    let bytes = std::fs::read(&path).unwrap();
    let e = read_recording_bytes("x.mcap", b"not an mcap file at all").unwrap_err();
    assert!(e.to_string().contains("x.mcap") && e.to_string().contains("not an MCAP"));
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for _ in 0..300 {
        let mut b = bytes.clone();
        for _ in 0..4 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let i = 8 + (state as usize) % (b.len() - 8);
            b[i] ^= (state >> 40) as u8 | 1;
        }
        let _ = read_recording_bytes("flipped.mcap", &b);
    }
}

#[test]
fn nan_messages_are_dropped_and_named() {
    let path = temp("nan.mcap");
    let f = std::fs::File::create(&path).unwrap();
    let mut w = RecordingWriter::new(std::io::BufWriter::new(f), &path, 4096).unwrap();
    for k in 0..10 {
        let mut s = sample(k);
        if k == 4 {
            s.tau_c = f64::NAN;
        }
        w.write(&s).unwrap();
    }
    w.finish().unwrap();
    let r = read_recording(&path).unwrap();
    assert_eq!(r.sensor.len(), 9);
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("exo/sensor") && w.contains("tau_c") && w.contains("nan.mcap")),
        "{:?}",
        r.warnings
    );
}

fn python() -> String {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/python/ensure_venv.sh");
    let out = Command::new("bash")
        .arg(&script)
        .output()
        .expect("running ensure_venv.sh");
    assert!(
        out.status.success(),
        "the Python cross-check needs python3 with venv and pip access to PyPI (mcap, mcap-ros2-support, numpy): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

fn tools_python(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tools/python")
        .join(name)
}

#[test]
fn python_mcap_ros2_support_decodes_every_field_exactly() {
    let path = temp("py-check.mcap");
    write_full(&path, 300, 4096);
    let out = Command::new(python())
        .arg(tools_python("read_recording.py"))
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = &v["topics"];
    assert_eq!(t["exo/sensor"]["count"], 300);
    assert_eq!(t["exo/sensor"]["schema"], "exo_msgs/msg/SensorSample");
    let f = |x: &serde_json::Value| -> f64 { x.as_str().unwrap().parse().unwrap() };
    for (k, m) in t["exo/sensor"]["messages"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let s = sample(k as u64);
        assert_eq!(m["seq"], s.seq);
        assert_eq!(m["stamp_ns"], s.stamp_ns);
        assert_eq!(m["_log_time"], s.stamp_ns, "log_time = stamp_ns");
        assert_eq!(f(&m["theta_e"]), s.theta_e);
        assert_eq!(f(&m["omega_e"]), s.omega_e);
        assert_eq!(f(&m["tau_c"]), s.tau_c);
        assert_eq!(f(&m["tau_s"]), s.tau_s);
        assert_eq!(m["status"], s.status);
    }
    for (k, m) in t["exo/protocol"]["messages"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let p = protocol(k as u32);
        assert_eq!(m["experiment"], p.experiment);
        assert_eq!(m["period"], p.period);
        assert_eq!(m["phase"], p.phase);
        assert_eq!(f(&m["omega"]), p.omega, "the float64 after the padding");
        assert_eq!(f(&m["bias_nm"]), p.bias_nm);
        assert_eq!(m["stamp_ns"], p.stamp_ns);
    }
    let b = &t["exo/bus/sensor"]["messages"][0];
    assert_eq!(b["encoder_counts"], -12345);
    assert_eq!(f(&b["cuff_wrench"][1]), -2.0);
    assert_eq!(v["metadata"]["exo"]["subject"], "B");
}

#[test]
fn a_recording_written_by_pythons_mcap_ros2_writer_is_read() {
    let path = temp("from-python.mcap");
    let out = Command::new(python())
        .arg(tools_python("write_recording.py"))
        .arg(&path)
        .args(["--periods", "2", "--subject", "PY"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r = read_recording(&path).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.meta("subject"), Some("PY"));
    assert_eq!(r.sensor.len(), 16_000);
    assert_eq!(r.sensor[1234].seq, 1234);
    assert_eq!(r.sensor[1234].stamp_ns, 1_234_000_000);
    // The writer leaves out ProtocolState.stamp_ns: it comes from the log time.
    assert_eq!(r.protocol[1].stamp_ns, 2_000_000_000);
    assert_eq!(r.protocol[1].phase, 3);
}
