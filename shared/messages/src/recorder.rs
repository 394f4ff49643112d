//! The recorder's progress: recorder → plant simulator (lockstep).
//!
//! In lockstep simulated time is the plant's to advance, and a recorder
//! that falls behind by more than its subscriber buffers hold loses
//! samples (iceoryx2's safe overflow drops the oldest). The recorder
//! therefore says how far its file reaches, and the plant holds the next
//! frame while the recorder is more than
//! [`RecorderProgress::MAX_LAG_FRAMES`] frames behind. In real time nobody
//! reads it: control never waits, and what the recorder misses it counts
//! and names (`exo.drops`).

use iceoryx2::prelude::ZeroCopySend;

/// How far the recorder has taken the run for its file: the frames whose
/// bus frame and the motor command answering it it has taken out of its
/// subscriber buffers and queued for its writing thread. In lockstep it
/// never discards what it has taken: when the writing thread is behind by
/// its whole queue (a slow disk) it stops taking, so its progress stops
/// and the plant holds.
///
/// 40 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("exo.RecorderProgress.v1")]
#[repr(C)]
pub struct RecorderProgress {
    /// Progress message sequence number (count), from 0 in each recorder
    /// process.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when it was published.
    pub stamp_ns: u64,
    /// Frames taken (count): one more than the highest bus frame `seq`
    /// through which the recorder has taken both `bus/sensor` and the
    /// `bus/motor` command answering it; 0 before it has taken any.
    pub frames_taken: u64,
    /// Samples missed so far over every recorded channel (count; sequence
    /// gaps in what it wrote), by this recorder process.
    pub missed: u64,
    /// The segment of the run's recording this recorder writes (1 = the
    /// first file, 2 = `…-part2.mcap` after a restart, …).
    pub segment: u32,
    /// The recorder's process id, by which a holding plant tells a stopped
    /// recorder (waited for) from a dead one (not waited for).
    pub pid: u32,
}

impl RecorderProgress {
    /// How many frames the recorder may be behind before the lockstep plant
    /// holds its next frame: half the subscriber buffer the recorder holds
    /// on each channel (`max_buffer` of the bus channels in the channel
    /// table, 8192). The other half is the margin for what the recorder
    /// receives on the other channels in one pass after the bus frames
    /// (the sample and the command of a frame are published between its bus
    /// frame and its motor command).
    pub const MAX_LAG_FRAMES: u64 =
        crate::channels::Channel::BusSensor.info().max_buffer as u64 / 2;

    /// How many frames the recorder is behind when the plant is about to
    /// send frame `next_frame` (frames `0..next_frame` published).
    pub fn lag(&self, next_frame: u64) -> u64 {
        next_frame.saturating_sub(self.frames_taken)
    }
}

impl crate::Message for RecorderProgress {
    const TYPE_NAME: &'static str = "exo.RecorderProgress.v1";
    const NAME: &'static str = "RecorderProgress";

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
        assert_eq!(size_of::<RecorderProgress>(), 40);
        assert_eq!(align_of::<RecorderProgress>(), 8);
        assert_eq!(offset_of!(RecorderProgress, seq), 0);
        assert_eq!(offset_of!(RecorderProgress, stamp_ns), 8);
        assert_eq!(offset_of!(RecorderProgress, frames_taken), 16);
        assert_eq!(offset_of!(RecorderProgress, missed), 24);
        assert_eq!(offset_of!(RecorderProgress, segment), 32);
        assert_eq!(offset_of!(RecorderProgress, pid), 36);
    }

    #[test]
    fn the_lag_is_the_frames_published_and_not_taken() {
        let p = RecorderProgress {
            frames_taken: 100,
            ..Default::default()
        };
        assert_eq!(p.lag(100), 0);
        assert_eq!(p.lag(4196), 4096);
        // A recorder ahead of the plant (a frame re-sent) is not behind.
        assert_eq!(p.lag(50), 0);
        assert_eq!(RecorderProgress::MAX_LAG_FRAMES, 4096);
    }
}
