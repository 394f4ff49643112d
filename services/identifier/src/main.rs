//! `exo-identifier`: feeds the run's samples, commands and protocol states to
//! [`exo_identifier::Identifier`] and publishes its FRF points and estimates
//! (`<instance>/identifier/frf`, `<instance>/identifier/estimate`). Off the
//! real-time path: it only subscribes to control channels, and a slow or dead
//! identifier costs control nothing (its subscribers overflow safely).

use std::time::Duration;

use anyhow::Result;
use exo_config::RunConfig;
use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_messages::{
    ActuatorCommand, FitModel, FrfPoint, ImpedanceEstimate, ProtocolState, SensorSample,
};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{Ipc, MAX_BUFFER, OFF_PATH_COALESCE};
use exo_service_kit::{init_logging, ServiceArgs, StopFlag};
use tracing::{error, info, warn};

fn main() {
    init_logging("identifier");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
    }
}

/// The identifier's settings from a run configuration.
fn settings(cfg: &RunConfig) -> IdentifierSettings {
    IdentifierSettings {
        rate_hz: cfg.run.rate_hz,
        arm_inertia_kg_m2: cfg.rig.arm_inertia_kg_m2,
        load_lever_arm_m: cfg.rig.load_lever_arm_m,
        k_range_nm_per_rad: cfg.controller.k_range_nm_per_rad,
        f_bounds: cfg.controller.f_bounds,
        ..IdentifierSettings::default()
    }
}

fn run(args: ServiceArgs) -> Result<()> {
    let cfg = RunConfig::from_file(&args.config)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        "identifier",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let sensor_in = ipc.inbox::<SensorSample>(Channel::Sensor, MAX_BUFFER)?;
    let command_in = ipc.inbox::<ActuatorCommand>(Channel::Command, MAX_BUFFER)?;
    let protocol_in = ipc.inbox::<ProtocolState>(Channel::Protocol, 256)?;
    let frf_out = ipc.outbox::<FrfPoint>(Channel::IdentifierFrf)?;
    let estimate_out = ipc.outbox::<ImpedanceEstimate>(Channel::IdentifierEstimate)?;
    let mut id = Identifier::new(settings(&cfg));
    let mut events = Vec::with_capacity(64);
    info!(
        "identifier: {} at {} Hz",
        cfg.subject().name,
        cfg.run.rate_hz
    );
    while !stop.requested() {
        let mut got = false;
        while let Some(p) = protocol_in.try_recv()? {
            id.on_protocol(&p, &mut events);
            got = true;
        }
        while let Some(c) = command_in.try_recv()? {
            id.on_command(&c);
            got = true;
        }
        while let Some(s) = sensor_in.try_recv()? {
            id.on_sample(&s, &mut events);
            got = true;
        }
        for e in events.drain(..) {
            match e {
                Event::Frf(p) => {
                    info!(
                        "identifier: experiment {} period {}: S_h({:.2} rad/s) = {:.2}{:+.2}j Nm/rad, coherence {:.3}",
                        p.experiment, p.period, p.omega, p.s_h_re, p.s_h_im, p.coherence
                    );
                    frf_out.send(p)?;
                }
                Event::Estimate(e) => {
                    if FitModel::from_u32(e.model) == Some(FitModel::M2) {
                        let f_test = if e.f_critical > 0.0 {
                            format!("F(M1−M3) = {:.1} (critical {:.2})", e.f_m1_m3, e.f_critical)
                        } else {
                            "no F-tests yet (M3 needs 3 points)".to_string()
                        };
                        info!(
                            "identifier: experiment {} M2 after {} points: K = {:.2} ± {:.2}, H = {:.2} ± {:.2} Nm/rad, M_h = {:.3} ± {:.3} kg·m², R² = {:.3}; {f_test}{}",
                            e.experiment, e.n_points, e.k_h, e.k_h_se, e.h_h, e.h_h_se, e.m_h, e.m_h_se, e.r2,
                            if e.recommended_f > 0.0 { format!("; recommended f = {:.3}", e.recommended_f) } else { String::new() }
                        );
                    }
                    estimate_out.send(e)?;
                }
                Event::Warning(w) => warn!("identifier: {w}"),
                Event::RefitNote(w) => info!("identifier: {w}"),
            }
        }
        if got {
            std::thread::sleep(OFF_PATH_COALESCE);
        } else {
            sensor_in.wait(Duration::from_millis(20))?;
        }
    }
    info!("identifier: stopped");
    Ok(())
}
