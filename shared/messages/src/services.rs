//! The one place that names every iceoryx2 service of exo, with its payload,
//! its publisher, its subscribers and the settings every process opens it with.
//!
//! The names below are those of the default instance `exo`. A run's
//! `[run] instance` (and every test) replaces that first segment with
//! [`instance_name`], so several runs, or parallel tests, never see each
//! other's samples.
//!
//! Wake-ups: the channels on the real-time path have a companion event
//! service (`<name>/event`); the publisher notifies it after each sample so
//! the one real-time reader sleeps in the kernel instead of polling. The
//! identifier and the recorder poll at their own pace and never listen, so
//! they add no work to a notify.

use crate::Message;

/// The first segment of every service name of the default instance.
pub const ROOT: &str = "exo";

/// Calibrated sensor samples ([`SensorSample`](crate::SensorSample)).
pub const SENSOR: &str = "exo/sensor";
/// Actuator commands ([`ActuatorCommand`](crate::ActuatorCommand)).
pub const COMMAND: &str = "exo/command";
/// Protocol state ([`ProtocolState`](crate::ProtocolState)).
pub const PROTOCOL: &str = "exo/protocol";
/// Raw bus frames of the simulated hardware ([`BusSensorFrame`](crate::BusSensorFrame)).
pub const BUS_SENSOR: &str = "exo/bus/sensor";
/// Motor commands to the simulated hardware ([`BusMotorCommand`](crate::BusMotorCommand)).
pub const BUS_MOTOR: &str = "exo/bus/motor";
/// Frequency-response points ([`FrfPoint`](crate::FrfPoint)).
pub const IDENTIFIER_FRF: &str = "exo/identifier/frf";
/// Impedance estimates ([`ImpedanceEstimate`](crate::ImpedanceEstimate)).
pub const IDENTIFIER_ESTIMATE: &str = "exo/identifier/estimate";
/// Operator commands ([`OperatorCommand`](crate::OperatorCommand)).
pub const OPERATOR: &str = "exo/operator";

/// Wake-up event: a new sample is on [`SENSOR`].
pub const SENSOR_EVENT: &str = "exo/sensor/event";
/// Wake-up event: a new command is on [`COMMAND`].
pub const COMMAND_EVENT: &str = "exo/command/event";
/// Wake-up event: a new frame is on [`BUS_SENSOR`].
pub const BUS_SENSOR_EVENT: &str = "exo/bus/sensor/event";
/// Wake-up event: a new command is on [`BUS_MOTOR`].
pub const BUS_MOTOR_EVENT: &str = "exo/bus/motor/event";

/// A process of exo (or the operator console).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Process {
    /// The simulated plant (stands in for the hardware bus).
    PlantSim,
    /// The sensor driver: owns the bus and the actuator.
    SensorDriver,
    /// The amplification controller and protocol clock.
    Controller,
    /// The online impedance identifier.
    Identifier,
    /// The MCAP recorder.
    Recorder,
    /// The operator console (the `exo` tool).
    Operator,
}

impl Process {
    /// Every process.
    pub const ALL: [Process; 6] = [
        Process::PlantSim,
        Process::SensorDriver,
        Process::Controller,
        Process::Identifier,
        Process::Recorder,
        Process::Operator,
    ];

    /// The process name, as in its binary and systemd unit (`exo-<name>`).
    pub fn name(self) -> &'static str {
        match self {
            Process::PlantSim => "plant-sim",
            Process::SensorDriver => "sensor-driver",
            Process::Controller => "controller",
            Process::Identifier => "identifier",
            Process::Recorder => "recorder",
            Process::Operator => "operator",
        }
    }
}

/// Settings of a publish-subscribe service. Every process opens a service
/// with the same settings (from [`SERVICES`]), so they always agree; iceoryx2
/// refuses to open a service whose existing settings are smaller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PubSubQos {
    /// Most publishers at once (count); more than one lets a restarted
    /// publisher come up before its killed predecessor is cleaned up.
    pub max_publishers: usize,
    /// Most subscribers at once (count).
    pub max_subscribers: usize,
    /// Most nodes (processes) that may open the service (count).
    pub max_nodes: usize,
    /// Deepest subscriber buffer (samples) a subscriber may ask for; a full
    /// buffer drops its oldest sample (safe overflow), so a publisher never blocks.
    pub subscriber_max_buffer_size: usize,
    /// Samples a subscriber may hold (borrow) at once.
    pub subscriber_max_borrowed_samples: usize,
    /// Samples a late-joining subscriber receives from before it connected (count).
    pub history_size: usize,
}

