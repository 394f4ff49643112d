//! The bare loops' stand-in processes: the bench binary re-executed with a
//! hidden `--role`. They have the pipeline's topology and payloads but none
//! of its work: a "driver" turns a `BusSensorFrame` into a `SensorSample`
//! with a few multiplications and forwards the controller's answer as a
//! `BusMotorCommand`; a "controller" (also the ping-pong's answering side)
//! answers each `SensorSample` with an `ActuatorCommand` from a two-term
//! law. No physics, no lag-filter cascade, no protocol, no watchdogs.

use std::os::unix::net::{UnixListener, UnixStream};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use exo_messages::{ActuatorCommand, BusMotorCommand, BusSensorFrame, SensorSample};
use exo_service_kit::channels::{BUS_MOTOR, BUS_SENSOR, COMMAND, SENSOR};
use exo_service_kit::ipc::Ipc;
use exo_service_kit::{request_realtime, RealtimeRequest, StopFlag};

use crate::link::{Got, Rx, Tx, UdsLink};

/// How long a role waits in one receive before checking its stop flag.
const POLL: Duration = Duration::from_millis(100);
/// How long the driver waits for the controller's answer to one sample.
const ANSWER_PATIENCE: Duration = Duration::from_secs(5);
/// How long a role waits for its peers to connect.
const CONNECT_PATIENCE: Duration = Duration::from_secs(30);

/// Encoder resolution of the stand-in calibration (counts per revolution).
const COUNTS_PER_REV: f64 = 524_288.0;
/// Cuff lever arm of the stand-in calibration (m).
const CUFF_LEVER_ARM_M: f64 = 0.25;
/// SEA stiffness of the stand-in calibration (Nm/rad).
const SEA_STIFFNESS_NM_PER_RAD: f64 = 350.0;
/// Gains of the stand-in control law: τ_d = −k θ_e − b ω_e + τ_c (Nm/rad, Nm·s/rad).
const K_NM_PER_RAD: f64 = 10.0;
const B_NM_S_PER_RAD: f64 = 0.5;

/// The stand-in driver's calibration: encoder counts → θ_e (rad), cuff
/// wrench → τ_c = r f_y + t_z (Nm), SEA counts → τ_s (Nm). The stamp and
/// sequence number are carried through, as the real driver does.
pub fn calibrate(f: &BusSensorFrame) -> SensorSample {
    let rad_per_count = std::f64::consts::TAU / COUNTS_PER_REV;
    SensorSample {
        seq: f.seq,
        stamp_ns: f.stamp_ns,
        theta_e: f.encoder_counts as f64 * rad_per_count,
        omega_e: 0.0,
        tau_c: CUFF_LEVER_ARM_M * f.cuff_wrench[1] + f.cuff_wrench[5],
        tau_s: SEA_STIFFNESS_NM_PER_RAD * f.sea_deflection_counts as f64 * rad_per_count,
        status: f.status,
        _pad: 0,
    }
}

/// The stand-in controller: τ_d = −k θ_e − b ω_e + τ_c (Nm); answers
/// sample `s` with command number `seq`, carrying its stamp through.
pub fn control(s: &SensorSample, seq: u64) -> ActuatorCommand {
    let tau_d = -K_NM_PER_RAD * s.theta_e - B_NM_S_PER_RAD * s.omega_e + s.tau_c;
    ActuatorCommand {
        seq,
        stamp_ns: s.stamp_ns,
        sensor_seq: s.seq,
        tau_d,
        tau_amplification: s.tau_c,
        mode: 1,
        ..Default::default()
    }
}

/// The stand-in driver's motor command for frame `frame` from the
/// controller's answer `c`.
pub fn to_motor(frame: &BusSensorFrame, c: &ActuatorCommand, seq: u64) -> BusMotorCommand {
    BusMotorCommand {
        seq,
        stamp_ns: frame.stamp_ns,
        frame_seq: frame.seq,
        tau_motor_nm: c.tau_d.clamp(-40.0, 40.0),
        enable: 1,
        _pad: 0,
    }
}

