//! The baselines: a ping-pong and the pipeline's three-process topology
//! with stand-in processes (see [`crate::roles`]), over iceoryx2 and over
//! Unix-domain sockets. The bench itself plays the plant: it stamps a probe
//! with `monotonic_ns()` immediately before sending it, paced like the
//! plant in real time (absolute deadlines, `clock_nanosleep`), or back to
//! back ("flat out", like lockstep), and stamps the answer on receipt.

use std::ffi::{OsStr, OsString};
use std::os::unix::net::UnixListener;
use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use exo_messages::{ActuatorCommand, BusMotorCommand, BusSensorFrame, SensorSample};
use exo_service_kit::channels::{BUS_MOTOR, BUS_SENSOR, COMMAND, SENSOR};
use exo_service_kit::ipc::Ipc;
use exo_service_kit::{monotonic_ns, sleep_until_ns};

use crate::link::{Answer, Got, Probe, Rx, Tx, UdsLink};
use crate::placement::{on_own_thread, place_this_thread, role_flags, Placement};
use crate::procs::Fleet;
use crate::roles::{accept_within, Transport};
use crate::stats::Latency;
use exo_service_kit::RealtimeRequest;

/// How long the start-up handshake may take.
const HANDSHAKE_PATIENCE: Duration = Duration::from_secs(30);
/// How long one probe may stay unanswered before the row fails.
const ANSWER_PATIENCE: Duration = Duration::from_secs(5);
/// One receive's wait before the children's liveness is checked.
const POLL: Duration = Duration::from_millis(100);

/// What a probe loop measured.
pub struct LoopStats {
    /// Probe sent → its answer received (ns), after the warm-up.
    pub round_trip: Latency,
    /// Round trips per second after the warm-up.
    pub rate_per_s: f64,
    /// Ticks after the warm-up whose deadline had passed by more than a
    /// period (paced loops), sent late without sleeping, as the plant does.
    pub late_ticks: u64,
}

/// How the bench paces its probes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// One probe per period (ns) on absolute deadlines, like the plant in real time.
    Period(u64),
    /// The next probe as soon as the answer is in, like lockstep.
    FlatOut,
}

/// Sends probes through `tx` and times their answers from `rx`, paced and
/// timed as `spec` says. The probing thread takes the placement `bench`
/// first (after the stand-ins were started, so that they do not inherit it).
fn probe_loop<P: Probe, A: Answer>(
    tx: &mut impl Tx<P>,
    rx: &mut impl Rx<A>,
    spec: &LoopSpec,
    bench: RealtimeRequest,
    fleet: &mut Fleet,
) -> Result<LoopStats> {
    let (pace, warmup, measure) = (spec.pace, spec.warmup, spec.measure);
    place_this_thread("bench", bench);
    // Handshake: probe 0 until it is answered (the peers may still be starting).
    let t = monotonic_ns();
    'handshake: loop {
        tx.send(&P::probe(0, monotonic_ns()))?;
        let sent = monotonic_ns();
        while monotonic_ns() - sent < 50_000_000 {
            match rx.recv(Duration::from_millis(50))? {
                Got::Msg(a) if a.answers() == 0 => break 'handshake,
                Got::Msg(_) | Got::Timeout => {}
                Got::Closed => bail!("the peer closed the link during the handshake"),
            }
        }
        fleet.check_alive()?;
        if monotonic_ns() - t > HANDSHAKE_PATIENCE.as_nanos() as u64 {
            bail!("no answer to the first probe within {HANDSHAKE_PATIENCE:?}");
        }
    }

    let mut round_trip = Latency::new();
    let mut late_ticks = 0u64;
    let start = monotonic_ns();
    let record_from = start + warmup.as_nanos() as u64;
    let end = record_from + measure.as_nanos() as u64;
    let mut seq = 1u64;
    loop {
        let now = monotonic_ns();
        if now >= end {
            break;
        }
        if let Pace::Period(p) = pace {
            let deadline = start + seq * p;
            if now > deadline + p {
                if deadline >= record_from {
                    late_ticks += 1;
                }
            } else {
                sleep_until_ns(deadline);
            }
        }
        let stamp = monotonic_ns();
        tx.send(&P::probe(seq, stamp))?;
        loop {
            match rx.recv(POLL)? {
                Got::Msg(a) if a.answers() == seq => {
                    let now = monotonic_ns();
                    if a.stamp_ns() != stamp {
                        bail!(
                            "the answer to probe {seq} carries stamp {} instead of {stamp}",
                            a.stamp_ns()
                        );
                    }
                    if stamp >= record_from {
                        round_trip.record(now - stamp);
                    }
                    break;
                }
                Got::Msg(_) => {} // a late duplicate from the handshake
                Got::Timeout => {
                    fleet.check_alive()?;
                    if monotonic_ns() - stamp > ANSWER_PATIENCE.as_nanos() as u64 {
                        bail!("no answer to probe {seq} within {ANSWER_PATIENCE:?}");
                    }
                }
                Got::Closed => bail!("the peer closed the link at probe {seq}"),
            }
        }
        seq += 1;
    }
    Ok(LoopStats {
        rate_per_s: round_trip.count() as f64 / measure.as_secs_f64(),
        round_trip,
        late_ticks,
    })
}

