//! Stopping child processes, the one way every exo program does it: a child
//! is asked to die with its parent ([`die_with_parent`]), and is stopped
//! with SIGTERM, a grace period, then SIGKILL, and always reaped
//! ([`stop_gracefully`]), so iceoryx2 sees it dead and no zombie or orphan
//! is left behind.

use std::io;
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

/// How often [`stop_gracefully`] looks whether the children have exited
/// during the grace period.
const POLL: Duration = Duration::from_millis(10);

/// Makes the child started by `cmd` get SIGTERM when its parent dies
/// (`PR_SET_PDEATHSIG`), so a `kill -9` of the parent never leaves it
/// running as an orphan: it stops as on Ctrl-C. The signal follows the
/// *thread* that spawns the child, so spawn from a thread that lives as
/// long as the child should. If the parent died before the child set this
/// up, the child ends itself at once (SIGTERM). Setting it up failing
/// makes `cmd.spawn()` fail.
pub fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    let parent = std::process::id();
    // SAFETY: between fork and exec the closure calls only async-signal-safe
    // functions (prctl, getppid, raise) and allocates nothing.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(io::Error::last_os_error());
            }
            if u32::try_from(libc::getppid()) != Ok(parent) {
                libc::raise(libc::SIGTERM);
            }
            Ok(())
        });
    }
}

/// How a child ended under [`stop_gracefully`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stopped {
    /// It had exited already, or exited within the grace period (on
    /// SIGTERM or by itself).
    Exited(ExitStatus),
    /// It was still running when the grace period ended: it was killed
    /// (SIGKILL) and reaped.
    Killed(ExitStatus),
}

impl Stopped {
    /// The child's exit status, however it came.
    pub fn status(&self) -> ExitStatus {
        match *self {
            Stopped::Exited(s) | Stopped::Killed(s) => s,
        }
    }
}

/// Stops `children` together: SIGTERM to each that is still running (so
/// it can release its shared memory), up to `grace` (a duration, from
/// after the signals) for all of them to exit, looking every 10 ms, then
/// SIGKILL to those still running; every child is reaped before this
/// returns. Never panics.
///
/// Returns one outcome per child, in the order given. An error is that of
/// waiting for the child (`waitpid`); such a child is killed and waited for
/// as well, as far as that succeeds, and the first error is returned.
pub fn stop_gracefully<'a>(
    children: impl IntoIterator<Item = &'a mut Child>,
    grace: Duration,
) -> Vec<io::Result<Stopped>> {
    /// A child and what is known of it so far.
    enum State {
        Running,
        Done(Stopped),
        Failed(io::Error),
    }
    let mut all: Vec<(&mut Child, State)> = children
        .into_iter()
        .map(|child| {
            let state = match child.try_wait() {
                Ok(Some(status)) => State::Done(Stopped::Exited(status)),
                Ok(None) => {
                    if let Ok(pid) = libc::pid_t::try_from(child.id()) {
                        // SAFETY: signalling our own child, not yet reaped
                        // (so its pid is still its own); no memory effects.
                        // A failure shows as the child outliving `grace`.
                        unsafe { libc::kill(pid, libc::SIGTERM) };
                    }
                    State::Running
                }
                Err(e) => State::Failed(e),
            };
            (child, state)
        })
        .collect();
    let deadline = Instant::now() + grace;
    loop {
        for (child, state) in &mut all {
            if matches!(state, State::Running) {
                match child.try_wait() {
                    Ok(Some(status)) => *state = State::Done(Stopped::Exited(status)),
                    Ok(None) => {}
                    Err(e) => *state = State::Failed(e),
                }
            }
        }
        if !all.iter().any(|(_, s)| matches!(s, State::Running)) {
            break;
        }
        let now = Instant::now();
        if now >= deadline {
            break;
        }
        std::thread::sleep(POLL.min(deadline - now));
    }
    all.into_iter()
        .map(|(child, state)| match state {
            State::Done(stopped) => Ok(stopped),
            State::Running => {
                // An error here (it exited meanwhile) is answered by the wait.
                let _ = child.kill();
                child.wait().map(Stopped::Killed)
            }
            State::Failed(e) => {
                let _ = child.kill();
                let _ = child.wait();
                Err(e)
            }
        })
        .collect()
}