/// Settings of an event service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EventQos {
    /// Most notifiers at once (count).
    pub max_notifiers: usize,
    /// Most listeners at once (count).
    pub max_listeners: usize,
    /// Most nodes (processes) that may open the service (count).
    pub max_nodes: usize,
}

/// Settings of the sample streams (one sample per control tick): no
/// history, so a late joiner never acts on an old sample; a buffer deep enough
/// for the recorder to lag 1 s at 1 kHz.
pub const STREAM_QOS: PubSubQos = PubSubQos {
    max_publishers: 2,
    max_subscribers: 6,
    max_nodes: 16,
    subscriber_max_buffer_size: 1024,
    subscriber_max_borrowed_samples: 2,
    history_size: 0,
};

/// Settings of state channels (rare updates, the latest one matters): a late
/// joiner receives the latest sample.
pub const STATE_QOS: PubSubQos = PubSubQos {
    max_publishers: 2,
    max_subscribers: 6,
    max_nodes: 16,
    subscriber_max_buffer_size: 1024,
    subscriber_max_borrowed_samples: 2,
    history_size: 1,
};

/// Settings of [`IDENTIFIER_FRF`]: a late joiner receives the last 16 points.
pub const FRF_QOS: PubSubQos = PubSubQos {
    history_size: 16,
    ..STATE_QOS
};

/// Settings of [`OPERATOR`]: no history, so a restarted controller never
/// replays an old command (e.g. a fault reset).
pub const OPERATOR_QOS: PubSubQos = PubSubQos {
    subscriber_max_buffer_size: 16,
    ..STREAM_QOS
};

/// Settings of the wake-up events.
pub const WAKE_QOS: EventQos = EventQos {
    max_notifiers: 2,
    max_listeners: 4,
    max_nodes: 16,
};

/// The messaging pattern of a service, with its settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServiceKind {
    /// Publish-subscribe of one payload type.
    PublishSubscribe(PubSubQos),
    /// Event (wake-up) without payload.
    Event(EventQos),
}

/// One row of the service table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServiceSpec {
    /// Service name of the default instance, e.g. `"exo/sensor"`.
    pub name: &'static str,
    /// Payload type name (`Message::TYPE_NAME`); `None` for an event service.
    pub payload: Option<&'static str>,
    /// The process that publishes (or, for an event, notifies).
    pub publisher: Process,
    /// The processes that subscribe (or, for an event, listen).
    pub subscribers: &'static [Process],
    /// Pattern and settings.
    pub kind: ServiceKind,
    /// For a publish-subscribe service, its wake-up event service; for an
    /// event service, the publish-subscribe service whose samples it announces.
    pub companion: Option<&'static str>,
}

use Process::{Controller, Identifier, Operator, PlantSim, Recorder, SensorDriver};

