//! `exo-live` as a process: subscribes to every channel of the channel
//! table (`exo_messages::channels`) and logs each sample, CDR-encoded as in
//! a recording, to its Foxglove channel, stepped by the one runner
//! (`exo_service_kit::runner`). Listens where `[live]` says (loopback,
//! port 8765 by default) and logs the address and a note when other hosts
//! can reach it. Like the recorder it takes its samples in batches (a pass,
//! then a millisecond's sleep), so it leaves the CPU to the control loop.

use std::sync::Arc;
use std::time::Duration;

use exo_messages::channels::{
    Channel, ProcessName, Topic, BUS_MOTOR, BUS_SENSOR, CHANNELS, COMMAND, IDENTIFIER_ESTIMATE,
    IDENTIFIER_FRF, OPERATOR, PROTOCOL, SENSOR,
};
use exo_recording::Recordable;
use exo_service_kit::ipc::{Connect, Inbox, Ipc, IpcError, DEEPEST, OFF_PATH_COALESCE};
use exo_service_kit::runner::{Context as RunContext, Flow, Process};
use exo_service_kit::{RealtimeProcess, ServiceArgs, StopFlag};
use foxglove::{PartialMetadata, RawChannel, WebSocketServerHandle};
use tracing::{info, warn};

use crate::{start_server, Listen, LiveChannels, LiveError};

/// Why the live-view process stops with an error.
#[derive(Debug, thiserror::Error)]
pub enum LiveProcessError {
    /// A channel could not be opened or received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The `[live]` table, the Foxglove channels or the server.
    #[error(transparent)]
    Live(#[from] LiveError),
    /// A channel outside the recording contract was asked for a tap.
    #[error("{topic}: not in the recording contract, not shown")]
    NotRecorded {
        /// The channel's topic.
        topic: &'static str,
    },
}

type Result<T, E = LiveProcessError> = std::result::Result<T, E>;

/// One subscribed channel and its Foxglove channel.
struct Tap<T: Recordable> {
    inbox: Inbox<T>,
    out: Arc<RawChannel>,
}

/// A tap of any payload type.
trait Forward {
    /// Logs everything waiting to Foxglove (encoding into `buf`); returns
    /// how many.
    fn forward(&self, buf: &mut Vec<u8>) -> Result<usize>;
    /// Waits up to `timeout` for a sample's wake-up event.
    fn wait(&self, timeout: Duration) -> Result<()>;
}

impl<T: Recordable> Tap<T> {
    fn boxed(ipc: &Ipc, live: &LiveChannels, topic: Topic<T>) -> Result<Box<dyn Forward>> {
        Ok(Box::new(Tap {
            inbox: ipc.inbox(topic, DEEPEST)?,
            out: Arc::clone(live.of(topic.channel())),
        }))
    }
}

impl<T: Recordable> Forward for Tap<T> {
    fn forward(&self, buf: &mut Vec<u8>) -> Result<usize> {
        let mut n = 0;
        while let Some(m) = self.inbox.try_recv()? {
            // Encoding costs nothing worth saving when no client listens,
            // but skip it then all the same.
            if self.out.has_sinks() {
                *buf = m.encode_into(std::mem::take(buf));
                self.out
                    .log_with_meta(buf, PartialMetadata::with_log_time(m.stamp_ns()));
            }
            n += 1;
        }
        Ok(n)
    }

    fn wait(&self, timeout: Duration) -> Result<()> {
        self.inbox.wait(timeout)?;
        Ok(())
    }
}

/// The tap of `channel` (exhaustive: a new channel must be given its tap
/// here before the live view builds).
fn open_tap(ipc: &Ipc, live: &LiveChannels, channel: Channel) -> Result<Box<dyn Forward>> {
    match channel {
        Channel::Sensor => Tap::boxed(ipc, live, SENSOR),
        Channel::Command => Tap::boxed(ipc, live, COMMAND),
        Channel::Protocol => Tap::boxed(ipc, live, PROTOCOL),
        Channel::BusSensor => Tap::boxed(ipc, live, BUS_SENSOR),
        Channel::BusMotor => Tap::boxed(ipc, live, BUS_MOTOR),
        Channel::IdentifierFrf => Tap::boxed(ipc, live, IDENTIFIER_FRF),
        Channel::IdentifierEstimate => Tap::boxed(ipc, live, IDENTIFIER_ESTIMATE),
        Channel::Operator => Tap::boxed(ipc, live, OPERATOR),
        Channel::OperatorReply | Channel::RecorderProgress | Channel::IdentifierProgress => {
            Err(LiveProcessError::NotRecorded {
                topic: channel.info().topic,
            })
        }
    }
}

/// The live-view process.
pub struct LiveProcess {
    /// The sample channel's tap (the one waited on) first, then the others.
    taps: Vec<Box<dyn Forward>>,
    server: Option<WebSocketServerHandle>,
    _channels: LiveChannels,
    buf: Vec<u8>,
    forwarded: u64,
}

impl Process for LiveProcess {
    type Args = ServiceArgs;
    type Error = LiveProcessError;
    const NAME: ProcessName = ProcessName::Live;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: RunContext<'_, ServiceArgs>) -> Result<Self> {
        let listen = Listen::of(cx.cfg.live.as_ref())?;
        let channels = LiveChannels::new()?;
        // Every tap is open before a client can connect, so a client that
        // has subscribed misses nothing published after that.
        let mut taps = vec![open_tap(cx.ipc, &channels, Channel::Sensor)?];
        for c in CHANNELS
            .iter()
            .filter(|c| c.recorded && c.channel != Channel::Sensor)
        {
            taps.push(open_tap(cx.ipc, &channels, c.channel)?);
        }
        let server = start_server(&channels, listen)?;
        let url = format!(
            "ws://{}:{}",
            match listen.addr {
                std::net::IpAddr::V6(a) => format!("[{a}]"),
                a => a.to_string(),
            },
            server.port()
        );
        info!(
            "live: Foxglove WebSocket server on {url} ({} channels of instance {})",
            CHANNELS.iter().filter(|c| c.recorded).count(),
            cx.cfg.run.instance
        );
        if !listen.is_loopback() {
            warn!(
                "live: listening on {} as [live] address asks: other hosts can connect, with no authentication",
                listen.addr
            );
        }
        Ok(LiveProcess {
            taps,
            server: Some(server),
            _channels: channels,
            buf: Vec::with_capacity(512),
            forwarded: 0,
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow> {
        let mut n = 0;
        for t in &self.taps {
            n += t.forward(&mut self.buf)?;
        }
        self.forwarded += n as u64;
        if n == 0 {
            self.taps[0].wait(Duration::from_millis(20))?;
        } else {
            std::thread::sleep(OFF_PATH_COALESCE);
        }
        Ok(Flow::Continue)
    }

    fn finish(mut self) -> Result<()> {
        if let Some(server) = self.server.take() {
            server.stop().wait_blocking();
        }
        info!("live: {} samples forwarded", self.forwarded);
        Ok(())
    }
}
