//! The error a message fails validation with, naming the offending field.

use thiserror::Error;

/// Why a message was rejected at a process boundary. Every variant names the
/// message type and the field, so a log line says exactly what was wrong.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum MessageError {
    /// A floating-point field is NaN or infinite.
    #[error("{message}.{field} is not finite ({value})")]
    NonFinite {
        /// Message type, e.g. `"SensorSample"`.
        message: &'static str,
        /// Field, e.g. `"tau_c"`.
        field: &'static str,
        /// The value found.
        value: f64,
    },
    /// A field is finite but outside the limits it was checked against.
    #[error("{message}.{field} = {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// Message type.
        message: &'static str,
        /// Field.
        field: &'static str,
        /// The value found (integer fields are converted to `f64`).
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// An enum-like `u32` field holds a value with no meaning.
    #[error("{message}.{field} = {value} is not a known code")]
    UnknownCode {
        /// Message type.
        message: &'static str,
        /// Field.
        field: &'static str,
        /// The value found.
        value: u32,
    },
    /// A bit-flag field sets bits that have no meaning.
    #[error("{message}.{field} = {value:#x} sets unknown bits {unknown:#x}")]
    UnknownFlags {
        /// Message type.
        message: &'static str,
        /// Field.
        field: &'static str,
        /// The value found.
        value: u32,
        /// The bits without a meaning.
        unknown: u32,
    },
}

impl MessageError {
    /// The message type the error is about, e.g. `"SensorSample"`.
    pub fn message(&self) -> &'static str {
        match *self {
            MessageError::NonFinite { message, .. }
            | MessageError::OutOfRange { message, .. }
            | MessageError::UnknownCode { message, .. }
            | MessageError::UnknownFlags { message, .. } => message,
        }
    }

    /// The offending field, e.g. `"tau_c"` or `"cuff_wrench[3]"`.
    pub fn field(&self) -> &'static str {
        match *self {
            MessageError::NonFinite { field, .. }
            | MessageError::OutOfRange { field, .. }
            | MessageError::UnknownCode { field, .. }
            | MessageError::UnknownFlags { field, .. } => field,
        }
    }
}

/// The first `(field, value)` pair whose value is NaN or infinite.
pub(crate) fn first_non_finite<const N: usize>(
    fields: [(&'static str, f64); N],
) -> Option<(&'static str, f64)> {
    fields.into_iter().find(|(_, v)| !v.is_finite())
}

/// `Err(NonFinite)` for the first non-finite field.
pub(crate) fn check_finite(
    message: &'static str,
    first: Option<(&'static str, f64)>,
) -> Result<(), MessageError> {
    match first {
        None => Ok(()),
        Some((field, value)) => Err(MessageError::NonFinite {
            message,
            field,
            value,
        }),
    }
}

/// `Err(OutOfRange)` unless `min <= value <= max` (NaN is out of range).
pub(crate) fn check_range(
    message: &'static str,
    field: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<(), MessageError> {
    if value >= min && value <= max {
        Ok(())
    } else {
        Err(MessageError::OutOfRange {
            message,
            field,
            value,
            min,
            max,
        })
    }
}

/// `Err(OutOfRange)` unless `|value| <= abs_max`.
pub(crate) fn check_abs(
    message: &'static str,
    field: &'static str,
    value: f64,
    abs_max: f64,
) -> Result<(), MessageError> {
    check_range(message, field, value, -abs_max, abs_max)
}

/// `Err(UnknownFlags)` if `value` sets a bit outside `known`.
pub(crate) fn check_flags(
    message: &'static str,
    field: &'static str,
    value: u32,
    known: u32,
) -> Result<(), MessageError> {
    let unknown = value & !known;
    if unknown == 0 {
        Ok(())
    } else {
        Err(MessageError::UnknownFlags {
            message,
            field,
            value,
            unknown,
        })
    }
}
