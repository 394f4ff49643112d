//! Helpers shared by the run file's tests: a scratch copy of `configs/`
//! with `default.toml` (or another of its files) edited, loaded with
//! [`RunConfig::from_file`].

use std::path::PathBuf;

use exo_config::{configs_dir, ConfigError, RunConfig};

/// A scratch copy of `configs/` with `default.toml` edited by `edits`,
/// loaded.
pub fn load_edited(tag: &str, edits: &[(&str, &str)]) -> (Result<RunConfig, ConfigError>, PathBuf) {
    load_edited_in(tag, "default.toml", edits)
}

/// The same with `file` (relative to `configs/`) edited.
pub fn load_edited_in(
    tag: &str,
    file: &str,
    edits: &[(&str, &str)],
) -> (Result<RunConfig, ConfigError>, PathBuf) {
    let dir = std::env::temp_dir().join(format!("exo-config-edges-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    for sub in ["plants", "subjects"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    for f in [
        "default.toml",
        "experiments.toml",
        "subjects/B.toml",
        "plants/default.toml",
    ] {
        std::fs::copy(configs_dir().join(f), dir.join(f)).unwrap();
    }
    let edited = dir.join(file);
    let mut text = std::fs::read_to_string(&edited).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from:?} not in {file}");
        text = text.replacen(from, to, 1);
    }
    std::fs::write(&edited, text).unwrap();
    (RunConfig::from_file(&dir.join("default.toml")), dir)
}

/// Asserts the edited run file is refused with an error naming `key`.
pub fn refused_naming(tag: &str, edits: &[(&str, &str)], key: &str) {
    let (r, dir) = load_edited(tag, edits);
    let err = r.err().unwrap_or_else(|| panic!("{edits:?} accepted"));
    assert!(
        err.each().iter().any(|e| e.to_string().contains(key)),
        "{edits:?}: {err}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

/// The edited run file, which must load.
pub fn accepted(tag: &str, edits: &[(&str, &str)]) -> RunConfig {
    let (r, dir) = load_edited(tag, edits);
    let _ = std::fs::remove_dir_all(dir);
    r.unwrap_or_else(|e| panic!("{edits:?} refused: {e}"))
}

/// A scratch copy of `configs/` with several of its files edited (each
/// `(file, edits)`, files relative to `configs/`), `default.toml` loaded.
pub fn load_files_edited(
    tag: &str,
    files: &[(&str, &[(&str, &str)])],
) -> (Result<RunConfig, ConfigError>, PathBuf) {
    let (_, dir) = load_edited_in(tag, "default.toml", &[]);
    for (file, edits) in files {
        let path = dir.join(file);
        let mut text = std::fs::read_to_string(&path).unwrap();
        for (from, to) in *edits {
            assert!(text.contains(from), "{from:?} not in {file}");
            text = text.replacen(from, to, 1);
        }
        std::fs::write(&path, text).unwrap();
    }
    (RunConfig::from_file(&dir.join("default.toml")), dir)
}
