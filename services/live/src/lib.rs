//! # exo-live (logic)
//!
//! The live view: every channel of a run, as it happens, to Foxglove over
//! its WebSocket protocol, through the Foxglove SDK (`foxglove` crate). Each
//! channel is advertised under its recording topic with the recording
//! contract's ros2msg schema and CDR encoding (`exo_recording::schema`), so
//! one Foxglove layout (`configs/foxglove/exo.json`) shows a live run and a
//! recorded one alike.
//!
//! It only subscribes. Its iceoryx2 subscribers never block a publisher,
//! and the WebSocket server queues at most [`MESSAGE_BACKLOG`] messages for
//! each client, dropping the oldest beyond that: a slow client loses
//! messages, a killed live process loses the view, neither touches control.
//! The SDK's tokio runtime lives in this process only.
//!
//! It listens on loopback unless `[live] address` asks for another address,
//! which it then logs as reachable from other hosts.

pub mod process;

use std::net::IpAddr;
use std::sync::Arc;

use exo_config::LiveSettings;
use exo_messages::channels::{Channel, ChannelInfo, CHANNELS};
use exo_recording::schema::{MESSAGE_ENCODING, SCHEMA_ENCODING};
use foxglove::{ChannelBuilder, Context, RawChannel, Schema, WebSocketServer};

/// Messages the server queues per client before it drops the oldest: a
/// client that falls behind by more (e.g. 13 000 ticks at five channels a
/// tick) loses the oldest, the run never waits for it.
pub const MESSAGE_BACKLOG: usize = 65_536;

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `[live] address` is not an IP address.
    #[error("[live] address {0:?} is not an IP address (e.g. 127.0.0.1, 0.0.0.0 or ::1)")]
    Address(String),
    /// The port is taken by another program.
    #[error("cannot listen on {addr} port {port}: the port is in use (another exo live or Foxglove bridge?); set [live] port to a free one, or 0 for any free port ({source})")]
    PortInUse {
        /// The address.
        addr: IpAddr,
        /// The port.
        port: u16,
        /// The system's error.
        source: std::io::Error,
    },
    /// The address is not one of this computer's, or may not be bound.
    #[error("cannot listen on {addr} port {port}: {source} (is {addr} an address of this computer? [live] address)")]
    Bind {
        /// The address.
        addr: IpAddr,
        /// The port.
        port: u16,
        /// The system's error.
        source: std::io::Error,
    },
    /// A channel of the table that the recording contract has no row for.
    #[error("channel {topic} has no row in the recording contract (exo_recording::schema)")]
    NoContractRow {
        /// The channel's topic.
        topic: &'static str,
    },
    /// The SDK refused to advertise a channel.
    #[error("advertising {topic}: {message}")]
    Advertise {
        /// The channel's topic.
        topic: &'static str,
        /// The SDK's error.
        message: String,
    },
    /// Anything else the SDK refused.
    #[error("the Foxglove server did not start on {addr} port {port}: {message}")]
    Server {
        /// The address.
        addr: IpAddr,
        /// The port.
        port: u16,
        /// The SDK's error.
        message: String,
    },
}

/// Where to listen: `[live]` parsed, loopback by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Listen {
    /// The IP address.
    pub addr: IpAddr,
    /// The TCP port (0 = any free one).
    pub port: u16,
}

impl Listen {
    /// From the run file's `[live]` table (absent: loopback, port 8765).
    pub fn of(settings: Option<&LiveSettings>) -> Result<Self, LiveError> {
        let default = LiveSettings::default();
        let s = settings.unwrap_or(&default);
        let addr = s
            .address()
            .parse::<IpAddr>()
            .map_err(|_| LiveError::Address(s.address().to_string()))?;
        Ok(Listen {
            addr,
            port: s.port(),
        })
    }

    /// Whether only this computer can connect.
    pub fn is_loopback(&self) -> bool {
        self.addr.is_loopback()
    }
}

/// The Foxglove channel of every exo channel, in [`Channel`] order, on
/// their own SDK context (so nothing else in the process logs to them).
pub struct LiveChannels {
    context: Arc<Context>,
    channels: Vec<Arc<RawChannel>>,
}

impl LiveChannels {
    /// Advertises every recorded channel of [`CHANNELS`] (the recording
    /// contract's) under its recording topic with its contract schema
    /// (ros2msg) and encoding (CDR). The recorded channels come first in
    /// the table, so a channel's index is its place here.
    pub fn new() -> Result<Self, LiveError> {
        let context = Context::new();
        let mut channels = Vec::with_capacity(CHANNELS.len());
        for c in CHANNELS.iter().filter(|c| c.recorded) {
            channels.push(build_channel(&context, c)?);
        }
        Ok(LiveChannels { context, channels })
    }

    /// The SDK context the channels are in.
    pub fn context(&self) -> &Arc<Context> {
        &self.context
    }

