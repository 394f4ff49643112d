//! The IPC helpers every exo process uses.
//!
//! * [`open_node`]: an iceoryx2 [`Node`] built with the project's
//!   configuration file loaded explicitly (argument, else
//!   `$EXO_ICEORYX2_CONFIG`, else `configs/iceoryx2.toml` of the source tree),
//!   which is also installed as iceoryx2's global configuration so no code
//!   path falls back to iceoryx2's own file search.
//! * [`open_publish_subscribe`] / [`open_event`]: open-or-create a service of
//!   [`services::SERVICES`] with the settings of its row, checking the payload
//!   type against the table; the `*_with` variants take any name and settings.
//! * [`Outbox`] (publisher + wake-up notifier) and [`Inbox`] (subscriber +
//!   optional wake-up listener), the per-channel ports of a process.
//! * [`cleanup_dead_nodes`]: removes what processes killed with `kill -9`
//!   left in shared memory, so a restarted process works again without anyone
//!   cleaning `/dev/shm`.
//!
//! Nothing here unwraps; every failure is an [`IpcError`] naming the file,
//! node or service.
//!
//! # Heap allocations per call (iceoryx2 0.10, measured by `tests/alloc.rs`)
//!
//! | call (steady state, after warm-up) | allocations |
//! |---|---|
//! | `Publisher::loan_uninit` + `write_payload` + `send` ([`Outbox::send`]) | 1 per sample |
//! | `Publisher::send_copy` | 1 per sample |
//! | `Subscriber::receive` ([`Inbox::try_recv`]) | 0 |
//! | `Notifier::notify` | 0 |
//! | `Listener::timed_wait`, `Listener::try_wait` ([`Inbox::wait`]) | 0 |
//! | `WaitSet::wait_and_process_once` (not used here) | 2 per wake-up |
//!
//! The publisher's allocation is the reference-counted per-sample state
//! (`ChunkMutSharedState`, an `Rc` for `ipc::Service`) that every loan
//! creates in `SampleMutUninit::new`. Every loan path of 0.10 (`loan`,
//! `loan_uninit`, `loan_slice*`, `send_copy`, flatbuffers) goes through it,
//! so there is no allocation-free send in 0.10; see `ALLOCATIONS.md`.
//!
//! # Waiting with a timeout
//!
//! iceoryx2 0.10's `Listener::timed_wait` on `ipc::Service` is a `recv` on a
//! Unix datagram socket with `SO_RCVTIMEO`: the kernel rounds the timeout up
//! to whole scheduler ticks (measured here: 1 µs, 100 µs and 2 ms timeouts
//! all took ≈ 7.7 ms), and a timeout below 1 µs truncates to zero, which the
//! kernel reads as "wait forever". [`Inbox::wait`] instead
//! polls the listener's file descriptor with `ppoll` (nanosecond timeout; a
//! zero timeout does not block) and then drains the notifications with the
//! non-blocking `try_wait`.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use iceoryx2::config::Config;
use iceoryx2::node::{Node, NodeBuilder, NodeCleanupFailure, NodeState};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{
    CallbackProgression, FileDescriptorBased, FilePath, NodeName, SemanticString as _, ServiceName,
    SignalHandlingMode,
};
use thiserror::Error;

use crate::services::{self, EventQos, PubSubQos, ServiceKind, ServiceSpec};
use crate::Message;

/// The iceoryx2 service flavour of exo: inter-process, POSIX shared memory.
pub type Svc = iceoryx2::service::ipc::Service;
/// A node of exo.
pub type ExoNode = Node<Svc>;
/// An opened publish-subscribe service carrying `T`.
pub type PubSubService<T> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>;
/// An opened event service.
pub type EventService = iceoryx2::service::port_factory::event::PortFactory<Svc>;
/// A publisher of `T`.
pub type ExoPublisher<T> = Publisher<Svc, T, ()>;
/// A subscriber of `T`.
pub type ExoSubscriber<T> = Subscriber<Svc, T, ()>;
/// A notifier of an event service.
pub type ExoNotifier = Notifier<Svc>;
/// A listener of an event service.
pub type ExoListener = Listener<Svc>;

