//! `exo-recorder` as a process: subscribes to every channel the channel
//! table (`exo_messages::channels`) marks recorded and
//! writes one contract MCAP (`--output FILE`, default
//! `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`) with the
//! run's metadata and its configuration files attached, stepped by the one
//! runner (`exo_service_kit::runner`). A recorder started on an output that
//! exists (a restart) continues in the next segment (`…-part2.mcap`). On
//! SIGTERM/SIGINT it drains what is still buffered, writes the drop counts
//! and the summary, and exits. Killed with SIGKILL, it leaves a file whose
//! complete chunks are readable.
//!
//! Receiving and writing are two threads: each step copies what waits into
//! the hand-off (or sleeps on the sensor channel's wake-up) and hands a
//! batch over when it is full or [`BATCH_MAX_AGE`] old; the writing thread
//! encodes, compresses and writes.
//!
//! Each step also publishes how far it has taken the run
//! (`exo/recorder/progress`, [`OffPathProgress`]: the frames taken out of
//! its buffers for the file), by which the plant holds simulated time in
//! lockstep while the recorder is behind, so that a stalled or slow
//! recorder loses nothing there. In lockstep the receiver also never
//! discards: with the writing thread a whole queue behind (a slow disk) it
//! stops taking, its progress stops and the plant holds.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use exo_config::TimingMode;
use exo_messages::channels::ProcessName;
use exo_messages::channels::{
    Channel, Topic, BUS_MOTOR, BUS_SENSOR, CHANNELS, COMMAND, IDENTIFIER_ESTIMATE, IDENTIFIER_FRF,
    OPERATOR, PROTOCOL, RECORDER_PROGRESS, SENSOR,
};
use exo_messages::{Message, OffPathProgress};
use exo_recording::RecordingError;
use exo_service_kit::ipc::{Connect, Inbox, Ipc, IpcError, Outbox, DEEPEST, OFF_PATH_COALESCE};
use exo_service_kit::runner::{Context as RunContext, Flow, Process};
use exo_service_kit::{monotonic_ns, RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{info, warn};

use crate::{
    batch_channel, default_output, start_recording, BatchReceiver, BatchSender, Drops, FileWriter,
    FramesTaken, Record, WriterGone,
};

type Writer = FileWriter;

/// Why the recorder process stops with an error.
#[derive(Debug, thiserror::Error)]
pub enum RecorderProcessError {
    /// A channel could not be opened, sent on or received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The recording could not be started or written (boxed, as each
    /// [`RecordingError`] below: the error stays small).
    #[error(transparent)]
    Recording(Box<RecordingError>),
    /// The segments a recorder before this one left unfinished could not
    /// be finished.
    #[error("finishing the segments of {}", first.display())]
    Orphans {
        /// The run's first segment.
        first: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The writing thread could not be started.
    #[error("starting the writing thread")]
    Spawn(#[source] std::io::Error),
    /// The writing thread has gone: it failed (its error comes when it is
    /// joined) or finished.
    #[error("the writing thread stopped")]
    WriterGone,
    /// The writing thread failed writing the file.
    #[error("the writing thread stopped")]
    Writer(#[source] Box<RecordingError>),
    /// The writing thread panicked.
    #[error("the writing thread panicked")]
    WriterPanicked,
    /// The file's summary could not be written.
    #[error("finishing {path}")]
    Finish {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: Box<RecordingError>,
    },
    /// A channel outside the recording contract was asked for a tap.
    #[error("{topic}: not in the recording contract, not recorded")]
    NotRecorded {
        /// The channel's topic.
        topic: &'static str,
    },
}

type Result<T, E = RecorderProcessError> = std::result::Result<T, E>;

/// Records per hand-off batch, and how many batches may wait for the writer:
/// 256 × 4 096 records (≤ 190 MB, allocated only as a stall needs them) ride
/// out 25 s of a stalled disk at 10 kHz with every topic recorded.
const BATCH_RECORDS: usize = 4096;
const MAX_PENDING_BATCHES: usize = 256;
/// A partly filled batch is handed over after this long, so the file never
/// lags far behind the run.
pub const BATCH_MAX_AGE: Duration = Duration::from_millis(100);
/// The writer closes a chunk at least this often, so a SIGKILL loses at
/// most about this much.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// The progress is published when it changed, and at least this often
/// (so a plant that connects late hears it).
const PROGRESS_EVERY: Duration = Duration::from_millis(50);
/// At the end, in lockstep, how long the receiver waits for room in the
/// writer's queue for what is still in its buffers before it discards.
const FINISH_PATIENCE: Duration = Duration::from_secs(5);

/// What the receiver does when the writer's queue is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum WhenFull {
    /// Stops taking: what waits stays in the subscriber buffers, the
    /// progress stops, and the plant holds (lockstep).
    Stop,
    /// Takes on and discards, counted as gaps (real time: control never
    /// waits, and the buffers would overflow anyway).
    Discard,
}

/// One subscribed channel.
struct Tap<T: Message> {
    inbox: Inbox<T>,
    wrap: fn(T) -> Record,
}

/// A tap of any payload type.
trait Drain {
    /// Moves what waits into the hand-off (all of it, or, with
    /// [`WhenFull::Stop`], until the hand-off is full), noting the frames
    /// taken; returns how many.
    fn drain(
        &self,
        out: &mut BatchSender,
        taken: &mut FramesTaken,
        full: WhenFull,
    ) -> Result<usize>;
    /// Waits up to `timeout` for a sample's wake-up event.
    fn wait(&self, timeout: Duration) -> Result<()>;
}

impl<T: Message> Tap<T> {
    fn boxed(ipc: &Ipc, topic: Topic<T>, wrap: fn(T) -> Record) -> Result<Box<dyn Drain>> {
        Ok(Box::new(Tap {
            // A restarted recorder takes what was published while it was
            // down, as far as the channel's history reaches.
            inbox: ipc.inbox_with_history(topic, DEEPEST, topic.info().history)?,
            wrap,
        }))
    }
}

impl<T: Message> Drain for Tap<T> {
    fn drain(
        &self,
        out: &mut BatchSender,
        taken: &mut FramesTaken,
        full: WhenFull,
    ) -> Result<usize> {
        let mut n = 0;
        loop {
            if full == WhenFull::Stop && out.is_full()? {
                break;
            }
            let Some(m) = self.inbox.try_recv()? else {
                break;
            };
            let r = (self.wrap)(m);
            taken.see(&r);
            out.push(r)?;
            n += 1;
        }
        Ok(n)
    }

    fn wait(&self, timeout: Duration) -> Result<()> {
        self.inbox.wait(timeout)?;
        Ok(())
    }
}

/// The tap of `channel`, each channel with the record that carries its
/// payload (the match is exhaustive: a new channel must be given its record
/// here before the recorder builds).
fn open_tap(ipc: &Ipc, channel: Channel) -> Result<Box<dyn Drain>> {
    match channel {
        Channel::Sensor => Tap::boxed(ipc, SENSOR, Record::Sensor),
        Channel::Command => Tap::boxed(ipc, COMMAND, Record::Command),
        Channel::Protocol => Tap::boxed(ipc, PROTOCOL, Record::Protocol),
        Channel::IdentifierFrf => Tap::boxed(ipc, IDENTIFIER_FRF, Record::Frf),
        Channel::IdentifierEstimate => Tap::boxed(ipc, IDENTIFIER_ESTIMATE, Record::Estimate),
        Channel::Operator => Tap::boxed(ipc, OPERATOR, Record::Operator),
        Channel::BusSensor => Tap::boxed(ipc, BUS_SENSOR, Record::BusSensor),
        Channel::BusMotor => Tap::boxed(ipc, BUS_MOTOR, Record::BusMotor),
        Channel::OperatorReply | Channel::RecorderProgress | Channel::IdentifierProgress => {
            Err(RecorderProcessError::NotRecorded {
                topic: channel.info().topic,
            })
        }
    }
}

impl From<RecordingError> for RecorderProcessError {
    fn from(e: RecordingError) -> Self {
        RecorderProcessError::Recording(Box::new(e))
    }
}

impl From<WriterGone> for RecorderProcessError {
    fn from(_: WriterGone) -> Self {
        RecorderProcessError::WriterGone
    }
}

/// A tap on every channel the table marks `recorded`; the sample channel's
/// is the one waited on.
struct Taps {
    sensor: Box<dyn Drain>,
    others: Vec<Box<dyn Drain>>,
}

impl Taps {
    fn open(ipc: &Ipc) -> Result<Self> {
        let mut others = Vec::new();
        for c in CHANNELS
            .iter()
            .filter(|c| c.recorded && c.channel != Channel::Sensor)
        {
            others.push(open_tap(ipc, c.channel)?);
        }
        Ok(Taps {
            sensor: open_tap(ipc, Channel::Sensor)?,
            others,
        })
    }

    fn drain(
        &self,
        out: &mut BatchSender,
        taken: &mut FramesTaken,
        full: WhenFull,
    ) -> Result<usize> {
        let mut n = self.sensor.drain(out, taken, full)?;
        for t in &self.others {
            n += t.drain(out, taken, full)?;
        }
        Ok(n)
    }
}

/// What the writing thread has counted, for the receiving thread to
/// publish ([`OffPathProgress::missed`]).
#[derive(Default)]
struct Written {
    /// [`Drops::total`].
    missed: AtomicU64,
}

/// The writing thread: writes every batch, counts gaps in what it writes
/// (and says how many in `written`), closes a chunk at least every
/// [`FLUSH_EVERY`]; returns the writer and the counts once the receiving
/// side has gone.
fn write_batches(
    mut w: Writer,
    batches: BatchReceiver,
    written: &Written,
) -> Result<(Writer, Drops), RecordingError> {
    let mut drops = Drops::default();
    let mut last_flush = Instant::now();
    loop {
        match batches.recv(FLUSH_EVERY) {
            Ok(Some(batch)) => {
                for r in &batch {
                    drops.see(r);
                    r.write_to(&mut w)?;
                }
                batches.recycle(batch);
                written.missed.store(drops.total(), Ordering::Release);
            }
            Ok(None) => {}
            Err(WriterGone) => return Ok((w, drops)),
        }
        if last_flush.elapsed() >= FLUSH_EVERY {
            w.flush()?;
            last_flush = Instant::now();
        }
    }
}

/// The recorder process.
pub struct RecorderProcess {
    taps: Taps,
    out: BatchSender,
    writer: JoinHandle<Result<(Writer, Drops), RecordingError>>,
    written: Arc<Written>,
    progress: Progress,
    taken: FramesTaken,
    when_full: WhenFull,
    path: PathBuf,
    received: u64,
    since_hand_off: Instant,
    started: Instant,
}

impl RecorderProcess {
    /// Takes what is still in the buffers at the end. In lockstep nothing
    /// is discarded while the writer makes room, for at most
    /// [`FINISH_PATIENCE`]; then (or in real time) what does not fit is.
    fn drain_to_the_end(&mut self) -> Result<usize> {
        let started = Instant::now();
        let mut n = 0;
        while self.when_full == WhenFull::Stop && started.elapsed() < FINISH_PATIENCE {
            n += self
                .taps
                .drain(&mut self.out, &mut self.taken, WhenFull::Stop)?;
            if !self.out.is_full()? {
                break;
            }
            std::thread::sleep(OFF_PATH_COALESCE);
        }
        Ok(n + self
            .taps
            .drain(&mut self.out, &mut self.taken, WhenFull::Discard)?)
    }
}

impl Process for RecorderProcess {
    type Args = ServiceArgs;
    type Error = RecorderProcessError;
    const NAME: ProcessName = ProcessName::Recorder;
    const REALTIME: Option<RealtimeProcess> = None;

    fn open(cx: RunContext<'_, ServiceArgs>) -> Result<Self> {
        let (cfg, args) = (cx.cfg, cx.args);
        let unix_s = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let first = args
            .output
            .clone()
            .unwrap_or_else(|| default_output(cfg, unix_s));
        // A restarted recorder never truncates what the one before it
        // wrote: it continues in the next segment, read with the first as
        // one recording.
        // A recorder before this one that died left its segment under its
        // partial name: its complete chunks are the run's recording so far.
        for done in exo_recording::segments::finish_orphans(&first).map_err(|source| {
            RecorderProcessError::Orphans {
                first: first.clone(),
                source,
            }
        })? {
            warn!(
                "recorder: {} was left unfinished by a recorder that died: kept, with what its complete chunks hold{}",
                done.0.display(),
                exo_recording::segments::given_up_note(&done.1)
            );
        }
        let (segment, path) = exo_recording::segments::next_free_segment(&first);
        // The progress comes first, with nothing written: once the taps are
        // open (which `exo run` waits for), a plant that starts holds for
        // this recorder; a restarted recorder's plant holds until it has
        // written what the channels' history gives it.
        let progress = Progress {
            outbox: cx.ipc.outbox(RECORDER_PROGRESS)?,
            last: OffPathProgress {
                segment,
                pid: std::process::id(),
                stamp_ns: monotonic_ns(),
                ..Default::default()
            },
            sent_at: Instant::now(),
        };
        progress.outbox.send(progress.last)?;
        let taps = Taps::open(cx.ipc)?;
        let mut w = start_recording(&path, cfg, &args.config)?;
        if segment > 1 {
            w.write_metadata(
                "exo.segment",
                &[
                    ("part".to_string(), segment.to_string()),
                    ("first".to_string(), first.display().to_string()),
                ]
                .into_iter()
                .collect(),
            )?;
            warn!(
                "recorder: {} exists (a recorder before this one wrote it): continuing the run's recording in segment {segment}, {}",
                first.display(),
                path.display()
            );
        }
        info!("recorder: writing {}", path.display());
        let (out, batches) = batch_channel(BATCH_RECORDS, MAX_PENDING_BATCHES);
        let written = Arc::new(Written::default());
        let writer = {
            let written = Arc::clone(&written);
            std::thread::Builder::new()
                .name("recorder-writer".into())
                .spawn(move || write_batches(w, batches, &written))
                .map_err(RecorderProcessError::Spawn)?
        };
        Ok(RecorderProcess {
            taps,
            out,
            writer,
            written,
            progress,
            taken: FramesTaken::default(),
            when_full: match cfg.run.timing {
                TimingMode::Lockstep => WhenFull::Stop,
                TimingMode::Realtime => WhenFull::Discard,
            },
            path,
            received: 0,
            since_hand_off: Instant::now(),
            started: Instant::now(),
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow> {
        let n = self
            .taps
            .drain(&mut self.out, &mut self.taken, self.when_full)?;
        self.received += n as u64;
        if n == 0 {
            self.taps.sensor.wait(Duration::from_millis(20))?;
        } else {
            std::thread::sleep(OFF_PATH_COALESCE);
        }
        if self.since_hand_off.elapsed() >= BATCH_MAX_AGE {
            self.out.hand_off()?;
            self.since_hand_off = Instant::now();
        }
        self.progress.publish(self.taken.count(), &self.written)?;
        Ok(Flow::Continue)
    }

    fn finish(mut self) -> Result<()> {
        let path = self.path.display().to_string();
        // Whatever ended the receiving, hand over what is left and let the
        // writer finish the file.
        let last = self.drain_to_the_end();
        let discarded = self.out.finish().unwrap_or_default();
        let (mut w, drops) = self
            .writer
            .join()
            .map_err(|_| RecorderProcessError::WriterPanicked)?
            .map_err(|e| RecorderProcessError::Writer(Box::new(e)))?;
        let received = self.received + last? as u64;
        // The last word on how far the file reaches.
        self.written.missed.store(drops.total(), Ordering::Release);
        self.progress.publish(self.taken.count(), &self.written)?;
        let counted = drops.counted();
        w.write_metadata("exo.drops", &drops.metadata(discarded))?;
        let written = w.messages_written();
        w.finish().map_err(|e| RecorderProcessError::Finish {
            path: path.clone(),
            source: Box::new(e),
        })?;
        let dropped = drops.total();
        let gaps: Vec<String> = counted
            .iter()
            .map(|(topic, c)| match c.first_missing {
                Some(first) => format!("{topic} {} (the first seq {first})", c.dropped),
                None => format!("{topic} {}", c.dropped),
            })
            .collect();
        if dropped > 0 || discarded > 0 {
            warn!(
                "recorder: {dropped} samples missed (sequence gaps); {discarded} received but discarded with the writer behind"
            );
        }
        info!(
            "recorder: sequence gaps per topic: {}; frames the sensor driver skipped (its own gaps, not missed here): {}",
            gaps.join(", "),
            drops.sensor.skipped_upstream
        );
        info!(
            "recorder: {written} messages in {:.1} s ({received} received), {dropped} missed, file {path}",
            self.started.elapsed().as_secs_f64(),
        );
        Ok(())
    }
}

/// The progress outbox and what it last said.
struct Progress {
    outbox: Outbox<OffPathProgress>,
    last: OffPathProgress,
    sent_at: Instant,
}

impl Progress {
    /// Publishes how far the writing thread has got, when that changed or
    /// [`PROGRESS_EVERY`] after the last.
    fn publish(&mut self, frames: u64, written: &Written) -> Result<()> {
        let missed = written.missed.load(Ordering::Acquire);
        let changed = (frames, missed) != (self.last.frames_taken, self.last.missed);
        if !changed && self.sent_at.elapsed() < PROGRESS_EVERY {
            return Ok(());
        }
        self.last = OffPathProgress {
            seq: self.last.seq + 1,
            stamp_ns: monotonic_ns(),
            frames_taken: frames,
            missed,
            ..self.last
        };
        self.outbox.send(self.last)?;
        self.sent_at = Instant::now();
        Ok(())
    }
}
