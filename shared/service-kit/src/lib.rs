//! # exo-service-kit
//!
//! The little that every exo process's `main.rs` shares, so each main stays
//! a thin wiring of IPC around its service's library.

pub mod access;
pub mod channels;
pub mod child;
pub mod collect;
pub mod ipc;
pub mod latency;
pub mod runner;

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use clap::Parser;

/// Command line of every exo service.
#[derive(Debug, Clone, Parser)]
pub struct ServiceArgs {
    /// The run configuration (e.g. configs/default.toml).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// The iceoryx2 configuration (default: $EXO_ICEORYX2_CONFIG, else configs/iceoryx2.toml).
    #[arg(long, value_name = "FILE")]
    pub iceoryx2_config: Option<PathBuf>,
    /// The file a service that writes one (the recorder) writes; each
    /// service documents its default.
    #[arg(long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Fault injection for tests: see the service's documentation.
    #[arg(long, value_name = "TICK", hide = true)]
    pub inject_fault_at: Option<u64>,
}

impl ServiceArgs {
    /// Parses the process's command line (exits with clap's message on error).
    pub fn from_command_line() -> Self {
        ServiceArgs::parse()
    }
}

/// ethercrab's line for each reply that came back after its cycle gave up
/// on it: the sensor driver counts those and summarises them at most once
/// a second (issue 33, item 4), so the per-frame line is off.
const ETHERCRAB_PER_FRAME: &str = "ethercrab::pdu_loop::frame_element=off";

/// Logs to standard error (`RUST_LOG` filters; default `info`).
pub fn init_logging(service: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let filter = match ETHERCRAB_PER_FRAME.parse() {
        Ok(d) => filter.add_directive(d),
        Err(_) => filter,
    };
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .without_time()
        .try_init();
    tracing::debug!(service, "logging started");
}

/// An error with its causes, each after `: ` (`outer: inner: innermost`,
/// following [`std::error::Error::source`]): how a process's failure is
/// logged ([`runner::main`]) and how a supervisor or a test prints one.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut out = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        out.push_str(": ");
        out.push_str(&c.to_string());
        cause = c.source();
    }
    out
}

/// A flag raised by SIGINT or SIGTERM: loops check it and exit cleanly, so
/// iceoryx2 resources are released.
#[derive(Debug, Clone)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// Installs the handlers.
    pub fn install() -> std::io::Result<Self> {
        let flag = Arc::new(AtomicBool::new(false));
        for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register(sig, Arc::clone(&flag))?;
        }
        Ok(StopFlag(flag))
    }
    /// A flag no signal raises (no handler is installed, so SIGINT and
    /// SIGTERM keep their default action): for stepping a
    /// [`runner::Process`] outside [`runner::main`], as a process's tests do.
    pub fn unraised() -> Self {
        StopFlag(Arc::new(AtomicBool::new(false)))
    }
    /// Whether a stop was requested.
    #[inline]
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds.
#[inline]
pub fn monotonic_ns() -> u64 {
    clock_ns(libc::CLOCK_MONOTONIC)
}

/// The clock `clock` (a `CLOCK_*` id) in nanoseconds.
#[inline]
fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid out-pointer; the callers pass valid clock ids.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleeps until the absolute monotonic time `deadline_ns` (no drift).
#[inline]
pub fn sleep_until_ns(deadline_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    // SAFETY: valid timespec; interrupted sleeps simply return early.
    unsafe {
        libc::clock_nanosleep(
            libc::CLOCK_MONOTONIC,
            libc::TIMER_ABSTIME,
            &ts,
            std::ptr::null_mut(),
        );
    }
}

/// Sleeps until `spin_ns` before the absolute monotonic time
/// `deadline_ns`, then polls the clock until the deadline: the kernel's
/// wake-up latency (timer slack, the scheduler's path back to the thread)
/// is spent before the deadline instead of after it, at the cost of up to
/// `spin_ns` of one core per call. `spin_ns` = 0 is [`sleep_until_ns`]
/// and one more reading of the clock.
/// Bounded: the spin ends at the deadline, and a wake-up already past it
/// returns at once. No allocation, no lock.
#[inline]
pub fn sleep_then_spin_until_ns(deadline_ns: u64, spin_ns: u64) {
    let wake_ns = deadline_ns.saturating_sub(spin_ns);
    if monotonic_ns() < wake_ns {
        sleep_until_ns(wake_ns);
    }
    while monotonic_ns() < deadline_ns {
        std::hint::spin_loop();
    }
}