/// Every service of exo.
pub const SERVICES: [ServiceSpec; 12] = [
    ServiceSpec {
        name: SENSOR,
        payload: Some(<crate::SensorSample as Message>::TYPE_NAME),
        publisher: SensorDriver,
        subscribers: &[Controller, Identifier, Recorder],
        kind: ServiceKind::PublishSubscribe(STREAM_QOS),
        companion: Some(SENSOR_EVENT),
    },
    ServiceSpec {
        name: COMMAND,
        payload: Some(<crate::ActuatorCommand as Message>::TYPE_NAME),
        publisher: Controller,
        subscribers: &[SensorDriver, Identifier, Recorder],
        kind: ServiceKind::PublishSubscribe(STREAM_QOS),
        companion: Some(COMMAND_EVENT),
    },
    ServiceSpec {
        name: PROTOCOL,
        payload: Some(<crate::ProtocolState as Message>::TYPE_NAME),
        publisher: Controller,
        subscribers: &[PlantSim, Identifier, Recorder],
        kind: ServiceKind::PublishSubscribe(STATE_QOS),
        companion: None,
    },
    ServiceSpec {
        name: BUS_SENSOR,
        payload: Some(<crate::BusSensorFrame as Message>::TYPE_NAME),
        publisher: PlantSim,
        subscribers: &[SensorDriver, Recorder],
        kind: ServiceKind::PublishSubscribe(STREAM_QOS),
        companion: Some(BUS_SENSOR_EVENT),
    },
    ServiceSpec {
        name: BUS_MOTOR,
        payload: Some(<crate::BusMotorCommand as Message>::TYPE_NAME),
        publisher: SensorDriver,
        subscribers: &[PlantSim, Recorder],
        kind: ServiceKind::PublishSubscribe(STREAM_QOS),
        companion: Some(BUS_MOTOR_EVENT),
    },
    ServiceSpec {
        name: IDENTIFIER_FRF,
        payload: Some(<crate::FrfPoint as Message>::TYPE_NAME),
        publisher: Identifier,
        subscribers: &[Recorder, Operator],
        kind: ServiceKind::PublishSubscribe(FRF_QOS),
        companion: None,
    },
    ServiceSpec {
        name: IDENTIFIER_ESTIMATE,
        payload: Some(<crate::ImpedanceEstimate as Message>::TYPE_NAME),
        publisher: Identifier,
        subscribers: &[Recorder, Operator],
        kind: ServiceKind::PublishSubscribe(STATE_QOS),
        companion: None,
    },
    ServiceSpec {
        name: OPERATOR,
        payload: Some(<crate::OperatorCommand as Message>::TYPE_NAME),
        publisher: Operator,
        subscribers: &[Controller, SensorDriver, Recorder],
        kind: ServiceKind::PublishSubscribe(OPERATOR_QOS),
        companion: None,
    },
    ServiceSpec {
        name: SENSOR_EVENT,
        payload: None,
        publisher: SensorDriver,
        subscribers: &[Controller],
        kind: ServiceKind::Event(WAKE_QOS),
        companion: Some(SENSOR),
    },
    ServiceSpec {
        name: COMMAND_EVENT,
        payload: None,
        publisher: Controller,
        subscribers: &[SensorDriver],
        kind: ServiceKind::Event(WAKE_QOS),
        companion: Some(COMMAND),
    },
    ServiceSpec {
        name: BUS_SENSOR_EVENT,
        payload: None,
        publisher: PlantSim,
        subscribers: &[SensorDriver],
        kind: ServiceKind::Event(WAKE_QOS),
        companion: Some(BUS_SENSOR),
    },
    ServiceSpec {
        name: BUS_MOTOR_EVENT,
        payload: None,
        publisher: SensorDriver,
        subscribers: &[PlantSim],
        kind: ServiceKind::Event(WAKE_QOS),
        companion: Some(BUS_MOTOR),
    },
];

/// The row of `name` (a default-instance name such as [`SENSOR`]).
pub fn spec(name: &str) -> Option<&'static ServiceSpec> {
    SERVICES.iter().find(|s| s.name == name)
}

/// The name of service `name` (a default-instance name such as [`SENSOR`])
/// in `instance`: the first segment `exo` is replaced, e.g.
/// `instance_name(SENSOR, "run7")` is `"run7/sensor"`. A name that does not
/// start with `exo/` is returned unchanged.
pub fn instance_name(name: &str, instance: &str) -> String {
    match name.strip_prefix(ROOT).filter(|rest| rest.starts_with('/')) {
        Some(rest) => format!("{instance}{rest}"),
        None => name.to_string(),
    }
}

