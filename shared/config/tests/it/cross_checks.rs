//! The run file's checks that look beyond one key: the experiment a
//! voluntary or release protocol holds must be in both the experiment
//! table and the subject file; a player's recording must exist; the output
//! directory must be a directory or creatable; the lockstep poll's unit.
//! (Survivors of the fresh mutation shard 6/10, seed 22466, stop 46.)

use std::time::Duration;

use crate::common::{accepted, load_edited, load_files_edited, refused_naming};

/// Subject B's experiment 9 (`configs/subjects/B.toml`), removed below.
const SUBJECT_B_NINE: &str = "[[experiment]]\nnumber = 9\nstiffness_nm_per_rad = 65.45\nhysteretic_damping_nm_per_rad = 38.08\n";

/// A voluntary protocol holding experiment `n` (after the `[controller]`
/// header's place in `default.toml`).
fn voluntary(n: u32) -> String {
    format!(
        "[voluntary]\namplitude_rad = 0.3\nomega_rad_s = 2.0\nduration_s = 10.0\ngrip_kg = 14.0\nbias_nm = 4.0\nexperiment = {n}\n\n[controller]\n"
    )
}

/// Whether the load was refused with one error naming `key` and `text`.
fn refused_with(r: Result<exo_config::RunConfig, exo_config::ConfigError>, key: &str, text: &str) {
    let err = r
        .err()
        .unwrap_or_else(|| panic!("accepted; expected {key}: {text}"));
    assert!(
        err.each().iter().any(|e| {
            let e = e.to_string();
            e.contains(key) && e.contains(text)
        }),
        "{err}"
    );
}

/// Experiment 9 is in the table (Table I has nine) but the subject file
/// lost it: a voluntary protocol that holds experiment 9 is refused naming
/// `voluntary.experiment`, and one that holds experiment 1 is not. The
/// protocol's own experiments (1 and 7) are in both, so only the held
/// experiment's check can refuse it.
#[test]
fn a_held_experiment_missing_from_the_subject_is_refused_naming_its_key() {
    let mode = ("mode = \"identification\"", "mode = \"voluntary\"");
    let held_nine = voluntary(9);
    let (r, dir) = load_files_edited(
        "held-subject",
        &[
            (
                "default.toml",
                &[mode, ("[controller]\n", held_nine.as_str())],
            ),
            ("subjects/B.toml", &[(SUBJECT_B_NINE, "")]),
        ],
    );
    refused_with(r, "voluntary.experiment", "experiment 9 must be in both");
    let _ = std::fs::remove_dir_all(dir);
    let held_one = voluntary(1);
    let (r, dir) = load_files_edited(
        "held-subject-ok",
        &[
            (
                "default.toml",
                &[mode, ("[controller]\n", held_one.as_str())],
            ),
            ("subjects/B.toml", &[(SUBJECT_B_NINE, "")]),
        ],
    );
    let _ = std::fs::remove_dir_all(dir);
    assert_eq!(
        r.map(|c| c.voluntary.map(|v| v.experiment)).ok(),
        Some(Some(1))
    );
}

/// The same for a release protocol whose experiment the table lacks.
#[test]
fn a_released_experiment_missing_from_the_table_is_refused_naming_its_key() {
    let mode = ("mode = \"identification\"", "mode = \"release\"");
    let release = "[release]\nexperiment = 9\nspring_torque_nm = 5.0\nhold_s = 5.0\nobserve_s = 5.0\n\n[services]\n";
    let table =
        std::fs::read_to_string(exo_config::configs_dir().join("experiments.toml")).unwrap();
    let nine = &table[table.find("[[experiment]]\nnumber = 9\n").unwrap()..];
    let (r, dir) = load_files_edited(
        "released-table",
        &[
            ("default.toml", &[mode, ("[services]\n", release)]),
            ("experiments.toml", &[(nine, "")]),
        ],
    );
    let _ = std::fs::remove_dir_all(dir);
    refused_with(r, "release.experiment", "experiment 9 must be in both");
}

/// A player replays a recording that exists; a missing one is refused
/// naming `player.file`. (The simulator, driver and controller are off:
/// the player publishes what they would.)
#[test]
fn a_players_recording_must_exist() {
    let services =
        "[services]\nplayer = true\nplant_sim = false\nsensor_driver = false\ncontroller = false\n";
    let player = |file: &str| format!("[player]\nfile = \"{file}\"\n\n[protocol]\n");
    let off = [
        ("plant_sim = true\n", ""),
        ("sensor_driver = true\n", ""),
        ("controller = true\n", ""),
    ];
    // The run file's own experiment table stands in for a recording: it
    // is a file.
    let exists = player("experiments.toml");
    let mut edits = off.to_vec();
    edits.extend([
        ("[services]\n", services),
        ("[protocol]\n", exists.as_str()),
    ]);
    let c = accepted("player-ok", &edits);
    assert!(c
        .player
        .is_some_and(|p| p.file.ends_with("experiments.toml")));
    let missing = player("no-such-recording.mcap");
    let mut edits = off.to_vec();
    edits.extend([
        ("[services]\n", services),
        ("[protocol]\n", missing.as_str()),
    ]);
    refused_naming("player-missing", &edits, "player.file");
}

/// `run.output_dir` (relative to the working directory): an existing
/// directory, or one that can be created below one, is taken; a path
/// through a file, or one the system cannot look up (a NUL byte), is
/// refused naming the key.
#[test]
fn the_output_directory_is_a_directory_or_can_be_made_one() {
    let key = "output_dir = \"out/runs\"";
    let configs = exo_config::configs_dir();
    let fresh = std::env::temp_dir().join(format!("exo-outdir-{}/a/b", std::process::id()));
    for (tag, ok) in [("outdir-dir", configs.clone()), ("outdir-new", fresh)] {
        let c = accepted(
            tag,
            &[(key, &format!("output_dir = {:?}", ok.display().to_string()))],
        );
        assert_eq!(c.run.output_dir, ok);
    }
    let through_file = configs.join("experiments.toml").join("out");
    refused_naming(
        "outdir-file",
        &[(
            key,
            &format!("output_dir = {:?}", through_file.display().to_string()),
        )],
        "run.output_dir",
    );
    refused_naming(
        "outdir-nul",
        &[(key, "output_dir = \"out\\u0000runs\"")],
        "run.output_dir",
    );
}

/// `run.lockstep_spin_us` is microseconds (the shipped 200 µs), and real
/// time never spins.
#[test]
fn the_lockstep_poll_is_in_microseconds_and_real_time_has_none() {
    let (r, dir) = load_edited("spin", &[]);
    let _ = std::fs::remove_dir_all(dir);
    let c = r.unwrap();
    assert_eq!(c.run.lockstep_spin_us, 200.0);
    assert_eq!(c.lockstep_spin(), Duration::from_micros(200));
    let c = accepted(
        "spin-realtime",
        &[("timing = \"lockstep\"", "timing = \"realtime\"")],
    );
    assert_eq!(c.lockstep_spin(), Duration::ZERO);
}
