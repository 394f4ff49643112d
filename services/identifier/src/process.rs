//! `exo-identifier` as a process: feeds the run's samples, commands and
//! protocol states to [`Identifier`] and publishes its FRF points and
//! estimates (`<instance>/identifier/frf`, `<instance>/identifier/estimate`),
//! stepped by the one runner (`exo_service_kit::runner`). Off the real-time
//! path: it only subscribes to control channels, and a slow or dead
//! identifier costs control nothing (its subscribers overflow safely). It
//! takes its samples in batches (a pass, then a millisecond's sleep).

use std::time::Duration;

use anyhow::Result;
use exo_messages::channels::ProcessName;
use exo_messages::{ActuatorCommand, FrfPoint, ImpedanceEstimate, ProtocolState, SensorSample};
use exo_service_kit::channels::{COMMAND, IDENTIFIER_ESTIMATE, IDENTIFIER_FRF, PROTOCOL, SENSOR};
use exo_service_kit::ipc::{Connect, Inbox, Outbox, DEEPEST, OFF_PATH_COALESCE};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{RealtimeProcess, ServiceArgs, StopFlag};
use tracing::info;

use crate::{Event, Identifier, IdentifierSettings};

/// The identifier process.
pub struct IdentifierProcess {
    id: Identifier,
    events: Vec<Event>,
    sensor_in: Inbox<SensorSample>,
    command_in: Inbox<ActuatorCommand>,
    protocol_in: Inbox<ProtocolState>,
    frf_out: Outbox<FrfPoint>,
    estimate_out: Outbox<ImpedanceEstimate>,
}

impl Process for IdentifierProcess {
    type Args = ServiceArgs;
    const NAME: ProcessName = ProcessName::Identifier;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self> {
        let ipc = cx.ipc;
        let p = IdentifierProcess {
            id: Identifier::new(IdentifierSettings::of_run(cx.cfg)),
            events: Vec::with_capacity(64),
            sensor_in: ipc.inbox(SENSOR, DEEPEST)?,
            command_in: ipc.inbox(COMMAND, DEEPEST)?,
            protocol_in: ipc.inbox(PROTOCOL, 256)?,
            frf_out: ipc.outbox(IDENTIFIER_FRF)?,
            estimate_out: ipc.outbox(IDENTIFIER_ESTIMATE)?,
        };
        info!(
            "identifier: {} at {} Hz",
            cx.cfg.subject().name,
            cx.cfg.run.rate_hz
        );
        Ok(p)
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow> {
        let mut got = false;
        while let Some(p) = self.protocol_in.try_recv()? {
            self.id.on_protocol(&p, &mut self.events);
            got = true;
        }
        while let Some(c) = self.command_in.try_recv()? {
            self.id.on_command(&c);
            got = true;
        }
        while let Some(s) = self.sensor_in.try_recv()? {
            self.id.on_sample(&s, &mut self.events);
            got = true;
        }
        for e in self.events.drain(..) {
            e.log();
            match e {
                Event::Frf(p) => self.frf_out.send(p)?,
                Event::Estimate(e) => self.estimate_out.send(e)?,
                Event::Warning(_) | Event::RefitNote(_) => {}
            }
        }
        if got {
            std::thread::sleep(OFF_PATH_COALESCE);
        } else {
            self.sensor_in.wait(Duration::from_millis(20))?;
        }
        Ok(Flow::Continue)
    }

    fn finish(self) -> Result<()> {
        info!("identifier: stopped");
        Ok(())
    }
}
