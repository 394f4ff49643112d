//! The replay backend: a recording played back into the pipeline as if it
//! came from the hardware, so the identifier (and the recorder) can be re-run
//! on old data. Frames come from the recording's `exo/bus/sensor` topic when
//! it has one (exo's own recordings: the driver's calibration runs again on
//! the raw counts), otherwise from `exo/sensor`, converted back to raw
//! readings with the rig's calibration ([`Calibration`]'s inverses). The
//! recorded protocol states and commands are published again at their time
//! stamps, since no controller runs during a replay. Samples carry the
//! `REPLAY` status bit. Frames are paced at `pace_hz` (the replay runs
//! faster than real time but never faster than subscribers can take).

use std::path::Path;
use std::time::Duration;

use crate::node::raw_frame;
use crate::{Calibration, HardwareBus, RawFrame};
use anyhow::{bail, Context, Result};
use exo_messages::{ActuatorCommand, ProtocolState};
use exo_recording::read_recording;

/// A recording as a hardware bus.
pub struct ReplayBus {
    frames: Vec<RawFrame>,
    /// Recorded protocol states, in time order.
    pub protocol: Vec<ProtocolState>,
    /// Recorded commands, in time order.
    pub commands: Vec<ActuatorCommand>,
    next: usize,
    period: Duration,
}

/// Why a replay cannot go on.
#[derive(Debug, thiserror::Error)]
#[error("replay: {0}")]
pub struct ReplayError(String);

impl ReplayBus {
    /// Loads `file`; `calibration` converts calibrated samples back to raw readings.
    pub fn open(file: &Path, calibration: &Calibration, pace_hz: f64) -> Result<Self> {
        let r = read_recording(file).with_context(|| format!("replay file {}", file.display()))?;
        for w in &r.warnings {
            tracing::warn!("replay: {w}");
        }
        let frames: Vec<RawFrame> = if !r.bus_sensor.is_empty() {
            r.bus_sensor.iter().map(raw_frame).collect()
        } else {
            r.sensor
                .iter()
                .map(|s| RawFrame {
                    seq: s.seq,
                    stamp_ns: s.stamp_ns,
                    encoder_counts: calibration.counts_of_theta(s.theta_e),
                    cuff_wrench: calibration.wrench_of_tau_c(s.tau_c),
                    sea_deflection_counts: calibration.counts_of_tau_s(s.tau_s),
                    status: 0,
                })
                .collect()
        };
        if frames.is_empty() {
            bail!(
                "{}: neither exo/bus/sensor nor exo/sensor has samples to replay",
                file.display()
            );
        }
        let mut protocol = r.protocol;
        protocol.sort_by_key(|p| p.stamp_ns);
        let mut commands = r.command;
        commands.sort_by_key(|c| c.stamp_ns);
        Ok(ReplayBus {
            frames,
            protocol,
            commands,
            next: 0,
            period: Duration::from_secs_f64(1.0 / pace_hz.max(1.0)),
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames (never, once opened: an empty recording
    /// is refused).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}

impl HardwareBus for ReplayBus {
    type Error = ReplayError;

    fn name(&self) -> &'static str {
        "replay"
    }

    fn read(&mut self, _timeout: Duration) -> Result<Option<RawFrame>, ReplayError> {
        let Some(f) = self.frames.get(self.next).copied() else {
            return Ok(None);
        };
        self.next += 1;
        std::thread::sleep(self.period);
        Ok(Some(f))
    }

    fn write(&mut self, _: u64, _: u64, _: f64, _: bool) -> Result<(), ReplayError> {
        Ok(()) // nothing to actuate
    }
}
