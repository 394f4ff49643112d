//! Every channel of exo, declared once: its name, its payload type, who
//! publishes it and who reads it, how deep a subscriber may buffer it, how
//! many publishers it allows, whether it is recorded and under which MCAP
//! schema. The IPC helpers (`exo_service_kit::ipc`), the runner, the
//! recorder, the player and the `exo` tool all read this table; nothing
//! else spells a channel's name.
//!
//! A channel is opened through its typed handle ([`SENSOR`], [`COMMAND`],
//! …), a [`Topic<T>`] whose payload type is checked against the table at
//! compile time, so a process cannot open `exo/sensor` with the wrong
//! message type.
//!
//! The processes are declared here too ([`ProcessName`]): the node names,
//! the binaries the supervisor starts, and the channel table's publishers
//! and subscribers all come from it.

use core::marker::PhantomData;

use crate::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, Message,
    OffPathProgress, OperatorCommand, OperatorReply, ProtocolState, SensorSample,
};

/// The processes of exo.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ProcessName {
    /// The plant simulator (stands in for the hardware on the bus).
    PlantSim,
    /// The sensor driver (talks to the bus, publishes calibrated samples).
    SensorDriver,
    /// The fractional-order controller and protocol sequencer.
    Controller,
    /// The online complex-stiffness identifier.
    Identifier,
    /// The MCAP recorder.
    Recorder,
    /// The player of a recording (stands in for driver and controller).
    Player,
    /// The live view: every channel to Foxglove over its WebSocket
    /// protocol (only subscribes).
    Live,
    /// The tunnel: channels to and from another host over Zenoh (on the
    /// exo computer it only subscribes).
    Tunnel,
    /// The operator console (`exo op`).
    Operator,
}

impl ProcessName {
    /// Every process, in start order (the operator console last; it is not
    /// started by the supervisor).
    pub const ALL: [ProcessName; 9] = [
        ProcessName::PlantSim,
        ProcessName::SensorDriver,
        ProcessName::Controller,
        ProcessName::Identifier,
        ProcessName::Recorder,
        ProcessName::Player,
        ProcessName::Live,
        ProcessName::Tunnel,
        ProcessName::Operator,
    ];

    /// Its name in logs, node names and the channel table, e.g.
    /// `"sensor-driver"`.
    pub const fn name(self) -> &'static str {
        match self {
            ProcessName::PlantSim => "plant-sim",
            ProcessName::SensorDriver => "sensor-driver",
            ProcessName::Controller => "controller",
            ProcessName::Identifier => "identifier",
            ProcessName::Recorder => "recorder",
            ProcessName::Player => "player",
            ProcessName::Live => "live",
            ProcessName::Tunnel => "tunnel",
            ProcessName::Operator => "operator",
        }
    }

    /// The executable that runs it, e.g. `"exo-sensor-driver"` (the
    /// operator console is a subcommand of `exo`).
    pub const fn binary(self) -> &'static str {
        match self {
            ProcessName::PlantSim => "exo-plant-sim",
            ProcessName::SensorDriver => "exo-sensor-driver",
            ProcessName::Controller => "exo-controller",
            ProcessName::Identifier => "exo-identifier",
            ProcessName::Recorder => "exo-recorder",
            ProcessName::Player => "exo-player",
            ProcessName::Live => "exo-live",
            ProcessName::Tunnel => "exo-tunnel",
            ProcessName::Operator => "exo",
        }
    }

    /// Its iceoryx2 node name (`-` is not allowed there), e.g.
    /// `"sensor_driver"`.
    pub const fn node_name(self) -> &'static str {
        match self {
            ProcessName::PlantSim => "plant_sim",
            ProcessName::SensorDriver => "sensor_driver",
            ProcessName::Controller => "controller",
            ProcessName::Identifier => "identifier",
            ProcessName::Recorder => "recorder",
            ProcessName::Player => "player",
            ProcessName::Live => "live",
            ProcessName::Tunnel => "tunnel",
            ProcessName::Operator => "operator",
        }
    }
}

