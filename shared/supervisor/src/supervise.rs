//! `exo run`'s process supervisor: starts the services of a run, forwards
//! their logs, reaps them (so iceoryx2 sees dead nodes as dead), stops them
//! all on Ctrl-C, SIGTERM or the first failure, and reports which one failed.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use exo_service_kit::error_chain;
use exo_service_kit::ipc::IpcError;

use crate::error::{Error, Result};

/// What a service's exit means for the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Its normal exit ends the run successfully (the controller, at protocol end).
    EndsRun,
    /// On the real-time path: any exit before the end fails the run.
    Critical,
    /// Off the real-time path (identifier, recorder): restarted on failure,
    /// at most `MAX_RESTARTS` times, never stopping control.
    Restartable,
    /// A watcher (the live view, the tunnel): restarted like
    /// [`Role::Restartable`], and once its restarts are spent (a port in
    /// use, an address that cannot be bound), the run goes on without it.
    /// The real-time path does not wait for it to start. Its stops are
    /// warnings, not faults of the run: it touches neither control nor
    /// the recording.
    Optional,
}

/// One service to run.
#[derive(Debug, Clone)]
pub struct ServiceSpec {
    /// Short name used in logs and errors, e.g. `controller`.
    pub name: &'static str,
    /// Executable.
    pub program: PathBuf,
    /// Arguments.
    pub args: Vec<String>,
    /// Role.
    pub role: Role,
    /// For an off-path service: how to tell it has opened all its ports.
    pub ready: Option<Ready>,
    /// Whether stopping this process (SIGSTOP) stops the run's simulated
    /// time, and for how long at most: the plant simulator in lockstep,
    /// which the supervisor holds while a restarted off-path service
    /// connects, so that in lockstep a restart loses nothing and costs the
    /// loop nothing. The bound stays below the loop's lockstep time-out.
    pub holds_clock: Option<Duration>,
}

/// How the supervisor tells that an off-path service has opened every port
/// it will use, so the real-time path can start after it: the real-time
/// processes then build their connections to it while nothing has a
/// deadline (see `exo_service_kit::ipc::Connect`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ready {
    /// The run's iceoryx2 instance.
    pub instance: String,
    /// What to look for.
    pub probe: ReadyProbe,
}

/// The port a service opens last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadyProbe {
    /// One more subscriber on the bus motor channel (the recorder's last tap).
    SubscribesBusMotor,
    /// A publisher on the estimate channel (the identifier's last port).
    PublishesEstimate,
}

/// How long the supervisor waits for the off-path services before it
/// starts the real-time path anyway (with a warning).
const READY_PATIENCE: Duration = Duration::from_secs(10);

impl Ready {
    fn count(&self, ipc: &exo_service_kit::ipc::Ipc) -> Result<usize, IpcError> {
        use exo_service_kit::channels::{BUS_MOTOR, IDENTIFIER_ESTIMATE};
        Ok(match self.probe {
            ReadyProbe::SubscribesBusMotor => ipc.port_counts(BUS_MOTOR)?.subscribers,
            ReadyProbe::PublishesEstimate => ipc.port_counts(IDENTIFIER_ESTIMATE)?.publishers,
        })
    }
}

