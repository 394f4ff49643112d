//! `[services]` and the settings of the processes that only watch or
//! replay a run (`[player]`, `[live]`, `[tunnel]`): none of them is on the
//! real-time path.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// `[player]`: a recording played back onto the run's channels by
/// `exo-player` (`services.player = true`), like `ros2 bag play`: re-run
/// the identifier and the recorder on old data; no plant, driver or
/// controller runs, nothing is actuated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlayerSettings {
    /// The recording (relative to the run file), with its later segments.
    pub file: PathBuf,
    /// Samples per second of wall time it delivers (default 5000). Range
    /// [1, 1 000 000].
    #[serde(default)]
    pub pace_hz: Option<f64>,
}

/// `[live]`: the live view (`services.live = true`), every channel to
/// Foxglove over its WebSocket protocol. It listens on loopback unless
/// another address is asked for here (and logs which).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LiveSettings {
    /// The IP address to listen on (default `127.0.0.1`, this computer
    /// only). `0.0.0.0` or a network interface's address lets other hosts
    /// connect: there is no authentication, so only on a trusted network.
    #[serde(default)]
    pub address: Option<String>,
    /// The TCP port (default 8765, Foxglove's; 0 = any free port, logged).
    #[serde(default)]
    pub port: Option<u16>,
}

impl LiveSettings {
    /// The default address: loopback only.
    pub const DEFAULT_ADDRESS: &'static str = "127.0.0.1";
    /// The default port (Foxglove's).
    pub const DEFAULT_PORT: u16 = 8765;

    /// The address to listen on.
    pub fn address(&self) -> &str {
        self.address.as_deref().unwrap_or(Self::DEFAULT_ADDRESS)
    }

    /// The port to listen on.
    pub fn port(&self) -> u16 {
        self.port.unwrap_or(Self::DEFAULT_PORT)
    }
}

/// `[tunnel]`: the run's channels to another host over Zenoh
/// (`services.tunnel = true`; ARCHITECTURE.md). On the exo computer the
/// tunnel only subscribes and publishes onto Zenoh; nothing from the
/// network is published onto its channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct TunnelSettings {
    /// Zenoh endpoints to listen on (default `["tcp/127.0.0.1:7447"]`, this
    /// computer only). Another host's address must be named here.
    #[serde(default)]
    pub listen: Option<Vec<String>>,
    /// A Zenoh configuration file (JSON5) for what the endpoints do not
    /// say: TLS, access control (relative to the run file).
    #[serde(default)]
    pub zenoh_config: Option<PathBuf>,
}

impl TunnelSettings {
    /// The default endpoint: loopback only.
    pub const DEFAULT_LISTEN: &'static str = "tcp/127.0.0.1:7447";

    /// The endpoints to listen on.
    pub fn listen(&self) -> Vec<String> {
        self.listen
            .clone()
            .unwrap_or_else(|| vec![Self::DEFAULT_LISTEN.to_string()])
    }
}

/// `[services]`: which processes `exo run` starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceSet {
    /// The plant simulator (the physical world).
    pub plant_sim: bool,
    /// The sensor driver (owns the actuator).
    pub sensor_driver: bool,
    /// The controller.
    pub controller: bool,
    /// The online identifier.
    #[serde(default)]
    pub identifier: bool,
    /// The MCAP recorder.
    #[serde(default)]
    pub recorder: bool,
    /// The player (`[player]`): a recording played onto the channels in
    /// place of plant, driver and controller.
    #[serde(default)]
    pub player: bool,
    /// The live view (`[live]`): every channel to Foxglove; only
    /// subscribes, and the run goes on without it if it fails.
    #[serde(default)]
    pub live: bool,
    /// The tunnel (`[tunnel]`): every channel to another host over Zenoh;
    /// only subscribes, and the run goes on without it if it fails.
    #[serde(default)]
    pub tunnel: bool,
}
