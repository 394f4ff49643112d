//! The one error type of the science core. Every variant names the quantity or
//! the data point at fault, so a caller can say which argument was wrong.

use thiserror::Error;

/// Result alias for the science core.
pub type Result<T, E = ScienceError> = std::result::Result<T, E>;

/// What can go wrong in the science core. No function of this crate panics on
/// user data or returns a silent NaN: it returns one of these instead.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ScienceError {
    /// A scalar input was NaN or infinite.
    #[error("{name} must be a finite number, got {value}")]
    NotFinite {
        /// The quantity, e.g. `"m_e_kg_m2"`.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A scalar input that must be strictly positive was not.
    #[error("{name} must be greater than zero, got {value}")]
    NotPositive {
        /// The quantity.
        name: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A scalar input lies outside its allowed interval.
    #[error("{name} must be in {allowed}, got {value}")]
    OutOfRange {
        /// The quantity.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// The allowed interval, written out, e.g. `"[0, 1)"`.
        allowed: &'static str,
    },
    /// The stiffness range has its bounds the wrong way round.
    #[error("stiffness range is reversed: k_min = {k_min} Nm/rad is above k_max = {k_max} Nm/rad")]
    ReversedRange {
        /// Lower bound given (Nm/rad).
        k_min: f64,
        /// Upper bound given (Nm/rad).
        k_max: f64,
    },
    /// An FRF point holds NaN or infinity.
    #[error(
        "FRF point {index} is not finite (omega = {omega} rad/s, value = {re} + {im}j Nm/rad)"
    )]
    NonFiniteData {
        /// Index of the point in the slice given.
        index: usize,
        /// Its frequency (rad/s).
        omega: f64,
        /// Real part of its value.
        re: f64,
        /// Imaginary part of its value.
        im: f64,
    },
    /// A data series holds a value outside the domain of the computation
    /// (e.g. a non-positive stiffness given to a log-log regression).
    #[error("{series}[{index}] = {value} is not allowed: {why}")]
    BadSample {
        /// Which series, e.g. `"k_nm_per_rad"`.
        series: &'static str,
        /// Index of the sample.
        index: usize,
        /// The value.
        value: f64,
        /// Why it is refused.
        why: &'static str,
    },
    /// Too few samples for the number of parameters to estimate.
    #[error("{what}: {needed} samples are needed, only {given} were given")]
    TooFewSamples {
        /// What was being estimated, e.g. `"fit of M3"`.
        what: String,
        /// The minimum number of samples.
        needed: usize,
        /// The number given.
        given: usize,
    },
    /// The least-squares problem has no unique solution.
    #[error("{what}: the design matrix is singular ({why})")]
    Singular {
        /// What was being estimated.
        what: String,
        /// A hint at the cause.
        why: &'static str,
    },
    /// Two slices that must pair up differ in length.
    #[error("{what}: {left} and {right} values do not pair up")]
    LengthMismatch {
        /// What was being computed.
        what: &'static str,
        /// Length of the first series.
        left: usize,
        /// Length of the second series.
        right: usize,
    },
    /// The design rules of the paper have no admissible answer for the inputs.
    #[error("{0}")]
    Infeasible(String),
}

/// Checks that `value` is finite.
pub(crate) fn finite(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ScienceError::NotFinite { name, value })
    }
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64> {
    finite(name, value)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(ScienceError::NotPositive { name, value })
    }
}