/// Off-path services started and not yet seen ready: (name, probe, node, count before start).
type Pending = Vec<(&'static str, Ready, exo_service_kit::ipc::Ipc, usize)>;

fn wait_ready(pending: &mut Pending, stop: &AtomicBool) {
    let start = Instant::now();
    while !pending.is_empty() && start.elapsed() < READY_PATIENCE && !stop.load(Ordering::Relaxed) {
        pending.retain(|(_, r, ipc, before)| r.count(ipc).map_or(true, |n| n <= *before));
        std::thread::sleep(Duration::from_millis(5));
    }
    for (name, ..) in pending.drain(..) {
        eprintln!(
            "exo: warning: {name} has not opened its ports after {READY_PATIENCE:?}; starting the real-time path anyway"
        );
    }
}

const MAX_RESTARTS: u32 = 3;
/// How long a service is given to stop after SIGTERM before SIGKILL. The
/// recorder spends it writing its file's last chunks and summary: on a
/// loaded 2-CPU machine (a test suite and a mutation run at once) 3 s was
/// not enough, and the killed recorder's file lost its summary (stop 35).
/// A service that has stopped costs nothing of it.
const STOP_GRACE: Duration = Duration::from_secs(15);

struct Running {
    spec: ServiceSpec,
    child: Child,
    restarts: u32,
    tail: Tail,
}

impl Running {
    fn last_lines(&self) -> String {
        let t = self.tail.lock().unwrap_or_else(PoisonError::into_inner);
        if t.is_empty() {
            String::new()
        } else {
            let lines: Vec<&str> = t.iter().map(String::as_str).collect();
            format!("; its last log lines:\n  {}", lines.join("\n  "))
        }
    }
}

/// Path of a sibling executable of the running `exo` (same target directory
/// or install prefix).
pub fn sibling_program(name: &str) -> Result<PathBuf> {
    let exe = std::env::current_exe().map_err(Error::LocateExe)?;
    let dir = exe
        .parent()
        .ok_or_else(|| Error::NoExeDirectory { exe: exe.clone() })?;
    let p = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    if !p.exists() {
        return Err(Error::ProgramNotFound {
            name: name.to_string(),
            dir: dir.to_path_buf(),
        });
    }
    Ok(p)
}

/// Whether the services' log lines are forwarded to the terminal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Logs {
    /// Every line, prefixed with the service's name.
    Forward,
    /// Kept back; the last lines of a failing service go into the error.
    Quiet,
}

const TAIL_LINES: usize = 15;

type Tail = Arc<Mutex<VecDeque<String>>>;

fn spawn(spec: &ServiceSpec, logs: Logs, tail: &Tail) -> Result<Child> {
    let mut cmd = Command::new(&spec.program);
    cmd.args(&spec.args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    // A `kill -9` of `exo run` leaves no service running as an orphan: each
    // gets SIGTERM and stops as on Ctrl-C (the driver and the controller
    // through their own safe paths). Every service is spawned from the
    // supervisor's own thread, which lives as long as the run.
    exo_service_kit::child::die_with_parent(&mut cmd);
    let mut child = cmd.spawn().map_err(|source| Error::Start {
        service: spec.name,
        program: spec.program.clone(),
        source,
    })?;
    for (stream, is_err) in [
        (
            child
                .stdout
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            false,
        ),
        (
            child
                .stderr
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            true,
        ),
    ] {
        if let Some(stream) = stream {
            let name = spec.name;
            let tail = Arc::clone(tail);
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    match (logs, is_err) {
                        (Logs::Forward, true) => eprintln!("[{name}] {line}"),
                        (Logs::Forward, false) => println!("[{name}] {line}"),
                        (Logs::Quiet, _) => {}
                    }
                    let mut t = tail.lock().unwrap_or_else(PoisonError::into_inner);
                    if t.len() == TAIL_LINES {
                        t.pop_front();
                    }
                    t.push_back(line);
                }
            });
        }
    }
    Ok(child)
}

/// Stops every service (SIGTERM, so each can release its shared memory;
/// SIGKILL after [`STOP_GRACE`]) and reaps them all, naming each that had
/// to be killed.
fn stop_all(running: &mut [Running]) {
    let outcomes = exo_service_kit::child::stop_gracefully(
        running.iter_mut().map(|r| &mut r.child),
        STOP_GRACE,
    );
    for (r, outcome) in running.iter().zip(outcomes) {
        if let Ok(exo_service_kit::child::Stopped::Killed(_)) = outcome {
            eprintln!(
                "exo: {} did not stop within {:?}; killing it",
                r.spec.name, STOP_GRACE
            );
        }
    }
}

fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("exit code {c}"),
        (None, Some(s)) => format!("signal {s}"),
        _ => "unknown status".into(),
    }
}

/// Runs the services until the one with [`Role::EndsRun`] exits cleanly,
/// a critical one fails, or a stop signal arrives; returns the restarts of
/// the services off the real-time path, one line each.
pub fn supervise(
    services: Vec<ServiceSpec>,
    logs: Logs,
    mut on_tick: impl FnMut(),
) -> Result<Vec<String>> {
    supervise_checked(services, logs, || {
        on_tick();
        Ok::<(), std::convert::Infallible>(())
    })
    .map(|s| s.restarts)
}

