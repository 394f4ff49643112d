//! The analysis windows of a protocol stream, cut in one place for every
//! post-hoc reader (`exo fit`'s time plots, `exo diagnose`'s reduction): a
//! window opens with a protocol state in [`ProtocolPhase::Analysis`] and
//! closes with the next state of another phase, or of another experiment
//! or period. (The online identifier cuts the same windows as the states
//! stream in, `exo_identifier::Identifier::on_protocol`.)

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
    /// Whether time stamp `t_ns` lies in the window (`[start, end)`; an open
    /// window has no end).
    pub fn contains(&self, t_ns: u64) -> bool {
        t_ns >= self.start_ns && self.end_ns.is_none_or(|e| t_ns < e)
    }
}

/// Every analysis window of `protocol` (time-ordered states), in order.
pub fn analysis_windows(protocol: &[ProtocolState]) -> Vec<AnalysisWindow> {
    let analysis = Some(ProtocolPhase::Analysis);
    let mut out = Vec::new();
    let mut open: Option<AnalysisWindow> = None;
    for p in protocol {
        let same = open
            .as_ref()
            .is_some_and(|w| (w.state.experiment, w.state.period) == (p.experiment, p.period));
        if p.protocol_phase() == analysis && same {
            continue;
        }
        if let Some(mut w) = open.take() {
            w.end_ns = Some(p.stamp_ns);
            out.push(w);
        }
        if p.protocol_phase() == analysis {
            open = Some(AnalysisWindow {
                state: *p,
                start_ns: p.stamp_ns,
                end_ns: None,
            });
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

    #[test]
    fn a_window_runs_from_the_analysis_state_to_the_next_phase_or_period() {
        use ProtocolPhase::*;
        let p = [
            state(1, 1, Settling, 0),
            state(1, 1, Analysis, 10),
            state(1, 1, Analysis, 15), // the once-a-second repeat
            state(1, 1, RampOut, 20),
            state(1, 2, Analysis, 30),
            state(2, 1, Analysis, 40), // another experiment, no state between
            state(2, 1, Rest, 50),
            state(2, 2, Analysis, 60), // the stream ends inside it
        ];
        let w = analysis_windows(&p);
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
}
