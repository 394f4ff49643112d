//! The child processes of one benchmark row: started with their standard
//! error in a log file, asked to die with the bench, and always stopped
//! (SIGTERM, then SIGKILL) and reaped, also when the row fails.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use exo_service_kit::child::{stop_gracefully, Stopped};

/// How long a child may take to exit after SIGTERM before it is killed.
const TERM_PATIENCE: Duration = Duration::from_secs(5);

/// The children of one row.
pub struct Fleet {
    dir: PathBuf,
    children: Vec<(String, Child)>,
}

impl Fleet {
    /// An empty fleet whose logs go to `dir`.
    pub fn new(dir: &Path) -> Self {
        Fleet {
            dir: dir.to_path_buf(),
            children: Vec::new(),
        }
    }

    /// The log file of child `name`.
    pub fn log_path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}.log"))
    }

    /// Starts `program` with `args` as child `name` (unique in the fleet).
    pub fn spawn(&mut self, name: &str, program: &Path, args: &[&std::ffi::OsStr]) -> Result<()> {
        let log_path = self.log_path(name);
        let log = std::fs::File::create(&log_path)
            .with_context(|| format!("creating {}", log_path.display()))?;
        let mut cmd = Command::new(program);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log);
        exo_service_kit::child::die_with_parent(&mut cmd);
        let child = cmd
            .spawn()
            .with_context(|| format!("starting {name} ({})", program.display()))?;
        self.children.push((name.to_string(), child));
        Ok(())
    }

    /// An error naming the first child that has exited, with the end of its log.
    pub fn check_alive(&mut self) -> Result<()> {
        for (name, child) in &mut self.children {
            if let Some(status) = child
                .try_wait()
                .with_context(|| format!("waiting for {name}"))?
            {
                let log = self.dir.join(format!("{name}.log"));
                bail!(
                    "{name} exited early ({status}); the end of {}:\n{}",
                    log.display(),
                    tail(&log, 15)
                );
            }
        }
        Ok(())
    }

    /// Whether child `name` is still running.
    pub fn is_running(&mut self, name: &str) -> bool {
        self.children
            .iter_mut()
            .find(|(n, _)| n == name)
            .is_some_and(|(_, c)| matches!(c.try_wait(), Ok(None)))
    }

    /// Stops every child: SIGTERM, up to 5 s to exit, then SIGKILL; all are
    /// reaped. Returns the names of those that had to be killed or exited
    /// with a failure.
    pub fn stop(&mut self) -> Vec<String> {
        let outcomes = stop_gracefully(self.children.iter_mut().map(|(_, c)| c), TERM_PATIENCE);
        let trouble = self
            .children
            .iter()
            .zip(outcomes)
            .filter_map(|((name, _), outcome)| match outcome {
                Ok(Stopped::Exited(status)) if status.success() => None,
                Ok(Stopped::Exited(status)) => Some(format!("{name} exited with {status}")),
                Ok(Stopped::Killed(_)) | Err(_) => {
                    Some(format!("{name} did not stop on SIGTERM and was killed"))
                }
            })
            .collect();
        self.children.clear();
        trouble
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The last `n` lines of a text file (empty if unreadable).
pub fn tail(path: &Path, n: usize) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}