/// Whether process `pid` runs (or is stopped: SIGSTOP), from
/// `/proc/<pid>/stat`; a zombie or a missing process is dead. Pid 0 (not
/// told) counts as alive.
pub fn process_alive(pid: u32) -> bool {
    if pid == 0 {
        return true;
    }
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // pid (comm) state …: the comm may hold spaces and parentheses.
        Ok(stat) => stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.split_whitespace().next())
            .is_some_and(|state| state != "Z" && state != "X"),
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    /// Starts `program` with `args`, to die with the test.
    fn start(program: &str, args: &[&str]) -> Child {
        let mut cmd = Command::new(program);
        cmd.args(args).stdout(std::process::Stdio::piped());
        die_with_parent(&mut cmd);
        cmd.spawn().expect("starting a child")
    }

    #[test]
    fn a_child_that_heeds_sigterm_exits_on_it_and_one_that_ignores_it_is_killed() {
        let mut heeds = start("sleep", &["30"]);
        // The shell says so once the trap is set, so SIGTERM cannot come
        // before it; `exec` hands the ignored SIGTERM on to `sleep`, so
        // SIGKILL leaves no orphan.
        let mut ignores = start("sh", &["-c", "trap '' TERM; echo ready; exec sleep 30"]);
        let mut ready = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(ignores.stdout.take().expect("piped")),
            &mut ready,
        )
        .expect("reading the child's output");
        assert_eq!(ready.trim(), "ready");

        let out = stop_gracefully([&mut heeds, &mut ignores], Duration::from_millis(200));
        assert_eq!(out.len(), 2);
        match out[0].as_ref().expect("stopping the first child") {
            Stopped::Exited(s) => assert_eq!(s.signal(), Some(libc::SIGTERM), "{s}"),
            other => panic!("the child heeding SIGTERM was killed: {other:?}"),
        }
        match out[1].as_ref().expect("stopping the second child") {
            Stopped::Killed(s) => assert_eq!(s.signal(), Some(libc::SIGKILL), "{s}"),
            other => panic!("the child ignoring SIGTERM was not killed: {other:?}"),
        }
        // Both are reaped: asking again gives the same statuses at once.
        assert_eq!(
            heeds.try_wait().ok().flatten(),
            Some(out[0].as_ref().unwrap().status())
        );
        assert_eq!(
            ignores.try_wait().ok().flatten(),
            Some(out[1].as_ref().unwrap().status())
        );
    }

    #[test]
    fn a_child_that_has_exited_is_reported_as_it_exited_and_not_signalled() {
        let mut done = start("sh", &["-c", "exit 3"]);
        let status = done.wait().expect("waiting");
        let out = stop_gracefully([&mut done], Duration::from_millis(200));
        assert_eq!(out.len(), 1);
        assert_eq!(*out[0].as_ref().unwrap(), Stopped::Exited(status));
        assert_eq!(status.code(), Some(3));
    }

    #[test]
    fn no_children_no_outcomes() {
        assert!(stop_gracefully([], Duration::ZERO).is_empty());
    }

    #[test]
    fn a_live_process_is_alive_and_a_reaped_one_is_not() {
        assert!(process_alive(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!process_alive(pid));
        // Stopped is alive: a recorder under SIGSTOP is waited for.
        let mut sleeper = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .unwrap();
        let pid = i32::try_from(sleeper.id()).unwrap();
        // SAFETY: signalling a child of this test.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGSTOP) }, 0);
        std::thread::sleep(std::time::Duration::from_millis(50));
        assert!(process_alive(sleeper.id()));
        let _ = sleeper.kill();
        let _ = sleeper.wait();
    }
}
