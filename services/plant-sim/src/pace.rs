//! Simulated time held for a recorder (or an identifier whose estimates
//! feed the controller) that falls behind (lockstep only).
//!
//! In lockstep the plant alone advances simulated time, and a subscriber
//! whose buffers overflow loses samples (iceoryx2's safe overflow drops the
//! oldest: publishers never block). So before each frame the plant asks
//! [`OffPathPace::check`], one pace per process it waits for, whether that
//! process (its last [`OffPathProgress`]) is more than
//! [`OffPathProgress::MAX_LAG_FRAMES`] frames behind, and holds the frame
//! (bounded waits, in the process) until it has caught up. The pace is a
//! plain type: no IPC, no clock; the process feeds it the progress and
//! decides how long to wait.
//!
//! No progress heard: no recorder in this run, nothing to wait for. A
//! recorder that does not catch up within the process's patience is given
//! up ([`OffPathPace::give_up`]): simulated time goes on, the recorder
//! counts what it misses and `exo run` names it, and the plant waits for
//! it again only once it has taken further (or a new one has started).
//! A recorder that has died is not waited for at all ([`OffPathPace::forget`]);
//! `exo run` restarts it and holds simulated time itself while the new one
//! connects.

use exo_messages::OffPathProgress;

/// Whether the next frame may go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// The recorder keeps up (or there is none, or it was given up).
    Go,
    /// The recorder is `lag` frames behind, more than it may be.
    Hold {
        /// Frames published and not yet taken by the recorder.
        lag: u64,
    },
}

/// The recorder's pace as the plant sees it.
#[derive(Debug, Clone, Default)]
pub struct OffPathPace {
    last: Option<OffPathProgress>,
    /// The progress when the plant gave up waiting.
    given_up: Option<OffPathProgress>,
}

impl OffPathPace {
    /// Nothing heard yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes the recorder's latest progress. A recorder that was given up
    /// is waited for again once it has taken further, or once another
    /// recorder (a restart, a new segment) speaks.
    pub fn on_progress(&mut self, p: &OffPathProgress) {
        if let Some(g) = self.given_up {
            if p.pid != g.pid || p.segment != g.segment || p.frames_taken > g.frames_taken {
                self.given_up = None;
            }
        }
        self.last = Some(*p);
    }

    /// Whether frame `next_frame` (frames `0..next_frame` published) may
    /// be sent now.
    pub fn check(&self, next_frame: u64) -> Pace {
        match self.last {
            Some(p) if self.given_up.is_none() => {
                let lag = p.lag(next_frame);
                if lag > OffPathProgress::MAX_LAG_FRAMES {
                    Pace::Hold { lag }
                } else {
                    Pace::Go
                }
            }
            _ => Pace::Go,
        }
    }

    /// Stops waiting for the recorder as it is now (the process's patience
    /// ran out).
    pub fn give_up(&mut self) {
        self.given_up = self.last;
    }

    /// Forgets the recorder (it has died): nothing is waited for until a
    /// recorder speaks again.
    pub fn forget(&mut self) {
        self.last = None;
        self.given_up = None;
    }

    /// The last progress heard, if any.
    pub fn last(&self) -> Option<&OffPathProgress> {
        self.last.as_ref()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MAX: u64 = OffPathProgress::MAX_LAG_FRAMES;

    fn progress(segment: u32, frames_taken: u64) -> OffPathProgress {
        OffPathProgress {
            segment,
            frames_taken,
            ..Default::default()
        }
    }

    #[test]
    fn without_a_recorder_nothing_is_held() {
        let pace = OffPathPace::new();
        assert_eq!(pace.check(0), Pace::Go);
        assert_eq!(pace.check(u64::MAX), Pace::Go);
    }

    #[test]
    fn a_recorder_more_than_its_margin_behind_holds_the_next_frame() {
        let mut pace = OffPathPace::new();
        pace.on_progress(&progress(1, 1000));
        assert_eq!(pace.check(1000 + MAX), Pace::Go);
        assert_eq!(pace.check(1001 + MAX), Pace::Hold { lag: MAX + 1 });
        // It catches up: the frame goes.
        pace.on_progress(&progress(1, 1001));
        assert_eq!(pace.check(1001 + MAX), Pace::Go);
    }

    #[test]
    fn a_recorder_that_starts_again_is_waited_for_from_nothing() {
        // A restarted recorder's first word: nothing taken yet; the
        // plant holds until it has taken what the channels' history
        // gave it.
        let mut pace = OffPathPace::new();
        pace.on_progress(&progress(1, 50_000));
        pace.on_progress(&progress(2, 0));
        assert_eq!(pace.check(50_001), Pace::Hold { lag: 50_001 });
        pace.on_progress(&progress(2, 49_000));
        assert_eq!(pace.check(50_001), Pace::Go);
    }

    #[test]
    fn a_recorder_that_has_died_is_not_waited_for_until_one_speaks_again() {
        let mut pace = OffPathPace::new();
        pace.on_progress(&progress(1, 10));
        assert!(matches!(pace.check(20 + MAX), Pace::Hold { .. }));
        pace.forget();
        assert_eq!(pace.check(20 + MAX), Pace::Go);
        pace.on_progress(&progress(2, 0));
        assert!(matches!(pace.check(20 + MAX), Pace::Hold { .. }));
    }

    #[test]
    fn a_recorder_given_up_is_waited_for_again_once_it_moves() {
        let mut pace = OffPathPace::new();
        pace.on_progress(&progress(1, 10));
        let next = 20 + MAX;
        assert!(matches!(pace.check(next), Pace::Hold { .. }));
        pace.give_up();
        // The same word again (it still says 10): the run goes on.
        pace.on_progress(&progress(1, 10));
        assert_eq!(pace.check(next), Pace::Go);
        assert_eq!(pace.check(next + 100_000), Pace::Go);
        // It has taken further: it is waited for again.
        pace.on_progress(&progress(1, 11));
        assert!(matches!(pace.check(next + 100_000), Pace::Hold { .. }));
        // A new recorder after one given up is waited for too.
        pace.give_up();
        pace.on_progress(&progress(2, 0));
        assert!(matches!(pace.check(next), Pace::Hold { .. }));
    }
}