/// Environment variable naming the iceoryx2 configuration file.
pub const CONFIG_ENV: &str = "EXO_ICEORYX2_CONFIG";

/// The project's iceoryx2 configuration in the source tree this crate was
/// built from (`<workspace>/configs/iceoryx2.toml`), the last fallback of
/// [`config_path`].
pub const SOURCE_TREE_CONFIG: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/iceoryx2.toml");

/// Samples a publisher may hold loaned at once (one being written, one spare).
pub const PUBLISHER_MAX_LOANED_SAMPLES: usize = 2;

/// An IPC failure, naming the file, node or service.
#[derive(Debug, Error)]
pub enum IpcError {
    /// The iceoryx2 configuration could not be loaded.
    #[error("iceoryx2 configuration {}: {reason}", path.display())]
    Config {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// A node or service name is not valid for iceoryx2.
    #[error("invalid {what} name `{name}`: {reason}")]
    InvalidName {
        /// `"node"` or `"service"`.
        what: &'static str,
        /// The name.
        name: String,
        /// What went wrong.
        reason: String,
    },
    /// The node could not be created.
    #[error("creating iceoryx2 node `{name}`: {reason}")]
    Node {
        /// Node name.
        name: String,
        /// What went wrong.
        reason: String,
    },
    /// The name is not in [`services::SERVICES`].
    #[error("`{service}` is not a service of exo (see exo_messages::services::SERVICES)")]
    UnknownService {
        /// The name asked for.
        service: String,
    },
    /// The service has another messaging pattern than the one asked for.
    #[error("`{service}` is not a service of the {expected} pattern")]
    WrongPattern {
        /// Service name.
        service: String,
        /// `"publish-subscribe"` or `"event"`.
        expected: &'static str,
    },
    /// A wake-up listener was asked for on a channel without a wake-up event.
    #[error("`{service}` has no wake-up event service; open it with `Wake::Poll`")]
    NoWakeEvent {
        /// Service name (with instance).
        service: String,
    },
    /// The payload type asked for is not the one the table names.
    #[error("`{service}` carries `{expected}`, not `{requested}`")]
    PayloadMismatch {
        /// Service name.
        service: String,
        /// Payload type name in the table.
        expected: &'static str,
        /// Payload type name asked for.
        requested: &'static str,
    },
    /// The service could not be opened or created (e.g. incompatible settings
    /// or payload layout of an existing service).
    #[error("opening service `{service}`: {reason}")]
    Service {
        /// Service name (with instance).
        service: String,
        /// What went wrong.
        reason: String,
    },
    /// A port could not be created, or an operation on it failed.
    #[error("{op} on `{service}`: {reason}")]
    Port {
        /// The operation, e.g. `"create publisher"`, `"send"`.
        op: &'static str,
        /// Service name (with instance).
        service: String,
        /// What went wrong.
        reason: String,
    },
    /// The nodes could not be listed for cleanup.
    #[error("listing iceoryx2 nodes: {reason}")]
    NodeList {
        /// What went wrong.
        reason: String,
    },
}

fn port_err(op: &'static str, service: &str, e: impl core::fmt::Debug) -> IpcError {
    IpcError::Port {
        op,
        service: service.to_string(),
        reason: format!("{e:?}"),
    }
}

/// The configuration file to load: `explicit` if given, else
/// `$EXO_ICEORYX2_CONFIG` if set and not empty, else [`SOURCE_TREE_CONFIG`].
pub fn config_path(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    match std::env::var_os(CONFIG_ENV) {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => PathBuf::from(SOURCE_TREE_CONFIG),
    }
}

fn iceoryx_file_path(path: &Path) -> Result<FilePath, IpcError> {
    let err = |reason: String| IpcError::Config {
        path: path.to_path_buf(),
        reason,
    };
    let absolute = std::fs::canonicalize(path).map_err(|e| err(e.to_string()))?;
    let text = absolute
        .to_str()
        .ok_or_else(|| err("the path is not UTF-8".into()))?;
    FilePath::new(text.as_bytes())
        .map_err(|e| err(format!("not a valid iceoryx2 file path: {e:?}")))
}

/// Loads an iceoryx2 configuration file. Keys the file leaves out take
/// iceoryx2's defaults. Note that iceoryx2 ignores unknown keys, so a
/// misspelled key is silently without effect (the crate's tests check the
/// project's file for that).
pub fn load_config(path: &Path) -> Result<Config, IpcError> {
    let file = iceoryx_file_path(path)?;
    Config::from_file(&file).map_err(|e| IpcError::Config {
        path: path.to_path_buf(),
        reason: format!("{e:?}"),
    })
}

/// Installs the file at `path` as iceoryx2's process-wide configuration
/// (`Config::global_config()`), which iceoryx2 falls back to where no
/// configuration is passed (e.g. when cleaning up a dead node whose details
/// are unreadable), so it never searches for a file of its own nor warns "No
/// config file was loaded". The first successful call of a process wins;
/// later calls are no-ops. Calls are serialised here because iceoryx2 0.10
/// warns when two threads install the global configuration at once.
pub fn install_global_config(path: &Path) -> Result<(), IpcError> {
    static INSTALLED: Mutex<bool> = Mutex::new(false);
    let mut installed = INSTALLED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if *installed {
        return Ok(());
    }
    let file = iceoryx_file_path(path)?;
    Config::setup_global_config_from_file(&file).map_err(|e| IpcError::Config {
        path: path.to_path_buf(),
        reason: format!("{e:?}"),
    })?;
    *installed = true;
    Ok(())
}

/// Creates the node `name` with the configuration file of
/// [`config_path`]`(config_file)`, installed also as iceoryx2's global
/// configuration. iceoryx2's own signal handling is disabled (processes
/// handle SIGINT/SIGTERM themselves). With the project's configuration,
/// creating a node also cleans up the resources of dead nodes.
pub fn open_node(name: &str, config_file: Option<&Path>) -> Result<ExoNode, IpcError> {
    let path = config_path(config_file);
    let config = load_config(&path)?;
    install_global_config(&path)?;
    open_node_with_config(name, &config)
}

/// Creates the node `name` with `config` (e.g. a test's configuration with its
/// own root path); iceoryx2's signal handling is disabled.
pub fn open_node_with_config(name: &str, config: &Config) -> Result<ExoNode, IpcError> {
    let node_name = NodeName::new(name).map_err(|e| IpcError::InvalidName {
        what: "node",
        name: name.to_string(),
        reason: format!("{e:?}"),
    })?;
    NodeBuilder::new()
        .name(&node_name)
        .config(config)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Svc>()
        .map_err(|e| IpcError::Node {
            name: name.to_string(),
            reason: format!("{e:?}"),
        })
}

fn service_name(name: &str) -> Result<ServiceName, IpcError> {
    ServiceName::new(name).map_err(|e| IpcError::InvalidName {
        what: "service",
        name: name.to_string(),
        reason: format!("{e:?}"),
    })
}

fn lookup(name: &str) -> Result<&'static ServiceSpec, IpcError> {
    services::spec(name).ok_or_else(|| IpcError::UnknownService {
        service: name.to_string(),
    })
}

