//! # exo-config
//!
//! One validated configuration for a run of exo. A run file (e.g.
//! `configs/default.toml`) names the processes to start, the plant model, the
//! subject, the protocol, the controller, the rig calibration and the safety
//! settings; it refers to the plant model, the subject and the experiment
//! table by paths relative to its own directory.
//!
//! Every table is `deny_unknown_fields`; every numeric key has a documented
//! range (in its doc comment and in [`RUN_RANGES`], [`EXPERIMENT_RANGES`],
//! [`SUBJECT_RANGES`]), NaN and ±inf are never in one; names that become
//! parts of file names are checked ([`check_name`]); durations are bounded
//! so each fits a `std::time::Duration` and no run lasts more than a day.
//! Every error names the file and the key (e.g. `configs/default.toml:
//! controller.f: must lie in [0, 1), got 1.2`), a parse error too (the key
//! under the parser's position), and loading reports every error it finds,
//! one per line ([`ConfigError::Several`]), not only the first.

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
    /// The file is not valid TOML for its schema (unknown key, missing
    /// field, wrong type, a number that does not fit an integer key).
    #[error("{file}: {}{message}", key.as_deref().map(|k| format!("{k}: ")).unwrap_or_default())]
    Parse {
        /// The file.
        file: PathBuf,
        /// The dotted key at fault (e.g. `protocol.periods[0]`), when the
        /// parser's position falls on one.
        key: Option<String>,
        /// The TOML parser's message, with line and column.
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
    /// Several errors, each naming its file and key, one per line.
    #[error("{}", .0.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n"))]
    Several(Vec<ConfigError>),
}

impl ConfigError {
    /// Every single error this holds (one, or each of [`ConfigError::Several`]).
    pub fn each(&self) -> Vec<&ConfigError> {
        match self {
            ConfigError::Several(v) => v.iter().flat_map(|e| e.each()).collect(),
            e => vec![e],
        }
    }

    /// One error from many: `None` for none, the error itself for one.
    pub fn from_many(errors: Vec<ConfigError>) -> Option<ConfigError> {
        let mut flat: Vec<ConfigError> = Vec::new();
        for e in errors {
            match e {
                ConfigError::Several(v) => flat.extend(v),
                e => flat.push(e),
            }
        }
        match flat.len() {
            0 => None,
            1 => flat.pop(),
            _ => Some(ConfigError::Several(flat)),
        }
    }
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

/// The dotted key (`run.rate_hz`, `experiment[3].alpha`,
/// `controller.k_range_nm_per_rad[1]`) of a TOML document `text` whose key,
/// value, table header or array element covers byte `at`: the narrowest one.
/// `None` when nothing does (e.g. a missing key at the top level) or the
/// text is not TOML.
pub fn toml_key_at(text: &str, at: usize) -> Option<String> {
    use toml::de::{DeTable, DeValue};
    type Best = Option<(usize, usize, String)>;
    fn consider(
        span: std::ops::Range<usize>,
        path: &str,
        at: usize,
        depth: usize,
        best: &mut Best,
    ) {
        let hit = span.contains(&at) || (span.start == at && span.end == at);
        if !hit {
            return;
        }
        let len = span.end - span.start;
        let better = match best {
            None => true,
            Some((l, d, _)) => len < *l || (len == *l && depth >= *d),
        };
        if better {
            *best = Some((len, depth, path.to_string()));
        }
    }
    fn visit(value: &DeValue<'_>, path: &str, at: usize, best: &mut Best, depth: usize) {
        match value {
            DeValue::Table(t) => {
                for (k, v) in t.iter() {
                    let p = if path.is_empty() {
                        k.get_ref().to_string()
                    } else {
                        format!("{path}.{}", k.get_ref())
                    };
                    consider(k.span(), &p, at, depth, best);
                    consider(v.span(), &p, at, depth, best);
                    visit(v.get_ref(), &p, at, best, depth + 1);
                }
            }
            DeValue::Array(a) => {
                for (i, item) in a.iter().enumerate() {
                    let p = format!("{path}[{i}]");
                    consider(item.span(), &p, at, depth, best);
                    visit(item.get_ref(), &p, at, best, depth + 1);
                }
            }
            _ => {}
        }
    }
    let doc = DeTable::parse(text).ok()?;
    let mut best = None;
    visit(&DeValue::Table(doc.into_inner()), "", at, &mut best, 0);
    best.map(|(_, _, p)| p).filter(|p| !p.is_empty())
}

/// A TOML parser error as (dotted key, message with line and column).
pub fn describe_toml_error(text: &str, e: &toml::de::Error) -> (Option<String>, String) {
    let Some(span) = e.span() else {
        return (None, e.message().to_string());
    };
    let key = toml_key_at(text, span.start);
    let before = &text[..span.start.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (
        key,
        format!("{} (line {line}, column {column})", e.message()),
    )
}

/// Parses TOML text of type `T`, naming `file` and the key in errors.
pub fn parse_toml<T: for<'de> Deserialize<'de>>(text: &str, file: &Path) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let (key, message) = describe_toml_error(text, &e);
        ConfigError::Parse {
            file: file.to_path_buf(),
            key,
            message,
        }
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

/// A number as errors show it: plainly, or in exponent form when very
/// large or small (`1e300`, not three hundred digits).
pub fn number(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && v != 0.0 && !(1e-6..1e9).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The allowed interval of a numeric key; NaN and ±inf never lie in one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
    /// Whether `lo` itself is excluded.
    pub lo_open: bool,
    /// Whether `hi` itself is excluded.
    pub hi_open: bool,
}

impl Range {
    /// `[lo, hi]`.
    pub const fn closed(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
        }
    }
    /// `(lo, hi]`: above `lo` (e.g. greater than zero), at most `hi`.
    pub const fn above(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: true,
            hi_open: false,
        }
    }
    /// `[lo, hi)`.
    pub const fn below(lo: f64, hi: f64) -> Self {
        Range {
            lo,
            hi,
            lo_open: false,
            hi_open: true,
        }
    }
    /// Whether `v` is finite and inside.
    pub fn contains(&self, v: f64) -> bool {
        v.is_finite()
            && (if self.lo_open {
                v > self.lo
            } else {
                v >= self.lo
            })
            && (if self.hi_open {
                v < self.hi
            } else {
                v <= self.hi
            })
    }
}