/// What a process asks of the operating system for its real-time loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RealtimeRequest {
    /// `SCHED_FIFO` at this priority (1–99), if set.
    pub sched_fifo_priority: Option<i32>,
    /// `mlockall(MCL_CURRENT)`, then `mlockall(MCL_FUTURE | MCL_ONFAULT)`:
    /// what is mapped later is locked as it is touched, not populated whole.
    pub lock_memory: bool,
    /// Pin the calling thread to this CPU, if set.
    pub cpu: Option<usize>,
}

/// A process of the real-time path, as `[realtime]` names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RealtimeProcess {
    /// `exo-plant-sim` (`plant_sim_cpu`).
    PlantSim,
    /// `exo-sensor-driver` (`sensor_driver_cpu`).
    SensorDriver,
    /// `exo-controller` (`controller_cpu`).
    Controller,
}

impl RealtimeRequest {
    /// What a run file's `[realtime]` section asks for `process`; nothing
    /// without one.
    pub fn of(rt: Option<&exo_config::RealtimeSettings>, process: RealtimeProcess) -> Self {
        let Some(rt) = rt else {
            return RealtimeRequest::default();
        };
        RealtimeRequest {
            sched_fifo_priority: rt.sched_fifo_priority,
            lock_memory: rt.lock_memory,
            cpu: match process {
                RealtimeProcess::PlantSim => rt.plant_sim_cpu,
                RealtimeProcess::SensorDriver => rt.sensor_driver_cpu,
                RealtimeProcess::Controller => rt.controller_cpu,
            },
        }
    }
}

/// What the operating system granted; each refusal is also logged as a warning.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RealtimeGrant {
    /// `SCHED_FIFO` is in effect.
    pub sched_fifo: bool,
    /// Memory is locked.
    pub memory_locked: bool,
    /// The thread is pinned.
    pub pinned: bool,
    /// One line per refusal, naming what was refused and why.
    pub refusals: Vec<String>,
}

/// Asks for real-time scheduling, locked memory and CPU pinning, as far as
/// the system permits; warns about, and carries on past, every refusal
/// (unprivileged users usually lack `CAP_SYS_NICE`, and `RLIMIT_MEMLOCK`
/// is often small). Call once before the loop, never per tick.
pub fn request_realtime(who: &str, req: RealtimeRequest) -> RealtimeGrant {
    let mut g = RealtimeGrant::default();
    if let Some(priority) = req.sched_fifo_priority {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: a valid sched_param for the calling process.
        if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
            g.sched_fifo = true;
        } else {
            g.refusals.push(format!(
                "SCHED_FIFO priority {priority} not permitted ({}); running with normal scheduling",
                std::io::Error::last_os_error()
            ));
        }
    }
    if req.lock_memory {
        // Everything mapped now is faulted in and locked at once. What is
        // mapped later (the shared-memory segment of a process that starts
        // or restarts, opened by iceoryx2 inside a tick) is locked page by
        // page as it is touched (MCL_ONFAULT), not populated whole at mmap
        // time: with plain MCL_FUTURE an identifier's restart cost the
        // plant a median of 18 missed 1 ms deadlines, with MCL_ONFAULT none
        // (BENCHMARKS.md, "Restarts off the control path"). A kernel
        // without MCL_ONFAULT (before 4.4) gets plain MCL_FUTURE.
        // SAFETY: plain system calls with valid flags.
        let locked = unsafe {
            libc::mlockall(libc::MCL_CURRENT) == 0
                && (libc::mlockall(libc::MCL_FUTURE | libc::MCL_ONFAULT) == 0
                    || libc::mlockall(libc::MCL_FUTURE) == 0)
        };
        if locked {
            g.memory_locked = true;
        } else {
            g.refusals.push(format!(
                "mlockall not permitted ({}); memory may page",
                std::io::Error::last_os_error()
            ));
        }
    }
    if let Some(cpu) = req.cpu {
        let ok = cpu < libc::CPU_SETSIZE as usize && {
            // SAFETY: a zeroed cpu_set_t is valid; CPU_SET stays within it (checked above).
            unsafe {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(cpu, &mut set);
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
            }
        };
        if ok {
            g.pinned = true;
        } else {
            g.refusals.push(format!(
                "pinning to CPU {cpu} failed ({})",
                std::io::Error::last_os_error()
            ));
        }
    }
    for r in &g.refusals {
        tracing::warn!("{who}: {r}");
    }
    if g.sched_fifo || g.memory_locked || g.pinned {
        tracing::info!(
            "{who}: real-time settings in effect: SCHED_FIFO {}, memory locked {}, pinned {}",
            g.sched_fifo,
            g.memory_locked,
            g.pinned
        );
    }
    g
}

