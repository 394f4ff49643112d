//! The one runner of every exo process. A process is a [`Process`]: its
//! ports on the run's channels around its node (the plain type of its
//! service library that is stepped with its inputs), and one bounded
//! [`Process::step`] — wait for what drives it, hand it to the node,
//! publish what comes back. [`main`] does the rest, the same way for all:
//! logging, the command line, the run configuration, the stop flag (SIGINT,
//! SIGTERM), the iceoryx2 node, in real time the process's scheduling
//! request and the connection of its ports before its loop and deadlines
//! start, the loop until the step says it is done or a stop is requested,
//! the process's own wind-down, and the exit code (1 with the error logged,
//! its whole chain of causes on one line, [`crate::error_chain`]).
//!
//! Errors: each process returns its own error enum ([`Process::Error`]);
//! the runner's own failures and the process's are one [`RunError`].
//!
//! Timing (lockstep or real time), deadlines and the safe state are the
//! step's and its node's: each process waits on a different thing (the plant
//! on its clock or on the motor command, the driver on the bus and the
//! controller, the controller on the samples).

use std::time::Duration;

use exo_config::{ConfigError, RunConfig, TimingMode};

use exo_messages::channels::ProcessName;

use crate::ipc::{settle_connections, Connect, Ipc, IpcError, REALTIME_SETTLE};
use crate::{
    error_chain, init_logging, request_realtime, RealtimeProcess, RealtimeRequest, StopFlag,
};

