//! # exo-player
//!
//! A recording played back onto a run's channels, like `ros2 bag play`:
//! with `services.player = true` and `[player] file = …` (and no plant,
//! driver or controller), `exo run` re-runs the identifier and the recorder
//! on old data — any contract recording, exo's own or another tool's.
//!
//! [`PlayerNode`] is the recording as one time-ordered stream of the
//! control path's messages: protocol states, commands and samples (at equal
//! stamps in that order), merged by `exo_analysis::Merge` as `exo fit`
//! hands them to the identifier. Samples carry the `REPLAY` status bit.
//! The identifier's outputs and the bus topics are not played: the
//! identifier and the recorder running on the replay make their own.
//! [`process::PlayerProcess`] publishes the stream, paced at
//! `player.pace_hz` samples per second of wall time.

pub mod process;

use std::path::{Path, PathBuf};

use exo_analysis::{Merge, Played};
use exo_messages::status;
use exo_recording::Record;
use exo_recording::{read_recording, Recording, RecordingError};

/// Why a recording cannot be played, naming the player's file.
#[derive(Debug, thiserror::Error)]
pub enum PlayerError {
    /// The file could not be read as a recording.
    #[error("player file {}", file.display())]
    Read {
        /// The player's file (`[player] file`).
        file: PathBuf,
        /// Why (boxed: the error stays small).
        source: Box<RecordingError>,
    },
    /// The recording has no sample to play.
    #[error("{}: exo/sensor has no samples to play", file.display())]
    NoSamples {
        /// The player's file (`[player] file`).
        file: PathBuf,
    },
}

/// A recording's control-path messages in time order.
#[derive(Debug, Clone)]
pub struct PlayerNode {
    stream: Vec<Record>,
    next: usize,
}

impl PlayerNode {
    /// Reads `file` (with its later segments) for playing.
    pub fn open(file: &Path) -> Result<Self, PlayerError> {
        let r = read_recording(file).map_err(|source| PlayerError::Read {
            file: file.to_path_buf(),
            source: Box::new(source),
        })?;
        for w in &r.warnings {
            tracing::warn!("player: {w}");
        }
        if r.sensor.is_empty() {
            return Err(PlayerError::NoSamples {
                file: file.to_path_buf(),
            });
        }
        Ok(Self::of(&r))
    }

    /// The stream of a recording already read: before each sample, the
    /// protocol states and commands stamped at or before it
    /// ([`exo_analysis::Merge`], as `exo fit` hands them to the identifier),
    /// then the protocol states after the last sample.
    pub fn of(r: &Recording) -> Self {
        let mut stream = Vec::with_capacity(r.sensor.len() + r.command.len() + r.protocol.len());
        let mut merge = Merge::new(&r.protocol, &r.command);
        for s in &r.sensor {
            let _ = merge.up_to(s.stamp_ns, |x| -> Result<(), std::convert::Infallible> {
                stream.push(match x {
                    Played::Protocol(p) => Record::Protocol(*p),
                    Played::Command(c) => Record::Command(*c),
                });
                Ok(())
            });
            let mut s = *s;
            s.status |= status::REPLAY;
            stream.push(Record::Sensor(s));
        }
        stream.extend(
            merge
                .remaining_protocol()
                .iter()
                .map(|p| Record::Protocol(*p)),
        );
        PlayerNode { stream, next: 0 }
    }

    /// The next message to publish, `None` at the end.
    pub fn next_record(&mut self) -> Option<Record> {
        let r = self.stream.get(self.next).copied();
        self.next += usize::from(r.is_some());
        r
    }

    /// Messages in the stream.
    pub fn len(&self) -> usize {
        self.stream.len()
    }

    /// Whether the stream is empty.
    pub fn is_empty(&self) -> bool {
        self.stream.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use exo_messages::{ActuatorCommand, ProtocolState, SensorSample};

    #[test]
    fn the_stream_is_in_time_order_states_and_commands_before_the_sample_of_their_stamp() {
        let r = Recording {
            sensor: (0..3)
                .map(|k| SensorSample {
                    seq: k,
                    stamp_ns: k * 10,
                    ..Default::default()
                })
                .collect(),
            command: vec![ActuatorCommand {
                sensor_seq: 1,
                stamp_ns: 10,
                ..Default::default()
            }],
            protocol: vec![
                ProtocolState {
                    stamp_ns: 10,
                    ..Default::default()
                },
                ProtocolState {
                    stamp_ns: 30,
                    ..Default::default()
                },
            ],
            ..Default::default()
        };
        let mut n = PlayerNode::of(&r);
        assert_eq!(n.len(), 6);
        let kinds: Vec<(char, u64)> = std::iter::from_fn(|| n.next_record())
            .map(|x| match x {
                Record::Sensor(s) => {
                    assert_ne!(s.status & status::REPLAY, 0, "a replayed sample says so");
                    ('s', s.stamp_ns)
                }
                Record::Command(c) => ('c', c.stamp_ns),
                Record::Protocol(p) => ('p', p.stamp_ns),
                other => panic!("not played: {other:?}"),
            })
            .collect();
        assert_eq!(
            kinds,
            [
                ('s', 0),
                ('p', 10),
                ('c', 10),
                ('s', 10),
                ('s', 20),
                ('p', 30)
            ]
        );
        assert_eq!(n.next_record(), None);
    }
}
