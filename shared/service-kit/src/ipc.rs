//! The IPC helpers every exo process uses: a node with the project's
//! iceoryx2 configuration loaded explicitly, and per-channel "outboxes"
//! (publisher + wake-up notifier) and "inboxes" (subscriber + listener).
//!
//! Every service is opened or created with the same settings here, so the
//! processes always agree on them. Publishers never block: a full subscriber
//! buffer drops its oldest sample (safe overflow); the recorder asks for a
//! deep buffer and counts drops from sequence gaps.

use std::fmt::Debug;
use std::path::{Path, PathBuf};
use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use thiserror::Error;

use exo_messages::channels::{Channel, Topic};
use exo_messages::Message;

/// The iceoryx2 service flavour of exo: inter-process, shared memory.
pub type Svc = iceoryx2::service::ipc::Service;

/// Environment variable naming the iceoryx2 configuration file.
pub const CONFIG_ENV: &str = "EXO_ICEORYX2_CONFIG";

/// The buffer to ask [`Ipc::inbox`] for to get the deepest the channel
/// allows (its [`ChannelInfo::max_buffer`](exo_messages::channels::ChannelInfo),
/// what the recorder and the identifier take).
pub const DEEPEST: usize = usize::MAX;

/// How long a process off the real-time path (identifier, recorder) sleeps
/// after a pass that found samples, so that it takes them in batches rather
/// than waking once per sample: at 1 kHz, or at tens of kHz in lockstep,
/// one wake-up per sample costs the real-time path CPU time on a two-core
/// machine. A millisecond's samples are far below the [`DEEPEST`] buffer a
/// subscriber can hold.
pub const OFF_PATH_COALESCE: Duration = Duration::from_millis(1);

