//! Latency histograms: allocation-free recording (usable on the real-time
//! path once created), percentiles from an HDR histogram with 3 significant
//! digits, and the exact maximum.

use serde::{Deserialize, Serialize};

/// Largest latency a histogram holds (ns): 60 s. Larger values are clamped
/// to it (the exact maximum is kept separately).
const HIGHEST_NS: u64 = 60_000_000_000;

/// A latency histogram (ns) with 3 significant digits (0.1 % resolution)
/// and the exact maximum. [`Latency::record`] never allocates: the buckets
/// for 1 ns … 60 s are allocated by [`Latency::new`].
#[derive(Debug, Clone)]
pub struct Latency {
    hist: hdrhistogram::Histogram<u64>,
    max_ns: u64,
}

impl Latency {
    /// An empty histogram covering 1 ns to 60 s (about 300 kB).
    pub fn new() -> Self {
        // The bounds are constants within hdrhistogram's limits (low ≥ 1,
        // high ≥ 2·low, 3 significant digits ≤ 5): creation cannot fail.
        let hist = hdrhistogram::Histogram::new_with_bounds(1, HIGHEST_NS, 3)
            .unwrap_or_else(|e| unreachable!("constant histogram bounds rejected: {e}"));
        Latency { hist, max_ns: 0 }
    }

    /// Records one latency (ns); 0 is recorded as 1 ns, values above 60 s
    /// as 60 s (the maximum stays exact). Never allocates.
    #[inline]
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

impl Default for Latency {
    fn default() -> Self {
        Latency::new()
    }
}

/// Percentiles of one histogram (ns). p50/p99/p99.9 are the histogram's
/// (within 0.1 %); the maximum is exact.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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

/// A duration in ns as microseconds for tables and logs: one decimal below
/// 1000 µs, none above (e.g. `12.3`, `4521`).
pub fn fmt_us(ns: u64) -> String {
    let us = ns as f64 / 1000.0;
    if us < 1000.0 {
        format!("{us:.1}")
    } else {
        format!("{us:.0}")
    }
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
    fn percentiles_of_a_known_distribution() {
        let mut l = Latency::new();
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

    #[test]
    fn values_beyond_the_range_are_clamped_but_the_maximum_is_exact() {
        let mut l = Latency::new();
        l.record(0);
        l.record(120_000_000_000);
        let s = l.summary().unwrap();
        assert_eq!(s.count, 2);
        assert_eq!(s.max_ns, 120_000_000_000);
        assert!(s.p99_ns <= HIGHEST_NS + HIGHEST_NS / 1000, "{}", s.p99_ns);
    }
}
