//! How far the identifier has taken the run, for the lockstep plant
//! (`exo/identifier/progress`, [`OffPathProgress`]): the frames whose sample
//! and the command answering it it has taken, and the samples it missed
//! (sequence gaps). A plain type: the process feeds it what it takes.

use exo_messages::{status, ActuatorCommand, OffPathProgress, SensorSample};

/// What the identifier has taken.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Taken {
    sample: Option<u64>,
    answered: Option<u64>,
    /// Samples missed (sum of the gaps in `exo/sensor`'s seq).
    pub missed: u64,
    /// The first sample seq missed, if any was.
    pub first_missing: Option<u64>,
}

impl Taken {
    /// Accounts for one sample taken. A gap before a sample the driver
    /// flags `FRAMES_SKIPPED` is the driver's own, not missed here; a
    /// sample re-sent (the same seq) or older is not a gap.
    pub fn on_sample(&mut self, s: &SensorSample) {
        if let Some(last) = self.sample {
            if s.seq > last + 1 && s.status & status::FRAMES_SKIPPED == 0 {
                self.missed += s.seq - last - 1;
                self.first_missing.get_or_insert(last + 1);
            }
        }
        self.sample = self.sample.max(Some(s.seq));
    }

    /// Accounts for one command taken.
    pub fn on_command(&mut self, c: &ActuatorCommand) {
        self.answered = self.answered.max(Some(c.sensor_seq));
    }

    /// [`OffPathProgress::frames_taken`]: one more than the highest frame
    /// through which both the sample and the command answering it were
    /// taken; 0 before both.
    pub fn frames(&self) -> u64 {
        match (self.sample, self.answered) {
            (Some(s), Some(c)) => s.min(c) + 1,
            _ => 0,
        }
    }

    /// Whether `p` says what this does (nothing new to publish).
    pub fn told(&self, p: &OffPathProgress) -> bool {
        (p.frames_taken, p.missed) == (self.frames(), self.missed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: u64) -> SensorSample {
        SensorSample {
            seq,
            ..Default::default()
        }
    }

    #[test]
    fn a_frame_is_taken_once_its_command_is_and_gaps_are_missed_samples() {
        let mut t = Taken::default();
        assert_eq!(t.frames(), 0);
        t.on_sample(&sample(0));
        assert_eq!(t.frames(), 0, "its command not yet taken");
        t.on_command(&ActuatorCommand {
            sensor_seq: 0,
            ..Default::default()
        });
        assert_eq!(t.frames(), 1);
        t.on_sample(&sample(1));
        t.on_sample(&sample(1)); // re-sent: no gap
        t.on_sample(&sample(5)); // 2, 3, 4 missed
        t.on_sample(&SensorSample {
            seq: 8,
            status: status::FRAMES_SKIPPED,
            ..Default::default()
        }); // the driver's own gap
        assert_eq!((t.missed, t.first_missing), (3, Some(2)));
        t.on_command(&ActuatorCommand {
            sensor_seq: 8,
            ..Default::default()
        });
        assert_eq!(t.frames(), 9);
        let told = OffPathProgress {
            frames_taken: 9,
            missed: 3,
            ..Default::default()
        };
        assert!(t.told(&told));
    }
}
