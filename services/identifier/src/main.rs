//! `exo-identifier`: feeds the run's samples, commands and protocol states to
//! [`exo_identifier::Identifier`] and publishes its FRF points and estimates
//! (`<instance>/identifier/frf`, `<instance>/identifier/estimate`). Off the
//! real-time path: it only subscribes to control channels, and a slow or dead
//! identifier costs control nothing (its subscribers overflow safely).

use std::time::Duration;

use anyhow::Result;
use exo_config::RunConfig;
use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_messages::{ActuatorCommand, FrfPoint, ImpedanceEstimate, ProtocolState, SensorSample};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{Ipc, MAX_BUFFER, OFF_PATH_COALESCE};
use exo_service_kit::{init_logging, ServiceArgs, StopFlag};
use tracing::{error, info};

fn main() {
    init_logging("identifier");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
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
    let mut id = Identifier::new(IdentifierSettings::of_run(&cfg));
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
            e.log();
            match e {
                Event::Frf(p) => frf_out.send(p)?,
                Event::Estimate(e) => estimate_out.send(e)?,
                Event::Warning(_) | Event::RefitNote(_) => {}
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
