//! The analysis windows of a protocol stream, cut in one place
//! ([`WindowCutter`]) for the online identifier
//! (`exo_identifier::Identifier::on_protocol`, as the states stream in)
//! and every post-hoc reader ([`analysis_windows`]: `exo fit`'s time plots,
//! `exo diagnose`'s reduction). A window opens with a protocol state in
//! [`ProtocolPhase::Analysis`] and closes with the next state of another
//! phase ([`Closing::Phase`], the identifier's rule), or also with an
//! analysis state of another experiment or period
//! ([`Closing::PhaseOrPeriod`], the post-hoc readers'). The two differ only
//! when analysis states of two periods follow each other with no other
//! phase between, which the controller never publishes (every period
//! passes through `RampOut`).

use exo_messages::{ProtocolPhase, ProtocolState};

/// One analysis window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalysisWindow {
    /// The protocol state that opened it (experiment, period, sine, load, α …).
    pub state: ProtocolState,
    /// Its first time stamp (ns): the opening state's.
    pub start_ns: u64,
    /// The stamp (ns) of the state that closed it; `None` when the stream
    /// ended inside it.
    pub end_ns: Option<u64>,
}

impl AnalysisWindow {
    /// The window `p` opens (no end yet).
    pub fn opened_by(p: &ProtocolState) -> Self {
        AnalysisWindow {
            state: *p,
            start_ns: p.stamp_ns,
            end_ns: None,
        }
    }

    /// Whether time stamp `t_ns` lies in the window (`[start, end)`; an open
    /// window has no end).
    pub fn contains(&self, t_ns: u64) -> bool {
        t_ns >= self.start_ns && self.end_ns.is_none_or(|e| t_ns < e)
    }
}

/// What closes an open analysis window, besides the end of the stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Closing {
    /// The next state of another phase; an analysis state of another
    /// experiment or period right after one continues the window (the
    /// online identifier's rule: a window is the span of the phase).
    Phase,
    /// The next state of another phase, or an analysis state of another
    /// experiment or period, which closes the window and opens the next
    /// (the post-hoc readers' rule, [`analysis_windows`]).
    PhaseOrPeriod,
}

/// What one protocol state does to the windows ([`WindowCutter::next`]):
/// first the open window closes (if `closes_at`), then a new one opens (if
/// `opens`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Cut {
    /// The open window ends at this time stamp (ns): the state's.
    pub closes_at: Option<u64>,
    /// The state opens a window (it is the window's state, and its stamp
    /// the window's start).
    pub opens: bool,
}

/// The one window cutter: fed the protocol states in time order, it says
/// where analysis windows open and close under its [`Closing`] rule.
/// Allocation-free, a few bytes of state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WindowCutter {
    closing: Closing,
    /// (experiment, period) of the open window's state, if one is open.
    open: Option<(u32, u32)>,
}

impl WindowCutter {
    /// A cutter with no window open.
    pub fn new(closing: Closing) -> Self {
        WindowCutter {
            closing,
            open: None,
        }
    }

    /// Whether a window is open (its last state was an analysis state).
    pub fn is_open(&self) -> bool {
        self.open.is_some()
    }

    /// Takes the next protocol state; an unknown phase code counts as
    /// another phase than analysis.
    pub fn next(&mut self, p: &ProtocolState) -> Cut {
        let analysis = p.protocol_phase() == Some(ProtocolPhase::Analysis);
        let key = (p.experiment, p.period);
        let continues = analysis
            && match (self.open, self.closing) {
                (None, _) => false,
                (Some(_), Closing::Phase) => true,
                (Some(open), Closing::PhaseOrPeriod) => open == key,
            };
        if continues {
            return Cut::default();
        }
        let closes_at = self.open.take().map(|_| p.stamp_ns);
        if analysis {
            self.open = Some(key);
        }
        Cut {
            closes_at,
            opens: analysis,
        }
    }
}

/// Every analysis window of `protocol` (time-ordered states), in order, cut
/// with [`Closing::PhaseOrPeriod`].
pub fn analysis_windows(protocol: &[ProtocolState]) -> Vec<AnalysisWindow> {
    let mut cutter = WindowCutter::new(Closing::PhaseOrPeriod);
    let mut out = Vec::new();
    let mut open: Option<AnalysisWindow> = None;
    for p in protocol {
        let cut = cutter.next(p);
        if let Some(end) = cut.closes_at {
            if let Some(mut w) = open.take() {
                w.end_ns = Some(end);
                out.push(w);
            }
        }
        if cut.opens {
            open = Some(AnalysisWindow::opened_by(p));
        }
    }
    out.extend(open);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(experiment: u32, period: u32, phase: ProtocolPhase, stamp_ns: u64) -> ProtocolState {
        ProtocolState {
            experiment,
            period,
            phase: phase.as_u32(),
            stamp_ns,
            ..Default::default()
        }
    }

    /// A stream with a repeat, two periods' analysis states in a row and an
    /// open end.
    fn stream() -> Vec<ProtocolState> {
        use ProtocolPhase::*;
        vec![
            state(1, 1, Settling, 0),
            state(1, 1, Analysis, 10),
            state(1, 1, Analysis, 15), // the once-a-second repeat
            state(1, 1, RampOut, 20),
            state(1, 2, Analysis, 30),
            state(2, 1, Analysis, 40), // another experiment, no state between
            state(2, 1, Rest, 50),
            state(2, 2, Analysis, 60), // the stream ends inside it
        ]
    }

    #[test]
    fn a_window_runs_from_the_analysis_state_to_the_next_phase_or_period() {
        let w = analysis_windows(&stream());
        let spans: Vec<_> = w
            .iter()
            .map(|w| (w.state.experiment, w.state.period, w.start_ns, w.end_ns))
            .collect();
        assert_eq!(
            spans,
            [
                (1, 1, 10, Some(20)),
                (1, 2, 30, Some(40)),
                (2, 1, 40, Some(50)),
                (2, 2, 60, None)
            ]
        );
        assert!(w[0].contains(10) && w[0].contains(19) && !w[0].contains(20));
        assert!(!w[0].contains(9) && w[3].contains(u64::MAX));
    }

    /// The cutter's events over one stream under each rule.
    fn cuts(closing: Closing, p: &[ProtocolState]) -> Vec<Cut> {
        let mut c = WindowCutter::new(closing);
        p.iter().map(|p| c.next(p)).collect()
    }

    #[test]
    fn the_two_closing_rules_differ_only_at_analysis_states_of_two_periods_in_a_row() {
        let mut p = stream();
        p.push(ProtocolState {
            phase: 99, // an unknown phase code is not analysis
            ..state(2, 2, ProtocolPhase::Settling, 80)
        });
        let cut = |closes_at, opens| Cut { closes_at, opens };
        let expected = |at_40| {
            vec![
                cut(None, false),
                cut(None, true),
                cut(None, false), // the repeat continues the window
                cut(Some(20), false),
                cut(None, true),
                at_40,
                cut(Some(50), false),
                cut(None, true),
                cut(Some(80), false),
            ]
        };
        // Another experiment's analysis state right after one: closes and
        // opens under the post-hoc rule, continues under the identifier's.
        assert_eq!(
            cuts(Closing::PhaseOrPeriod, &p),
            expected(cut(Some(40), true))
        );
        assert_eq!(cuts(Closing::Phase, &p), expected(cut(None, false)));
        let mut c = WindowCutter::new(Closing::Phase);
        assert!(!c.is_open());
        c.next(&p[1]);
        assert!(c.is_open());
        c.next(&p[8]);
        assert!(!c.is_open());
    }
}
