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
            samples: Collector::start_filtered(&node, instance, SENSOR, is_fault_sample)
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

    /// The faults seen before the run's end ([`describe`]).
    pub fn faults(self) -> Result<Vec<String>> {
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
        let mut faults = describe(&commands, &samples);
        faults.extend(describe_late(&late));
        Ok(faults)
    }
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