/// What a supervised run came to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Supervised {
    /// How it ended.
    pub ended: Ended,
    /// Each restart of a service off the real-time path: which, why, when.
    pub restarts: Vec<String>,
}

/// How a supervised run ended without error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// The named service with [`Role::EndsRun`] exited cleanly.
    By(&'static str),
    /// A stop signal (Ctrl-C, SIGTERM) arrived.
    Signal,
}

/// [`supervise`], with a check every tick (about 20 ms): an error from
/// `on_tick` stops every service and is the run's error
/// ([`Error::Check`]). Returns which service ended the run, or that a
/// signal did, and the restarts.
pub fn supervise_checked<E>(
    services: Vec<ServiceSpec>,
    logs: Logs,
    mut on_tick: impl FnMut() -> Result<(), E>,
) -> Result<Supervised>
where
    E: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, Arc::clone(&stop)).map_err(Error::Signals)?;
    }
    let mut running: Vec<Running> = Vec::new();
    let mut pending: Pending = Vec::new();
    for spec in services {
        // The real-time path starts once the off-path services before it
        // have opened their ports.
        if !matches!(spec.role, Role::Restartable | Role::Optional) {
            wait_ready(&mut pending, &stop);
        }
        if let Some(r) = &spec.ready {
            let node = format!("exo_sup_{}_{}", std::process::id(), pending.len());
            let probe = exo_service_kit::ipc::Ipc::open(&node, &r.instance, None)
                .and_then(|ipc| Ok((r.count(&ipc)?, ipc)));
            match probe {
                Ok((before, ipc)) => pending.push((spec.name, r.clone(), ipc, before)),
                Err(e) => eprintln!(
                    "exo: warning: cannot watch {} start: {}",
                    spec.name,
                    error_chain(&e)
                ),
            }
        }
        let tail = Tail::default();
        match spawn(&spec, logs, &tail) {
            Ok(child) => running.push(Running {
                spec,
                child,
                restarts: 0,
                tail,
            }),
            Err(e) => {
                stop_all(&mut running);
                return Err(e);
            }
        }
    }
    let started = std::time::Instant::now();
    let mut restarts = Vec::new();
    let outcome: Result<Ended> = 'supervise: loop {
        if stop.load(Ordering::Relaxed) {
            eprintln!("exo: stop requested; stopping every service");
            break Ok(Ended::Signal);
        }
        // The process that holds simulated time, if any (the plant in
        // lockstep), while it runs.
        let clock = running.iter().find_map(|r| {
            let pid = libc::pid_t::try_from(r.child.id()).ok()?;
            r.spec.holds_clock.map(|patience| (pid, patience))
        });
        let mut gone = Vec::new();
        for (i, r) in running.iter_mut().enumerate() {
            let status = match r.child.try_wait() {
                Ok(Some(s)) => s,
                Ok(None) => continue,
                Err(error) => {
                    break 'supervise Err(Error::Wait {
                        service: r.spec.name,
                        error,
                    })
                }
            };
            let name = r.spec.name;
            match r.spec.role {
                Role::EndsRun if status.success() => break 'supervise Ok(Ended::By(name)),
                Role::Optional if r.restarts >= MAX_RESTARTS || status.success() => {
                    eprintln!(
                        "exo: warning: {name} stopped ({}){}; the run goes on without it",
                        describe(status),
                        if status.success() {
                            String::new()
                        } else {
                            format!(" after {} restarts", r.restarts)
                        }
                    );
                    gone.push(i);
                }
                Role::Restartable | Role::Optional if r.restarts < MAX_RESTARTS => {
                    r.restarts += 1;
                    // Control goes on, but not for free: the restarted
                    // process's new ports make the real-time path build
                    // connections (ARCHITECTURE.md, "Start-up order").
                    eprintln!(
                        "exo: {name} stopped ({}); restarting it ({}/{MAX_RESTARTS}); {}",
                        describe(status),
                        r.restarts,
                        if clock.is_some() {
                            "simulated time is held until it has connected"
                        } else {
                            "control goes on (a restart can cost the real-time path deadlines while its ports connect)"
                        }
                    );
                    // A watcher's restart is no fault of the run: it
                    // touches neither control nor the recording.
                    if r.spec.role == Role::Restartable {
                        restarts.push(format!(
                            "the {name} stopped ({}) {:.1} s into the run and was restarted ({}/{MAX_RESTARTS})",
                            describe(status),
                            started.elapsed().as_secs_f64(),
                            r.restarts
                        ));
                    }
                    match restart(r, logs, clock) {
                        Ok(None) => {}
                        Ok(Some(warning)) => {
                            eprintln!("exo: warning: {warning}");
                            restarts.push(warning);
                        }
                        Err(e) => break 'supervise Err(e),
                    }
                }
                _ => {
                    break 'supervise Err(Error::Stopped {
                        service: name,
                        program: r.spec.program.clone(),
                        status: describe(status),
                        last_lines: if logs == Logs::Quiet {
                            r.last_lines()
                        } else {
                            String::new()
                        },
                    })
                }
            }
        }
        for i in gone.into_iter().rev() {
            running.remove(i);
        }
        if let Err(e) = on_tick() {
            let message = error_chain(&*e.into());
            // Quiet runs kept the services' logs back: give the error the
            // real-time path's last lines, which say why.
            let message = match logs {
                Logs::Quiet => {
                    let tails: String = running
                        .iter()
                        .filter(|r| !matches!(r.spec.role, Role::Restartable | Role::Optional))
                        .map(|r| format!("\n{}{}", r.spec.name, r.last_lines()))
                        .collect();
                    format!("{message}\nthe real-time path's logs:{tails}")
                }
                Logs::Forward => message,
            };
            break 'supervise Err(Error::Check { message });
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    stop_all(&mut running);
    outcome.map(|ended| Supervised { ended, restarts })
}

