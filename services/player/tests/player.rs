//! The player process refuses what it cannot play, naming it. (Being an
//! integration test, this also makes `cargo test --workspace` build the
//! `exo-player` binary that `exo run` starts and `tests/tests/it/recordings.rs`
//! plays a recording through.)

use std::process::Command;

fn configs() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}

#[test]
fn a_run_file_without_a_player_table_is_refused_by_name() {
    let out = Command::new(env!("CARGO_BIN_EXE_exo-player"))
        .arg("--config")
        .arg(configs().join("default.toml"))
        .env("RUST_LOG", "error")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("no [player] table"), "{err}");
}

#[test]
fn a_recording_that_is_not_one_is_refused_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("exo-player-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let junk = dir.join("junk.mcap");
    std::fs::write(&junk, b"not a recording").unwrap();
    let text = std::fs::read_to_string(configs().join("default.toml"))
        .unwrap()
        .replace("\"plants/", &format!("\"{}/plants/", configs().display()))
        .replace(
            "\"subjects/",
            &format!("\"{}/subjects/", configs().display()),
        )
        .replace(
            "\"experiments.toml\"",
            &format!("\"{}/experiments.toml\"", configs().display()),
        )
        + &format!("\n[player]\nfile = \"{}\"\n", junk.display());
    let run = dir.join("run.toml");
    std::fs::write(&run, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_exo-player"))
        .arg("--config")
        .arg(&run)
        .env("RUST_LOG", "error")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("junk.mcap"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
