//! The frequency bands the located mismatch ([`crate::engine`]) and the
//! characterisation of what remains ([`crate::remains`]) summarise by: one
//! place, below both, so neither imports the other for it.

/// The frequency band of ω (rad/s) the location and the characterisation of
/// what remains summarise by.
pub(crate) fn band_of(w: f64) -> &'static str {
    if w < 4.0 {
        "low (< 4 rad/s)"
    } else if w < 10.0 {
        "mid (4–10 rad/s)"
    } else {
        "high (≥ 10 rad/s)"
    }
}
