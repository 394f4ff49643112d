//! The crate's error: each variant names the file, or the option the
//! figure needs.

use std::path::PathBuf;

use exo_impedance::ScienceError;

/// Why a figure, page or file could not be made.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or directory could not be created or written.
    #[error("{action} {}", path.display())]
    File {
        /// `creating` or `writing`.
        action: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The plotting library refused (its message).
    #[error("plotting failed: {message}")]
    Plot {
        /// The plotting library's error, as it prints it.
        message: String,
    },
    /// `exo design`'s Bode plot without the human's loss factor.
    #[error("the Bode plot needs the human's loss factor: give --beta0/--beta1 or --loss-factor")]
    NoLossFactor,
    /// A quantity of the science core refused.
    #[error(transparent)]
    Science(#[from] ScienceError),
    /// The JSON document could not be written.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl Error {
    /// [`Error::File`] for `path` with `action`.
    pub(crate) fn file<'a>(
        action: &'static str,
        path: &'a std::path::Path,
    ) -> impl FnOnce(std::io::Error) -> Error + 'a {
        move |source| Error::File {
            action,
            path: path.to_path_buf(),
            source,
        }
    }
}

/// The crate's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
