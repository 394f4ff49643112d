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
use exo_config::{ProtocolMode, RunConfig, TimingMode};
use exo_messages::{BusMotorCommand, BusSensorFrame, ProtocolPhase, ProtocolState};
use exo_plant_sim::{Plant, PlantModel, PostureDrive};
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
    let period_s = 1.0 / cfg.run.rate_hz;
    let steps = period_s / model.integration.step_s;
    if (steps - steps.round()).abs() > 1e-9 {
        bail!(
            "{}: integration.step_s = {} does not divide the control period {} s",
            cfg.plant_model.display(),
            model.integration.step_s,
            period_s
        );
    }
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

    let mut plant = Plant::new(&model);
    if cfg.run.timing == TimingMode::Realtime {
        request_realtime(
            "plant-sim",
            RealtimeRequest::of(cfg.realtime.as_ref(), RealtimeProcess::PlantSim),
        );
    }
    let voluntary = match (cfg.protocol.mode, cfg.voluntary) {
        (ProtocolMode::Voluntary, Some(v)) => Some((v.amplitude_rad, v.omega_rad_s)),
        _ => None,
    };
    let mut drive = PostureDrive::new(
        model.human.rest_angle_rad,
        model.human.active_angle_rad,
        voluntary,
    );
    if let Some(v) = cfg.voluntary.filter(|_| voluntary.is_some()) {
        if let Some(e) = cfg.subject().get(v.experiment) {
            plant.set_human_impedance(e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
        }
        plant.set_excitation_omega(v.omega_rad_s);
    }
    // Spring-release test: the springs pull until the analysis phase starts.
    let release = cfg
        .release
        .filter(|_| cfg.protocol.mode == ProtocolMode::Release);
    if let Some(r) = release {
        if let Some(e) = cfg.subject().get(r.experiment) {
            plant.set_human_impedance(e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
        }
        plant.set_external_torque_nm(r.spring_torque_nm);
    }
    let mut released = false;
    let mut protocol = ProtocolState::default();
    let period_ns = (period_s * 1e9).round() as u64;
    let max_ticks = cfg.run.max_sim_time_s.map(|t| (t / period_s).ceil() as u64);
    let mut tau_motor = 0.0;
    let mut missed_deadlines = 0u64;
    if cfg.run.timing == TimingMode::Realtime {
        settle_connections(&[&bus_out, &motor_in, &protocol_in], REALTIME_SETTLE_PLANT)?;
    }
    let wall_start = monotonic_ns();
    info!(
        "plant-sim: {:?} at {} Hz, step {} s, subject {}, model {}",
        cfg.run.timing,
        cfg.run.rate_hz,
        model.integration.step_s,
        cfg.subject().name,
        cfg.plant_model.display()
    );
    let mut k: u64 = 0;
    while !stop.requested() && max_ticks.is_none_or(|m| k < m) {
        while let Some(p) = protocol_in.try_recv()? {
            if (p.experiment, p.omega, p.load_kg)
                != (protocol.experiment, protocol.omega, protocol.load_kg)
            {
                if let Some(e) = cfg.subject().get(p.experiment) {
                    plant.set_human_impedance(
                        e.stiffness_nm_per_rad,
                        e.hysteretic_damping_nm_per_rad,
                    );
                }
                // B_eq = H/ω follows the running sine; without one (voluntary
                // motion, spring release) the plant keeps its setting.
                if p.omega > 0.0 && p.amplitude > 0.0 {
                    plant.set_excitation_omega(p.omega);
                }
                if p.load_kg > 0.0 {
                    plant.set_load_kg(p.load_kg);
                }
            }
            protocol = p;
        }
        if release.is_some() && !released && protocol.phase == ProtocolPhase::Analysis.as_u32() {
            plant.set_external_torque_nm(0.0);
            released = true;
            info!(
                "plant-sim: springs released at sim {:.3} s",
                plant.truth().t_s
            );
        }
        let raw = plant.raw_sensors();
        let mut wrench = raw.cuff_wrench;
        if args.inject_fault_at.is_some_and(|n| k >= n) {
            wrench[1] = f64::NAN;
        }
        let frame = BusSensorFrame {
            seq: k,
            stamp_ns: match cfg.run.timing {
                TimingMode::Lockstep => k * period_ns,
                TimingMode::Realtime => monotonic_ns(),
            },
            encoder_counts: raw.encoder_counts,
            cuff_wrench: wrench,
            sea_deflection_counts: raw.sea_deflection_counts,
            status: 0,
            _pad: 0,
        };
        bus_out.send(frame)?;
        match cfg.run.timing {
            TimingMode::Lockstep => {
                let started = Instant::now();
                let mut last_send = started;
                'answer: loop {
                    if stop.requested() {
                        break 'answer;
                    }
                    if let Some(cmd) = motor_in.recv_timeout(Duration::from_millis(20))? {
                        if cmd.frame_seq == k {
                            tau_motor = if cmd.enable != 0 {
                                cmd.tau_motor_nm
                            } else {
                                0.0
                            };
                            break 'answer;
                        }
                        continue;
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
            TimingMode::Realtime => {
                let deadline = wall_start + (k + 1) * period_ns;
                let now = monotonic_ns();
                if now > deadline + period_ns {
                    missed_deadlines += 1;
                } else {
                    sleep_until_ns(deadline);
                }
                while let Some(cmd) = motor_in.try_recv()? {
                    tau_motor = if cmd.enable != 0 {
                        cmd.tau_motor_nm
                    } else {
                        0.0
                    };
                }
            }
        }
        plant.set_drive(drive.update(period_s, protocol.phase));
        plant.advance(period_s, tau_motor);
        k += 1;
        if k.is_multiple_of(cfg.run.rate_hz as u64 * 10) {
            let t = plant.truth();
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
    info!("plant-sim: stopped after {k} ticks");
    Ok(())
}