/// Starts the stand-in `role` of `spec`'s loop over `transport` with the
/// arguments `rest` and the placement flags `placed`; named `<tag>-<role>`.
fn spawn_stand_in(
    fleet: &mut Fleet,
    spec: &LoopSpec,
    role: &str,
    transport: &str,
    rest: &[&OsStr],
    placed: &[OsString],
) -> Result<()> {
    let mut args: Vec<&OsStr> = vec![
        "--role".as_ref(),
        role.as_ref(),
        "--transport".as_ref(),
        transport.as_ref(),
    ];
    args.extend_from_slice(rest);
    args.extend(placed.iter().map(OsString::as_os_str));
    fleet.spawn(&format!("{}-{role}", spec.tag), spec.exe, &args)
}

/// Who plays whom in a bare loop, and where each runs.
struct Cast {
    /// The bench's probing thread (the driver of a ping-pong, the plant of a loop).
    bench: RealtimeRequest,
    /// Flags of the stand-in driver (loops only).
    driver: Vec<OsString>,
    /// Flags of the stand-in controller.
    controller: Vec<OsString>,
}

impl Cast {
    fn new(shape: Shape, placement: Option<&Placement>) -> Self {
        let p = placement.copied().unwrap_or_default();
        Cast {
            bench: match shape {
                Shape::PingPong => p.driver,
                Shape::ThreeProcess => p.plant,
            },
            driver: role_flags(&p.driver),
            controller: role_flags(&p.controller),
        }
    }
}

/// Shape of a bare loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Bench ↔ controller stand-in: `SensorSample` out, `ActuatorCommand` back.
    PingPong,
    /// Bench (plant) → driver → controller → driver → bench, the pipeline's
    /// topology and payloads.
    ThreeProcess,
}

/// One bare loop to run: its shape, pacing and time, where its logs go, and
/// a tag naming its instance, sockets and stand-ins.
pub struct LoopSpec<'a> {
    /// The bench executable (re-run as the stand-ins).
    pub exe: &'a Path,
    /// Ping-pong or three-process loop.
    pub shape: Shape,
    /// Paced like the plant or flat out.
    pub pace: Pace,
    /// Not recorded.
    pub warmup: Duration,
    /// Recorded.
    pub measure: Duration,
    /// Logs and sockets.
    pub dir: &'a Path,
    /// Unique per row.
    pub tag: &'a str,
}

/// Runs a bare loop over `transport` on a thread of its own; with
/// `placement`, every process and the bench's probing thread placed as the
/// pipeline's would be.
pub fn run(
    transport: Transport,
    spec: &LoopSpec,
    placement: Option<&Placement>,
) -> Result<LoopStats> {
    let cast = Cast::new(spec.shape, placement);
    on_own_thread(spec.tag, || match transport {
        Transport::Iox => iceoryx2(spec, &cast),
        Transport::Uds => unix_socket(spec, &cast),
    })
}

