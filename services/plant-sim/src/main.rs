//! `exo-plant-sim`: the physical world as a process. Publishes raw bus frames
//! (`<instance>/bus/sensor`) and applies the motor commands it receives
//! (`<instance>/bus/motor`); follows the protocol state to set the subject's
//! impedance per experiment, the load, and the posture.
//!
//! Timing: in *lockstep* the plant advances one control period only once the
//! motor command answering the current frame has arrived (same seed ⇒
//! identical run); in *real time* it advances on the wall clock with
//! absolute deadlines and holds the latest command.
//!
//! `--inject-fault-at N` (tests): from tick N the cuff sensor reads NaN.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use exo_config::{RunConfig, TimingMode};
use exo_messages::{BusMotorCommand, BusSensorFrame, ProtocolState};
use exo_plant_sim::{PlantModel, PlantNode};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{settle_connections, Ipc, REALTIME_SETTLE_PLANT};
use exo_service_kit::{
    init_logging, monotonic_ns, request_realtime, sleep_until_ns, RealtimeProcess, RealtimeRequest,
    ServiceArgs, StopFlag,
};
use tracing::{info, warn};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const GIVE_UP_AFTER: Duration = Duration::from_secs(20);

fn main() {
    init_logging("plant-sim");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        tracing::error!("{e:#}");
        std::process::exit(1);
    }
}

fn run(args: ServiceArgs) -> Result<()> {
    let cfg = RunConfig::from_file(&args.config)?;
    let model = PlantModel::from_file(&cfg.plant_model)?;
    let mut node = PlantNode::new(&cfg, &model, args.inject_fault_at)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        "plant_sim",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let bus_out = ipc.outbox::<BusSensorFrame>(Channel::BusSensor)?;
    let motor_in = ipc
        .inbox::<BusMotorCommand>(Channel::BusMotor, 64)?
        .with_spin(cfg.lockstep_spin());
    let protocol_in = ipc.inbox::<ProtocolState>(Channel::Protocol, 64)?;
    let realtime = cfg.run.timing == TimingMode::Realtime;
    if realtime {
        request_realtime(
            "plant-sim",
            RealtimeRequest::of(cfg.realtime.as_ref(), RealtimeProcess::PlantSim),
        );
        settle_connections(&[&bus_out, &motor_in, &protocol_in], REALTIME_SETTLE_PLANT)?;
    }
    let period_ns = node.period_ns();
    let mut missed_deadlines = 0u64;
    let wall_start = monotonic_ns();
    info!(
        "plant-sim: {:?} at {} Hz, step {} s, subject {}, model {}",
        cfg.run.timing,
        cfg.run.rate_hz,
        model.integration.step_s,
        cfg.subject().name,
        cfg.plant_model.display()
    );
    while !stop.requested() && !node.finished() {
        while let Some(p) = protocol_in.try_recv()? {
            node.on_protocol(&p);
        }
        let k = node.tick();
        let frame = node.frame(if realtime {
            monotonic_ns()
        } else {
            node.lockstep_stamp_ns()
        });
        bus_out.send(frame)?;
        if realtime {
            let deadline = wall_start + (k + 1) * period_ns;
            if monotonic_ns() > deadline + period_ns {
                missed_deadlines += 1;
            } else {
                sleep_until_ns(deadline);
            }
            while let Some(cmd) = motor_in.try_recv()? {
                node.hold_motor(&cmd);
            }
        } else {
            let started = Instant::now();
            let mut last_send = started;
            while !stop.requested() {
                match motor_in.recv_timeout(Duration::from_millis(20))? {
                    Some(cmd) if node.on_motor(&cmd) => break,
                    Some(_) => continue,
                    None => {}
                }
                if last_send.elapsed() > RESEND_AFTER {
                    bus_out.send(frame)?;
                    last_send = Instant::now();
                }
                if started.elapsed() > GIVE_UP_AFTER {
                    bail!("no motor command for frame {k} within {GIVE_UP_AFTER:?}: is the sensor driver running?");
                }
            }
        }
        node.advance();
        if node.tick().is_multiple_of(cfg.run.rate_hz as u64 * 10) {
            let t = node.truth();
            info!(
                "plant-sim: sim {:.1} s, wall {:.1} s, θ = {:.3} rad, missed deadlines {missed_deadlines}",
                t.t_s,
                (monotonic_ns() - wall_start) as f64 * 1e-9,
                t.theta_e_rad
            );
        }
    }
    if missed_deadlines > 0 {
        warn!("plant-sim: {missed_deadlines} missed real-time deadlines");
    }
    info!("plant-sim: stopped after {} ticks", node.tick());
    Ok(())
}
