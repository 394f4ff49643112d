//! The crate's error: each variant names the file, the field or the
//! argument it refuses.

use std::path::PathBuf;

use exo_impedance::ScienceError;
use exo_recording::RecordingError;

use crate::trials::SpecError;

/// What the analysis refuses, naming the file, field or argument.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A study file could not be read.
    #[error("reading study file {}", file.display())]
    ReadStudy {
        /// The study file.
        file: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A study file is not TOML.
    #[error("{}", file.display())]
    StudySyntax {
        /// The study file.
        file: PathBuf,
        /// The parser's message.
        source: toml::de::Error,
    },
    /// A study file's content refused: `detail` names the trial and the key.
    #[error("{}: {detail}", file.display())]
    Study {
        /// The study file.
        file: PathBuf,
        /// The trial (`trial 2 (b.csv)`), the key and what is wrong.
        detail: String,
    },
    /// A trial's value out of range ([`crate::trials::TrialSpec::validate`]).
    #[error("{}: {error}", csv.display())]
    Spec {
        /// The trial's CSV.
        csv: PathBuf,
        /// The key, its value and what it must be.
        error: SpecError,
    },
    /// A CSV could not be read.
    #[error("reading {}", file.display())]
    ReadCsv {
        /// The CSV.
        file: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A CSV refused as a whole (empty, a missing column, too few samples,
    /// an implausible rate).
    #[error("{}: {detail}", file.display())]
    Csv {
        /// The CSV.
        file: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// A line of a CSV refused (a missing or non-finite value, time not
    /// increasing, a gap).
    #[error("{} line {line}: {detail}", file.display())]
    CsvLine {
        /// The CSV.
        file: PathBuf,
        /// The line (1 = the header's line when it is the first).
        line: usize,
        /// The column and what is wrong.
        detail: String,
    },
    /// A CSV cell that is not a number.
    #[error("{} line {line}: `{column}` = {raw:?} is not a number", file.display())]
    CsvNumber {
        /// The CSV.
        file: PathBuf,
        /// The line.
        line: usize,
        /// The column's name.
        column: String,
        /// The cell as written.
        raw: String,
        /// The parser's message.
        source: std::num::ParseFloatError,
    },
    /// Writing or reading the recording built from a CSV.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The power law of a simulated subject's inputs could not be fitted.
    #[error("subject {subject}: power law of the inputs")]
    InputPowerLaw {
        /// The subject's name.
        subject: String,
        /// Why.
        source: ScienceError,
    },
    /// [`crate::study::analyse`] was given no subject with FRF points.
    #[error("nothing to analyse: no subject with FRF points")]
    NothingToAnalyse,
    /// The release test's input refused
    /// ([`crate::stability::Detector::classify`]): `detail` names the argument.
    #[error("stability: {detail}")]
    Stability {
        /// The argument and what is wrong with it.
        detail: String,
    },
}

/// The crate's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