/// The CPUs the calling thread may run on.
pub fn allowed_cpus() -> std::io::Result<Vec<usize>> {
    // SAFETY: a zeroed cpu_set_t is valid; sched_getaffinity fills it and
    // CPU_ISSET reads within it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Err(std::io::Error::last_os_error());
        }
        Ok((0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect())
    }
}

/// What [`keep_off_cpus`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum KeptOff {
    /// Confined to these CPUs (those it could use, less the ones kept off).
    Confined(Vec<usize>),
    /// It used none of the CPUs to keep off: nothing changed.
    AlreadyOff,
    /// It could use no other CPU: nothing changed.
    NoneLeft,
}

/// Keeps the calling thread, and every thread and process it starts
/// afterwards, off the CPUs `keep_off` (those of the control path): it is
/// confined to the CPUs it may use now less those. A child may still pin
/// itself anywhere (`request_realtime`), which is how the control path
/// takes the CPUs kept free for it.
pub fn keep_off_cpus(keep_off: &[usize]) -> std::io::Result<KeptOff> {
    let now = allowed_cpus()?;
    let rest: Vec<usize> = now
        .iter()
        .copied()
        .filter(|c| !keep_off.contains(c))
        .collect();
    if rest.is_empty() {
        return Ok(KeptOff::NoneLeft);
    }
    if rest.len() == now.len() {
        return Ok(KeptOff::AlreadyOff);
    }
    // SAFETY: a zeroed cpu_set_t is valid; every CPU in `rest` came from
    // sched_getaffinity, so CPU_SET stays within the set.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        for &c in &rest {
            libc::CPU_SET(c, &mut set);
        }
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(KeptOff::Confined(rest))
}

#[cfg(test)]
mod realtime_tests {
    use super::*;

    #[test]
    fn keeping_off_cpus_confines_the_thread_to_the_rest_or_changes_nothing() {
        // On a thread of its own, so the test harness's threads keep theirs.
        std::thread::spawn(|| {
            let all = allowed_cpus().unwrap();
            assert!(!all.is_empty());
            // Keeping off every CPU would leave none: nothing changes.
            assert_eq!(keep_off_cpus(&all).unwrap(), KeptOff::NoneLeft);
            assert_eq!(allowed_cpus().unwrap(), all);
            // Keeping off a CPU not in use changes nothing either.
            assert_eq!(keep_off_cpus(&[usize::MAX]).unwrap(), KeptOff::AlreadyOff);
            if all.len() >= 2 {
                let KeptOff::Confined(rest) = keep_off_cpus(&all[..1]).unwrap() else {
                    panic!("not confined");
                };
                assert_eq!(rest, all[1..].to_vec());
                assert_eq!(allowed_cpus().unwrap(), rest);
                // What the thread starts afterwards inherits the confinement.
                let inner = std::thread::spawn(|| allowed_cpus().unwrap())
                    .join()
                    .unwrap();
                assert_eq!(inner, rest);
                // And may still pin itself to a CPU kept off.
                let g = request_realtime(
                    "test",
                    RealtimeRequest {
                        cpu: Some(all[0]),
                        ..Default::default()
                    },
                );
                assert!(g.pinned, "{:?}", g.refusals);
                assert_eq!(allowed_cpus().unwrap(), vec![all[0]]);
            }
        })
        .join()
        .unwrap();
    }

