//! The crate's error: each variant names the file, the option, the
//! subject or the experiment it is about.

use std::collections::BTreeSet;
use std::path::PathBuf;

use exo_config::{ConfigError, LayoutError};
use exo_impedance::ScienceError;
use exo_plant_model::PlantModelError;
use exo_recording::RecordingError;
use exo_sim::SimError;

/// Why an experiment could not be run or a recording not fitted.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A run file, subject or experiment table refused.
    #[error(transparent)]
    Config(Box<ConfigError>),
    /// A plant model refused.
    #[error(transparent)]
    PlantModel(Box<PlantModelError>),
    /// A study file, CSV or the analysis refused.
    #[error(transparent)]
    Analysis(Box<exo_analysis::Error>),
    /// A recording could not be read or written.
    #[error(transparent)]
    Recording(Box<RecordingError>),
    /// The in-process simulation could not be set up or written.
    #[error(transparent)]
    Sim(Box<SimError>),
    /// A quantity of the science core refused (the SEA, the loop).
    #[error(transparent)]
    Science(Box<ScienceError>),
    /// The controller's layout could not be built from the run file.
    #[error(transparent)]
    Layout(Box<LayoutError>),
    /// A file or directory could not be resolved, created or written.
    #[error("{action} {}", path.display())]
    File {
        /// `resolving`, `creating` or `writing`.
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A run file could not be written as TOML.
    #[error("writing {what}")]
    RunFile {
        /// Which run file (`the subject's run file`, …).
        what: &'static str,
        /// Why.
        source: toml::ser::Error,
    },
    /// A subject's simulation could not be set up or its recording written.
    #[error("simulating subject {subject} ({})", run_file.display())]
    Simulation {
        /// The subject's run name.
        subject: String,
        /// Its run file.
        run_file: PathBuf,
        /// Why.
        source: Box<SimError>,
    },
    /// A subject's recording could not be finished.
    #[error("finishing {}", recording.display())]
    Finish {
        /// The recording.
        recording: PathBuf,
        /// Why.
        source: Box<RecordingError>,
    },
    /// A subject's simulation latched a safe state.
    #[error(
        "subject {subject}: {latched}, {at}; the run is stopped (the recording so far is {})",
        recording.display()
    )]
    SafeState {
        /// The subject's run name.
        subject: String,
        /// Who latched, in which mode, when.
        latched: String,
        /// Where in the protocol (`in experiment 3 period 2`).
        at: String,
        /// The recording so far.
        recording: PathBuf,
    },
    /// A subject's simulation reached its bound before the protocol's end.
    #[error(
        "subject {subject}: the run reached its bound of {bound_s:.1} s simulated before the controller finished the protocol ({})",
        run_file.display()
    )]
    Bound {
        /// The subject's run name.
        subject: String,
        /// The bound (s simulated).
        bound_s: f64,
        /// Its run file.
        run_file: PathBuf,
    },
    /// A simulation's worker ended without a result.
    #[error("the simulation did not run")]
    NotRun,
    /// An input's worker ended without a result.
    #[error("{} was not read", path.display())]
    NotRead {
        /// The input.
        path: PathBuf,
    },
    /// A recording's metadata value that is not a number.
    #[error("{recording}: metadata exo.{key} = {value:?} is not a number")]
    MetadataNumber {
        /// The recording (its source).
        recording: String,
        /// The metadata key.
        key: String,
        /// The value as written.
        value: String,
        /// The parser's message.
        source: std::num::ParseFloatError,
    },
    /// A recording's metadata value refused.
    #[error("{recording}: metadata exo.{key} = {detail}")]
    Metadata {
        /// The recording (its source).
        recording: String,
        /// The metadata key.
        key: String,
        /// The value and what it must be.
        detail: String,
    },
    /// An option of `exo fit` out of range.
    #[error("{option} = {detail}")]
    Option {
        /// The option (`--level`, …).
        option: &'static str,
        /// Its value and what it must be.
        detail: String,
    },
    /// No input of `exo fit` gave a point.
    #[error(
        "no FRF point in {}:\n  {}",
        recordings.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "),
        warnings.join("\n  ")
    )]
    NoFrfPoint {
        /// The recordings given.
        recordings: Vec<PathBuf>,
        /// Every warning of the inputs.
        warnings: Vec<String>,
    },
    /// The inputs of `exo fit` are of different joints.
    #[error("the recordings are of different joints ({joints:?}); fit them apart or give --joint")]
    MixedJoints {
        /// The joints' names.
        joints: BTreeSet<&'static str>,
    },
    /// A tuning trial could not be simulated.
    #[error("trial f = {f:.3} at experiment {experiment}")]
    Trial {
        /// The fractional order tried.
        f: f64,
        /// The experiment.
        experiment: u32,
        /// Why.
        source: Box<SimError>,
    },
    /// A tuning trial ended before its release.
    #[error("the trial never reached the release (no analysis phase)")]
    NoRelease {
        /// The fractional order tried.
        f: f64,
        /// The experiment.
        experiment: u32,
    },
    /// The subject of `exo tune` refused with the run file.
    #[error("subject {subject}")]
    Subject {
        /// The subject's name.
        subject: String,
        /// Why.
        source: Box<ConfigError>,
    },
    /// An experiment of `exo tune` not in the experiment table.
    #[error("experiment {experiment} is not in the table")]
    NotInTable {
        /// The experiment.
        experiment: u32,
    },
    /// An experiment of `exo tune` the subject does not have.
    #[error("subject {subject} has no experiment {experiment}")]
    NotInSubject {
        /// The subject's name.
        subject: String,
        /// The experiment.
        experiment: u32,
    },
    /// The tuning search found no boundary at an experiment.
    #[error("experiment {experiment}: {detail}")]
    NoBoundary {
        /// The experiment.
        experiment: u32,
        /// What the release did.
        detail: String,
    },
}

/// The errors of other crates, boxed so that [`Error`] stays small.
macro_rules! boxed_from {
    ($($variant:ident($ty:ty)),* $(,)?) => {
        $(impl From<$ty> for Error {
            fn from(e: $ty) -> Self {
                Error::$variant(Box::new(e))
            }
        })*
    };
}

boxed_from!(
    Config(ConfigError),
    PlantModel(PlantModelError),
    Analysis(exo_analysis::Error),
    Recording(RecordingError),
    Sim(SimError),
    Science(ScienceError),
    Layout(LayoutError),
);

/// The crate's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
