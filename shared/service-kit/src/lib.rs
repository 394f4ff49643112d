//! # exo-service-kit
//!
//! The little that every exo process's `main.rs` shares, so each main stays
//! a thin wiring of IPC around its service's library.

pub mod channels;
pub mod collect;
pub mod ipc;

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

/// Logs to standard error (`RUST_LOG` filters; default `info`).
pub fn init_logging(service: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .without_time()
        .try_init();
    tracing::debug!(service, "logging started");
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
    /// Whether a stop was requested.
    #[inline]
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds.
#[inline]
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid out-pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
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

/// Asks for real-time scheduling (SCHED_FIFO at `priority`), locks memory and
/// pins to `cpu` where permitted; warns, and carries on, where not.
pub fn request_realtime(priority: i32, cpu: Option<usize>) {
    // SAFETY: plain system calls with valid arguments.
    unsafe {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        if libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) != 0 {
            tracing::warn!(
                "SCHED_FIFO priority {priority} not permitted ({}); running with normal scheduling",
                std::io::Error::last_os_error()
            );
        }
        if libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) != 0 {
            tracing::warn!(
                "mlockall not permitted ({}); memory may page",
                std::io::Error::last_os_error()
            );
        }
        if let Some(cpu) = cpu {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
                tracing::warn!(
                    "pinning to CPU {cpu} failed ({})",
                    std::io::Error::last_os_error()
                );
            }
        }
    }
}