/// A bare loop over iceoryx2 on the channels (and service settings) of the
/// pipeline, under a fresh instance.
fn iceoryx2(spec: &LoopSpec, cast: &Cast) -> Result<LoopStats> {
    let instance = format!("pb{}{}", spec.tag, std::process::id());
    let ipc = Ipc::open("bench_plant", &instance, None)?;
    let mut fleet = Fleet::new(spec.dir);
    let rest = ["--instance".as_ref(), instance.as_ref()];
    let controller = |fleet: &mut Fleet| {
        spawn_stand_in(fleet, spec, "controller", "iox", &rest, &cast.controller)
    };
    let stats = match spec.shape {
        Shape::PingPong => {
            let mut tx = ipc.outbox(SENSOR)?;
            let mut rx = ipc.inbox(COMMAND, 64)?;
            controller(&mut fleet)?;
            probe_loop(&mut tx, &mut rx, spec, cast.bench, &mut fleet)?
        }
        Shape::ThreeProcess => {
            let mut tx = ipc.outbox(BUS_SENSOR)?;
            let mut rx = ipc.inbox(BUS_MOTOR, 64)?;
            controller(&mut fleet)?;
            spawn_stand_in(&mut fleet, spec, "driver", "iox", &rest, &cast.driver)?;
            probe_loop(&mut tx, &mut rx, spec, cast.bench, &mut fleet)?
        }
    };
    let trouble = fleet.stop();
    if !trouble.is_empty() {
        bail!("stopping the stand-ins: {}", trouble.join("; "));
    }
    Ok(stats)
}

fn bind(path: &Path) -> Result<UnixListener> {
    let _ = std::fs::remove_file(path);
    UnixListener::bind(path).with_context(|| format!("binding {}", path.display()))
}

/// A bare loop over Unix-domain stream sockets.
fn unix_socket(spec: &LoopSpec, cast: &Cast) -> Result<LoopStats> {
    let mut fleet = Fleet::new(spec.dir);
    let plant_path = spec.dir.join(format!("{}-plant.sock", spec.tag));
    let listener = bind(&plant_path)?;
    let plant: &OsStr = plant_path.as_os_str();
    // The controller answers the bench directly (ping-pong) or the driver,
    // which binds its own socket before connecting to ours.
    let (controller_socket, peer_name) = match spec.shape {
        Shape::PingPong => (plant_path.clone(), "controller"),
        Shape::ThreeProcess => {
            let ctrl_path = spec.dir.join(format!("{}-ctrl.sock", spec.tag));
            let _ = std::fs::remove_file(&ctrl_path);
            let rest = [
                "--connect".as_ref(),
                plant,
                "--listen".as_ref(),
                ctrl_path.as_os_str(),
            ];
            spawn_stand_in(&mut fleet, spec, "driver", "uds", &rest, &cast.driver)?;
            (ctrl_path, "driver")
        }
    };
    let rest = ["--connect".as_ref(), controller_socket.as_os_str()];
    spawn_stand_in(
        &mut fleet,
        spec,
        "controller",
        "uds",
        &rest,
        &cast.controller,
    )?;
    let stream = accept_within(&listener, HANDSHAKE_PATIENCE, "bench", || {
        fleet.check_alive()
    })?;
    let mut rx = UdsLink::new(stream, peer_name)?;
    let mut tx = rx.try_clone()?;
    let stats = match spec.shape {
        Shape::PingPong => probe_loop::<SensorSample, ActuatorCommand>(
            &mut tx, &mut rx, spec, cast.bench, &mut fleet,
        )?,
        Shape::ThreeProcess => probe_loop::<BusSensorFrame, BusMotorCommand>(
            &mut tx, &mut rx, spec, cast.bench, &mut fleet,
        )?,
    };
    // Closing the socket lets the stand-ins finish on their own.
    drop(tx);
    drop(rx);
    let trouble = fleet.stop();
    if !trouble.is_empty() {
        bail!("stopping the stand-ins: {}", trouble.join("; "));
    }
    Ok(stats)
}
