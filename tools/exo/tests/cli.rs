//! The `exo` binary's command surface (this file also makes `cargo test`
//! build the binary the workspace integration tests run).

use std::process::Command;

fn exo(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_exo"))
        .args(args)
        .output()
        .expect("exo runs")
}

#[test]
fn every_command_is_listed() {
    let out = exo(&["--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for cmd in ["design", "run", "tune", "fit", "report", "import"] {
        assert!(help.contains(cmd), "`{cmd}` missing from:\n{help}");
    }
}

#[test]
fn a_missing_argument_is_named() {
    let out = exo(&["fit"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("RECORDINGS"));
    let out = exo(&["run", "/nonexistent/run.toml"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/run.toml"));
}