/// The service table as Markdown (name, pattern, payload, publisher,
/// subscribers), for documentation and `exo` tool output.
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| service | pattern | payload | publisher / notifier | subscribers / listeners |\n|---|---|---|---|---|\n",
    );
    for s in &SERVICES {
        let pattern = match s.kind {
            ServiceKind::PublishSubscribe(_) => "publish-subscribe",
            ServiceKind::Event(_) => "event",
        };
        let subs: Vec<&str> = s.subscribers.iter().map(|p| p.name()).collect();
        out.push_str(&format!(
            "| `{}` | {} | {} | {} | {} |\n",
            s.name,
            pattern,
            s.payload.map_or("—".to_string(), |p| format!("`{p}`")),
            s.publisher.name(),
            subs.join(", ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn names_are_unique_and_well_formed() {
        let names: HashSet<&str> = SERVICES.iter().map(|s| s.name).collect();
        assert_eq!(names.len(), SERVICES.len(), "duplicate service name");
        for s in &SERVICES {
            assert!(s.name.starts_with("exo/"), "{}", s.name);
            assert!(!s.name.ends_with('/') && !s.name.contains("//"));
            assert_eq!(spec(s.name), Some(s));
            let subs: HashSet<_> = s.subscribers.iter().collect();
            assert_eq!(subs.len(), s.subscribers.len(), "{}", s.name);
            assert!(!subs.contains(&s.publisher), "{}", s.name);
        }
        assert_eq!(spec("exo/nothing"), None);
    }

    #[test]
    fn every_const_is_in_the_table() {
        for name in [
            SENSOR,
            COMMAND,
            PROTOCOL,
            BUS_SENSOR,
            BUS_MOTOR,
            IDENTIFIER_FRF,
            IDENTIFIER_ESTIMATE,
            OPERATOR,
            SENSOR_EVENT,
            COMMAND_EVENT,
            BUS_SENSOR_EVENT,
            BUS_MOTOR_EVENT,
        ] {
            assert!(spec(name).is_some(), "{name} missing from SERVICES");
        }
    }

    #[test]
    fn payloads_are_unique_and_companions_pair_up() {
        let payloads: Vec<&str> = SERVICES.iter().filter_map(|s| s.payload).collect();
        let unique: HashSet<&str> = payloads.iter().copied().collect();
        assert_eq!(unique.len(), payloads.len());
        for s in &SERVICES {
            match s.kind {
                ServiceKind::PublishSubscribe(q) => {
                    assert!(s.payload.is_some());
                    assert!(q.subscriber_max_buffer_size >= 1 && q.max_subscribers >= 1);
                    assert!(q.max_subscribers >= s.subscribers.len());
                }
                ServiceKind::Event(q) => {
                    assert!(s.payload.is_none());
                    assert!(q.max_listeners >= s.subscribers.len());
                }
            }
            if let Some(c) = s.companion {
                let other = spec(c).expect("companion is in the table");
                assert_eq!(other.companion, Some(s.name));
                assert_eq!(other.publisher, s.publisher, "{}", s.name);
                assert_ne!(
                    matches!(other.kind, ServiceKind::Event(_)),
                    matches!(s.kind, ServiceKind::Event(_))
                );
                let (pubsub, event) = match s.kind {
                    ServiceKind::PublishSubscribe(_) => (s.name, c),
                    ServiceKind::Event(_) => (c, s.name),
                };
                assert_eq!(event, format!("{pubsub}/event"));
            }
        }
        assert_eq!(spec(SENSOR).and_then(|s| s.companion), Some(SENSOR_EVENT));
        assert_eq!(
            spec(OPERATOR).map(|s| s.kind),
            Some(ServiceKind::PublishSubscribe(OPERATOR_QOS))
        );
        assert_eq!(OPERATOR_QOS.history_size, 0);
    }

    #[test]
    fn instance_names() {
        assert_eq!(instance_name(SENSOR, "exo"), "exo/sensor");
        assert_eq!(instance_name(SENSOR, "run7"), "run7/sensor");
        assert_eq!(instance_name(BUS_MOTOR_EVENT, "t-1"), "t-1/bus/motor/event");
        assert_eq!(instance_name("exotic/x", "run7"), "exotic/x");
    }

    #[test]
    fn markdown_table_lists_every_service() {
        let t = markdown_table();
        assert_eq!(t.lines().count(), 2 + SERVICES.len());
        assert!(t.contains("| `exo/sensor` | publish-subscribe | `exo.SensorSample.v1` | sensor-driver | controller, identifier, recorder |"), "{t}");
    }
}