impl std::fmt::Display for Range {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}{}, {}{}",
            if self.lo_open { '(' } else { '[' },
            number(self.lo),
            number(self.hi),
            if self.hi_open { ')' } else { ']' }
        )
    }
}

/// A table of documented ranges: a key pattern (array indices written
/// `[*]`, e.g. `experiment[*].alpha`) and its range.
pub type Ranges = &'static [(&'static str, Range)];

/// The pattern of a key: every `[n]` becomes `[*]`.
pub fn key_pattern(key: &str) -> String {
    let mut out = String::with_capacity(key.len());
    let mut in_index = false;
    for ch in key.chars() {
        match ch {
            '[' => {
                in_index = true;
                out.push_str("[*]");
            }
            ']' => in_index = false,
            _ if in_index => {}
            _ => out.push(ch),
        }
    }
    out
}

/// The documented range of `key` in `table`.
pub fn range_of(table: Ranges, key: &str) -> Option<Range> {
    let pattern = key_pattern(key);
    table.iter().find(|(k, _)| *k == pattern).map(|(_, r)| *r)
}

/// A checker for values read from `file`: the single-value checks return
/// the first error (for `?`); the `note_*` and [`Check::key`] checks
/// collect every error, for [`Check::finish`].
pub struct Check<'a> {
    file: &'a Path,
    ranges: Ranges,
    errors: std::cell::RefCell<Vec<ConfigError>>,
}

