//! The channels the exo processes open, keyed for the IPC helpers. The
//! service names follow `exo_messages::services` (`exo/sensor`, …) with the
//! first segment replaced by the run's `instance` (from `[run] instance`),
//! so several runs, or parallel tests, do not see each other's samples.

/// A channel of exo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Channel {
    /// Calibrated samples (`SensorSample`).
    Sensor,
    /// Controller commands (`ActuatorCommand`).
    Command,
    /// Protocol state (`ProtocolState`).
    Protocol,
    /// Raw bus frames from the simulated hardware (`BusSensorFrame`).
    BusSensor,
    /// Motor commands to the simulated hardware (`BusMotorCommand`).
    BusMotor,
    /// Identifier FRF points (`FrfPoint`).
    IdentifierFrf,
    /// Identifier estimates (`ImpedanceEstimate`).
    IdentifierEstimate,
    /// Operator commands (`OperatorCommand`).
    Operator,
}

/// A channel's description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelInfo {
    /// The channel.
    pub channel: Channel,
    /// Service name suffix (after `<instance>/`).
    pub suffix: &'static str,
    /// Payload type name (the `type_name` of its `ZeroCopySend` derive).
    pub payload: &'static str,
    /// Publishing process.
    pub publisher: &'static str,
    /// Subscribing processes.
    pub subscribers: &'static [&'static str],
    /// Whether a wake-up event accompanies each sample (`<name>/event`).
    pub has_event: bool,
    /// How many publishers the channel allows: 1 for the control path's
    /// channels (samples, commands, the bus), so a second controller,
    /// driver or plant on a running instance is refused at start instead
    /// of interleaving its messages with the first's.
    pub max_publishers: usize,
}

/// Every channel of exo.
pub const CHANNELS: [ChannelInfo; 8] = [
    ChannelInfo {
        channel: Channel::Sensor,
        suffix: "sensor",
        payload: "exo.SensorSample.v1",
        publisher: "sensor-driver",
        subscribers: &["controller", "identifier", "recorder"],
        has_event: true,
        max_publishers: 1,
    },
    ChannelInfo {
        channel: Channel::Command,
        suffix: "command",
        payload: "exo.ActuatorCommand.v1",
        publisher: "controller",
        subscribers: &["sensor-driver", "identifier", "recorder"],
        has_event: true,
        max_publishers: 1,
    },
    ChannelInfo {
        channel: Channel::Protocol,
        suffix: "protocol",
        payload: "exo.ProtocolState.v1",
        publisher: "controller",
        subscribers: &["plant-sim", "sensor-driver", "identifier", "recorder"],
        has_event: false,
        max_publishers: 4,
    },
    ChannelInfo {
        channel: Channel::BusSensor,
        suffix: "bus/sensor",
        payload: "exo.BusSensorFrame.v1",
        publisher: "plant-sim",
        subscribers: &["sensor-driver"],
        has_event: true,
        max_publishers: 1,
    },
    ChannelInfo {
        channel: Channel::BusMotor,
        suffix: "bus/motor",
        payload: "exo.BusMotorCommand.v1",
        publisher: "sensor-driver",
        subscribers: &["plant-sim"],
        has_event: true,
        max_publishers: 1,
    },
    ChannelInfo {
        channel: Channel::IdentifierFrf,
        suffix: "identifier/frf",
        payload: "exo.FrfPoint.v2",
        publisher: "identifier",
        subscribers: &["recorder"],
        has_event: false,
        max_publishers: 4,
    },
    ChannelInfo {
        channel: Channel::IdentifierEstimate,
        suffix: "identifier/estimate",
        payload: "exo.ImpedanceEstimate.v1",
        publisher: "identifier",
        subscribers: &["controller", "recorder"],
        has_event: false,
        max_publishers: 4,
    },
    ChannelInfo {
        channel: Channel::Operator,
        suffix: "operator",
        payload: "exo.OperatorCommand.v1",
        publisher: "operator",
        subscribers: &["controller", "sensor-driver"],
        has_event: false,
        max_publishers: 4,
    },
];

impl Channel {
    /// The channel's description.
    pub fn info(self) -> &'static ChannelInfo {
        CHANNELS
            .iter()
            .find(|c| c.channel == self)
            .unwrap_or(&CHANNELS[0])
    }

    /// The full service name for `instance`, e.g. `exo/sensor`.
    pub fn service_name(self, instance: &str) -> String {
        format!("{instance}/{}", self.info().suffix)
    }

    /// The name of its wake-up event service, e.g. `exo/sensor/event`.
    pub fn event_name(self, instance: &str) -> String {
        format!("{instance}/{}/event", self.info().suffix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_every_channel_is_listed_once() {
        let mut names: Vec<String> = CHANNELS
            .iter()
            .map(|c| c.channel.service_name("exo"))
            .collect();
        names.extend(
            CHANNELS
                .iter()
                .filter(|c| c.has_event)
                .map(|c| c.channel.event_name("exo")),
        );
        let n = names.len();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), n);
        for c in &CHANNELS {
            assert_eq!(c.channel.info().suffix, c.suffix);
        }
        assert_eq!(Channel::Sensor.service_name("run7"), "run7/sensor");
    }
}