/// Answers every `SensorSample` with an `ActuatorCommand` until stopped or
/// the peer closes.
fn serve_controller(
    rx: &mut impl Rx<SensorSample>,
    tx: &mut impl Tx<ActuatorCommand>,
    stop: &StopFlag,
) -> Result<()> {
    let mut seq = 0u64;
    while !stop.requested() {
        match rx.recv(POLL)? {
            Got::Msg(s) => {
                tx.send(&control(&s, seq))?;
                seq += 1;
            }
            Got::Timeout => {}
            Got::Closed => break,
        }
    }
    Ok(())
}

/// Forwards every frame to the controller as a sample and its answer back
/// as a motor command, until stopped or the plant closes.
fn serve_driver(
    plant_rx: &mut impl Rx<BusSensorFrame>,
    plant_tx: &mut impl Tx<BusMotorCommand>,
    ctrl_tx: &mut impl Tx<SensorSample>,
    ctrl_rx: &mut impl Rx<ActuatorCommand>,
    stop: &StopFlag,
) -> Result<()> {
    let mut seq = 0u64;
    while !stop.requested() {
        let frame = match plant_rx.recv(POLL)? {
            Got::Msg(f) => f,
            Got::Timeout => continue,
            Got::Closed => break,
        };
        ctrl_tx.send(&calibrate(&frame))?;
        let asked = Instant::now();
        let answer = loop {
            match ctrl_rx.recv(POLL)? {
                Got::Msg(c) if c.sensor_seq == frame.seq => break Some(c),
                Got::Msg(_) => {}
                Got::Timeout if stop.requested() => break None,
                Got::Timeout if asked.elapsed() > ANSWER_PATIENCE => {
                    bail!(
                        "driver: no answer from the controller to sample {} within {ANSWER_PATIENCE:?}",
                        frame.seq
                    )
                }
                Got::Timeout => {}
                Got::Closed => bail!("driver: the controller closed its socket"),
            }
        };
        let Some(c) = answer else { break };
        plant_tx.send(&to_motor(&frame, &c, seq))?;
        seq += 1;
    }
    Ok(())
}

fn connect(path: &Path, what: &str) -> Result<UnixStream> {
    let t = Instant::now();
    loop {
        match UnixStream::connect(path) {
            Ok(s) => return Ok(s),
            Err(e) if t.elapsed() > CONNECT_PATIENCE => {
                return Err(e).with_context(|| format!("{what}: connect to {}", path.display()))
            }
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
    }
}

/// Accepts one connection on `listener` within `patience` (the listener is
/// polled, so a peer that never comes is an error, not a hang).
pub fn accept_within(
    listener: &UnixListener,
    patience: Duration,
    what: &str,
    mut alive: impl FnMut() -> Result<()>,
) -> Result<UnixStream> {
    listener
        .set_nonblocking(true)
        .with_context(|| format!("{what}: listener non-blocking"))?;
    let t = Instant::now();
    loop {
        match listener.accept() {
            Ok((s, _)) => return Ok(s),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if t.elapsed() > patience {
                    bail!("{what}: no connection within {patience:?}");
                }
                alive()?;
                std::thread::sleep(Duration::from_millis(5));
            }
            Err(e) => return Err(e).with_context(|| format!("{what}: accept")),
        }
    }
}

/// The transport of a bare loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Transport {
    /// iceoryx2 via exo-service-kit (publish-subscribe + event wake-up).
    Iox,
    /// Unix-domain stream sockets (blocking reads).
    Uds,
}

/// A stand-in process.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Role {
    /// Answers samples with commands (the ping-pong's far end and the loop's controller).
    Controller,
    /// Forwards frames to the controller and its answers back to the plant.
    Driver,
}

/// Where a stand-in finds its peers.
#[derive(Debug, Clone)]
pub struct RoleArgs {
    /// Which stand-in.
    pub role: Role,
    /// Over what.
    pub transport: Transport,
    /// iceoryx2 instance prefix (iox).
    pub instance: Option<String>,
    /// Socket to connect to: the bench's (controller of a ping-pong, driver)
    /// or the driver's (controller of the loop) (uds).
    pub connect: Option<std::path::PathBuf>,
    /// Socket the driver listens on for its controller (uds).
    pub listen: Option<std::path::PathBuf>,
    /// CPU and scheduling of the process whose place the stand-in takes
    /// (`crate::placement`).
    pub realtime: RealtimeRequest,
}

