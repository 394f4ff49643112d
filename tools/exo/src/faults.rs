//! What `exo run` watches for besides the processes' exits: the safe state
//! the controller or the sensor driver latched, bus or drive faults, and
//! the simulated bus's missed real-time deadlines, seen on the run's own
//! channels. A run that finishes with any of them is
//! named in the summary and exits with [`FINISHED_WITH_FAULTS`], not 0.
//!
//! The run's end is not a fault: once the controller has finished the
//! protocol (its first command in mode `Done`) or the plant has stopped
//! (its last bus frame), the driver latching for want of commands or
//! frames is the shutdown, so what is stamped after that is left out.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use anyhow::{Context, Result};
use exo_messages::{
    bus_status, status, ActuatorCommand, BusSensorFrame, ControlMode, SensorSample,
};
use exo_service_kit::channels::{BUS_SENSOR, COMMAND, SENSOR};
use exo_service_kit::collect::Collector;

/// The exit code of a run that ended normally with a fault on the way
/// (1 is a run that could not finish).
pub const FINISHED_WITH_FAULTS: i32 = 3;

/// A run that finished, with the faults it met.
#[derive(Debug)]
pub struct FinishedWithFaults(pub Vec<String>);

impl std::fmt::Display for FinishedWithFaults {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the run finished with faults (exit code {FINISHED_WITH_FAULTS}):\n  {}",
            self.0.join("\n  ")
        )
    }
}

impl std::error::Error for FinishedWithFaults {}

/// Keeps the commands in a safe-state mode and the samples flagged with a
/// safe state or a bus fault, as they are published.
pub struct FaultWatch {
    commands: Collector<ActuatorCommand>,
    samples: Collector<SensorSample>,
    frames: Collector<BusSensorFrame>,
    /// Stamp (ns) of the first `Done` command.
    done_ns: Arc<AtomicU64>,
    /// Stamp (ns) of the last bus frame.
    last_frame_ns: Arc<AtomicU64>,
}

impl FaultWatch {
    /// Starts watching run `instance` (before its processes start).
    pub fn start(instance: &str) -> Result<Self> {
        let node = format!("exo_faults_{}", std::process::id());
        let done_ns = Arc::new(AtomicU64::new(u64::MAX));
        let last_frame_ns = Arc::new(AtomicU64::new(u64::MAX));
        let (done, last) = (Arc::clone(&done_ns), Arc::clone(&last_frame_ns));
        Ok(FaultWatch {
            commands: Collector::start_filtered(
                &node,
                instance,
                COMMAND,
                move |c: &ActuatorCommand| {
                    if c.control_mode() == Some(ControlMode::Done) {
                        done.fetch_min(c.stamp_ns, Ordering::Relaxed);
                    }
                    is_fault_command(c)
                },
            )
            .context("watching the commands for a safe state")?,
            samples: Collector::start_filtered(&node, instance, SENSOR, |s: &SensorSample| {
                is_fault_sample(s) || is_missed_sample(s)
            })
            .context("watching the samples for faults")?,
            // Keeps the late frames, and the last one's stamp.
            frames: Collector::start_filtered(
                &node,
                instance,
                BUS_SENSOR,
                move |f: &BusSensorFrame| {
                    last.store(f.stamp_ns, Ordering::Relaxed);
                    f.status & bus_status::LATE != 0
                },
            )
            .context("watching the bus for its last frame")?,
            done_ns,
            last_frame_ns,
        })
    }

    /// The faults seen before the run's end ([`describe`]), and the
    /// missed cycles the bus tolerated ([`describe_missed`]).
    pub fn faults(self) -> Result<(Vec<String>, Option<String>)> {
        let (commands, samples) = (self.commands.finish()?, self.samples.finish()?);
        let late = self.frames.finish()?;
        let end_ns = self
            .done_ns
            .load(Ordering::Relaxed)
            .min(self.last_frame_ns.load(Ordering::Relaxed));
        let before_end = |stamp_ns: u64| stamp_ns <= end_ns;
        let commands: Vec<_> = commands
            .into_iter()
            .filter(|c| before_end(c.stamp_ns))
            .collect();
        let samples: Vec<_> = samples
            .into_iter()
            .filter(|s| before_end(s.stamp_ns))
            .collect();
        let late: Vec<_> = late
            .into_iter()
            .filter(|f| before_end(f.stamp_ns))
            .collect();
        let (faulty, missed): (Vec<_>, Vec<_>) = samples.into_iter().partition(is_fault_sample);
        let mut faults = describe(&commands, &faulty);
        faults.extend(describe_late(&late));
        Ok((faults, describe_missed(&missed)))
    }
}

/// A sample whose bus cycle was missed and tolerated: its frame late, or
/// its reply lost (the last values repeated).
pub fn is_missed_sample(s: &SensorSample) -> bool {
    s.status & (status::LATE | status::STALE) != 0
}

