//! The crate's error: each variant names the file, the program or the
//! service it is about.

use std::path::PathBuf;

/// Why a run could not be checked, started or supervised to its end.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The run file or a file it names was refused by
    /// [`crate::check_run`]: every error, each naming its file and key.
    #[error(
        "{} is refused ({} error{}); nothing was started:\n  {}",
        config.display(),
        errors.len(),
        if errors.len() == 1 { "" } else { "s" },
        errors.join("\n  ")
    )]
    Refused {
        /// The run file.
        config: PathBuf,
        /// Every error found, one line each.
        errors: Vec<String>,
    },
    /// The running `exo` could not locate its own executable.
    #[error("locating the exo executable")]
    LocateExe(#[source] std::io::Error),
    /// The running `exo`'s path has no directory.
    #[error("exo executable has no directory")]
    NoExeDirectory {
        /// The executable's path.
        exe: PathBuf,
    },
    /// A service's program is not next to `exo`.
    #[error(
        "{name} not found next to exo ({}): build the workspace (cargo build --release --workspace)",
        dir.display()
    )]
    ProgramNotFound {
        /// The program's name.
        name: String,
        /// The directory `exo` is in.
        dir: PathBuf,
    },
    /// The stop signals' handlers could not be installed.
    #[error("installing signal handlers")]
    Signals(#[source] std::io::Error),
    /// A service could not be started.
    #[error("starting {service} ({})", program.display())]
    Start {
        /// The service.
        service: &'static str,
        /// Its program.
        program: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A service's status could not be read.
    #[error("waiting for {service}: {error}")]
    Wait {
        /// The service.
        service: &'static str,
        /// Why.
        error: std::io::Error,
    },
    /// A service stopped when it must not: a critical one, or a
    /// restartable one past its restarts.
    #[error("process `{service}` ({}) stopped with {status}{last_lines}", program.display())]
    Stopped {
        /// The service.
        service: &'static str,
        /// Its program.
        program: PathBuf,
        /// Its exit code or signal (`exit code 1`, `signal 9`).
        status: String,
        /// Its last log lines, when they were kept back (`Logs::Quiet`),
        /// else empty.
        last_lines: String,
    },
    /// The caller's check of [`crate::supervise_checked`] failed: its
    /// message with its causes, and with quiet logs the real-time path's
    /// last log lines.
    #[error("{message}")]
    Check {
        /// The check's error, its causes after `: `.
        message: String,
    },
}

/// The crate's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
