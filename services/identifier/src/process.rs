//! `exo-identifier` as a process: feeds the run's samples, commands and
//! protocol states to [`Identifier`] and publishes its FRF points and
//! estimates (`<instance>/identifier/frf`, `<instance>/identifier/estimate`),
//! stepped by the one runner (`exo_service_kit::runner`). Off the real-time
//! path: it only subscribes to control channels, and a slow or dead
//! identifier costs control nothing (its subscribers overflow safely). It
//! takes its samples in batches (a pass, then a millisecond's sleep).
//!
//! Each step also publishes how far it has taken the run
//! (`<instance>/identifier/progress`, [`Taken`]): in lockstep, when its
//! estimates feed the controller (`controller.adopt_recommended_f` or `protocol.stop_when`), the
//! plant holds simulated time while the identifier is behind, so it misses
//! no sample; the samples it missed are logged at the end.

use std::time::{Duration, Instant};

use exo_messages::channels::ProcessName;
use exo_messages::{
    ActuatorCommand, FrfPoint, ImpedanceEstimate, OffPathProgress, ProtocolState, SensorSample,
};
use exo_service_kit::channels::{
    COMMAND, IDENTIFIER_ESTIMATE, IDENTIFIER_FRF, IDENTIFIER_PROGRESS, PROTOCOL, SENSOR,
};
use exo_service_kit::ipc::{Connect, Inbox, IpcError, Outbox, DEEPEST, OFF_PATH_COALESCE};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{monotonic_ns, RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{info, warn};

use crate::taken::Taken;
use crate::{Event, Identifier};

/// The progress is published when it changed, and at least this often.
const PROGRESS_EVERY: Duration = Duration::from_millis(50);

/// Why the identifier process stops with an error: only its channels can
/// fail (building the identifier from the run file cannot).
#[derive(Debug, thiserror::Error)]
pub enum IdentifierProcessError {
    /// A channel could not be opened, sent on or received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The run's multisine cannot be estimated line by line.
    #[error("protocol.multisine: {0}")]
    Multisine(String),
}

/// What the identifier says at its end about the samples it missed
/// (sequence gaps in `exo/sensor`): how many and the first; nothing when
/// it missed none.
fn missed_note(taken: &Taken) -> Option<String> {
    taken.first_missing.map(|first| {
        format!(
            "identifier: {} samples missed (sequence gaps), the first seq {first}",
            taken.missed
        )
    })
}

/// The identifier process.
pub struct IdentifierProcess {
    id: Identifier,
    events: Vec<Event>,
    sensor_in: Inbox<SensorSample>,
    command_in: Inbox<ActuatorCommand>,
    protocol_in: Inbox<ProtocolState>,
    frf_out: Outbox<FrfPoint>,
    estimate_out: Outbox<ImpedanceEstimate>,
    progress_out: Outbox<OffPathProgress>,
    taken: Taken,
    told: OffPathProgress,
    told_at: Instant,
}

impl Process for IdentifierProcess {
    type Args = ServiceArgs;
    type Error = IdentifierProcessError;
    const NAME: ProcessName = ProcessName::Identifier;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self, IdentifierProcessError> {
        let ipc = cx.ipc;
        // The progress first, with nothing taken (the estimate outbox,
        // which `exo run` waits for, is the last port).
        let progress_out = ipc.outbox(IDENTIFIER_PROGRESS)?;
        let told = OffPathProgress {
            stamp_ns: monotonic_ns(),
            pid: std::process::id(),
            ..Default::default()
        };
        progress_out.send(told)?;
        let id = Identifier::of_run(cx.cfg).map_err(IdentifierProcessError::Multisine)?;
        let p = IdentifierProcess {
            id,
            events: Vec::with_capacity(64),
            sensor_in: ipc.inbox(SENSOR, DEEPEST)?,
            command_in: ipc.inbox(COMMAND, DEEPEST)?,
            protocol_in: ipc.inbox(PROTOCOL, 256)?,
            frf_out: ipc.outbox(IDENTIFIER_FRF)?,
            estimate_out: ipc.outbox(IDENTIFIER_ESTIMATE)?,
            progress_out,
            taken: Taken::default(),
            told,
            told_at: Instant::now(),
        };
        info!(
            "identifier: {} at {} Hz",
            cx.cfg.subject().name,
            cx.cfg.run.rate_hz
        );
        Ok(p)
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow, IdentifierProcessError> {
        let mut got = false;
        while let Some(p) = self.protocol_in.try_recv()? {
            self.id.on_protocol(&p, &mut self.events);
            got = true;
        }
        while let Some(c) = self.command_in.try_recv()? {
            self.id.on_command(&c);
            self.taken.on_command(&c);
            got = true;
        }
        while let Some(s) = self.sensor_in.try_recv()? {
            self.id.on_sample(&s, &mut self.events);
            self.taken.on_sample(&s);
            got = true;
        }
        for e in self.events.drain(..) {
            e.log();
            match e {
                Event::Frf(p) => self.frf_out.send(p)?,
                Event::Estimate(e) => self.estimate_out.send(e)?,
                Event::Warning(_) | Event::RefitNote(_) => {}
            }
        }
        if !self.taken.told(&self.told) || self.told_at.elapsed() >= PROGRESS_EVERY {
            self.told = OffPathProgress {
                seq: self.told.seq + 1,
                stamp_ns: monotonic_ns(),
                frames_taken: self.taken.frames(),
                missed: self.taken.missed,
                ..self.told
            };
            self.progress_out.send(self.told)?;
            self.told_at = Instant::now();
        }
        if got {
            std::thread::sleep(OFF_PATH_COALESCE);
        } else {
            self.sensor_in.wait(Duration::from_millis(20))?;
        }
        Ok(Flow::Continue)
    }

    fn finish(self) -> Result<(), IdentifierProcessError> {
        if let Some(note) = missed_note(&self.taken) {
            warn!("{note}");
        }
        info!("identifier: stopped");
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use exo_config::RunConfig;
    use exo_messages::OffPathProgress;
    use exo_service_kit::channels::IDENTIFIER_PROGRESS;
    use exo_service_kit::ipc::{Inbox, Ipc};
    use exo_service_kit::runner::{Context, Process};
    use exo_service_kit::{monotonic_ns, ServiceArgs, StopFlag};

    use super::{IdentifierProcess, PROGRESS_EVERY};

    /// The default run's identifier process on the instance `id<tag><pid>`,
    /// with the plant's side of its progress channel, opened first.
    fn rig(tag: &str) -> (IdentifierProcess, Inbox<OffPathProgress>, Ipc) {
        let file = exo_config::configs_dir().join("default.toml");
        let mut cfg = RunConfig::from_file(&file).unwrap();
        cfg.run.instance = format!("id{tag}{}", std::process::id());
        let ipc = Ipc::open("identifier_step_test", &cfg.run.instance, None).unwrap();
        let progress = ipc.inbox(IDENTIFIER_PROGRESS, 16).unwrap();
        let args = ServiceArgs {
            config: file,
            iceoryx2_config: None,
            output: None,
            inject_fault_at: None,
        };
        let process = IdentifierProcess::open(Context {
            cfg: &cfg,
            ipc: &ipc,
            args: &args,
        })
        .unwrap();
        (process, progress, ipc)
    }

    /// The first progress, sent as the process opens, names it (its pid:
    /// the plant stops waiting for a process whose pid is gone) with a
    /// stamp on the monotonic clock, nothing taken.
    #[test]
    fn the_first_progress_names_the_process_with_nothing_taken() {
        let before = monotonic_ns();
        let (_p, progress, _ipc) = rig("first");
        let first = progress.try_recv().unwrap().expect("a progress at open");
        assert_eq!(first.pid, std::process::id());
        assert!(
            first.stamp_ns >= before && first.stamp_ns <= monotonic_ns(),
            "{first:?}"
        );
        assert_eq!((first.seq, first.frames_taken, first.missed), (0, 0, 0));
    }

    /// With nothing taken the progress is repeated once `PROGRESS_EVERY`
    /// has passed (a heartbeat: the plant sees the process alive), not at
    /// every step.
    #[test]
    fn with_nothing_taken_the_progress_is_a_heartbeat() {
        let (mut p, progress, _ipc) = rig("beat");
        while progress.try_recv().unwrap().is_some() {}
        p.told_at = std::time::Instant::now();
        p.step(&StopFlag::unraised()).unwrap();
        assert!(
            progress.try_recv().unwrap().is_none(),
            "nothing new, not yet due"
        );
        p.told_at = std::time::Instant::now()
            .checked_sub(2 * PROGRESS_EVERY)
            .unwrap();
        p.step(&StopFlag::unraised()).unwrap();
        let beat = progress.try_recv().unwrap().expect("a heartbeat");
        assert_eq!((beat.seq, beat.frames_taken), (1, 0));
    }

    /// What was taken is published at the step that took it: the frames
    /// whose sample and command are in (here 0, 1 and 3: four frames) and
    /// the samples missed (seq 2), with the next seq and a fresh stamp.
    #[test]
    fn what_a_step_takes_is_told_at_once() {
        use exo_messages::{ActuatorCommand, SensorSample};
        use exo_service_kit::channels::{COMMAND, SENSOR};
        let (mut p, progress, ipc) = rig("taken");
        let first = progress.try_recv().unwrap().expect("a progress at open");
        let samples = ipc.outbox(SENSOR).unwrap();
        let commands = ipc.outbox(COMMAND).unwrap();
        for seq in [0u64, 1, 3] {
            samples
                .send(SensorSample {
                    seq,
                    stamp_ns: seq * 1_000_000,
                    ..Default::default()
                })
                .unwrap();
            commands
                .send(ActuatorCommand {
                    seq,
                    stamp_ns: seq * 1_000_000,
                    sensor_seq: seq,
                    ..Default::default()
                })
                .unwrap();
        }
        p.told_at = std::time::Instant::now();
        let before = monotonic_ns();
        p.step(&StopFlag::unraised()).unwrap();
        let told = progress.try_recv().unwrap().expect("what was taken");
        assert_eq!(
            (told.seq, told.frames_taken, told.missed),
            (first.seq + 1, 4, 1)
        );
        assert!(told.stamp_ns >= before, "{told:?}");
        assert_eq!(told.pid, std::process::id());
    }

    /// The end's note on missed samples: their count and the first, or
    /// nothing when none was missed.
    #[test]
    fn the_end_names_the_samples_missed() {
        use exo_messages::SensorSample;
        let mut t = crate::taken::Taken::default();
        assert_eq!(super::missed_note(&t), None);
        for seq in [0u64, 1, 4, 5, 9] {
            t.on_sample(&SensorSample {
                seq,
                ..Default::default()
            });
        }
        assert_eq!(
            super::missed_note(&t).as_deref(),
            Some("identifier: 5 samples missed (sequence gaps), the first seq 2")
        );
    }
}
