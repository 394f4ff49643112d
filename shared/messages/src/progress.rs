//! How far a process off the control path has taken the run: recorder,
//! identifier → plant simulator (lockstep).
//!
//! In lockstep simulated time is the plant's to advance, and a subscriber
//! that falls behind by more than its buffers hold loses samples
//! (iceoryx2's safe overflow drops the oldest). The recorder (always) and
//! the identifier (when its estimates feed the controller,
//! `controller.adopt_recommended_f`, `protocol.stop_when`) therefore say how far they have taken
//! the run, each on its own channel, and the plant holds the next frame
//! while one is more than [`OffPathProgress::MAX_LAG_FRAMES`] frames
//! behind. In real time nobody reads them: control never waits, and what
//! the recorder misses it counts and names (`exo.drops`).

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

/// How far a process off the control path has taken the run. The
/// recorder: the frames whose bus frame and the motor command answering it
/// it has taken out of its subscriber buffers and queued for its writing
/// thread (in lockstep it never discards what it has taken: when the
/// writing thread is behind by its whole queue, a slow disk, it stops
/// taking, so its progress stops and the plant holds). The identifier:
/// the frames whose sample and the command answering it it has taken.
///
/// 40 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.OffPathProgress.v1")
)]
#[repr(C)]
pub struct OffPathProgress {
    /// Progress message sequence number (count), from 0 in each recorder
    /// process.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when it was published.
    pub stamp_ns: u64,
    /// Frames taken (count): one more than the highest frame `seq` through
    /// which the process has taken both channels it counts (recorder:
    /// `bus/sensor` and the `bus/motor` command answering it; identifier:
    /// `sensor` and the `command` answering it); 0 before it has taken any.
    pub frames_taken: u64,
    /// Samples missed so far (count; sequence gaps): the recorder's over
    /// every recorded channel in what it wrote, the identifier's in the
    /// samples it took.
    pub missed: u64,
    /// The segment of the run's recording this recorder writes (1 = the
    /// first file, 2 = `…-part2.mcap` after a restart, …); 0 from the
    /// identifier.
    pub segment: u32,
    /// The process id, by which a holding plant tells a stopped process
    /// (waited for) from a dead one (not waited for) and a restarted one
    /// from the one before.
    pub pid: u32,
}

impl OffPathProgress {
    /// How many frames a process may be behind before the lockstep plant
    /// holds its next frame: half the subscriber buffer the recorder and
    /// the identifier hold on each channel (`max_buffer` of the tick-rate
    /// channels in the channel table, 8192). The other half is the margin
    /// for what they take on their other channels in one pass.
    pub const MAX_LAG_FRAMES: u64 =
        crate::channels::Channel::BusSensor.info().max_buffer as u64 / 2;

    /// How many frames the process is behind when the plant is about to
    /// send frame `next_frame` (frames `0..next_frame` published).
    pub fn lag(&self, next_frame: u64) -> u64 {
        next_frame.saturating_sub(self.frames_taken)
    }
}

impl crate::Message for OffPathProgress {
    const TYPE_NAME: &'static str = "exo.OffPathProgress.v1";
    const NAME: &'static str = "OffPathProgress";

    /// No floating-point field.
    fn first_non_finite(&self) -> Option<(&'static str, f64)> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn progress_layout() {
        assert_eq!(size_of::<OffPathProgress>(), 40);
        assert_eq!(align_of::<OffPathProgress>(), 8);
        assert_eq!(offset_of!(OffPathProgress, seq), 0);
        assert_eq!(offset_of!(OffPathProgress, stamp_ns), 8);
        assert_eq!(offset_of!(OffPathProgress, frames_taken), 16);
        assert_eq!(offset_of!(OffPathProgress, missed), 24);
        assert_eq!(offset_of!(OffPathProgress, segment), 32);
        assert_eq!(offset_of!(OffPathProgress, pid), 36);
    }

    #[test]
    fn the_lag_is_the_frames_published_and_not_taken() {
        let p = OffPathProgress {
            frames_taken: 100,
            ..Default::default()
        };
        assert_eq!(p.lag(100), 0);
        assert_eq!(p.lag(4196), 4096);
        // A recorder ahead of the plant (a frame re-sent) is not behind.
        assert_eq!(p.lag(50), 0);
        assert_eq!(OffPathProgress::MAX_LAG_FRAMES, 4096);
    }
}