/// The missed cycles the bus tolerated (samples passing
/// [`is_missed_sample`]), as one line with the counts and the longest run
/// of consecutive samples, or none.
pub fn describe_missed(missed: &[SensorSample]) -> Option<String> {
    let first = missed.first()?;
    let count = |bit: u32| missed.iter().filter(|s| s.status & bit != 0).count();
    let (mut longest, mut run) = (1, 1);
    for w in missed.windows(2) {
        run = if w[1].seq == w[0].seq + 1 { run + 1 } else { 1 };
        longest = longest.max(run);
    }
    Some(format!(
        "the bus missed cycles and rode through: {} samples late, {} stale (reply lost, last values repeated), the longest run {longest} in a row, the first at sample {} (stamp {:.3} s)",
        count(status::LATE),
        count(status::STALE),
        first.seq,
        first.stamp_ns as f64 * 1e-9
    ))
}

/// The bus frames flagged late ([`bus_status::LATE`]: the simulated bus
/// missed real-time deadlines), as one line, or none.
pub fn describe_late(late: &[BusSensorFrame]) -> Option<String> {
    let first = late.first()?;
    Some(format!(
        "the bus (plant-sim) missed {} real-time deadlines, the first before frame {} (stamp {:.3} s)",
        late.len(),
        first.seq,
        first.stamp_ns as f64 * 1e-9
    ))
}

/// A command in a safe-state mode.
pub fn is_fault_command(c: &ActuatorCommand) -> bool {
    ControlMode::from_u32(c.mode).is_some_and(ControlMode::is_safe_state)
}

/// A sample flagged with the driver's safe state or a fault.
pub fn is_fault_sample(s: &SensorSample) -> bool {
    s.status & (status::SAFE_STATE | status::FAULT_MASK) != 0
}

/// The faults in the commands and samples that passed [`is_fault_command`]
/// and [`is_fault_sample`], one line each: the first of each kind, with its
/// simulated time and how many messages carried it.
pub fn describe(commands: &[ActuatorCommand], samples: &[SensorSample]) -> Vec<String> {
    {
        let mut out = Vec::new();
        if let Some(c) = commands.first() {
            out.push(format!(
                "the controller commanded its safe state ({}) from sample {} (stamp {:.3} s), {} commands in all",
                ControlMode::from_u32(c.mode).map_or("?", ControlMode::name),
                c.sensor_seq,
                c.stamp_ns as f64 * 1e-9,
                commands.len()
            ));
        }
        for (bit, what) in [
            (
                status::SAFE_STATE,
                "the sensor driver latched its safe state",
            ),
            (status::BUS_FAULT, "the bus or the drive reported a fault"),
            (status::ENCODER_FAULT, "the joint encoder reported a fault"),
            (
                status::FT_FAULT,
                "the cuff force/torque sensor reported a fault",
            ),
            (
                status::SEA_FAULT,
                "the SEA deflection sensor reported a fault",
            ),
        ] {
            let mut flagged = samples.iter().filter(|s| s.status & bit != 0);
            if let Some(first) = flagged.next() {
                out.push(format!(
                    "{what} at sample {} (stamp {:.3} s), {} samples in all",
                    first.seq,
                    first.stamp_ns as f64 * 1e-9,
                    1 + flagged.count()
                ));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missed_cycles_are_counted_with_their_longest_run() {
        assert_eq!(describe_missed(&[]), None);
        let sample = |seq: u64, status: u32| SensorSample {
            seq,
            stamp_ns: seq * 1_000_000,
            status,
            ..Default::default()
        };
        let missed = [
            sample(7, status::LATE),
            sample(20, status::STALE),
            sample(21, status::STALE),
            sample(22, status::STALE | status::LATE),
            sample(24, status::STALE),
        ];
        assert!(missed.iter().all(is_missed_sample));
        assert!(!is_missed_sample(&sample(3, status::REPLAY)));
        let line = describe_missed(&missed).unwrap();
        assert!(
            line.contains("2 samples late, 4 stale")
                && line.contains("longest run 3 in a row")
                && line.contains("first at sample 7 (stamp 0.007 s)"),
            "{line}"
        );
    }

    #[test]
    fn late_frames_are_named_with_their_count_and_the_first() {
        assert_eq!(describe_late(&[]), None);
        let frame = |seq: u64| BusSensorFrame {
            seq,
            stamp_ns: seq * 1_000_000,
            status: bus_status::LATE,
            ..Default::default()
        };
        let line = describe_late(&[frame(1500), frame(1501), frame(2000)]).unwrap();
        assert!(
            line.contains("missed 3 real-time deadlines")
                && line.contains("frame 1500")
                && line.contains("1.500 s"),
            "{line}"
        );
    }
}