    /// Locked memory as asked: what is mapped after the request is locked
    /// page by page as it is touched (`MCL_FUTURE | MCL_ONFAULT`), not
    /// populated whole at `mmap` (plain `MCL_FUTURE`, which made a peer's
    /// restart cost the real-time path deadlines) and not left unlocked.
    /// Read from the kernel's own account (`/proc/self/smaps`, `Locked:`)
    /// of a 64-page mapping made afterwards with one page touched. Where
    /// locking is not permitted, the refusal is named instead.
    #[test]
    fn memory_mapped_after_the_request_is_locked_as_it_is_touched() {
        let g = request_realtime(
            "test",
            RealtimeRequest {
                lock_memory: true,
                ..Default::default()
            },
        );
        if !g.memory_locked {
            // Root may always lock memory (CAP_IPC_LOCK): a refusal there
            // is a fault of the request, not of the machine.
            // SAFETY: a plain system call without arguments.
            assert_ne!(unsafe { libc::geteuid() }, 0, "{:?}", g.refusals);
            assert!(g.refusals[0].contains("mlockall"), "{:?}", g.refusals);
            return;
        }
        let page = 4096;
        let len = 64 * page;
        // SAFETY: a fresh private anonymous mapping, written within it, then
        // unmapped; nothing else refers to it.
        let locked_kb = unsafe {
            let p = libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            );
            assert_ne!(p, libc::MAP_FAILED);
            std::ptr::write_volatile(p.cast::<u8>(), 1);
            let start = format!("{:x}-", p as usize);
            let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
            let locked = smaps
                .lines()
                .skip_while(|l| !l.starts_with(&start))
                .find_map(|l| l.strip_prefix("Locked:"))
                .map(|v| v.trim().trim_end_matches(" kB").parse::<usize>().unwrap());
            libc::munmap(p, len);
            // Back to the test process's default for the other tests.
            libc::munlockall();
            locked
        };
        assert_eq!(locked_kb, Some(page / 1024), "64 pages mapped, one touched");
    }

    #[test]
    fn nothing_asked_nothing_granted_or_refused() {
        let g = request_realtime("test", RealtimeRequest::default());
        assert_eq!(g, RealtimeGrant::default());
    }

    #[test]
    fn an_impossible_cpu_is_refused_by_name_and_the_process_carries_on() {
        let g = request_realtime(
            "test",
            RealtimeRequest {
                cpu: Some(1 << 20),
                ..Default::default()
            },
        );
        assert!(!g.pinned);
        assert_eq!(g.refusals.len(), 1);
        assert!(g.refusals[0].contains("CPU 1048576"), "{:?}", g.refusals);
    }
}

#[cfg(test)]
mod wait_tests {
    use super::{monotonic_ns, sleep_then_spin_until_ns};

    /// The spinning wait never returns before its deadline (the clock is
    /// polled up to it), whether the spin is shorter than what is left
    /// (asleep first) or longer (spinning throughout), and a deadline long
    /// past, or a spin beyond the clock's origin, returns at once instead of
    /// hanging or underflowing. Its gain in lateness is a timing property,
    /// measured by the `timer_latency` example, not asserted here.
    #[test]
    fn the_spinning_wait_returns_at_or_after_its_deadline_and_at_once_when_past() {
        for spin_ns in [1, 200_000, 5_000_000] {
            let deadline = monotonic_ns() + 2_000_000;
            sleep_then_spin_until_ns(deadline, spin_ns);
            assert!(monotonic_ns() >= deadline, "spin {spin_ns} ns");
        }
        sleep_then_spin_until_ns(monotonic_ns().saturating_sub(1_000_000_000), 1_000_000);
        sleep_then_spin_until_ns(0, u64::MAX);
    }

    /// The thread's own CPU time (ns).
    fn thread_cpu_ns() -> u64 {
        super::clock_ns(libc::CLOCK_THREAD_CPUTIME_ID)
    }

    /// The wait sleeps for all but its spin: over a 50 ms wait with a 1 ms
    /// spin the thread uses far less CPU than the wait lasts. A wait that
    /// spun throughout would use about 50 ms of CPU, or less only where the
    /// machine took the CPU away; the bound (25 ms) is on CPU time, which
    /// a loaded machine can only lower, so it holds on any machine.
    #[test]
    fn the_spinning_wait_sleeps_until_its_spin_begins() {
        let before = thread_cpu_ns();
        sleep_then_spin_until_ns(monotonic_ns() + 50_000_000, 1_000_000);
        let used = thread_cpu_ns() - before;
        assert!(used < 25_000_000, "{used} ns of CPU in a 50 ms wait");
    }
}