/// Why a process's run failed: the runner's own steps, or the process's
/// ([`Process::Error`]). Each variant shows what it wraps unchanged (its
/// message and causes), so the logged chain names the file, node or
/// channel as the wrapped error does.
#[derive(Debug, thiserror::Error)]
pub enum RunError<E> {
    /// The run file (`--config`) could not be read or is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The SIGINT/SIGTERM handlers could not be installed.
    #[error("installing the SIGINT and SIGTERM handlers")]
    Stop(#[source] std::io::Error),
    /// The iceoryx2 node, or the connection of the process's ports (in
    /// real time before its loop, in lockstep after an idle step).
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The process's own error: opening, a step or its wind-down.
    #[error(transparent)]
    Process(E),
}

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
    /// What its [`open`](Process::open), [`step`](Process::step) and
    /// [`finish`](Process::finish) fail with: the process's own enum,
    /// naming what it refuses and wrapping the errors of the crates it
    /// wires.
    type Error: std::error::Error + Send + Sync + 'static;
    /// Opens its ports and builds its node.
    fn open(cx: Context<'_, Self::Args>) -> Result<Self, Self::Error>;
    /// Its ports, connected before its real-time loop starts.
    fn ports(&self) -> Vec<&dyn Connect>;
    /// One bounded step. `stop` lets a step that waits return early.
    fn step(&mut self, stop: &StopFlag) -> Result<Flow, Self::Error>;
    /// Winds down after the loop (a stop request, [`Flow::Done`] or a
    /// step's error).
    fn finish(self) -> Result<(), Self::Error> {
        Ok(())
    }
}

/// Runs process `P`: never returns; exits 0, or 1 with the error logged
/// with its causes (`outer: inner: innermost`).
pub fn main<P: Process>() -> ! {
    init_logging(P::NAME.name());
    let code = match run::<P>(<P::Args as clap::Parser>::parse()) {
        Ok(()) => 0,
        Err(e) => {
            tracing::error!("{}", error_chain(&e));
            1
        }
    };
    std::process::exit(code)
}

fn run<P: Process>(args: P::Args) -> Result<(), RunError<P::Error>> {
    let service = args.as_ref();
    let cfg = RunConfig::from_file(&service.config)?;
    let stop = StopFlag::install().map_err(RunError::Stop)?;
    let ipc = Ipc::open(
        P::NAME.node_name(),
        &cfg.run.instance,
        service.iceoryx2_config.as_deref(),
    )?;
    let process = P::open(Context {
        cfg: &cfg,
        ipc: &ipc,
        args: &args,
    })
    .map_err(RunError::Process)?;
    if let (TimingMode::Realtime, Some(role)) = (cfg.run.timing, P::REALTIME) {
        request_realtime(
            P::NAME.name(),
            RealtimeRequest::of(cfg.realtime.as_ref(), role),
        );
        settle_connections(&process.ports(), P::SETTLE)?;
    }
    drive(process, &stop, cfg.run.timing)
}

/// Steps `process` until a stop is requested, a step says
/// [`Flow::Done`] or fails, or connecting its ports after an idle step
/// fails; then winds it down, whatever ended the loop (the recorder
/// finishes its file after an error too). The loop's error comes first:
/// when the wind-down fails as well, its error is logged and the loop's
/// returned.
fn drive<P: Process>(
    mut process: P,
    stop: &StopFlag,
    timing: TimingMode,
) -> Result<(), RunError<P::Error>> {
    let looped = loop {
        if stop.requested() {
            break Ok(());
        }
        match process.step(stop) {
            Ok(Flow::Continue) => {}
            Ok(Flow::Idle) => {
                if let Err(e) = on_idle(timing, &process.ports()) {
                    break Err(RunError::Ipc(e));
                }
            }
            Ok(Flow::Done) => break Ok(()),
            Err(e) => break Err(RunError::Process(e)),
        }
    };
    let finished = process.finish().map_err(RunError::Process);
    if let (Err(_), Err(e)) = (&looped, &finished) {
        tracing::error!("{}: winding down: {}", P::NAME.name(), error_chain(e));
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

/// The loop and the wind-down without IPC: a process with no ports, the
/// stop flag never raised. The chain's format is [`crate::error_chain`]'s.
#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::rc::Rc;

    use super::*;
    use crate::ServiceArgs;

    /// Three errors, each the cause of the one before.
    #[derive(Debug, thiserror::Error)]
    enum Nested {
        #[error("a")]
        A(#[source] Box<Nested>),
        #[error("b")]
        B(#[source] Box<Nested>),
        #[error("c")]
        C,
    }

    #[test]
    fn the_chain_is_each_error_then_its_causes() {
        let e = Nested::A(Box::new(Nested::B(Box::new(Nested::C))));
        assert_eq!(error_chain(&e), "a: b: c");
        assert_eq!(error_chain(&Nested::C), "c");
        // Wrapped by the runner, the process's error reads the same.
        let run: RunError<Nested> = RunError::Process(e);
        assert_eq!(error_chain(&run), "a: b: c");
    }

    /// What the test process says.
    #[derive(Debug, thiserror::Error)]
    enum TestError {
        #[error("step {0} failed")]
        Step(u32),
        #[error("winding down failed")]
        Finish,
    }

    /// Steps `Continue`, `Idle`, then fails at step `fail_at` (or is done
    /// there, with `fail_at` = 0 never failing); counts its wind-downs.
    struct Failing {
        steps: u32,
        fail_at: u32,
        finish_fails: bool,
        finished: Rc<Cell<u32>>,
    }

    impl Failing {
        fn new(fail_at: u32, finish_fails: bool) -> (Self, Rc<Cell<u32>>) {
            let finished = Rc::new(Cell::new(0));
            let p = Failing {
                steps: 0,
                fail_at,
                finish_fails,
                finished: Rc::clone(&finished),
            };
            (p, finished)
        }
    }

    impl Process for Failing {
        type Args = ServiceArgs;
        type Error = TestError;
        const NAME: ProcessName = ProcessName::Player;
        const REALTIME: Option<RealtimeProcess> = None;

        fn open(_cx: Context<'_, ServiceArgs>) -> Result<Self, TestError> {
            unreachable!("the tests build it themselves")
        }

        fn ports(&self) -> Vec<&dyn Connect> {
            vec![]
        }

        fn step(&mut self, _stop: &StopFlag) -> Result<Flow, TestError> {
            self.steps += 1;
            match self.steps {
                1 => Ok(Flow::Continue),
                2 => Ok(Flow::Idle),
                n if n == self.fail_at => Err(TestError::Step(n)),
                _ if self.fail_at == 0 => Ok(Flow::Done),
                _ => Ok(Flow::Continue),
            }
        }

        fn finish(self) -> Result<(), TestError> {
            self.finished.set(self.finished.get() + 1);
            if self.finish_fails {
                Err(TestError::Finish)
            } else {
                Ok(())
            }
        }
    }

    #[test]
    fn a_failing_step_ends_the_run_with_its_error_after_the_wind_down() {
        let (p, finished) = Failing::new(5, false);
        let e = drive(p, &StopFlag::unraised(), TimingMode::Lockstep).unwrap_err();
        assert!(matches!(e, RunError::Process(TestError::Step(5))), "{e:?}");
        assert_eq!(error_chain(&e), "step 5 failed");
        assert_eq!(finished.get(), 1, "winds down once");
    }

    #[test]
    fn when_the_wind_down_fails_too_the_steps_error_is_returned() {
        let (p, finished) = Failing::new(3, true);
        let e = drive(p, &StopFlag::unraised(), TimingMode::Realtime).unwrap_err();
        assert!(matches!(e, RunError::Process(TestError::Step(3))), "{e:?}");
        assert_eq!(finished.get(), 1);
    }

    #[test]
    fn a_done_run_returns_the_wind_downs_outcome() {
        let (p, finished) = Failing::new(0, false);
        drive(p, &StopFlag::unraised(), TimingMode::Lockstep).unwrap();
        assert_eq!(finished.get(), 1);
        let (p, _) = Failing::new(0, true);
        let e = drive(p, &StopFlag::unraised(), TimingMode::Lockstep).unwrap_err();
        assert!(matches!(e, RunError::Process(TestError::Finish)), "{e:?}");
    }

    /// A run file that cannot be read ends the run before anything opens,
    /// with the config's error naming the file (the process is never
    /// opened: `Failing::open` would panic).
    #[test]
    fn a_missing_run_file_ends_the_run_naming_it() {
        let args = ServiceArgs {
            config: "/nonexistent/exo-run.toml".into(),
            iceoryx2_config: None,
            output: None,
            inject_fault_at: None,
        };
        let e = run::<Failing>(args).unwrap_err();
        assert!(matches!(e, RunError::Config(_)), "{e:?}");
        assert!(error_chain(&e).contains("/nonexistent/exo-run.toml"), "{e}");
    }
}
