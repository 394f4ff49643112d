//! The recorder process refuses a bad run file by name, before touching
//! shared memory or the disk (this file also makes `cargo test` build the
//! binary the workspace integration tests run).

use std::process::Command;

#[test]
fn a_missing_run_file_is_named() {
    let out = Command::new(env!("CARGO_BIN_EXE_exo-recorder"))
        .args([
            "--config",
            "/nonexistent/run.toml",
            "--output",
            "/tmp/never.mcap",
        ])
        .output()
        .expect("exo-recorder runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/run.toml"));
    assert!(!std::path::Path::new("/tmp/never.mcap").exists());
}
