//! What the identifier produces ([`Event`]) and the log line of each,
//! as the identifier process writes it.

use exo_messages::{FitModel, FrfPoint, ImpedanceEstimate};

/// What the identifier produced.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A new FRF point.
    Frf(FrfPoint),
    /// A refit after a window (one per model fitted).
    Estimate(ImpedanceEstimate),
    /// Something could not be used or computed, and why.
    Warning(String),
    /// A note of the online refit (a model not fitted yet, no power law or
    /// recommended f yet): of interest live, not to a post-hoc analysis
    /// that fits every experiment itself.
    RefitNote(String),
}

impl Event {
    /// Logs the event as the identifier process does: [`Event::line`] at
    /// its level.
    pub fn log(&self) {
        match self.line() {
            Some((tracing::Level::WARN, line)) => tracing::warn!("{line}"),
            Some((_, line)) => tracing::info!("{line}"),
            None => {}
        }
    }

    /// The event's log line and its level: each FRF point, the M2 refit
    /// with its F-test and recommended f (the other models' refits have
    /// none), warnings as warnings, refit notes as information.
    pub fn line(&self) -> Option<(tracing::Level, String)> {
        use tracing::Level;
        match self {
            Event::Frf(p) => Some((
                Level::INFO,
                format!(
                    "identifier: experiment {} period {}: S_h({:.2} rad/s) = {:.2}{:+.2}j Nm/rad, coherence {:.3}",
                    p.experiment, p.period, p.omega, p.s_h_re, p.s_h_im, p.coherence
                ),
            )),
            Event::Estimate(e) if FitModel::from_u32(e.model) == Some(FitModel::M2) => {
                let f_test = if e.f_critical > 0.0 {
                    format!("F(M1−M3) = {:.1} (critical {:.2})", e.f_m1_m3, e.f_critical)
                } else {
                    "no F-tests yet (M3 needs 3 points)".to_string()
                };
                let f = if e.recommended_f > 0.0 {
                    format!("; recommended f = {:.3}", e.recommended_f)
                } else {
                    String::new()
                };
                Some((
                    Level::INFO,
                    format!(
                        "identifier: experiment {} M2 after {} points: K = {:.2} ± {:.2}, H = {:.2} ± {:.2} Nm/rad, M_h = {:.3} ± {:.3} kg·m², R² = {:.3}; {f_test}{f}",
                        e.experiment, e.n_points, e.k_h, e.k_h_se, e.h_h, e.h_h_se, e.m_h, e.m_h_se, e.r2
                    ),
                ))
            }
            Event::Estimate(_) => None,
            Event::Warning(w) => Some((Level::WARN, format!("identifier: {w}"))),
            Event::RefitNote(w) => Some((Level::INFO, format!("identifier: {w}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `log` writes [`Event::line`] at its level, and nothing for a line
    /// that is `None` (captured by a subscriber of the test's own).
    #[test]
    fn log_writes_the_line_at_its_level() {
        use std::sync::{Arc, Mutex};
        #[derive(Clone, Default)]
        struct Buf(Arc<Mutex<Vec<u8>>>);
        impl std::io::Write for Buf {
            fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
                self.0.lock().unwrap().extend_from_slice(b);
                Ok(b.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let buf = Buf::default();
        let writer = buf.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_writer(move || writer.clone())
            .with_ansi(false)
            .without_time()
            .with_target(false)
            .finish();
        tracing::subscriber::with_default(subscriber, || {
            Event::Warning("w1".into()).log();
            Event::RefitNote("n1".into()).log();
            Event::Estimate(ImpedanceEstimate {
                model: FitModel::M1 as u32,
                ..ImpedanceEstimate::default()
            })
            .log();
        });
        let text = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
        assert_eq!(
            text.lines().collect::<Vec<_>>(),
            [" WARN identifier: w1", " INFO identifier: n1"],
            "{text}"
        );
    }

    /// Each event's line, written out by hand: the FRF point's S_h, the M2
    /// refit with its F-test (or none yet) and recommended f (or none),
    /// nothing for the other models, warnings at WARN.
    #[test]
    fn each_event_logs_its_own_line_at_its_level() {
        use tracing::Level;
        let p = FrfPoint {
            experiment: 4,
            period: 2,
            omega: 2.5179,
            s_h_re: 40.123,
            s_h_im: -3.456,
            coherence: 0.98765,
            ..FrfPoint::default()
        };
        assert_eq!(
            Event::Frf(p).line(),
            Some((
                Level::INFO,
                "identifier: experiment 4 period 2: S_h(2.52 rad/s) = 40.12-3.46j Nm/rad, coherence 0.988".into()
            ))
        );
        let m2 = ImpedanceEstimate {
            experiment: 7,
            n_points: 10,
            model: FitModel::M2 as u32,
            k_h: 80.0,
            k_h_se: 1.5,
            h_h: 12.25,
            h_h_se: 0.5,
            m_h: 0.08,
            m_h_se: 0.004,
            r2: 0.9991,
            f_m1_m3: 12.34,
            f_critical: 4.46,
            recommended_f: 0.456,
            ..ImpedanceEstimate::default()
        };
        let head = "identifier: experiment 7 M2 after 10 points: K = 80.00 ± 1.50, H = 12.25 ± 0.50 Nm/rad, M_h = 0.080 ± 0.004 kg·m², R² = 0.999; ";
        let line = |e: ImpedanceEstimate| Event::Estimate(e).line();
        assert_eq!(
            line(m2),
            Some((
                Level::INFO,
                format!("{head}F(M1−M3) = 12.3 (critical 4.46); recommended f = 0.456")
            ))
        );
        let early = ImpedanceEstimate {
            f_critical: 0.0,
            recommended_f: 0.0,
            ..m2
        };
        assert_eq!(
            line(early),
            Some((
                Level::INFO,
                format!("{head}no F-tests yet (M3 needs 3 points)")
            ))
        );
        for other in [FitModel::M1, FitModel::M3] {
            let e = ImpedanceEstimate {
                model: other as u32,
                ..m2
            };
            assert_eq!(line(e), None, "{other:?}");
        }
        assert_eq!(
            Event::Warning("w".into()).line(),
            Some((Level::WARN, "identifier: w".into()))
        );
        assert_eq!(
            Event::RefitNote("n".into()).line(),
            Some((Level::INFO, "identifier: n".into()))
        );
    }
}
