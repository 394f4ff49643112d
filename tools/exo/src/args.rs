//! Value parsers for command-line numbers: NaN and infinity are refused at the
//! boundary, with the argument named by clap in the message.

/// A finite `f64`.
pub fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("must be a finite number, got {s}"))
    }
}

/// A finite `f64` strictly greater than zero.
pub fn positive(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be greater than zero, got {s}"))
    }
}

/// A fractional order in the open interval (0, 1).
pub fn fractional_order(s: &str) -> Result<f64, String> {
    let v = finite(s)?;
    if v > 0.0 && v < 1.0 {
        Ok(v)
    } else {
        Err(format!("the fractional order must lie in (0, 1), got {s}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsers_refuse_non_finite_and_out_of_range() {
        assert!(finite("nan").is_err());
        assert!(finite("inf").is_err());
        assert!(finite("abc").is_err());
        assert_eq!(finite(" 2.5 ").unwrap(), 2.5);
        assert!(positive("0").is_err());
        assert!(positive("-1").is_err());
        assert!(fractional_order("1").is_err());
        assert!(fractional_order("0").is_err());
        assert_eq!(fractional_order("0.44").unwrap(), 0.44);
    }
}