impl<'a> Check<'a> {
    /// Checks for values read from `file`.
    pub fn new(file: &'a Path) -> Self {
        Self::with_ranges(file, &[])
    }
    /// Checks for values read from `file`, whose keys have the ranges `ranges`.
    pub fn with_ranges(file: &'a Path, ranges: Ranges) -> Self {
        Check {
            file,
            ranges,
            errors: std::cell::RefCell::new(Vec::new()),
        }
    }
    /// The file checked.
    pub fn file(&self) -> &Path {
        self.file
    }
    /// `value` of `key` must lie in the key's documented range (its entry
    /// in the ranges this checker was made with); records the error and
    /// returns `false` otherwise.
    pub fn key(&self, key: &str, value: f64) -> bool {
        match range_of(self.ranges, key) {
            Some(r) => self.in_range(key, value, r),
            None => {
                self.push(invalid(
                    self.file,
                    key,
                    "has no documented range (a bug of exo-config)",
                ));
                false
            }
        }
    }
    /// `value` of `key` must lie in `r`; records the error and returns `false` otherwise.
    pub fn in_range(&self, key: &str, value: f64, r: Range) -> bool {
        if r.contains(value) {
            return true;
        }
        let message = if value.is_finite() {
            format!("must lie in {r}, got {}", number(value))
        } else {
            format!("must be a finite number in {r}, got {value}")
        };
        self.push(invalid(self.file, key, message));
        false
    }
    /// Records an error about `key`.
    pub fn note(&self, key: &str, message: impl Into<String>) {
        self.push(invalid(self.file, key, message));
    }
    /// Records an error (of this or another file).
    pub fn push(&self, e: ConfigError) {
        self.errors.borrow_mut().push(e);
    }
    /// Records the error of `r`, if any, and returns its value.
    pub fn take<T>(&self, r: Result<T>) -> Option<T> {
        match r {
            Ok(v) => Some(v),
            Err(e) => {
                self.push(e);
                None
            }
        }
    }
    /// Whether any error has been recorded.
    pub fn failed(&self) -> bool {
        !self.errors.borrow().is_empty()
    }
    /// `Ok` when nothing was recorded, else every recorded error.
    pub fn finish(self) -> Result<()> {
        match ConfigError::from_many(self.errors.into_inner()) {
            None => Ok(()),
            Some(e) => Err(e),
        }
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

/// A name that becomes part of a file or service name (a subject's name):
/// non-empty, at most 64 characters, no path separator (`/`, `\`), no
/// `..`, no control character, not starting with `.` or `-`.
pub fn check_name(name: &str) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("must not be empty".into());
    }
    if name.chars().count() > 64 {
        return Err(format!(
            "must be at most 64 characters, got {}",
            name.chars().count()
        ));
    }
    if let Some(c) = name.chars().find(|c| c.is_control()) {
        return Err(format!(
            "must not contain a control character, got {:?} in {name:?}",
            c
        ));
    }
    if name.contains(['/', '\\']) {
        return Err(format!(
            "must not contain a path separator ('/' or '\\'), got {name:?}"
        ));
    }
    if name.contains("..") {
        return Err(format!("must not contain '..', got {name:?}"));
    }
    if name.starts_with(['.', '-']) {
        return Err(format!("must not start with '.' or '-', got {name:?}"));
    }
    Ok(())
}

/// The longest simulated or wall-clock duration exo accepts anywhere (s):
/// a day. Every duration key is bounded by it, so each fits a
/// `std::time::Duration` and no run silently lasts for ever.
pub const MAX_DURATION_S: f64 = 86_400.0;

/// Experiment numbers run from 1 to this (the protocol channel carries
/// 0–9, `exo_messages::protocol::MAX_EXPERIMENT`).
pub const MAX_EXPERIMENT: u32 = 9;

/// Periods per experiment run from 1 to this (the protocol channel carries
/// 0–10, `exo_messages::protocol::MAX_PERIOD`).
pub const MAX_PERIOD: u32 = 10;

mod ethercat;
mod experiments;
mod run;
mod subject;
pub mod toml_paths;

pub use ethercat::{
    role_name, EthercatSettings, PdoEntry, PdoRole, PdoSettings, DEFAULT_MISSED_SPAN_MS,
    MAX_MISSED_SPAN_MS, MAX_PDO_BYTES, MAX_PDO_ENTRIES, WATCHDOG_DIVIDER_100_US,
};
pub use experiments::{ExperimentSpec, ExperimentTable, ProtocolTiming, EXPERIMENT_RANGES};
pub use run::{
    gravity_moment_nm, BusBackend, BusSettings, ControllerSettings, LayoutError, LimitSettings,
    LiveSettings, MultisineError, MultisineSettings, PlayerSettings, ProtocolMode,
    ProtocolSettings, RealtimeSettings, ReleaseSettings, RigSettings, RunConfig, RunSettings,
    SafeState, SafetySettings, ServiceSet, StopWhen, TimingMode, TunnelSettings, VoluntarySettings,
    GRAVITY_M_S2, RUN_RANGES,
};
pub use subject::{ReportedPowerLaw, Subject, SubjectExperiment, SUBJECT_RANGES};

/// The workspace's `configs/` directory (for tests and defaults).
pub fn configs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}
