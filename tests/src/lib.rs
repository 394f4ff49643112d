//! Helpers for the workspace-level integration tests in `tests/tests/`: they
//! run the real exo binaries, built by `cargo test --workspace`.

use std::path::PathBuf;
use std::process::{Command, Output};

/// Path of a workspace binary in the same target directory as the running test.
pub fn workspace_bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("path of the running test binary");
    // target/<profile>/deps/<test> -> target/<profile>/<name>
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("test binary lives in target/<profile>/deps");
    let bin = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.exists(),
        "{} is not built: run the tests with `cargo test --workspace`",
        bin.display()
    );
    bin
}

/// Runs `exo` with `args` and returns its output.
pub fn exo(args: &[&str]) -> Output {
    Command::new(workspace_bin("exo"))
        .args(args)
        .output()
        .expect("failed to start exo")
}

/// Standard output as UTF-8 text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Standard error as UTF-8 text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
