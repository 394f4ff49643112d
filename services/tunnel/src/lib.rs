//! # exo-tunnel (logic)
//!
//! The run's channels to another host over Zenoh, so that a second computer
//! (an operator station, a computer running the identifier or a diagnosis)
//! subscribes to the exo computer's channels. iceoryx2's own tunnel
//! (`iceoryx2-tunnel`) exists only for iceoryx2 0.8, not our 0.10, so
//! this uses Zenoh directly.
//!
//! Two directions, one binary:
//!
//! - **export** (on the exo computer, `services.tunnel = true`): subscribes
//!   to every channel and puts each sample, CDR-encoded as in a recording
//!   (`exo_recording::schema`, portable across machines), on the Zenoh key
//!   [`key`] (`<instance>/<channel>`, e.g. `exo/sensor`). It only
//!   subscribes to iceoryx2 and only publishes to Zenoh: nothing from the
//!   network reaches the exo computer's channels, so the actuator command
//!   path cannot be driven from another host. A slow link makes the export
//!   wait (Zenoh's congestion control "block"; Zenoh closes a link stalled
//!   for 5 s) rather than drop: the export is its own process, so its wait
//!   never delays control, and a subscriber on the other computer gets
//!   every sample as long as the export keeps within its channels' 8192
//!   sample buffers (beyond, iceoryx2 drops the oldest, as for any slow
//!   subscriber). Zenoh's default, "drop", drops a sample whose queue
//!   stays full for 1 ms, which a loaded computer does.
//! - **import** (on the other computer, `exo-tunnel --import-from
//!   tcp/HOST:7447 --remote-instance exo`): subscribes to the remote
//!   instance's keys and publishes every sample onto that computer's own
//!   channels of its run file's instance, where its identifier, recorder or
//!   live view read them as if the run were local. Samples that do not
//!   decode, carry NaN/inf or come on a key of no channel are counted and
//!   named in the log, never published.
//!
//! The export listens on loopback (`tcp/127.0.0.1:7447`) unless `[tunnel]
//! listen` names another endpoint (logged); multicast scouting is off, so
//! the exo computer announces nothing on the network. Access beyond that is
//! Zenoh's: TLS with client certificates (`[tunnel] zenoh_config`).

pub mod process;

use std::path::{Path, PathBuf};

use exo_messages::channels::{Channel, CHANNELS};

/// Why a Zenoh configuration cannot be built, naming the file or the key.
#[derive(Debug, thiserror::Error)]
pub enum TunnelError {
    /// The Zenoh configuration file (`[tunnel] zenoh_config`) refused.
    #[error("{}: {message}", file.display())]
    ConfigFile {
        /// The file.
        file: PathBuf,
        /// Zenoh's message.
        message: String,
    },
    /// A key of the Zenoh configuration refused its value.
    #[error("Zenoh configuration {key} = {value}: {message}")]
    ConfigKey {
        /// The key (`listen/endpoints`, …).
        key: String,
        /// The value, as JSON5.
        value: String,
        /// Zenoh's message.
        message: String,
    },
    /// The endpoints could not be written as JSON.
    #[error("endpoints")]
    Endpoints(#[source] serde_json::Error),
}

/// The Zenoh key of `channel` of `instance`, e.g. `exo/sensor`.
pub fn key(instance: &str, channel: Channel) -> String {
    channel.service_name(instance)
}

/// The channel a Zenoh key of `instance` names, if any.
pub fn channel_of_key(instance: &str, key: &str) -> Option<Channel> {
    let suffix = key.strip_prefix(instance)?.strip_prefix('/')?;
    CHANNELS
        .iter()
        .map(|c| c.channel)
        .find(|c| c.suffix() == suffix)
}

/// A Zenoh peer configuration: `file` (JSON5) if given, then the
/// endpoints to listen on and to connect to, multicast scouting off.
pub fn zenoh_config(
    listen: &[String],
    connect: &[String],
    file: Option<&Path>,
) -> Result<zenoh::Config, TunnelError> {
    let mut c = match file {
        Some(f) => zenoh::Config::from_file(f).map_err(|e| TunnelError::ConfigFile {
            file: f.to_path_buf(),
            message: e.to_string(),
        })?,
        None => zenoh::Config::default(),
    };
    let set = |c: &mut zenoh::Config, k: &str, v: &str| {
        c.insert_json5(k, v).map_err(|e| TunnelError::ConfigKey {
            key: k.to_string(),
            value: v.to_string(),
            message: e.to_string(),
        })
    };
    set(&mut c, "mode", "\"peer\"")?;
    set(
        &mut c,
        "listen/endpoints",
        &serde_json::to_string(listen).map_err(TunnelError::Endpoints)?,
    )?;
    set(
        &mut c,
        "connect/endpoints",
        &serde_json::to_string(connect).map_err(TunnelError::Endpoints)?,
    )?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    Ok(c)
}

/// Whether a Zenoh endpoint (`tcp/127.0.0.1:7447`) is on loopback only.
pub fn is_loopback_endpoint(endpoint: &str) -> bool {
    let Some((_, addr)) = endpoint.split_once('/') else {
        return false;
    };
    let addr = addr.split('#').next().unwrap_or(addr);
    addr.parse::<std::net::SocketAddr>()
        .is_ok_and(|a| a.ip().is_loopback())
        || addr.starts_with("localhost:")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_the_instance_and_the_channel_and_back() {
        assert_eq!(key("exo", Channel::Sensor), "exo/sensor");
        assert_eq!(key("run7", Channel::BusMotor), "run7/bus/motor");
        for c in &CHANNELS {
            assert_eq!(channel_of_key("r", &key("r", c.channel)), Some(c.channel));
        }
        assert_eq!(channel_of_key("r", "r/nothing"), None);
        assert_eq!(channel_of_key("r", "other/sensor"), None);
        assert_eq!(channel_of_key("r", "rr/sensor"), None);
    }

    #[test]
    fn loopback_endpoints_are_told_from_others() {
        assert!(is_loopback_endpoint("tcp/127.0.0.1:7447"));
        assert!(is_loopback_endpoint("tcp/[::1]:7447"));
        assert!(is_loopback_endpoint("tcp/localhost:7447"));
        assert!(!is_loopback_endpoint("tcp/0.0.0.0:7447"));
        assert!(!is_loopback_endpoint("tcp/192.168.1.5:7447"));
        assert!(!is_loopback_endpoint("garbage"));
    }

    #[test]
    fn the_configuration_is_a_peer_without_scouting() {
        let c = zenoh_config(
            &["tcp/127.0.0.1:0".into()],
            &["tcp/10.0.0.2:7447".into()],
            None,
        )
        .unwrap();
        assert_eq!(c.get_json("mode").unwrap(), "\"peer\"");
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert!(c
            .get_json("listen/endpoints")
            .unwrap()
            .contains("tcp/127.0.0.1:0"));
        assert!(c
            .get_json("connect/endpoints")
            .unwrap()
            .contains("tcp/10.0.0.2:7447"));
        let e = zenoh_config(&[], &[], Some(Path::new("/nonexistent/zenoh.json5"))).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/zenoh.json5"), "{e}");
    }
}