fn pubsub_spec<T: Message>(name: &str) -> Result<(&'static ServiceSpec, PubSubQos), IpcError> {
    let spec = lookup(name)?;
    let ServiceKind::PublishSubscribe(qos) = spec.kind else {
        return Err(IpcError::WrongPattern {
            service: name.to_string(),
            expected: "publish-subscribe",
        });
    };
    match spec.payload {
        Some(p) if p == T::TYPE_NAME => Ok((spec, qos)),
        other => Err(IpcError::PayloadMismatch {
            service: name.to_string(),
            expected: other.unwrap_or("no payload"),
            requested: T::TYPE_NAME,
        }),
    }
}

fn event_spec(name: &str) -> Result<(&'static ServiceSpec, EventQos), IpcError> {
    let spec = lookup(name)?;
    match spec.kind {
        ServiceKind::Event(qos) => Ok((spec, qos)),
        ServiceKind::PublishSubscribe(_) => Err(IpcError::WrongPattern {
            service: name.to_string(),
            expected: "event",
        }),
    }
}

/// Opens or creates the publish-subscribe service `name` (a
/// [`services`] constant such as [`services::SENSOR`]) of `instance` for
/// payload `T`, with the settings of its row in [`services::SERVICES`].
/// Fails if `T` is not the payload the table names.
pub fn open_publish_subscribe<T: Message>(
    node: &ExoNode,
    name: &str,
    instance: &str,
) -> Result<PubSubService<T>, IpcError> {
    let (_, qos) = pubsub_spec::<T>(name)?;
    open_publish_subscribe_with::<T>(node, &services::instance_name(name, instance), &qos)
}

