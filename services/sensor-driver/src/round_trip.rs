//! The control round trip as the driver sees it: from just before it
//! publishes a `SensorSample` to just after it receives the controller's
//! `ActuatorCommand` answering that sample (sensor → controller → driver).
//! The same interval a bare ping-pong measures, taken inside the loop, so
//! the bus (simulator or hardware) is not in it.

use exo_service_kit::latency::{Latency, Summary};
use serde::Serialize;

/// Round-trip statistics of one run. Recording never allocates (the
/// histogram is allocated by [`RoundTrip::new`]); the first `warmup_ns`
/// after the first recorded round trip are left out (connection set-up,
/// page faults, cold caches).
#[derive(Debug, Clone)]
pub struct RoundTrip {
    latency: Latency,
    warmup_ns: u64,
    first_sent_ns: Option<u64>,
    window: Option<(u64, u64)>,
    skipped: u64,
}

/// What [`RoundTrip::report`] gives: the percentiles and the window they
/// cover.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RoundTripReport {
    /// Warm-up left out (s).
    pub warmup_s: f64,
    /// From the first to the last recorded round trip's send time (s).
    pub window_s: f64,
    /// Round trips inside the warm-up, not recorded.
    pub skipped: u64,
    /// Percentiles of the recorded round trips (ns).
    #[serde(flatten)]
    pub latency: Summary,
}

impl RoundTrip {
    /// Empty statistics that leave out the first `warmup_s` seconds
    /// (negative or non-finite: none).
    pub fn new(warmup_s: f64) -> Self {
        let warmup_ns = if warmup_s.is_finite() && warmup_s > 0.0 {
            (warmup_s * 1e9) as u64
        } else {
            0
        };
        RoundTrip {
            latency: Latency::new(),
            warmup_ns,
            first_sent_ns: None,
            window: None,
            skipped: 0,
        }
    }

    /// Counts the warm-up from `origin_ns` (`CLOCK_MONOTONIC`, ns) rather
    /// than from the first round trip recorded, so that statistics fed
    /// from different points of one cycle leave out the same stretch.
    pub fn start_warmup_at(&mut self, origin_ns: u64) {
        self.first_sent_ns = Some(origin_ns);
    }

    /// One round trip: the sample was published at `sent_ns` and its
    /// command received at `received_ns` (both `CLOCK_MONOTONIC`, ns).
    #[inline]
    pub fn record(&mut self, sent_ns: u64, received_ns: u64) {
        let first = *self.first_sent_ns.get_or_insert(sent_ns);
        if sent_ns < first.saturating_add(self.warmup_ns) {
            self.skipped += 1;
            return;
        }
        self.latency.record(received_ns.saturating_sub(sent_ns));
        self.window = Some(match self.window {
            None => (sent_ns, sent_ns),
            Some((a, _)) => (a, sent_ns),
        });
    }

    /// The percentiles after the warm-up, or `None` if none was recorded.
    pub fn report(&self) -> Option<RoundTripReport> {
        let latency = self.latency.summary()?;
        let (a, b) = self.window?;
        Some(RoundTripReport {
            warmup_s: self.warmup_ns as f64 * 1e-9,
            window_s: (b - a) as f64 * 1e-9,
            skipped: self.skipped,
            latency,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_warm_up_is_left_out_and_the_window_spans_the_rest() {
        let mut rt = RoundTrip::new(0.5);
        assert!(rt.report().is_none());
        // 1 kHz for 2 s: round trips of 100 µs in the first 0.5 s, 40 µs after.
        for k in 0..2000u64 {
            let sent = 1_000_000_000 + k * 1_000_000;
            let rtt = if k < 500 { 100_000 } else { 40_000 };
            rt.record(sent, sent + rtt);
        }
        let r = rt.report().unwrap();
        assert_eq!(r.skipped, 500);
        assert_eq!(r.latency.count, 1500);
        assert_eq!(r.latency.max_ns, 40_000);
        assert!((r.window_s - 1.499).abs() < 1e-9, "{}", r.window_s);
        assert_eq!(r.warmup_s, 0.5);
    }

    /// With the warm-up counted from an origin 0.2 s before the first
    /// round trip, 0.3 s of a 0.5 s warm-up is left: at 1 kHz, 300 skipped.
    #[test]
    fn a_warm_up_from_a_given_origin_leaves_out_less() {
        let mut rt = RoundTrip::new(0.5);
        rt.start_warmup_at(800_000_000);
        for k in 0..1000u64 {
            let sent = 1_000_000_000 + k * 1_000_000;
            rt.record(sent, sent + 10_000);
        }
        let r = rt.report().unwrap();
        assert_eq!((r.skipped, r.latency.count), (300, 700));
    }

    #[test]
    fn no_warm_up_records_everything_and_a_reversed_clock_counts_zero() {
        let mut rt = RoundTrip::new(f64::NAN);
        rt.record(10, 5);
        rt.record(20, 70);
        let r = rt.report().unwrap();
        assert_eq!(r.latency.count, 2);
        assert_eq!(r.latency.max_ns, 50);
        assert_eq!(r.skipped, 0);
    }

    #[test]
    fn the_report_is_json_with_flat_percentiles() {
        let mut rt = RoundTrip::new(0.0);
        rt.record(0, 30_000);
        let v = serde_json::to_value(rt.report().unwrap()).unwrap();
        assert_eq!(v["count"], 1);
        assert!(v["p99_ns"].as_u64().unwrap() >= 29_970);
        assert!(v.get("window_s").is_some());
    }
}
