//! The one runner of every exo process. A process is a [`Process`]: its
//! ports on the run's channels around its node (the plain type of its
//! service library that is stepped with its inputs), and one bounded
//! [`Process::step`] — wait for what drives it, hand it to the node,
//! publish what comes back. [`main`] does the rest, the same way for all:
//! logging, the command line, the run configuration, the stop flag (SIGINT,
//! SIGTERM), the iceoryx2 node, in real time the process's scheduling
//! request and the connection of its ports before its loop and deadlines
//! start, the loop until the step says it is done or a stop is requested,
//! the process's own wind-down, and the exit code (1 with the error logged).
//!
//! Timing (lockstep or real time), deadlines and the safe state are the
//! step's and its node's: each process waits on a different thing (the plant
//! on its clock or on the motor command, the driver on the bus and the
//! controller, the controller on the samples).

use std::time::Duration;

use anyhow::Result;
use exo_config::{RunConfig, TimingMode};

use exo_messages::channels::ProcessName;

use crate::ipc::{settle_connections, Connect, Ipc, REALTIME_SETTLE};
use crate::{init_logging, request_realtime, RealtimeProcess, RealtimeRequest, StopFlag};

/// Whether a process goes on after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Step again.
    Continue,
    /// Nothing came within the step's bounded wait: step again. In
    /// lockstep the runner first connects the process's ports to peers that
    /// appeared meanwhile. A restarted recorder is handed the channels'
    /// history only when each publisher connects to it, which iceoryx2 does
    /// on the publisher's next send; while simulated time is held for that
    /// recorder nobody sends, so without this it waited for its history
    /// until the plant's patience ran out (30 s of wall time, measured).
    /// In real time nothing is done: control is never paused there, and a
    /// connection is built on the next send as before.
    Idle,
    /// The process's work is done: wind down and exit 0.
    Done,
}

/// What [`Process::open`] gets.
pub struct Context<'a, A> {
    /// The run configuration.
    pub cfg: &'a RunConfig,
    /// The process's iceoryx2 node for the run's instance.
    pub ipc: &'a Ipc,
    /// The process's command line.
    pub args: &'a A,
}

/// One exo process: its ports and its node.
pub trait Process: Sized {
    /// The process's command line (every service's `ServiceArgs`, or more).
    type Args: clap::Parser + AsRef<crate::ServiceArgs>;
    /// Which process it is (its name in logs, e.g. `sensor-driver`, and
    /// its iceoryx2 node name, e.g. `sensor_driver`).
    const NAME: ProcessName;
    /// Its place on the control path, when it has one (real-time requests
    /// and connection settling apply to it).
    const REALTIME: Option<RealtimeProcess>;
    /// How long its ports take to connect before real-time control starts.
    const SETTLE: Duration = REALTIME_SETTLE;
    /// Opens its ports and builds its node.
    fn open(cx: Context<'_, Self::Args>) -> Result<Self>;
    /// Its ports, connected before its real-time loop starts.
    fn ports(&self) -> Vec<&dyn Connect>;
    /// One bounded step. `stop` lets a step that waits return early.
    fn step(&mut self, stop: &StopFlag) -> Result<Flow>;
    /// Winds down after the loop (a stop request, [`Flow::Done`] or a
    /// step's error).
    fn finish(self) -> Result<()> {
        Ok(())
    }
}

/// Runs process `P`: never returns; exits 0, or 1 with the error logged.
pub fn main<P: Process>() -> ! {
    init_logging(P::NAME.name());
    let code = match run::<P>(<P::Args as clap::Parser>::parse()) {
        Ok(()) => 0,
        Err(e) => {
            tracing::error!("{e:#}");
            1
        }
    };
    std::process::exit(code)
}

fn run<P: Process>(args: P::Args) -> Result<()> {
    let service = args.as_ref();
    let cfg = RunConfig::from_file(&service.config)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        P::NAME.node_name(),
        &cfg.run.instance,
        service.iceoryx2_config.as_deref(),
    )?;
    let mut process = P::open(Context {
        cfg: &cfg,
        ipc: &ipc,
        args: &args,
    })?;
    if let (TimingMode::Realtime, Some(role)) = (cfg.run.timing, P::REALTIME) {
        request_realtime(
            P::NAME.name(),
            RealtimeRequest::of(cfg.realtime.as_ref(), role),
        );
        settle_connections(&process.ports(), P::SETTLE)?;
    }
    let looped = loop {
        if stop.requested() {
            break Ok(());
        }
        match process.step(&stop) {
            Ok(Flow::Continue) => {}
            Ok(Flow::Idle) => {
                if let Err(e) = on_idle(cfg.run.timing, &process.ports()) {
                    break Err(e.into());
                }
            }
            Ok(Flow::Done) => break Ok(()),
            Err(e) => break Err(e),
        }
    };
    // A process winds down whatever ended its loop (the recorder finishes
    // its file after an error too); the loop's error comes first.
    let finished = process.finish();
    if let (Err(_), Err(e)) = (&looped, &finished) {
        tracing::error!("{}: winding down: {e:#}", P::NAME.name());
    }
    looped.and(finished)
}

/// What the runner does after a step that returned [`Flow::Idle`]: in
/// lockstep, connects each of a process's `ports` to the peers that
/// appeared since its last connection; in real time, nothing.
pub fn on_idle(timing: TimingMode, ports: &[&dyn Connect]) -> Result<(), crate::ipc::IpcError> {
    match timing {
        TimingMode::Lockstep => ports.iter().try_for_each(|p| p.connect()),
        TimingMode::Realtime => Ok(()),
    }
}

impl AsRef<crate::ServiceArgs> for crate::ServiceArgs {
    fn as_ref(&self) -> &crate::ServiceArgs {
        self
    }
}