/// Runs a stand-in until the bench stops it (SIGTERM; the bench also
/// arranges SIGTERM on its own death) or closes its socket.
pub fn run_role(a: &RoleArgs) -> Result<()> {
    let stop = StopFlag::install().context("installing the signal handlers")?;
    if a.realtime != RealtimeRequest::default() {
        for r in request_realtime("stand-in", a.realtime).refusals {
            eprintln!("exo-pipeline-bench --role {:?}: {r}", a.role);
        }
    }
    match a.transport {
        Transport::Iox => {
            let instance = a
                .instance
                .as_deref()
                .context("--instance is required with --transport iox")?;
            match a.role {
                Role::Controller => {
                    let ipc = Ipc::open("bench_controller", instance, None)?;
                    let mut rx = ipc.inbox(SENSOR, 64)?;
                    let mut tx = ipc.outbox(COMMAND)?;
                    serve_controller(&mut rx, &mut tx, &stop)
                }
                Role::Driver => {
                    let ipc = Ipc::open("bench_driver", instance, None)?;
                    let mut plant_rx = ipc.inbox(BUS_SENSOR, 64)?;
                    let mut plant_tx = ipc.outbox(BUS_MOTOR)?;
                    let mut ctrl_tx = ipc.outbox(SENSOR)?;
                    let mut ctrl_rx = ipc.inbox(COMMAND, 64)?;
                    serve_driver(
                        &mut plant_rx,
                        &mut plant_tx,
                        &mut ctrl_tx,
                        &mut ctrl_rx,
                        &stop,
                    )
                }
            }
        }
        Transport::Uds => {
            let peer_path = a
                .connect
                .as_deref()
                .context("--connect is required with --transport uds")?;
            match a.role {
                Role::Controller => {
                    let mut rx = UdsLink::new(connect(peer_path, "controller")?, "peer")?;
                    let mut tx = rx.try_clone()?;
                    serve_controller(&mut rx, &mut tx, &stop)
                }
                Role::Driver => {
                    let listen = a
                        .listen
                        .as_deref()
                        .context("--listen is required for the uds driver")?;
                    let listener = UnixListener::bind(listen)
                        .with_context(|| format!("driver: bind {}", listen.display()))?;
                    let mut plant_rx = UdsLink::new(connect(peer_path, "driver")?, "plant")?;
                    let mut plant_tx = plant_rx.try_clone()?;
                    let ctrl = accept_within(&listener, CONNECT_PATIENCE, "driver", || {
                        if stop.requested() {
                            bail!("driver: stopped while waiting for the controller");
                        }
                        Ok(())
                    })?;
                    let mut ctrl_rx = UdsLink::new(ctrl, "controller")?;
                    let mut ctrl_tx = ctrl_rx.try_clone()?;
                    serve_driver(
                        &mut plant_rx,
                        &mut plant_tx,
                        &mut ctrl_tx,
                        &mut ctrl_rx,
                        &stop,
                    )
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stand_ins_carry_sequence_and_stamp_through() {
        let f = BusSensorFrame {
            seq: 17,
            stamp_ns: 1_000_123,
            encoder_counts: (COUNTS_PER_REV / 4.0) as i64,
            cuff_wrench: [0.0, 4.0, 0.0, 0.0, 0.0, 0.5],
            sea_deflection_counts: 0,
            status: 0,
            _pad: 0,
        };
        let s = calibrate(&f);
        assert_eq!((s.seq, s.stamp_ns), (17, 1_000_123));
        assert!((s.theta_e - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((s.tau_c - 1.5).abs() < 1e-12);
        let c = control(&s, 5);
        assert_eq!((c.sensor_seq, c.stamp_ns, c.seq), (17, 1_000_123, 5));
        assert!((c.tau_d - (-K_NM_PER_RAD * std::f64::consts::FRAC_PI_2 + 1.5)).abs() < 1e-12);
        let m = to_motor(&f, &c, 2);
        assert_eq!((m.frame_seq, m.stamp_ns, m.seq), (17, 1_000_123, 2));
        assert_eq!(m.tau_motor_nm, c.tau_d);
    }
}