impl core::fmt::Display for ProcessName {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// A channel of exo (the index into [`CHANNELS`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(usize)]
pub enum Channel {
    /// Calibrated samples (`SensorSample`).
    Sensor = 0,
    /// Controller commands (`ActuatorCommand`).
    Command = 1,
    /// Protocol state (`ProtocolState`).
    Protocol = 2,
    /// Raw bus frames from the (simulated) hardware (`BusSensorFrame`).
    BusSensor = 3,
    /// Motor commands to the (simulated) hardware (`BusMotorCommand`).
    BusMotor = 4,
    /// Identifier FRF points (`FrfPoint`).
    IdentifierFrf = 5,
    /// Identifier estimates (`ImpedanceEstimate`).
    IdentifierEstimate = 6,
    /// Operator commands (`OperatorCommand`).
    Operator = 7,
    /// The controller's answers to operator commands (`OperatorReply`).
    OperatorReply = 8,
    /// How far the recorder has taken the run (`OffPathProgress`).
    RecorderProgress = 9,
    /// How far the identifier has taken the run (`OffPathProgress`).
    IdentifierProgress = 10,
}

/// A channel's declaration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelInfo {
    /// The channel.
    pub channel: Channel,
    /// Its name on the default instance `exo`, which is also its topic in a
    /// recording, e.g. `"exo/sensor"`. On another instance the first
    /// segment is the instance's name ([`Channel::service_name`]).
    pub topic: &'static str,
    /// Payload type name (the message's [`Message::TYPE_NAME`], which is the
    /// `type_name` of its `ZeroCopySend` derive with the feature `ipc`).
    pub payload: &'static str,
    /// Publishing process.
    pub publisher: ProcessName,
    /// Subscribing processes.
    pub subscribers: &'static [ProcessName],
    /// Whether a wake-up event accompanies each sample (`<name>/event`).
    pub has_event: bool,
    /// How many publishers the channel allows: 1 for the control path's
    /// channels (samples, commands, the bus), so a second controller,
    /// driver or plant on a running instance is refused at start instead
    /// of interleaving its messages with the first's.
    pub max_publishers: usize,
    /// The deepest buffer a subscriber may ask for, in samples (the
    /// recorder's and the identifier's: 8 s of samples at 1 kHz).
    pub max_buffer: usize,
    /// Whether the recorder writes it to the MCAP file.
    pub recorded: bool,
    /// How many of its last samples the publisher keeps for a subscriber
    /// that joins late and asks for them (a restarted recorder, which so
    /// picks up what was published while it was down); other subscribers
    /// take the last one only.
    pub history: usize,
    /// Its ros2msg schema name in a recording.
    pub schema: &'static str,
}

