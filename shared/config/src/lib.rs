//! # exo-config
//!
//! One validated configuration for a run of exo. A run file (e.g.
//! `configs/default.toml`) names the processes to start, the plant model, the
//! subject, the protocol, the controller, the rig calibration and the safety
//! settings; it refers to the plant model, the subject and the experiment
//! table by paths relative to its own directory.
//!
//! Every table is `deny_unknown_fields`; every error names the file and the
//! key (e.g. `configs/default.toml: controller.f: must lie in [0, 1), got 1.2`).

use std::path::{Path, PathBuf};

use serde::Deserialize;
use thiserror::Error;

/// A configuration error, naming the file and the key.
#[derive(Debug, Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not valid TOML for its schema (unknown key, missing field, wrong type).
    #[error("{file}: {message}")]
    Parse {
        /// The file.
        file: PathBuf,
        /// The TOML parser's message, with line, column and key.
        message: String,
    },
    /// A value is out of its allowed range.
    #[error("{file}: {key}: {message}")]
    Invalid {
        /// The file.
        file: PathBuf,
        /// The key path, e.g. `safety.command_deadline_ms`.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// Result alias.
pub type Result<T, E = ConfigError> = std::result::Result<T, E>;

fn invalid(file: &Path, key: impl Into<String>, message: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        file: file.to_path_buf(),
        key: key.into(),
        message: message.into(),
    }
}

/// Parses TOML text of type `T`, naming `file` in errors.
pub fn parse_toml<T: for<'de> Deserialize<'de>>(text: &str, file: &Path) -> Result<T> {
    toml::from_str(text).map_err(|e| ConfigError::Parse {
        file: file.to_path_buf(),
        message: e.to_string().trim_end().replace('\n', "\n    "),
    })
}

/// Reads and parses a TOML file of type `T`.
pub fn read_toml<T: for<'de> Deserialize<'de>>(file: &Path) -> Result<T> {
    let text = std::fs::read_to_string(file).map_err(|source| ConfigError::Io {
        file: file.to_path_buf(),
        source,
    })?;
    parse_toml(&text, file)
}

/// A checker for numbers read from `file`.
pub struct Check<'a> {
    file: &'a Path,
}

impl<'a> Check<'a> {
    /// Checks for values read from `file`.
    pub fn new(file: &'a Path) -> Self {
        Check { file }
    }
    /// `value` must be finite.
    pub fn finite(&self, key: &str, value: f64) -> Result<f64> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(invalid(
                self.file,
                key,
                format!("must be a finite number, got {value}"),
            ))
        }
    }
    /// `value` must be finite and > 0.
    pub fn positive(&self, key: &str, value: f64) -> Result<f64> {
        self.finite(key, value)?;
        if value > 0.0 {
            Ok(value)
        } else {
            Err(invalid(
                self.file,
                key,
                format!("must be greater than zero, got {value}"),
            ))
        }
    }
    /// `value` must be finite and ≥ 0.
    pub fn non_negative(&self, key: &str, value: f64) -> Result<f64> {
        self.finite(key, value)?;
        if value >= 0.0 {
            Ok(value)
        } else {
            Err(invalid(
                self.file,
                key,
                format!("must be zero or more, got {value}"),
            ))
        }
    }
    /// `lo ≤ value ≤ hi`.
    pub fn within(&self, key: &str, value: f64, lo: f64, hi: f64) -> Result<f64> {
        self.finite(key, value)?;
        if (lo..=hi).contains(&value) {
            Ok(value)
        } else {
            Err(invalid(
                self.file,
                key,
                format!("must lie in [{lo}, {hi}], got {value}"),
            ))
        }
    }
    /// A free-form error about `key`.
    pub fn fail(&self, key: &str, message: impl Into<String>) -> ConfigError {
        invalid(self.file, key, message)
    }
}

mod experiments;
mod run;
mod subject;

pub use experiments::{ExperimentSpec, ExperimentTable, ProtocolTiming};
pub use run::{
    BusBackend, BusSettings, ControllerSettings, LimitSettings, ProtocolMode, ProtocolSettings,
    RealtimeSettings, ReleaseSettings, RigSettings, RunConfig, RunSettings, SafeState,
    SafetySettings, ServiceSet, TimingMode, VoluntarySettings, GRAVITY_M_S2,
};
pub use subject::{ReportedPowerLaw, Subject, SubjectExperiment};

/// The workspace's `configs/` directory (for tests and defaults).
pub fn configs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}
