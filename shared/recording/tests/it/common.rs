//! Fixtures shared by the recording tests: one message of every type with
//! every field set (distinct, non-zero, not round numbers), a full
//! recording of them, and self-removing temporary directories.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use exo_messages::*;
use exo_recording::{Recording, RecordingWriter};

/// A directory under the system temp dir, removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(test: &str) -> Self {
        let d = std::env::temp_dir().join(format!("exo-recording-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        TempDir(d)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub fn f(k: u64, scale: f64) -> f64 {
    // Values whose decimal form is long, so a lossy float path shows.
    scale * (1.0 + k as f64) / 3.0 + (k as f64).sqrt() * 1e-7
}

pub fn sample(k: u64) -> SensorSample {
    SensorSample {
        seq: k,
        stamp_ns: 1_000_000 * k + 17,
        theta_e: 0.1 + f(k, 1e-3),
        omega_e: -f(k, 0.25),
        tau_c: 1.0 / (k as f64 + 3.0),
        tau_s: std::f64::consts::PI * f(k, 1.0),
        status: (k % 3) as u32 + 1,
        _pad: 0,
    }
}

pub fn command(k: u64) -> ActuatorCommand {
    ActuatorCommand {
        seq: k + 5,
        stamp_ns: 1_000_000 * k + 21,
        sensor_seq: k,
        tau_d: f(k, 0.5),
        tau_gravity: 3.0 + f(k, 1e-4),
        tau_amplification: -f(k, 1.5),
        tau_bias: 4.0 - f(k, 1e-3),
        tau_excitation: (k as f64).sin() + 1e-9,
        mode: 1 + (k % 5) as u32,
        _pad: 0,
    }
}

pub fn protocol(k: u64) -> ProtocolState {
    ProtocolState {
        experiment: 1 + (k % 9) as u32,
        period: 1 + (k % 10) as u32,
        phase: 1 + (k % 5) as u32,
        _pad: 0,
        omega: 2.0 * 10f64.powf(0.1 * k as f64),
        amplitude: f(k, 2.0),
        alpha: 4.0 + f(k, 0.01),
        load_kg: 4.5 + f(k, 0.001),
        grip_kg: 27.0 - f(k, 0.1),
        bias_nm: 8.0 + f(k, 0.3),
        stamp_ns: 1_000_000 * k + 23,
    }
}

pub fn frf(k: u64) -> FrfPoint {
    FrfPoint {
        seq: k + 1,
        stamp_ns: 1_000_000 * k + 29,
        experiment: 2 + (k % 7) as u32,
        period: 3 + (k % 7) as u32,
        omega: 3.17 + f(k, 1.0),
        s_h_re: 30.0 + f(k, 1.0),
        s_h_im: 12.0 + f(k, 0.5),
        s_hea_re: 20.0 - f(k, 1.0),
        s_hea_im: 12.5 + f(k, 0.2),
        sea_re: 0.98 - f(k, 1e-3),
        sea_im: -0.1 - f(k, 1e-3),
        coherence: 0.97 - f(k, 1e-4),
        noise_rel: 0.01 + f(k, 1e-5),
        s_he_re: 20.0 - f(k, 1.0),
        s_he_im: 12.5 + f(k, 0.2),
        s_he_noise_rel: 0.02 + f(k, 1e-5),
    }
}

pub fn estimate(k: u64) -> ImpedanceEstimate {
    let x = |i: u64| f(k * 31 + i, 0.7);
    ImpedanceEstimate {
        seq: k + 2,
        stamp_ns: 1_000_000 * k + 31,
        experiment: 2 + (k % 7) as u32,
        period: 3,
        n_points: 4 + k as u32,
        model: 1 + (k % 3) as u32,
        k_h: x(1),
        k_h_se: x(2),
        h_h: x(3),
        h_h_se: x(4),
        b_h: x(5),
        b_h_se: x(6),
        m_h: x(7),
        m_h_se: x(8),
        c_h: x(9),
        c_h_se: x(10),
        r2: x(11),
        f_m1_m3: x(12),
        f_m2_m3: x(13),
        f_critical: x(14),
        beta0: -x(15),
        beta1: x(16),
        power_law_r2: x(17),
        recommended_f: x(18),
    }
}

pub fn operator(k: u64) -> OperatorCommand {
    OperatorCommand {
        seq: k + 3,
        stamp_ns: 1_000_000 * k + 37,
        kind: 1 + (k % 4) as u32,
        _pad: 0,
        value: f(k, 0.35),
    }
}

pub fn bus_sensor(k: u64) -> BusSensorFrame {
    BusSensorFrame {
        seq: k + 4,
        stamp_ns: 1_000_000 * k + 11,
        encoder_counts: -12345 - k as i64,
        cuff_wrench: [
            f(k, 1.0),
            -f(k, 2.0),
            f(k, 3.0),
            f(k, 0.1),
            f(k, 0.2),
            -f(k, 0.3),
        ],
        sea_deflection_counts: 77 + k as i64,
        status: (k % 2) as u32 + 1,
        _pad: 0,
    }
}

pub fn bus_motor(k: u64) -> BusMotorCommand {
    BusMotorCommand {
        seq: k + 6,
        stamp_ns: 1_000_000 * k + 13,
        frame_seq: k + 4,
        tau_motor_nm: f(k, 2.5),
        enable: 1,
        _pad: 0,
    }
}

/// What [`write_to`] wrote.
#[derive(Debug, Default, Clone)]
pub struct Expected {
    pub sensor: Vec<SensorSample>,
    pub command: Vec<ActuatorCommand>,
    pub protocol: Vec<ProtocolState>,
    pub frf: Vec<FrfPoint>,
    pub estimate: Vec<ImpedanceEstimate>,
    pub operator: Vec<OperatorCommand>,
    pub bus_sensor: Vec<BusSensorFrame>,
    pub bus_motor: Vec<BusMotorCommand>,
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    pub config: String,
}

pub const CONFIG: &str = "[run]\nrate_hz = 1000.0\n# the whole run file\n";

/// A recording with every topic: `ticks` control ticks (sensor, command
/// and both bus topics each tick), a protocol state every 100 ticks, an
/// FRF point and an estimate every 500, an operator command every 1000.
pub fn write_to<W: Write + Seek>(w: &mut RecordingWriter<W>, ticks: u64) -> Expected {
    let mut e = Expected::default();
    w.register_contract().unwrap();
    let mut meta = BTreeMap::new();
    meta.insert("subject".to_string(), "B".to_string());
    meta.insert("experiment.1.alpha".to_string(), "4".to_string());
    w.write_run_info(&meta, CONFIG).unwrap();
    for k in 0..ticks {
        macro_rules! put {
            ($v:ident, $m:expr) => {{
                let m = $m;
                w.write(&m).unwrap();
                e.$v.push(m);
            }};
        }
        put!(bus_sensor, bus_sensor(k));
        put!(sensor, sample(k));
        if k % 100 == 0 {
            put!(protocol, protocol(k / 100));
        }
        put!(command, command(k));
        put!(bus_motor, bus_motor(k));
        if k % 500 == 499 {
            put!(frf, frf(k / 500));
            put!(estimate, estimate(k / 500));
        }
        if k % 1000 == 1 {
            put!(operator, operator(k / 1000));
        }
    }
    let drops: BTreeMap<String, String> = [("exo/sensor", "0"), ("exo/command", "2")]
        .into_iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    w.write_metadata("exo.drops", &drops).unwrap();
    let mut exo = meta.clone();
    exo.insert("software_version".into(), exo_recording::SOFTWARE.into());
    exo.insert("config_toml".into(), CONFIG.into());
    e.metadata.insert("exo".into(), exo);
    e.metadata.insert("exo.drops".into(), drops);
    e.config = CONFIG.to_string();
    e
}

pub fn write_full(path: &Path, ticks: u64, chunk_bytes: u64) -> Expected {
    let f = std::fs::File::create(path).unwrap();
    let mut w = RecordingWriter::new(std::io::BufWriter::new(f), path, chunk_bytes).unwrap();
    let e = write_to(&mut w, ticks);
    w.finish().unwrap();
    e
}

/// Every topic, metadata record and the attachment read back exactly.
pub fn assert_same(r: &Recording, e: &Expected) {
    assert_eq!(r.sensor, e.sensor);
    assert_eq!(r.command, e.command);
    assert_eq!(r.protocol, e.protocol);
    assert_eq!(r.frf, e.frf);
    assert_eq!(r.estimate, e.estimate);
    assert_eq!(r.operator, e.operator);
    assert_eq!(r.bus_sensor, e.bus_sensor);
    assert_eq!(r.bus_motor, e.bus_motor);
    assert_eq!(r.metadata, e.metadata);
    assert_eq!(r.attachment("config.toml"), Some(e.config.as_bytes()));
}

/// The Python interpreter of the venv with mcap and mcap-ros2-support.
/// Fails the test (never skips) when it cannot be made.
pub fn python() -> String {
    let script = tools_python("ensure_venv.sh");
    let out = std::process::Command::new("bash")
        .arg(&script)
        .output()
        .expect("running tools/python/ensure_venv.sh (needs bash)");
    assert!(
        out.status.success(),
        "the Python cross-check needs python3 with venv and pip access to PyPI \
         (mcap, mcap-ros2-support, numpy); tools/python/ensure_venv.sh failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

pub fn tools_python(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tools/python")
        .join(name)
}