/// An IPC error, naming the service or file.
#[derive(Debug, Error)]
pub enum IpcError {
    /// The iceoryx2 configuration could not be loaded.
    #[error("iceoryx2 configuration {path}: {message}")]
    Config {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The node could not be created.
    #[error("iceoryx2 node `{name}`: {message}")]
    Node {
        /// Node name.
        name: String,
        /// What went wrong.
        message: String,
    },
    /// A second publisher on a channel that allows one
    /// ([`ChannelInfo::max_publishers`](crate::channels::ChannelInfo)).
    #[error("`{service}` already has its publisher (the {owner}): only one process may publish on it; is another {owner} running on instance `{instance}`? ({message})")]
    SecondPublisher {
        /// Service name.
        service: String,
        /// The process that publishes on it.
        owner: &'static str,
        /// The run's instance.
        instance: String,
        /// What iceoryx2 said.
        message: String,
    },
    /// A service or port could not be opened, or an operation on it failed.
    #[error("{what} on `{service}`: {message}")]
    Port {
        /// Which operation.
        what: &'static str,
        /// Service name.
        service: String,
        /// What went wrong.
        message: String,
    },
}

fn port_err(what: &'static str, service: &str, e: impl Debug) -> IpcError {
    IpcError::Port {
        what,
        service: service.to_string(),
        message: format!("{e:?}"),
    }
}

/// The configuration file to load: `explicit`, else `$EXO_ICEORYX2_CONFIG`,
/// else `configs/iceoryx2.toml` of the source tree this was built from.
pub fn config_path(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os(CONFIG_ENV) {
        return PathBuf::from(p);
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/iceoryx2.toml")
}

/// Loads an iceoryx2 configuration file.
pub fn load_config(path: &Path) -> Result<Config, IpcError> {
    let err = |message: String| IpcError::Config {
        path: path.to_path_buf(),
        message,
    };
    let text = path
        .to_str()
        .ok_or_else(|| err("path is not UTF-8".into()))?;
    let file = FilePath::new(text.as_bytes()).map_err(|e| err(format!("invalid path: {e:?}")))?;
    Config::from_file(&file).map_err(|e| err(format!("{e:?}")))
}

/// A process's iceoryx2 node and the instance prefix of its services.
pub struct Ipc {
    node: Node<Svc>,
    instance: String,
}

impl Ipc {
    /// Creates the node `name` with the configuration at `config` (see
    /// [`config_path`]), made this user's ([`crate::access`]), for the
    /// services of `instance`; the same file becomes iceoryx2's global
    /// configuration, so nothing falls back to iceoryx2's defaults. Dead
    /// nodes of earlier, killed processes are cleaned up on the way.
    pub fn open(name: &str, instance: &str, config: Option<&Path>) -> Result<Self, IpcError> {
        let path = crate::access::per_user_config(&config_path(config), Path::new("/tmp"))?;
        let cfg = load_config(&path)?;
        if let Some(text) = path.to_str() {
            if let Ok(file) = FilePath::new(text.as_bytes()) {
                // Only the first call of a process takes effect; every call
                // derives the same file.
                let _ = Config::setup_global_config_from_file(&file);
            }
        }
        let node_err = |message: String| IpcError::Node {
            name: name.to_string(),
            message,
        };
        let node_name = NodeName::new(name).map_err(|e| node_err(format!("{e:?}")))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(|e| node_err(format!("{e:?}")))?;
        crate::access::restrict_shm(&cfg.global.prefix.to_string());
        let ipc = Ipc {
            node,
            instance: instance.to_string(),
        };
        ipc.cleanup_dead_nodes();
        Ok(ipc)
    }

    /// The instance prefix.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// Removes the resources of nodes whose processes died (e.g. `kill -9`).
    /// Returns how many were cleaned up.
    pub fn cleanup_dead_nodes(&self) -> usize {
        let state = self.node.try_cleanup_dead_nodes();
        state.cleanups as usize
    }

    fn pubsub<T: Message>(
        &self,
        topic: Topic<T>,
    ) -> Result<
        (
            String,
            iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>,
        ),
        IpcError,
    > {
        let info = topic.info();
        let name = topic.channel().service_name(&self.instance);
        let sn = ServiceName::new(&name).map_err(|e| port_err("service name", &name, e))?;
        let factory = self
            .node
            .service_builder(&sn)
            .publish_subscribe::<T>()
            .max_publishers(info.max_publishers)
            .max_subscribers(8)
            .max_nodes(16)
            .history_size(info.history.max(1))
            .subscriber_max_buffer_size(info.max_buffer)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| port_err("open publish-subscribe service", &name, e))?;
        Ok((name, factory))
    }

    fn event(
        &self,
        ch: Channel,
    ) -> Result<
        Option<(
            String,
            iceoryx2::service::port_factory::event::PortFactory<Svc>,
        )>,
        IpcError,
    > {
        if !ch.info().has_event {
            return Ok(None);
        }
        let name = ch.event_name(&self.instance);
        let sn = ServiceName::new(&name).map_err(|e| port_err("service name", &name, e))?;
        let factory = self
            .node
            .service_builder(&sn)
            .event()
            .max_listeners(8)
            .max_notifiers(8)
            .max_nodes(16)
            .open_or_create()
            .map_err(|e| port_err("open event service", &name, e))?;
        Ok(Some((name, factory)))
    }

    /// How many publishers and subscribers `topic` has now, whoever they are.
    pub fn port_counts<T: Message>(&self, topic: Topic<T>) -> Result<PortCounts, IpcError> {
        let (_, f) = self.pubsub(topic)?;
        let d = f.dynamic_config();
        Ok(PortCounts {
            publishers: d.number_of_publishers(),
            subscribers: d.number_of_subscribers(),
        })
    }

    /// A publisher on `topic` and, where the channel has one, its wake-up
    /// notifier.
    pub fn outbox<T: Message>(&self, topic: Topic<T>) -> Result<Outbox<T>, IpcError> {
        let (name, f) = self.pubsub(topic)?;
        let info = topic.info();
        let publisher = f.publisher_builder().create().map_err(|e| {
            if info.max_publishers == 1 && f.dynamic_config().number_of_publishers() >= 1 {
                IpcError::SecondPublisher {
                    service: name.clone(),
                    owner: info.publisher.name(),
                    instance: self.instance.clone(),
                    message: format!("{e:?}"),
                }
            } else {
                port_err("create publisher", &name, e)
            }
        })?;
        let notifier = match self.event(topic.channel())? {
            Some((en, ef)) => Some(
                ef.notifier_builder()
                    .create()
                    .map_err(|e| port_err("create notifier", &en, e))?,
            ),
            None => None,
        };
        Ok(Outbox {
            name,
            publisher,
            notifier,
        })
    }

    /// A subscriber on `topic` with a buffer of `buffer` samples (at most
    /// the channel's `max_buffer`) and, where the channel has one, its
    /// wake-up listener. On connecting it receives the last sample
    /// published before it, if any.
    pub fn inbox<T: Message>(&self, topic: Topic<T>, buffer: usize) -> Result<Inbox<T>, IpcError> {
        self.inbox_with_history(topic, buffer, 1)
    }

    /// [`Ipc::inbox`] that receives, on connecting, up to `history` of the
    /// samples published before it (at most the channel's `history` and
    /// the buffer): what a restarted recorder asks for.
    pub fn inbox_with_history<T: Message>(
        &self,
        topic: Topic<T>,
        buffer: usize,
        history: usize,
    ) -> Result<Inbox<T>, IpcError> {
        let (name, f) = self.pubsub(topic)?;
        let buffer = buffer.clamp(1, topic.info().max_buffer);
        let subscriber = f
            .subscriber_builder()
            .buffer_size(buffer)
            .history_request(history.min(topic.info().history.max(1)).min(buffer))
            .create()
            .map_err(|e| port_err("create subscriber", &name, e))?;
        let listener = match self.event(topic.channel())? {
            Some((en, ef)) => Some(
                ef.listener_builder()
                    .create()
                    .map_err(|e| port_err("create listener", &en, e))?,
            ),
            None => None,
        };
        // SAFETY: the descriptor stays owned by the listener, which lives as
        // long as the inbox; we only poll it.
        let fd = listener
            .as_ref()
            .map(|l| unsafe { l.file_descriptor().native_handle() });
        Ok(Inbox {
            name,
            subscriber,
            factory: f,
            listener,
            fd,
            spin: Duration::ZERO,
            undrained: std::cell::Cell::new(0),
        })
    }
}

/// How many ports a publish-subscribe channel has ([`Ipc::port_counts`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortCounts {
    /// Publishers.
    pub publishers: usize,
    /// Subscribers.
    pub subscribers: usize,
}