/// Opens or creates the publish-subscribe service with the full name
/// `service` for payload `T` with `qos`; safe overflow is on (a full
/// subscriber buffer drops its oldest sample, a publisher never blocks).
pub fn open_publish_subscribe_with<T: Message>(
    node: &ExoNode,
    service: &str,
    qos: &PubSubQos,
) -> Result<PubSubService<T>, IpcError> {
    node.service_builder(&service_name(service)?)
        .publish_subscribe::<T>()
        .max_publishers(qos.max_publishers)
        .max_subscribers(qos.max_subscribers)
        .max_nodes(qos.max_nodes)
        .subscriber_max_buffer_size(qos.subscriber_max_buffer_size)
        .subscriber_max_borrowed_samples(qos.subscriber_max_borrowed_samples)
        .history_size(qos.history_size)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| IpcError::Service {
            service: service.to_string(),
            reason: format!("{e:?}"),
        })
}

/// Opens or creates the event service `name` (a [`services`] constant such
/// as [`services::SENSOR_EVENT`]) of `instance` with the settings of its row.
pub fn open_event(node: &ExoNode, name: &str, instance: &str) -> Result<EventService, IpcError> {
    let (_, qos) = event_spec(name)?;
    open_event_with(node, &services::instance_name(name, instance), &qos)
}

/// Opens or creates the event service with the full name `service` with `qos`.
pub fn open_event_with(
    node: &ExoNode,
    service: &str,
    qos: &EventQos,
) -> Result<EventService, IpcError> {
    node.service_builder(&service_name(service)?)
        .event()
        .max_notifiers(qos.max_notifiers)
        .max_listeners(qos.max_listeners)
        .max_nodes(qos.max_nodes)
        .open_or_create()
        .map_err(|e| IpcError::Service {
            service: service.to_string(),
            reason: format!("{e:?}"),
        })
}

/// What [`cleanup_dead_nodes`] found and did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CleanupReport {
    /// Nodes whose process is alive (count).
    pub alive: usize,
    /// Nodes whose process is gone without cleaning up (count).
    pub dead: usize,
    /// Dead nodes whose resources this call removed (count).
    pub cleaned: usize,
    /// Dead nodes another process was already cleaning up, or had cleaned (count).
    pub cleaned_elsewhere: usize,
    /// Dead nodes whose cleanup failed, e.g. for permissions or another
    /// iceoryx2 version (count).
    pub failed: usize,
    /// Nodes whose state could not be read (count).
    pub inaccessible: usize,
}

/// Lists every node under `config` (iceoryx2's `Node::list`) and removes the
/// stale resources of the dead ones (`DeadNodeView::try_remove_stale_resources`):
/// their ports leave every service and their shared memory is released, so a
/// process restarted after `kill -9` can open its ports again. Never blocks
/// on a node another process is cleaning up.
pub fn cleanup_dead_nodes(config: &Config) -> Result<CleanupReport, IpcError> {
    let mut report = CleanupReport::default();
    Node::<Svc>::list(config, |state| {
        match state {
            NodeState::Alive(_) => report.alive += 1,
            NodeState::Dead(view) => {
                report.dead += 1;
                match view.try_remove_stale_resources() {
                    Ok(()) => report.cleaned += 1,
                    Err(
                        NodeCleanupFailure::ResourcesAlreadyCleanedUp
                        | NodeCleanupFailure::AnotherInstanceIsCleaningUpTheNode,
                    ) => report.cleaned_elsewhere += 1,
                    Err(_) => report.failed += 1,
                }
            }
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => report.inaccessible += 1,
        }
        CallbackProgression::Continue
    })
    .map_err(|e| IpcError::NodeList {
        reason: format!("{e:?}"),
    })?;
    Ok(report)
}

/// A channel's sending side: a publisher and, if the channel has a wake-up
/// event, its notifier.
pub struct Outbox<T: Message> {
    service: String,
    publisher: ExoPublisher<T>,
    notifier: Option<ExoNotifier>,
}

