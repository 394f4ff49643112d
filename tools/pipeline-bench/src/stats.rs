//! The pass/miss verdicts, the machine's load, and the latency histograms
//! (shared with the services: `exo_service_kit::latency`).

pub use exo_service_kit::latency::{fmt_us, Latency, Summary};

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
    fn verdicts_follow_the_goal_and_refuse_nan() {
        assert_eq!(verdict(2.9, 3.0, Goal::AtMost), "PASS");
        assert_eq!(verdict(3.0, 3.0, Goal::AtMost), "PASS");
        assert_eq!(verdict(3.1, 3.0, Goal::AtMost), "MISS");
        assert_eq!(verdict(49.0, 50.0, Goal::AtLeast), "MISS");
        assert_eq!(verdict(50.0, 50.0, Goal::AtLeast), "PASS");
        assert_eq!(verdict(f64::NAN, 3.0, Goal::AtMost), "MISS");
        assert_eq!(verdict(f64::NAN, 50.0, Goal::AtLeast), "MISS");
    }
}