/// A publisher and its wake-up notifier.
pub struct Outbox<T: Debug + ZeroCopySend + Copy + 'static> {
    name: String,
    publisher: Publisher<Svc, T, ()>,
    notifier: Option<Notifier<Svc>>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Outbox<T> {
    /// Publishes `value` (copied into shared memory) and wakes the listeners.
    /// Never blocks.
    pub fn send(&self, value: T) -> Result<(), IpcError> {
        self.publisher
            .send_copy(value)
            .map_err(|e| port_err("send", &self.name, e))?;
        if let Some(n) = &self.notifier {
            n.notify().map_err(|e| port_err("notify", &self.name, e))?;
        }
        Ok(())
    }

    /// The service name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

/// A port whose shared-memory connections to its peers can be brought up
/// to date on demand.
pub trait Connect {
    /// Builds the connections to peers that appeared since the last call.
    ///
    /// iceoryx2 does this by itself on the next send or receive, but a
    /// connection that the peer is building at the same moment makes the
    /// port wait (up to `global.creation-timeout`) until the peer has
    /// finished: a real-time process whose peer is an ordinary process
    /// starved of CPU then waits on it (priority inversion, measured: the
    /// control path missed its 5 ms deadline at start-up while `exo fit`
    /// ran beside it). The real-time processes therefore connect during
    /// [`settle_connections`], before their deadlines start.
    fn connect(&self) -> Result<(), IpcError>;
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Connect for Outbox<T> {
    fn connect(&self) -> Result<(), IpcError> {
        self.publisher
            .update_connections()
            .map_err(|e| port_err("update connections", &self.name, e))?;
        if let Some(n) = &self.notifier {
            n.update_connections()
                .map_err(|e| port_err("update connections", &self.name, e))?;
        }
        Ok(())
    }
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Connect for Inbox<T> {
    fn connect(&self) -> Result<(), IpcError> {
        self.subscriber
            .update_connections()
            .map_err(|e| port_err("update connections", &self.name, e))
    }
}

/// How long the real-time processes connect to their peers before their
/// loops start: the sensor driver and the controller this long, the plant
/// simulator (whose first tick starts the clock) [`REALTIME_SETTLE_PLANT`].
pub const REALTIME_SETTLE: Duration = Duration::from_millis(500);
/// The plant simulator's settle time: longer than the others', so they are
/// listening when its first frame comes.
pub const REALTIME_SETTLE_PLANT: Duration = Duration::from_millis(700);

/// Connects `ports` to their peers for `duration`, every 5 ms, so that a
/// real-time loop started afterwards finds every connection built (see
/// [`Connect`]). Called once before the loop, never per tick.
pub fn settle_connections(ports: &[&dyn Connect], duration: Duration) -> Result<(), IpcError> {
    let start = std::time::Instant::now();
    loop {
        for p in ports {
            p.connect()?;
        }
        if start.elapsed() >= duration {
            return Ok(());
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A subscriber and its wake-up listener.
pub struct Inbox<T: Debug + ZeroCopySend + Copy + 'static> {
    name: String,
    subscriber: Subscriber<Svc, T, ()>,
    /// The channel, to look up who publishes on it.
    factory: iceoryx2::service::port_factory::publish_subscribe::PortFactory<Svc, T, ()>,
    listener: Option<Listener<Svc>>,
    fd: Option<i32>,
    spin: Duration,
    /// Samples taken by polling whose wake-ups are still queued.
    undrained: std::cell::Cell<u32>,
}

/// A polling receiver leaves the wake-ups of the samples it took queued and
/// drains them only before it sleeps or after this many: each drain is a
/// system call, and a queue of a few dozen datagrams is far from filling
/// the socket.
const MAX_UNDRAINED: u32 = 32;

impl<T: Debug + ZeroCopySend + Copy + 'static> Inbox<T> {
    /// Whether a process publishing on this channel is alive (running or
    /// stopped, [`crate::child::process_alive`]). A publisher whose process
    /// died stays registered until iceoryx2 cleans its node up; its pid is
    /// then dead. No publisher registered: `false`. A publisher whose pid
    /// cannot be read counts as alive. Reads `/proc`: for a wait that has
    /// already lasted, never per tick.
    pub fn publisher_alive(&self) -> bool {
        let mut alive = false;
        self.factory.dynamic_config().list_publishers(|d| {
            alive = match d.node_id.pid::<Svc>() {
                Ok(pid) => u32::try_from(pid.value()).map_or(true, crate::child::process_alive),
                Err(_) => true,
            };
            if alive {
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
        alive
    }

    /// The next sample, if one is waiting.
    pub fn try_recv(&self) -> Result<Option<T>, IpcError> {
        Ok(self
            .subscriber
            .receive()
            .map_err(|e| port_err("receive", &self.name, e))?
            .map(|s| *s.payload()))
    }

    /// Waits at most `timeout` for a wake-up unless a sample is already
    /// waiting: a bounded wait, no busy spin, no allocation.
    ///
    /// iceoryx2 0.10's `Listener::timed_wait` rests on `SO_RCVTIMEO`, which
    /// the kernel rounds up to whole scheduler ticks (≈ 8 ms measured here
    /// for a 1 µs timeout); too coarse for a 5 ms deadline at 1 kHz. So the
    /// listener's file descriptor is polled with `ppoll` (nanosecond timeout)
    /// and the notifications are then drained with `try_wait`. Channels
    /// without an event sleep a tenth of `timeout`.
    pub fn wait(&self, timeout: Duration) -> Result<(), IpcError> {
        // Wake-ups of samples already taken would end the sleep at once:
        // drain them first, then look for samples, then sleep (a sample
        // published after the look wakes the sleep).
        self.drain_wake_ups()?;
        if self
            .subscriber
            .has_samples()
            .map_err(|e| port_err("has_samples", &self.name, e))?
        {
            return Ok(());
        }
        match self.fd {
            Some(fd) => {
                let mut pfd = libc::pollfd {
                    fd,
                    events: libc::POLLIN,
                    revents: 0,
                };
                let ts = libc::timespec {
                    tv_sec: timeout.as_secs() as libc::time_t,
                    tv_nsec: timeout.subsec_nanos() as libc::c_long,
                };
                // SAFETY: one valid pollfd, a valid timespec, no signal mask.
                let rc = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
                if rc < 0 {
                    let err = std::io::Error::last_os_error();
                    if err.kind() != std::io::ErrorKind::Interrupted {
                        return Err(port_err("ppoll", &self.name, err));
                    }
                }
                self.drain_wake_ups()
            }
            None => {
                std::thread::sleep(timeout / 10);
                Ok(())
            }
        }
    }

    fn drain_wake_ups(&self) -> Result<(), IpcError> {
        self.undrained.set(0);
        if let Some(l) = &self.listener {
            l.try_wait(|_| {})
                .map_err(|e| port_err("try_wait", &self.name, e))?;
        }
        Ok(())
    }

    /// Polls for up to `spin` (yielding the CPU between polls) before
    /// [`recv_timeout`](Self::recv_timeout) sleeps in the kernel. For the
    /// lockstep loop, where the answer usually comes within microseconds and
    /// a kernel wake-up costs tens of them; zero (the default) never spins.
    pub fn with_spin(mut self, spin: Duration) -> Self {
        self.spin = spin;
        self
    }

    /// Receives with a bounded wait: the next sample, or `None` after `timeout`.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<Option<T>, IpcError> {
        if let Some(v) = self.try_recv()? {
            return Ok(Some(v));
        }
        if !self.spin.is_zero() {
            let spin = self.spin.min(timeout);
            let start = std::time::Instant::now();
            // Yield between polls: with more processes in the loop than
            // cores, giving the CPU away at once beats busy polling (measured:
            // 64 polls per yield cut the lockstep rate from ~43k to ~30k
            // ticks/s on two cores).
            while start.elapsed() < spin {
                std::thread::yield_now();
                if let Some(v) = self.try_recv()? {
                    let n = self.undrained.get() + 1;
                    if n >= MAX_UNDRAINED {
                        self.drain_wake_ups()?;
                        self.undrained.set(0);
                    } else {
                        self.undrained.set(n);
                    }
                    return Ok(Some(v));
                }
            }
        }
        self.wait(timeout)?;
        self.try_recv()
    }

    /// The service name.
    pub fn name(&self) -> &str {
        &self.name
    }
}