/// Starts `r` again. With `clock` (the pid of the process holding
/// simulated time and the longest it may be held) the clock is stopped
/// first and resumed once the new process has opened its ports (its
/// [`Ready`] probe), or after the patience, which is returned as a warning:
/// samples published after the old process died and before the new one
/// connected come to it from the channels' history, so in lockstep none is
/// lost. Without a clock (real time) it starts after a back-off.
fn restart(
    r: &mut Running,
    logs: Logs,
    clock: Option<(libc::pid_t, Duration)>,
) -> Result<Option<String>> {
    let Some((pid, patience)) = clock else {
        std::thread::sleep(Duration::from_millis(200 * u64::from(r.restarts)));
        r.child = spawn(&r.spec, logs, &r.tail)?;
        return Ok(None);
    };
    // SAFETY: signalling a child of ours that has not been reaped.
    unsafe { libc::kill(pid, libc::SIGSTOP) };
    let held = Instant::now();
    // A probe node that also clears the dead process's ports, so the count
    // before the start is without them.
    let probe = r.spec.ready.as_ref().and_then(|ready| {
        let node = format!("exo_sup_{}_restart", std::process::id());
        let ipc = exo_service_kit::ipc::Ipc::open(&node, &ready.instance, None).ok()?;
        let before = ready.count(&ipc).ok()?;
        Some((ready, ipc, before))
    });
    let started = spawn(&r.spec, logs, &r.tail);
    let mut ready = probe.is_none();
    if let (Ok(_), Some((ready_probe, ipc, before))) = (&started, &probe) {
        while held.elapsed() < patience {
            if ready_probe.count(ipc).is_ok_and(|n| n > *before) {
                ready = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    // SAFETY: as above.
    unsafe { libc::kill(pid, libc::SIGCONT) };
    r.child = started?;
    Ok((!ready).then(|| {
        format!(
            "the {} had not opened its ports {:.0} ms after its restart; simulated time went on without it, so samples may be missing from its output",
            r.spec.name,
            patience.as_secs_f64() * 1e3
        )
    }))
}

/// The standard argument list of a service: `--config FILE`.
pub fn config_args(config: &Path) -> Vec<String> {
    vec!["--config".into(), config.display().to_string()]
}