/// Every channel of exo, in [`Channel`] order.
pub const CHANNELS: [ChannelInfo; 11] = [
    ChannelInfo {
        channel: Channel::Sensor,
        topic: "exo/sensor",
        payload: SensorSample::TYPE_NAME,
        publisher: ProcessName::SensorDriver,
        subscribers: &[
            ProcessName::Controller,
            ProcessName::Identifier,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: true,
        max_publishers: 1,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/SensorSample",
    },
    ChannelInfo {
        channel: Channel::Command,
        topic: "exo/command",
        payload: ActuatorCommand::TYPE_NAME,
        publisher: ProcessName::Controller,
        subscribers: &[
            ProcessName::SensorDriver,
            ProcessName::Identifier,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: true,
        max_publishers: 1,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/ActuatorCommand",
    },
    ChannelInfo {
        channel: Channel::Protocol,
        topic: "exo/protocol",
        payload: ProtocolState::TYPE_NAME,
        publisher: ProcessName::Controller,
        subscribers: &[
            ProcessName::PlantSim,
            ProcessName::SensorDriver,
            ProcessName::Identifier,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: false,
        max_publishers: 4,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/ProtocolState",
    },
    ChannelInfo {
        channel: Channel::BusSensor,
        topic: "exo/bus/sensor",
        payload: BusSensorFrame::TYPE_NAME,
        publisher: ProcessName::PlantSim,
        subscribers: &[
            ProcessName::SensorDriver,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: true,
        max_publishers: 1,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/BusSensorFrame",
    },
    ChannelInfo {
        channel: Channel::BusMotor,
        topic: "exo/bus/motor",
        payload: BusMotorCommand::TYPE_NAME,
        publisher: ProcessName::SensorDriver,
        subscribers: &[
            ProcessName::PlantSim,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: true,
        max_publishers: 1,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/BusMotorCommand",
    },
    ChannelInfo {
        channel: Channel::IdentifierFrf,
        topic: "exo/identifier/frf",
        payload: FrfPoint::TYPE_NAME,
        publisher: ProcessName::Identifier,
        subscribers: &[
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: false,
        max_publishers: 4,
        max_buffer: SPARSE,
        recorded: true,
        history: SPARSE,
        schema: "exo_msgs/msg/FrfPoint",
    },
    ChannelInfo {
        channel: Channel::IdentifierEstimate,
        topic: "exo/identifier/estimate",
        payload: ImpedanceEstimate::TYPE_NAME,
        publisher: ProcessName::Identifier,
        subscribers: &[
            ProcessName::Controller,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: false,
        max_publishers: 4,
        max_buffer: SPARSE,
        recorded: true,
        history: SPARSE,
        schema: "exo_msgs/msg/ImpedanceEstimate",
    },
    ChannelInfo {
        channel: Channel::Operator,
        topic: "exo/operator",
        payload: OperatorCommand::TYPE_NAME,
        publisher: ProcessName::Operator,
        subscribers: &[
            ProcessName::Controller,
            ProcessName::SensorDriver,
            ProcessName::Recorder,
            ProcessName::Live,
            ProcessName::Tunnel,
        ],
        has_event: false,
        max_publishers: 4,
        max_buffer: DEEP,
        recorded: true,
        history: DEEP,
        schema: "exo_msgs/msg/OperatorCommand",
    },
    ChannelInfo {
        channel: Channel::OperatorReply,
        topic: "exo/operator/reply",
        payload: OperatorReply::TYPE_NAME,
        publisher: ProcessName::Controller,
        subscribers: &[ProcessName::Operator],
        has_event: false,
        // One controller answers (a second is refused at start on
        // `exo/command`).
        max_publishers: 1,
        max_buffer: REPLIES,
        // Not in the recording contract (the operator's command is, and the
        // controller's log says what it did); the replies are for the
        // console that asked.
        recorded: false,
        history: 0,
        schema: "",
    },
    ChannelInfo {
        channel: Channel::RecorderProgress,
        topic: "exo/recorder/progress",
        payload: OffPathProgress::TYPE_NAME,
        publisher: ProcessName::Recorder,
        // In lockstep the plant holds its next frame while the recorder is
        // more than `OffPathProgress::MAX_LAG_FRAMES` behind.
        subscribers: &[ProcessName::PlantSim],
        // The holding plant sleeps on it.
        has_event: true,
        // Two: a restarted recorder's publisher must not wait for the dead
        // one's to be cleaned up.
        max_publishers: 2,
        max_buffer: PROGRESS,
        // Not in the recording contract: it says how far the recording
        // reaches, for the plant in lockstep.
        recorded: false,
        // The last one, for a plant that connects after it was published.
        history: 1,
        schema: "",
    },
    ChannelInfo {
        channel: Channel::IdentifierProgress,
        topic: "exo/identifier/progress",
        payload: OffPathProgress::TYPE_NAME,
        publisher: ProcessName::Identifier,
        // In lockstep, when the identifier's estimates feed the controller
        // (`controller.adopt_recommended_f` or `protocol.stop_when`), the plant holds its next
        // frame while the identifier is more than
        // `OffPathProgress::MAX_LAG_FRAMES` behind.
        subscribers: &[ProcessName::PlantSim],
        has_event: true,
        max_publishers: 2,
        max_buffer: PROGRESS,
        recorded: false,
        history: 1,
        schema: "",
    },
];

/// The buffer bound of the recorder's progress: only the last one counts.
const PROGRESS: usize = 16;

/// The buffer bound of the operator replies: more than a console sends
/// before it reads.
const REPLIES: usize = 16;

/// The subscriber buffer bound of the tick-rate channels (8 s at 1 kHz).
const DEEP: usize = 8192;

/// The buffer and history bound of the identifier's channels, which carry a
/// few samples per analysis window (one estimate per model, the window's
/// FRF points: one per sine, at most `broadband_points`, 20, per broadband
/// window): 256 is minutes of windows. Kept small because every subscriber
/// maps the publisher's data segment, sized by it (issue 32 item 4).
const SPARSE: usize = 256;

/// The default instance, whose channel names are the recording's topics.
pub const DEFAULT_INSTANCE: &str = "exo";

impl Channel {
    /// The channel's declaration.
    pub const fn info(self) -> &'static ChannelInfo {
        &CHANNELS[self as usize]
    }

    /// Its name after the instance, e.g. `"sensor"` or `"bus/motor"`.
    pub fn suffix(self) -> &'static str {
        let topic = self.info().topic;
        topic
            .strip_prefix(DEFAULT_INSTANCE)
            .and_then(|s| s.strip_prefix('/'))
            .unwrap_or(topic)
    }

    /// The full service name for `instance`, e.g. `exo/sensor`.
    pub fn service_name(self, instance: &str) -> String {
        format!("{instance}/{}", self.suffix())
    }

    /// The name of its wake-up event service, e.g. `exo/sensor/event`.
    pub fn event_name(self, instance: &str) -> String {
        format!("{instance}/{}/event", self.suffix())
    }

    /// The channel recorded under `topic`, if any.
    pub fn of_topic(topic: &str) -> Option<Channel> {
        CHANNELS
            .iter()
            .find(|c| c.topic == topic)
            .map(|c| c.channel)
    }
}

/// A channel with its payload type: what the IPC helpers open. Built only
/// by [`Topic::new`], which checks at compile time (in the constants below)
/// that `T` is the payload the table declares:
///
/// ```
/// use exo_messages::channels::{Channel, Topic};
/// const SAMPLES: Topic<exo_messages::SensorSample> = Topic::new(Channel::Sensor);
/// assert_eq!(SAMPLES.info().topic, "exo/sensor");
/// ```
///
/// while the wrong payload does not build:
///
/// ```compile_fail
/// use exo_messages::channels::{Channel, Topic};
/// const SAMPLES: Topic<exo_messages::ActuatorCommand> = Topic::new(Channel::Sensor);
/// assert_eq!(SAMPLES.info().topic, "exo/sensor");
/// ```
pub struct Topic<T: Message> {
    channel: Channel,
    payload: PhantomData<fn() -> T>,
}

impl<T: Message> Clone for Topic<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T: Message> Copy for Topic<T> {}

impl<T: Message> core::fmt::Debug for Topic<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "Topic({}: {})", self.channel.info().topic, T::TYPE_NAME)
    }
}

impl<T: Message> Topic<T> {
    /// The typed handle of `channel`; panics (at compile time, in a
    /// `const`) if `T` is not the payload [`CHANNELS`] declares for it.
    pub const fn new(channel: Channel) -> Self {
        assert!(
            same_str(channel.info().payload, T::TYPE_NAME),
            "payload type does not match the channel table"
        );
        Topic {
            channel,
            payload: PhantomData,
        }
    }

    /// The channel.
    pub const fn channel(self) -> Channel {
        self.channel
    }

    /// The channel's declaration.
    pub const fn info(self) -> &'static ChannelInfo {
        self.channel.info()
    }
}

const fn same_str(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// `exo/sensor`: calibrated samples, sensor driver → controller, identifier.
pub const SENSOR: Topic<SensorSample> = Topic::new(Channel::Sensor);
/// `exo/command`: torque commands, controller → sensor driver.
pub const COMMAND: Topic<ActuatorCommand> = Topic::new(Channel::Command);
/// `exo/protocol`: the protocol's state, controller → everyone.
pub const PROTOCOL: Topic<ProtocolState> = Topic::new(Channel::Protocol);
/// `exo/bus/sensor`: raw frames, (simulated) hardware → sensor driver.
pub const BUS_SENSOR: Topic<BusSensorFrame> = Topic::new(Channel::BusSensor);
/// `exo/bus/motor`: motor commands, sensor driver → (simulated) hardware.
pub const BUS_MOTOR: Topic<BusMotorCommand> = Topic::new(Channel::BusMotor);
/// `exo/identifier/frf`: FRF points of the online identifier.
pub const IDENTIFIER_FRF: Topic<FrfPoint> = Topic::new(Channel::IdentifierFrf);
/// `exo/identifier/estimate`: K, H estimates of the online identifier.
pub const IDENTIFIER_ESTIMATE: Topic<ImpedanceEstimate> = Topic::new(Channel::IdentifierEstimate);
/// `exo/operator`: operator commands, `exo op` → controller, sensor driver.
pub const OPERATOR: Topic<OperatorCommand> = Topic::new(Channel::Operator);
/// `exo/operator/reply`: the controller's answer to each operator command,
/// controller → `exo op`.
pub const OPERATOR_REPLY: Topic<OperatorReply> = Topic::new(Channel::OperatorReply);
/// `exo/recorder/progress`: how far the recorder has written the run,
/// recorder → plant simulator (which holds simulated time for it in lockstep).
pub const RECORDER_PROGRESS: Topic<OffPathProgress> = Topic::new(Channel::RecorderProgress);
/// `exo/identifier/progress`: how far the identifier has taken the run,
/// identifier → plant simulator (which holds simulated time for it in
/// lockstep when its estimates feed the controller).
pub const IDENTIFIER_PROGRESS: Topic<OffPathProgress> = Topic::new(Channel::IdentifierProgress);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_in_channel_order_and_names_are_unique() {
        for (i, c) in CHANNELS.iter().enumerate() {
            assert_eq!(c.channel as usize, i, "{} out of order", c.topic);
            assert_eq!(c.channel.info().topic, c.topic);
            assert!(c.topic.starts_with("exo/"), "{}", c.topic);
            assert!(c.max_buffer >= 1 && c.max_publishers >= 1);
            // A subscriber's buffer must hold the history it asks for.
            assert!(c.history <= c.max_buffer, "{}", c.topic);
        }
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
        assert_eq!(Channel::Sensor.service_name("run7"), "run7/sensor");
        assert_eq!(Channel::BusMotor.event_name("r"), "r/bus/motor/event");
        assert_eq!(Channel::of_topic("exo/bus/motor"), Some(Channel::BusMotor));
        assert_eq!(Channel::of_topic("exo/other"), None);
    }

    #[test]
    fn the_typed_handles_carry_the_declared_payloads() {
        assert_eq!(SENSOR.info().payload, "exo.SensorSample.v1");
        assert_eq!(COMMAND.channel(), Channel::Command);
        assert_eq!(OPERATOR.info().topic, "exo/operator");
        assert!(!same_str("exo.SensorSample.v1", "exo.SensorSample.v2"));
        assert!(!same_str("a", "ab"));
        assert!(same_str("", ""));
    }

    #[test]
    fn process_names_are_distinct_and_node_names_are_their_names() {
        for p in ProcessName::ALL {
            assert_eq!(p.node_name(), p.name().replace('-', "_"));
            assert_eq!(
                ProcessName::ALL
                    .iter()
                    .filter(|q| q.name() == p.name())
                    .count(),
                1
            );
            if p != ProcessName::Operator {
                assert_eq!(p.binary(), format!("exo-{}", p.name()));
            }
        }
        // Every publisher and subscriber in the table is a process of exo
        // that is not also its own subscriber.
        for c in &CHANNELS {
            assert!(!c.subscribers.contains(&c.publisher), "{}", c.topic);
            // The watchers read every channel of the recording contract
            // (issue 17).
            for w in [
                ProcessName::Recorder,
                ProcessName::Live,
                ProcessName::Tunnel,
            ] {
                assert!(
                    !c.recorded || c.subscribers.contains(&w),
                    "{} lacks {w}",
                    c.topic
                );
            }
        }
    }
}