    /// The Foxglove channel of `channel`.
    pub fn of(&self, channel: Channel) -> &Arc<RawChannel> {
        &self.channels[channel as usize]
    }

    /// Every channel.
    pub fn all(&self) -> &[Arc<RawChannel>] {
        &self.channels
    }
}

fn build_channel(context: &Arc<Context>, c: &ChannelInfo) -> Result<Arc<RawChannel>, LiveError> {
    let row =
        exo_recording::schema::find(c.topic).ok_or(LiveError::NoContractRow { topic: c.topic })?;
    let schema = Schema::new(row.schema_name, SCHEMA_ENCODING, row.text().into_bytes());
    ChannelBuilder::new(c.topic)
        .message_encoding(MESSAGE_ENCODING)
        .schema(schema)
        .context(context)
        .build_raw()
        .map_err(|e| LiveError::Advertise {
            topic: c.topic,
            message: e.to_string(),
        })
}

/// Starts the Foxglove WebSocket server for `channels` on `listen`: the
/// handle (keep it: dropping it keeps the server running, `stop` ends it)
/// and the port it listens on (the one asked for, or the free one given
/// for port 0).
pub fn start_server(
    channels: &LiveChannels,
    listen: Listen,
) -> Result<foxglove::WebSocketServerHandle, LiveError> {
    // Refuse clearly before the SDK tries: its own error does not say which
    // of the two it is.
    if let Err(e) = std::net::TcpListener::bind((listen.addr, listen.port)) {
        return Err(match e.kind() {
            std::io::ErrorKind::AddrInUse => LiveError::PortInUse {
                addr: listen.addr,
                port: listen.port,
                source: e,
            },
            _ => LiveError::Bind {
                addr: listen.addr,
                port: listen.port,
                source: e,
            },
        });
    }
    WebSocketServer::new()
        .name("exo")
        .bind(listen.addr.to_string(), listen.port)
        .context(channels.context())
        .message_backlog_size(MESSAGE_BACKLOG)
        .start_blocking()
        .map_err(|e| LiveError::Server {
            addr: listen.addr,
            port: listen.port,
            message: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_listens_on_loopback_unless_asked() {
        let l = Listen::of(None).unwrap();
        assert_eq!(l.addr.to_string(), "127.0.0.1");
        assert_eq!(l.port, 8765);
        assert!(l.is_loopback());
        let asked = LiveSettings {
            address: Some("0.0.0.0".into()),
            port: Some(9000),
        };
        let l = Listen::of(Some(&asked)).unwrap();
        assert!(!l.is_loopback());
        assert_eq!(l.port, 9000);
        let bad = LiveSettings {
            address: Some("localhost:80".into()),
            port: None,
        };
        let e = Listen::of(Some(&bad)).unwrap_err().to_string();
        assert!(
            e.contains("\"localhost:80\"") && e.contains("[live] address"),
            "{e}"
        );
    }

    #[test]
    fn every_channel_is_advertised_with_its_recording_schema() {
        let live = LiveChannels::new().unwrap();
        let recorded = CHANNELS.iter().filter(|c| c.recorded).count();
        assert_eq!(live.all().len(), recorded);
        // The recorded channels come first in the table (a channel's index
        // is its place among the advertised ones).
        assert!(CHANNELS[..recorded].iter().all(|c| c.recorded));
        for c in CHANNELS.iter().filter(|c| c.recorded) {
            let ch = live.of(c.channel);
            assert_eq!(ch.topic(), c.topic);
            assert_eq!(ch.message_encoding(), "cdr");
            let s = ch.schema().unwrap();
            assert_eq!(s.name, c.schema);
            assert_eq!(s.encoding, "ros2msg");
            let row = exo_recording::schema::find(c.topic).unwrap();
            assert_eq!(s.data.as_ref(), row.text().as_bytes());
        }
    }

    #[test]
    fn a_port_in_use_and_an_address_not_ours_are_named() {
        let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = taken.local_addr().unwrap().port();
        let live = LiveChannels::new().unwrap();
        let addr: IpAddr = "127.0.0.1".parse().unwrap();
        let e = start_server(&live, Listen { addr, port }).unwrap_err();
        assert!(matches!(e, LiveError::PortInUse { .. }), "{e}");
        assert!(e.to_string().contains("in use"), "{e}");
        // TEST-NET-1 (RFC 5737): never an address of this computer.
        let addr: IpAddr = "192.0.2.1".parse().unwrap();
        let e = start_server(&live, Listen { addr, port: 0 }).unwrap_err();
        assert!(matches!(e, LiveError::Bind { .. }), "{e}");
        assert!(e.to_string().contains("192.0.2.1"), "{e}");
        // A free port works, and the server says which.
        let addr: IpAddr = "127.0.0.1".parse().unwrap();
        let h = start_server(&live, Listen { addr, port: 0 }).unwrap();
        assert_ne!(h.port(), 0);
        let _ = h.stop();
    }
}
