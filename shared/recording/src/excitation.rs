//! The periodic excitation a run applied, as the `exo` metadata record
//! says it (issue 34 item 1; `docs/recording-format.md`, keys appended to
//! the contract): for a multisine run, the period's length in samples and
//! each excited line's bin, relative amplitude and phase. With the
//! protocol states' `amplitude` (each experiment's peak torque, Nm) they
//! give the excitation of every period: `τ_x[n] = amplitude · Σ_l a_l
//! cos(2π b_l n / N + φ_l)` from the start of the settling window. A
//! recording without these keys had no designed periodic excitation (the
//! sine steps, or a broadband record): its broadband windows are then
//! estimated by Welch's method.

use std::collections::BTreeMap;

/// `excitation`: `"multisine"` when the keys below are present.
pub const EXCITATION: &str = "excitation";
/// `multisine_period_samples`: samples in one period (a whole number).
pub const PERIOD_SAMPLES: &str = "multisine_period_samples";
/// `multisine_bins`: the excited bins (cycles per period), comma-separated.
pub const BINS: &str = "multisine_bins";
/// `multisine_amplitudes`: each line's amplitude relative to the peak.
pub const AMPLITUDES: &str = "multisine_amplitudes";
/// `multisine_phases_rad`: each line's phase (rad) at sample 0 of a period.
pub const PHASES_RAD: &str = "multisine_phases_rad";

/// The lines of a periodic multisine, as recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct MultisineLines {
    /// Samples in one period.
    pub period_samples: usize,
    /// Excited bins (cycles per period), increasing.
    pub bins: Vec<usize>,
    /// Each line's amplitude, relative to the excitation's peak.
    pub amplitudes: Vec<f64>,
    /// Each line's phase (rad) at sample 0 of a period.
    pub phases_rad: Vec<f64>,
}

impl MultisineLines {
    /// Adds the keys to an `exo` metadata map.
    pub fn write_to(&self, meta: &mut BTreeMap<String, String>) {
        let join = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(",")
        };
        meta.insert(EXCITATION.into(), "multisine".into());
        meta.insert(PERIOD_SAMPLES.into(), self.period_samples.to_string());
        meta.insert(
            BINS.into(),
            self.bins
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(","),
        );
        meta.insert(AMPLITUDES.into(), join(&self.amplitudes));
        meta.insert(PHASES_RAD.into(), join(&self.phases_rad));
    }

    /// The lines an `exo` metadata record names (`meta` looks a key up):
    /// `Ok(None)` when it names no multisine (no `excitation` key, or
    /// another excitation); an error naming the key when one is missing,
    /// is not a number, is not finite, or the lists' lengths differ, or a
    /// bin is 0, not below Nyquist or named twice.
    pub fn read_from<'a>(meta: impl Fn(&str) -> Option<&'a str>) -> Result<Option<Self>, String> {
        if meta(EXCITATION) != Some("multisine") {
            return Ok(None);
        }
        let get = |key: &str| meta(key).ok_or_else(|| format!("metadata {key} is missing"));
        let period_samples: usize = get(PERIOD_SAMPLES)?
            .trim()
            .parse()
            .map_err(|e| format!("metadata {PERIOD_SAMPLES}: {e}"))?;
        let bins = get(BINS)?
            .split(',')
            .map(|b| b.trim().parse::<usize>())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("metadata {BINS}: {e}"))?;
        let floats = |key: &str| -> Result<Vec<f64>, String> {
            let v = get(key)?
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| format!("metadata {key}: {e}"))?;
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(format!("metadata {key}: {x} is not finite"));
            }
            if v.len() != bins.len() {
                return Err(format!(
                    "metadata {key}: {} values for {} bins",
                    v.len(),
                    bins.len()
                ));
            }
            Ok(v)
        };
        let (amplitudes, phases_rad) = (floats(AMPLITUDES)?, floats(PHASES_RAD)?);
        for (i, &b) in bins.iter().enumerate() {
            if b == 0 || 2 * b >= period_samples || bins[..i].contains(&b) {
                return Err(format!(
                    "metadata {BINS}: bin {b} is 0, not below Nyquist of a {period_samples}-sample period, or named twice"
                ));
            }
        }
        Ok(Some(MultisineLines {
            period_samples,
            bins,
            amplitudes,
            phases_rad,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines() -> MultisineLines {
        MultisineLines {
            period_samples: 10_000,
            bins: vec![4, 7, 12],
            amplitudes: vec![0.3, 0.3, 0.3],
            phases_rad: vec![0.0, -1.25, 2.5],
        }
    }

    #[test]
    fn lines_written_are_read_back_exactly() {
        let mut m = BTreeMap::new();
        lines().write_to(&mut m);
        assert_eq!(m[BINS], "4,7,12");
        assert_eq!(m[PERIOD_SAMPLES], "10000");
        let back = MultisineLines::read_from(|k| m.get(k).map(String::as_str)).unwrap();
        assert_eq!(back, Some(lines()));
    }

    #[test]
    fn a_record_without_a_multisine_names_none() {
        let m: BTreeMap<String, String> = BTreeMap::new();
        assert_eq!(
            MultisineLines::read_from(|k| m.get(k).map(String::as_str)),
            Ok(None)
        );
    }

    #[test]
    fn a_bad_key_is_named() {
        let cases: [(&str, &str, &str); 6] = [
            (BINS, "4,x,12", BINS),
            (BINS, "4,7,7", BINS),
            (BINS, "4,7,5000", BINS),
            (PERIOD_SAMPLES, "ten", PERIOD_SAMPLES),
            (AMPLITUDES, "0.3,0.3", AMPLITUDES),
            (PHASES_RAD, "0.0,NaN,1.0", PHASES_RAD),
        ];
        for (key, value, named) in cases {
            let mut m = BTreeMap::new();
            lines().write_to(&mut m);
            m.insert(key.to_string(), value.to_string());
            let err = MultisineLines::read_from(|k| m.get(k).map(String::as_str)).unwrap_err();
            assert!(err.contains(named), "{key} = {value}: {err}");
        }
        let mut m = BTreeMap::new();
        lines().write_to(&mut m);
        m.remove(PHASES_RAD);
        let err = MultisineLines::read_from(|k| m.get(k).map(String::as_str)).unwrap_err();
        assert!(err.contains("missing") && err.contains(PHASES_RAD), "{err}");
    }
}