impl<T: Message> core::fmt::Debug for Outbox<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Outbox")
            .field("service", &self.service)
            .field("notifies", &self.notifier.is_some())
            .finish()
    }
}

impl<T: Message> Outbox<T> {
    /// Opens channel `name` (e.g. [`services::SENSOR`]) of `instance` for
    /// sending: a publisher and, where the table gives the channel a wake-up
    /// event, a notifier on it.
    pub fn open(node: &ExoNode, name: &str, instance: &str) -> Result<Self, IpcError> {
        let (spec, _) = pubsub_spec::<T>(name)?;
        let service = services::instance_name(name, instance);
        let publisher = open_publish_subscribe::<T>(node, name, instance)?
            .publisher_builder()
            .max_loaned_samples(PUBLISHER_MAX_LOANED_SAMPLES)
            .create()
            .map_err(|e| port_err("create publisher", &service, e))?;
        let notifier = match spec.companion {
            Some(event) => Some(
                open_event(node, event, instance)?
                    .notifier_builder()
                    .create()
                    .map_err(|e| port_err("create notifier", &service, e))?,
            ),
            None => None,
        };
        Ok(Outbox {
            service,
            publisher,
            notifier,
        })
    }

    /// Writes `value` into a loaned shared-memory sample, delivers it, then
    /// wakes the channel's listeners. Never blocks (safe overflow). Returns
    /// the number of subscribers it was delivered to. One heap allocation
    /// (iceoryx2 0.10's per-loan state); the notify makes none.
    pub fn send(&self, value: T) -> Result<usize, IpcError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| port_err("loan", &self.service, e))?;
        let delivered = sample
            .write_payload(value)
            .send()
            .map_err(|e| port_err("send", &self.service, e))?;
        if let Some(n) = &self.notifier {
            n.notify()
                .map_err(|e| port_err("notify", &self.service, e))?;
        }
        Ok(delivered)
    }

    /// The publisher, for what [`send`](Self::send) does not cover.
    pub fn publisher(&self) -> &ExoPublisher<T> {
        &self.publisher
    }

    /// The wake-up notifier, if the channel has one.
    pub fn notifier(&self) -> Option<&ExoNotifier> {
        self.notifier.as_ref()
    }

    /// The full service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

/// Whether an [`Inbox`] sleeps on the channel's wake-up event or polls.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// Listen on the channel's wake-up event (the real-time reader of a
    /// channel; the channel must have an event in the table).
    Listen,
    /// Poll (identifier, recorder): no listener, so publishers do no work for this reader.
    Poll,
}

/// How often a polling [`Inbox::wait`] looks for samples.
pub const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// A channel's receiving side: a subscriber and, with [`Wake::Listen`], a
/// wake-up listener.
pub struct Inbox<T: Message> {
    service: String,
    subscriber: ExoSubscriber<T>,
    listener: Option<ExoListener>,
}

impl<T: Message> core::fmt::Debug for Inbox<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Inbox")
            .field("service", &self.service)
            .field("listens", &self.listener.is_some())
            .finish()
    }
}

impl<T: Message> Inbox<T> {
    /// Opens channel `name` (e.g. [`services::SENSOR`]) of `instance` for
    /// receiving with a buffer of `buffer` samples (clamped to the channel's
    /// maximum; the oldest sample is dropped when it is full).
    pub fn open(
        node: &ExoNode,
        name: &str,
        instance: &str,
        buffer: usize,
        wake: Wake,
    ) -> Result<Self, IpcError> {
        let (spec, qos) = pubsub_spec::<T>(name)?;
        let service = services::instance_name(name, instance);
        let subscriber = open_publish_subscribe::<T>(node, name, instance)?
            .subscriber_builder()
            .buffer_size(buffer.clamp(1, qos.subscriber_max_buffer_size))
            .create()
            .map_err(|e| port_err("create subscriber", &service, e))?;
        let listener = match (wake, spec.companion) {
            (Wake::Poll, _) => None,
            (Wake::Listen, None) => return Err(IpcError::NoWakeEvent { service }),
            (Wake::Listen, Some(event)) => Some(
                open_event(node, event, instance)?
                    .listener_builder()
                    .create()
                    .map_err(|e| port_err("create listener", &service, e))?,
            ),
        };
        Ok(Inbox {
            service,
            subscriber,
            listener,
        })
    }

