//! `exo-player` as a process: [`PlayerNode`]'s stream published on the
//! run's channels, stepped by the one runner (`exo_service_kit::runner`),
//! one message per step, a sample every `1/player.pace_hz` s of wall time
//! (default 5000 per second: faster than real time, never faster than the
//! subscribers take them). When the recording ends it lets the subscribers
//! take the last messages (0.5 s) and exits 0, which ends the run.

use std::time::Duration;

use exo_messages::channels::ProcessName;
use exo_messages::{ActuatorCommand, ProtocolState, SensorSample};
use exo_recording::Record;
use exo_service_kit::channels::{COMMAND, PROTOCOL, SENSOR};
use exo_service_kit::ipc::{Connect, IpcError, Outbox};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{RealtimeProcess, ServiceArgs, StopFlag};
use tracing::info;

use crate::{PlayerError, PlayerNode};

/// Why the player process stops with an error.
#[derive(Debug, thiserror::Error)]
pub enum PlayerProcessError {
    /// The run file names no recording to play.
    #[error("player: the run file has no [player] table naming the recording")]
    NoPlayerTable,
    /// The recording cannot be played.
    #[error(transparent)]
    Player(#[from] PlayerError),
    /// A channel could not be opened or sent on.
    #[error(transparent)]
    Ipc(#[from] IpcError),
}

/// The player process.
pub struct PlayerProcess {
    node: PlayerNode,
    sample_out: Outbox<SensorSample>,
    command_out: Outbox<ActuatorCommand>,
    protocol_out: Outbox<ProtocolState>,
    period: Duration,
    played: u64,
}

impl Process for PlayerProcess {
    type Args = ServiceArgs;
    type Error = PlayerProcessError;
    const NAME: ProcessName = ProcessName::Player;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self, PlayerProcessError> {
        let settings = cx
            .cfg
            .player
            .as_ref()
            .ok_or(PlayerProcessError::NoPlayerTable)?;
        let node = PlayerNode::open(&settings.file)?;
        info!(
            "player: playing {} messages of {}",
            node.len(),
            settings.file.display()
        );
        Ok(PlayerProcess {
            node,
            sample_out: cx.ipc.outbox(SENSOR)?,
            command_out: cx.ipc.outbox(COMMAND)?,
            protocol_out: cx.ipc.outbox(PROTOCOL)?,
            period: Duration::from_secs_f64(1.0 / settings.pace_hz.unwrap_or(5000.0).max(1.0)),
            played: 0,
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![&self.sample_out, &self.command_out, &self.protocol_out]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow, PlayerProcessError> {
        match self.node.next_record() {
            Some(Record::Sensor(s)) => {
                self.sample_out.send(s)?;
                std::thread::sleep(self.period);
            }
            Some(Record::Command(c)) => self.command_out.send(c)?,
            Some(Record::Protocol(p)) => self.protocol_out.send(p)?,
            Some(_) => {}
            None => {
                // Let the subscribers take the last messages before the
                // process (and its publishers) goes.
                std::thread::sleep(Duration::from_millis(500));
                return Ok(Flow::Done);
            }
        }
        self.played += 1;
        Ok(Flow::Continue)
    }

    fn finish(self) -> Result<(), PlayerProcessError> {
        info!("player: {} messages played", self.played);
        Ok(())
    }
}
