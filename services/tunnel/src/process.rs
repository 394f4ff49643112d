//! `exo-tunnel` as a process, stepped by the one runner: the export (every
//! channel of the run onto Zenoh) or, with `--import-from`, the import (a
//! remote exo computer's channels onto this computer's). See the crate
//! documentation for what crosses the network and how access is limited.

use std::collections::BTreeMap;
use std::time::Duration;

use exo_messages::channels::{
    Channel, ProcessName, Topic, BUS_MOTOR, BUS_SENSOR, CHANNELS, COMMAND, IDENTIFIER_ESTIMATE,
    IDENTIFIER_FRF, OPERATOR, PROTOCOL, SENSOR,
};
use exo_recording::Recordable;
use exo_service_kit::ipc::{Connect, Inbox, Ipc, IpcError, Outbox, DEEPEST, OFF_PATH_COALESCE};
use exo_service_kit::runner::{Context as RunContext, Flow, Process};
use exo_service_kit::{RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{info, warn};
use zenoh::Wait;

use crate::{channel_of_key, is_loopback_endpoint, key, zenoh_config, TunnelError};

/// Why the tunnel process stops with an error. Zenoh's errors are kept as
/// their message (`message`): their `Display` already includes their cause.
#[derive(Debug, thiserror::Error)]
pub enum TunnelProcessError {
    /// A channel could not be opened, sent on or received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The Zenoh configuration could not be built.
    #[error(transparent)]
    Config(#[from] TunnelError),
    /// Export: the Zenoh session could not listen where `[tunnel] listen` says.
    #[error("tunnel: cannot listen on {endpoints} ([tunnel] listen): {message}")]
    Listen {
        /// The endpoints, comma-separated.
        endpoints: String,
        /// Zenoh's message.
        message: String,
    },
    /// Import: the Zenoh session could not connect to `--import-from`.
    #[error("tunnel: cannot connect to {endpoint}: {message}")]
    Connect {
        /// The endpoint.
        endpoint: String,
        /// Zenoh's message.
        message: String,
    },
    /// Export: a channel's Zenoh publisher could not be declared.
    #[error("declaring the Zenoh publisher {key}: {message}")]
    DeclarePublisher {
        /// Its key.
        key: String,
        /// Zenoh's message.
        message: String,
    },
    /// Export: a sample could not be put on Zenoh.
    #[error("Zenoh put on {key}: {message}")]
    Put {
        /// The key.
        key: String,
        /// Zenoh's message.
        message: String,
    },
    /// Import: the remote instance's keys could not be subscribed to.
    #[error("subscribing to {keys}: {message}")]
    Subscribe {
        /// The key expression (`<remote>/**`).
        keys: String,
        /// Zenoh's message.
        message: String,
    },
    /// Import: receiving from the Zenoh subscriber failed.
    #[error("Zenoh subscriber: {0}")]
    Subscriber(String),
    /// The Zenoh session could not be closed.
    #[error("closing the Zenoh session: {0}")]
    Close(String),
    /// A channel outside the recording contract was asked for a port.
    #[error("{topic}: not in the recording contract, not tunnelled")]
    NotTunnelled {
        /// The channel's topic.
        topic: &'static str,
    },
}

type Result<T, E = TunnelProcessError> = std::result::Result<T, E>;

/// Command line of `exo-tunnel`: every service's, plus the import side's.
#[derive(Debug, clap::Parser)]
#[command(name = "exo-tunnel")]
pub struct TunnelArgs {
    #[command(flatten)]
    service: ServiceArgs,
    /// Import instead of export: connect to the exo computer's tunnel at
    /// this Zenoh endpoint (e.g. tcp/192.168.1.10:7447) and publish its
    /// channels onto this computer's instance (the run file's
    /// `run.instance`).
    #[arg(long, value_name = "ENDPOINT")]
    pub import_from: Option<String>,
    /// With --import-from: the exo computer's instance (default: the same
    /// name as the run file's).
    #[arg(long, value_name = "NAME")]
    pub remote_instance: Option<String>,
}

impl AsRef<ServiceArgs> for TunnelArgs {
    fn as_ref(&self) -> &ServiceArgs {
        &self.service
    }
}

/// One channel exported: its subscriber and its Zenoh publisher.
struct Export<T: Recordable> {
    inbox: Inbox<T>,
    publisher: zenoh::pubsub::Publisher<'static>,
}

/// One channel imported: its publisher on this computer.
struct Import<T: Recordable> {
    outbox: Outbox<T>,
}

/// A channel of either direction, whatever its payload.
trait Port {
    /// Export: puts everything waiting on Zenoh; returns how many.
    fn export(&self, _buf: &mut Vec<u8>) -> Result<usize> {
        Ok(0)
    }
    /// Import: decodes one Zenoh payload and publishes it; `Err` says why
    /// it was refused.
    fn import(&self, _payload: &[u8]) -> std::result::Result<(), String> {
        Err("not an import".into())
    }
    /// Waits up to `timeout` for a sample's wake-up (export).
    fn wait(&self, _timeout: Duration) -> Result<()> {
        Ok(())
    }
}

impl<T: Recordable> Port for Export<T> {
    fn export(&self, buf: &mut Vec<u8>) -> Result<usize> {
        let mut n = 0;
        while let Some(m) = self.inbox.try_recv()? {
            *buf = m.encode_into(std::mem::take(buf));
            self.publisher
                .put(buf.as_slice())
                .wait()
                .map_err(|e| TunnelProcessError::Put {
                    key: self.publisher.key_expr().to_string(),
                    message: e.to_string(),
                })?;
            n += 1;
        }
        Ok(n)
    }

    fn wait(&self, timeout: Duration) -> Result<()> {
        self.inbox.wait(timeout)?;
        Ok(())
    }
}

impl<T: Recordable> Port for Import<T> {
    fn import(&self, payload: &[u8]) -> std::result::Result<(), String> {
        let m = T::decode(payload, 0).map_err(|e| e.to_string())?;
        if let Some((field, v)) = m.first_non_finite() {
            return Err(format!("field {field} is {v}"));
        }
        self.outbox.send(m).map_err(|e| e.to_string())
    }
}

fn export<T: Recordable>(
    ipc: &Ipc,
    session: &zenoh::Session,
    topic: Topic<T>,
) -> Result<Box<dyn Port>> {
    let k = key(ipc.instance(), topic.channel());
    let publisher = session
        .declare_publisher(k.clone())
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .wait()
        .map_err(|e| TunnelProcessError::DeclarePublisher {
            key: k.clone(),
            message: e.to_string(),
        })?;
    Ok(Box::new(Export {
        inbox: ipc.inbox(topic, DEEPEST)?,
        publisher,
    }))
}

fn import<T: Recordable>(ipc: &Ipc, topic: Topic<T>) -> Result<Box<dyn Port>> {
    Ok(Box::new(Import {
        outbox: ipc.outbox(topic)?,
    }))
}

/// The port of `channel` (exhaustive: a new channel must be given its port
/// here before the tunnel builds).
fn port(ipc: &Ipc, session: Option<&zenoh::Session>, channel: Channel) -> Result<Box<dyn Port>> {
    macro_rules! either {
        ($topic:expr) => {
            match session {
                Some(s) => export(ipc, s, $topic),
                None => import(ipc, $topic),
            }
        };
    }
    match channel {
        Channel::Sensor => either!(SENSOR),
        Channel::Command => either!(COMMAND),
        Channel::Protocol => either!(PROTOCOL),
        Channel::BusSensor => either!(BUS_SENSOR),
        Channel::BusMotor => either!(BUS_MOTOR),
        Channel::IdentifierFrf => either!(IDENTIFIER_FRF),
        Channel::IdentifierEstimate => either!(IDENTIFIER_ESTIMATE),
        Channel::Operator => either!(OPERATOR),
        Channel::OperatorReply | Channel::RecorderProgress | Channel::IdentifierProgress => {
            Err(TunnelProcessError::NotTunnelled {
                topic: channel.info().topic,
            })
        }
    }
}

/// What the process does.
enum Side {
    /// Every channel onto Zenoh (the sample channel's port first).
    Export(Vec<Box<dyn Port>>),
    /// A remote instance's keys onto this computer's channels.
    Import {
        remote: String,
        subscriber:
            zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
        ports: Vec<Box<dyn Port>>,
        /// Refused samples per key (a count, and the first reason).
        refused: BTreeMap<String, (u64, String)>,
    },
}

/// The tunnel process.
pub struct TunnelProcess {
    side: Side,
    session: zenoh::Session,
    buf: Vec<u8>,
    moved: u64,
}

impl Process for TunnelProcess {
    type Args = TunnelArgs;
    type Error = TunnelProcessError;
    const NAME: ProcessName = ProcessName::Tunnel;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: RunContext<'_, TunnelArgs>) -> Result<Self> {
        let settings = cx.cfg.tunnel.clone().unwrap_or_default();
        let file = settings.zenoh_config.as_deref();
        match &cx.args.import_from {
            None => {
                let listen = settings.listen();
                let config = zenoh_config(&listen, &[], file)?;
                let session =
                    zenoh::open(config)
                        .wait()
                        .map_err(|e| TunnelProcessError::Listen {
                            endpoints: listen.join(", "),
                            message: e.to_string(),
                        })?;
                let mut ports = vec![port(cx.ipc, Some(&session), Channel::Sensor)?];
                for c in CHANNELS
                    .iter()
                    .filter(|c| c.recorded && c.channel != Channel::Sensor)
                {
                    ports.push(port(cx.ipc, Some(&session), c.channel)?);
                }
                info!(
                    "tunnel: exporting the {} channels of instance {} on Zenoh, listening on {} (keys {}/…)",
                    CHANNELS.iter().filter(|c| c.recorded).count(),
                    cx.ipc.instance(),
                    listen.join(", "),
                    cx.ipc.instance()
                );
                for e in listen.iter().filter(|e| !is_loopback_endpoint(e)) {
                    warn!("tunnel: listening on {e} as [tunnel] listen asks: other hosts can subscribe to every channel");
                }
                Ok(TunnelProcess {
                    side: Side::Export(ports),
                    session,
                    buf: Vec::with_capacity(512),
                    moved: 0,
                })
            }
            Some(from) => {
                let remote = cx
                    .args
                    .remote_instance
                    .clone()
                    .unwrap_or_else(|| cx.ipc.instance().to_string());
                let config = zenoh_config(&[], std::slice::from_ref(from), file)?;
                let session =
                    zenoh::open(config)
                        .wait()
                        .map_err(|e| TunnelProcessError::Connect {
                            endpoint: from.clone(),
                            message: e.to_string(),
                        })?;
                let mut ports = Vec::with_capacity(CHANNELS.len());
                for c in CHANNELS.iter().filter(|c| c.recorded) {
                    ports.push(port(cx.ipc, None, c.channel)?);
                }
                let keys = format!("{remote}/**");
                let subscriber = session
                    .declare_subscriber(keys.clone())
                    .wait()
                    .map_err(|e| TunnelProcessError::Subscribe {
                        keys: keys.clone(),
                        message: e.to_string(),
                    })?;
                info!(
                    "tunnel: importing instance {remote} from {from} onto this computer's instance {}",
                    cx.ipc.instance()
                );
                Ok(TunnelProcess {
                    side: Side::Import {
                        remote,
                        subscriber,
                        ports,
                        refused: BTreeMap::new(),
                    },
                    session,
                    buf: Vec::new(),
                    moved: 0,
                })
            }
        }
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow> {
        match &mut self.side {
            Side::Export(ports) => {
                let mut n = 0;
                for p in ports.iter() {
                    n += p.export(&mut self.buf)?;
                }
                self.moved += n as u64;
                if n == 0 {
                    ports[0].wait(Duration::from_millis(20))?;
                } else {
                    std::thread::sleep(OFF_PATH_COALESCE);
                }
            }
            Side::Import {
                remote,
                subscriber,
                ports,
                refused,
            } => {
                let first = subscriber
                    .recv_timeout(Duration::from_millis(20))
                    .map_err(|e| TunnelProcessError::Subscriber(e.to_string()))?;
                let mut next = first;
                while let Some(sample) = next {
                    let k = sample.key_expr().as_str().to_string();
                    let outcome = match channel_of_key(remote, &k) {
                        Some(c) => ports[c as usize].import(&sample.payload().to_bytes()),
                        None => Err("no channel of exo has this key".to_string()),
                    };
                    match outcome {
                        Ok(()) => self.moved += 1,
                        Err(why) => {
                            let entry = refused.entry(k.clone()).or_insert((0, why.clone()));
                            if entry.0 == 0 {
                                warn!("tunnel: refused a sample on {k}: {why} (further ones on this key are counted)");
                            }
                            entry.0 += 1;
                        }
                    }
                    next = subscriber
                        .try_recv()
                        .map_err(|e| TunnelProcessError::Subscriber(e.to_string()))?;
                }
            }
        }
        Ok(Flow::Continue)
    }

    fn finish(self) -> Result<()> {
        if let Side::Import { refused, .. } = &self.side {
            for (k, (n, why)) in refused {
                warn!("tunnel: {n} samples on {k} refused ({why})");
            }
        }
        info!("tunnel: {} samples moved", self.moved);
        self.session
            .close()
            .wait()
            .map_err(|e| TunnelProcessError::Close(e.to_string()))?;
        Ok(())
    }
}