    /// The oldest waiting sample, copied out of shared memory, if any. No
    /// allocation, no blocking.
    pub fn try_recv(&self) -> Result<Option<T>, IpcError> {
        Ok(self
            .subscriber
            .receive()
            .map_err(|e| port_err("receive", &self.service, e))?
            .map(|s| *s.payload()))
    }

    /// The newest waiting sample and how many older ones were discarded to
    /// reach it (a real-time reader acts on the newest only).
    pub fn latest(&self) -> Result<Option<(T, usize)>, IpcError> {
        let mut newest = None;
        let mut discarded = 0;
        while let Some(v) = self.try_recv()? {
            if newest.replace(v).is_some() {
                discarded += 1;
            }
        }
        Ok(newest.map(|v| (v, discarded)))
    }

    /// Whether a sample is waiting.
    pub fn has_samples(&self) -> Result<bool, IpcError> {
        self.subscriber
            .has_samples()
            .map_err(|e| port_err("has_samples", &self.service, e))
    }

    /// Waits at most `timeout` until a sample is waiting and returns whether
    /// one is. Returns at once if one already is. With [`Wake::Listen`] it
    /// sleeps in `ppoll` on the listener's descriptor (nanosecond timeout, no
    /// busy spin, no allocation) and then drains the wake-ups; with
    /// [`Wake::Poll`] it looks every [`POLL_INTERVAL`].
    pub fn wait(&self, timeout: Duration) -> Result<bool, IpcError> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.has_samples()? {
                self.drain_wake_ups()?;
                return Ok(true);
            }
            let now = Instant::now();
            if now >= deadline {
                self.drain_wake_ups()?;
                return Ok(false);
            }
            let left = deadline - now;
            match &self.listener {
                Some(l) => {
                    // Spurious wake-ups (a stale notification) loop back.
                    wait_readable(l, left).map_err(|e| port_err("ppoll", &self.service, e))?;
                    self.drain_wake_ups()?;
                }
                None => std::thread::sleep(left.min(POLL_INTERVAL)),
            }
        }
    }

    fn drain_wake_ups(&self) -> Result<(), IpcError> {
        if let Some(l) = &self.listener {
            l.try_wait(|_| {})
                .map_err(|e| port_err("try_wait", &self.service, e))?;
        }
        Ok(())
    }

    /// The next sample, waiting at most `timeout` for one.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<Option<T>, IpcError> {
        if let Some(v) = self.try_recv()? {
            return Ok(Some(v));
        }
        self.wait(timeout)?;
        self.try_recv()
    }

    /// The subscriber, for what the methods here do not cover.
    pub fn subscriber(&self) -> &ExoSubscriber<T> {
        &self.subscriber
    }

    /// The wake-up listener, with [`Wake::Listen`].
    pub fn listener(&self) -> Option<&ExoListener> {
        self.listener.as_ref()
    }

    /// The full service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

/// Sleeps until `listener` has a pending notification or `timeout` passed,
/// with `ppoll` on its file descriptor (nanosecond timeout; zero does not
/// block). Returns whether it became readable. Does not consume the
/// notification: call `try_wait` after it. An interrupting signal counts as a
/// timeout.
pub fn wait_readable(listener: &ExoListener, timeout: Duration) -> std::io::Result<bool> {
    // SAFETY: the descriptor is owned by the listener, which outlives this
    // call; it is only polled, never closed or read here.
    let fd = unsafe { listener.file_descriptor().native_handle() };
    let mut pfd = libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    };
    let ts = libc::timespec {
        tv_sec: timeout.as_secs().min(libc::time_t::MAX as u64) as libc::time_t,
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
    let rc = unsafe { libc::ppoll(&mut pfd, 1, &ts, core::ptr::null()) };
    if rc < 0 {
        let err = std::io::Error::last_os_error();
        if err.kind() == std::io::ErrorKind::Interrupted {
            return Ok(false);
        }
        return Err(err);
    }
    Ok(rc > 0)
}
