//! Latency histograms, their percentiles, and the pass/miss verdicts.

use anyhow::{Context, Result};
use hdrhistogram::Histogram;

/// Largest latency a histogram holds (ns): 60 s. Larger values are clamped
/// to it (and the exact maximum is kept separately).
const HIGHEST_NS: u64 = 60_000_000_000;

/// A latency histogram (ns) with 3 significant digits (0.1 % resolution)
/// and the exact maximum.
pub struct Latency {
    hist: Histogram<u64>,
    max_ns: u64,
}

impl Latency {
    /// An empty histogram covering 1 ns to 60 s.
    pub fn new() -> Result<Self> {
        Ok(Latency {
            hist: Histogram::new_with_bounds(1, HIGHEST_NS, 3)
                .context("creating the latency histogram")?,
            max_ns: 0,
        })
    }

    /// Records one latency (ns); 0 is recorded as 1 ns.
    pub fn record(&mut self, ns: u64) {
        self.hist.saturating_record(ns.max(1));
        self.max_ns = self.max_ns.max(ns);
    }

    /// Number of recorded values.
    pub fn count(&self) -> u64 {
        self.hist.len()
    }

    /// The percentiles, or `None` when nothing was recorded.
    pub fn summary(&self) -> Option<Summary> {
        if self.hist.is_empty() {
            return None;
        }
        Some(Summary {
            count: self.hist.len(),
            p50_ns: self.hist.value_at_quantile(0.50),
            p99_ns: self.hist.value_at_quantile(0.99),
            p999_ns: self.hist.value_at_quantile(0.999),
            max_ns: self.max_ns,
            mean_ns: self.hist.mean(),
        })
    }
}

/// Percentiles of one histogram (ns). p50/p99/p99.9 are the histogram's
/// (within 0.1 %); the maximum is exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Number of values.
    pub count: u64,
    /// Median (ns).
    pub p50_ns: u64,
    /// 99th percentile (ns).
    pub p99_ns: u64,
    /// 99.9th percentile (ns).
    pub p999_ns: u64,
    /// Maximum (ns).
    pub max_ns: u64,
    /// Mean (ns).
    pub mean_ns: f64,
}

/// A duration in ns as microseconds for the table: one decimal below
/// 1000 µs, none above (e.g. `12.3`, `4521`).
pub fn fmt_us(ns: u64) -> String {
    let us = ns as f64 / 1000.0;
    if us < 1000.0 {
        format!("{us:.1}")
    } else {
        format!("{us:.0}")
    }
}

/// Which way a target goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Goal {
    /// The measured value must be at most the target.
    AtMost,
    /// The measured value must be at least the target.
    AtLeast,
}

/// `PASS` when `measured` meets `target` in the direction of `goal`,
/// `MISS` otherwise (also for NaN: nothing measured is not a pass).
pub fn verdict(measured: f64, target: f64, goal: Goal) -> &'static str {
    let ok = match goal {
        Goal::AtMost => measured <= target,
        Goal::AtLeast => measured >= target,
    };
    if ok {
        "PASS"
    } else {
        "MISS"
    }
}

/// The one-minute load average of the machine (`/proc/loadavg`), if readable.
pub fn load_average_1min() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn microseconds_have_one_decimal_below_a_millisecond() {
        assert_eq!(fmt_us(0), "0.0");
        assert_eq!(fmt_us(12_345), "12.3");
        assert_eq!(fmt_us(999_949), "999.9");
        assert_eq!(fmt_us(4_521_400), "4521");
    }

    #[test]
    fn verdicts_follow_the_goal_and_refuse_nan() {
        assert_eq!(verdict(2.9, 3.0, Goal::AtMost), "PASS");
        assert_eq!(verdict(3.0, 3.0, Goal::AtMost), "PASS");
        assert_eq!(verdict(3.1, 3.0, Goal::AtMost), "MISS");
        assert_eq!(verdict(49.0, 50.0, Goal::AtLeast), "MISS");
        assert_eq!(verdict(50.0, 50.0, Goal::AtLeast), "PASS");
        assert_eq!(verdict(f64::NAN, 3.0, Goal::AtMost), "MISS");
        assert_eq!(verdict(f64::NAN, 50.0, Goal::AtLeast), "MISS");
    }

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut l = Latency::new().unwrap();
        assert!(l.summary().is_none());
        // 1..=1000 µs, one each.
        for us in 1..=1000u64 {
            l.record(us * 1000);
        }
        let s = l.summary().unwrap();
        assert_eq!(s.count, 1000);
        let close = |got: u64, want: u64| (got as f64 - want as f64).abs() <= want as f64 * 1e-3;
        assert!(close(s.p50_ns, 500_000), "p50 {}", s.p50_ns);
        assert!(close(s.p99_ns, 990_000), "p99 {}", s.p99_ns);
        assert!(close(s.p999_ns, 999_000), "p99.9 {}", s.p999_ns);
        assert_eq!(s.max_ns, 1_000_000);
    }
}
