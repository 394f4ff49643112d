//! # exo-recorder (logic)
//!
//! The recorder writes every channel of a run into one contract MCAP
//! (`docs/recording-format.md`) through `exo-recording`. It only
//! subscribes: iceoryx2 subscribers with safe overflow never block a
//! publisher, so a slow, killed or hung recorder cannot delay control; what
//! it misses it counts from gaps in each topic's `seq` ([`DropCounter`]) and
//! reports in its log and in the file's `exo.drops` metadata.
//!
//! Receiving and writing are two threads: the receiving thread only copies
//! samples out of shared memory into batches ([`batch_channel`]); the
//! writing thread encodes, compresses and writes them. A disk that stalls
//! for seconds (page-cache pressure, another process reading gigabytes)
//! then stalls only the writer, while the receiver keeps draining the
//! subscriber buffers, which hold [`DEEPEST`](exo_service_kit::ipc::DEEPEST)
//! samples per topic (8 s at 1 kHz, 0.8 s at 10 kHz). The batches queued
//! between them are bounded ([`BatchSender`]); what does not fit is not
//! written, and so is counted as a gap like any other miss.

pub mod process;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::time::Duration;

use exo_config::RunConfig;
use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, SensorSample,
};
pub use exo_recording::Record;
use exo_recording::{Recordable, RecordingError, RecordingWriter};

/// Counts samples missed on one topic from gaps in a sequence number that
/// rises by one per sample.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DropCounter {
    last: Option<u64>,
    /// Samples seen.
    pub received: u64,
    /// Samples missed (sum of the gaps).
    pub dropped: u64,
    /// Samples that went backwards or repeated (a restarted publisher, a re-send).
    pub out_of_order: u64,
    /// Sequence numbers the publisher itself skipped, by its own account
    /// (not missed here).
    pub skipped_upstream: u64,
    /// The first sequence number missed, if any was.
    pub first_missing: Option<u64>,
}

impl DropCounter {
    /// Accounts for one sample with sequence number `seq`.
    pub fn see(&mut self, seq: u64) {
        self.see_flagged(seq, false);
    }

    /// [`DropCounter::see`] for a sample that says whether its publisher
    /// skipped the numbers just before it (e.g. the sensor driver's
    /// `FRAMES_SKIPPED`): such a gap is the publisher's, not a drop.
    pub fn see_flagged(&mut self, seq: u64, publisher_skipped: bool) {
        self.received += 1;
        match self.last {
            Some(last) if seq > last + 1 && publisher_skipped => {
                self.skipped_upstream += seq - last - 1
            }
            Some(last) if seq > last + 1 => {
                self.dropped += seq - last - 1;
                self.first_missing.get_or_insert(last + 1);
            }
            Some(last) if seq > last => {}
            Some(_) => self.out_of_order += 1,
            None => {}
        }
        if self.last.is_none_or(|l| seq > l) {
            self.last = Some(seq);
        }
    }
}

/// Per topic, the samples missed in what was written (sequence gaps).
#[derive(Debug, Clone, Default)]
pub struct Drops {
    /// `exo/sensor`.
    pub sensor: DropCounter,
    /// `exo/command`.
    pub command: DropCounter,
    /// `exo/identifier/frf`.
    pub frf: DropCounter,
    /// `exo/identifier/estimate`.
    pub estimate: DropCounter,
    /// `exo/bus/sensor`.
    pub bus_sensor: DropCounter,
    /// `exo/bus/motor`.
    pub bus_motor: DropCounter,
}

impl Drops {
    /// Accounts for one written record. The protocol topic has no `seq`;
    /// operator commands come from short-lived `exo` invocations, each
    /// numbering from 0, so their `seq` says nothing about misses.
    pub fn see(&mut self, r: &Record) {
        match r {
            Record::Sensor(m) => self
                .sensor
                .see_flagged(m.seq, m.status & exo_messages::status::FRAMES_SKIPPED != 0),
            Record::Command(m) => self.command.see(m.seq),
            Record::Protocol(_) | Record::Operator(_) => {}
            Record::Frf(m) => self.frf.see(m.seq),
            Record::Estimate(m) => self.estimate.see(m.seq),
            Record::BusSensor(m) => self.bus_sensor.see(m.seq),
            Record::BusMotor(m) => self.bus_motor.see(m.seq),
        }
    }

    /// `(topic, counter)` of every counted topic.
    pub fn counted(&self) -> [(&'static str, &DropCounter); 6] {
        [
            (SensorSample::TOPIC, &self.sensor),
            (ActuatorCommand::TOPIC, &self.command),
            (FrfPoint::TOPIC, &self.frf),
            (ImpedanceEstimate::TOPIC, &self.estimate),
            (BusSensorFrame::TOPIC, &self.bus_sensor),
            (BusMotorCommand::TOPIC, &self.bus_motor),
        ]
    }

    /// The `exo.drops` metadata record: per topic, samples missed and,
    /// where any were, the first missing seq (`<topic>.first_missing`); how
    /// many records the writer's queue discarded (`discarded`); and the
    /// frames the sensor driver itself skipped (its own gaps, not missed
    /// here).
    pub fn metadata(&self, discarded: u64) -> BTreeMap<String, String> {
        let counted = self.counted();
        let mut m = drops_metadata(counted.iter().copied());
        for (topic, c) in counted {
            if let Some(first) = c.first_missing {
                m.insert(
                    format!("{topic}{}", exo_recording::drops::FIRST_MISSING),
                    first.to_string(),
                );
            }
        }
        m.insert("writer_queue_discarded".into(), discarded.to_string());
        m.insert(
            "exo/sensor.skipped_by_driver".into(),
            self.sensor.skipped_upstream.to_string(),
        );
        m
    }

    /// Samples missed over all topics.
    pub fn total(&self) -> u64 {
        self.counted().iter().map(|(_, c)| c.dropped).sum()
    }
}

/// How far the recorder has taken the run's frames
/// ([`exo_messages::OffPathProgress::frames_taken`]): the highest bus
/// frame `seq` taken, and the highest frame a taken motor command answered.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FramesTaken {
    frame: Option<u64>,
    answered: Option<u64>,
}

impl FramesTaken {
    /// Accounts for one record taken.
    pub fn see(&mut self, r: &Record) {
        match r {
            Record::BusSensor(m) => self.frame = self.frame.max(Some(m.seq)),
            Record::BusMotor(m) => self.answered = self.answered.max(Some(m.frame_seq)),
            _ => {}
        }
    }

    /// One more than the highest bus frame through which both the frame
    /// and the motor command answering it were taken; 0 before both.
    pub fn count(&self) -> u64 {
        match (self.frame, self.answered) {
            (Some(frame), Some(answered)) => frame.min(answered) + 1,
            _ => 0,
        }
    }
}

/// The receiving end's half of the hand-off: collects records into a batch
/// and passes full (or due) batches to the writer without ever blocking.
/// At most `max_pending` batches wait for the writer; when they are all
/// taken and the current batch is full, further records are discarded
/// ([`BatchSender::discarded`]) and show as gaps in the file. Batches come
/// back from the writer for reuse, so in steady state nothing is allocated.
pub struct BatchSender {
    tx: SyncSender<Vec<Record>>,
    spare: Receiver<Vec<Record>>,
    current: Vec<Record>,
    batch: usize,
    discarded: u64,
}

/// The writing end's half of the hand-off.
pub struct BatchReceiver {
    rx: Receiver<Vec<Record>>,
    back: SyncSender<Vec<Record>>,
}

/// A bounded batch hand-off: batches of `batch` records, at most
/// `max_pending` of them queued for the writer.
pub fn batch_channel(batch: usize, max_pending: usize) -> (BatchSender, BatchReceiver) {
    let batch = batch.max(1);
    let max_pending = max_pending.max(1);
    let (tx, rx) = mpsc::sync_channel(max_pending);
    let (back, spare) = mpsc::sync_channel(max_pending + 2);
    (
        BatchSender {
            tx,
            spare,
            current: Vec::with_capacity(batch),
            batch,
            discarded: 0,
        },
        BatchReceiver { rx, back },
    )
}

/// The writer has gone (it failed or finished).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriterGone;

impl BatchSender {
    /// Adds one record; hands the batch over when it is full.
    pub fn push(&mut self, r: Record) -> Result<(), WriterGone> {
        if self.current.len() >= self.batch {
            self.hand_off()?;
            if self.current.len() >= self.batch {
                self.discarded += 1;
                return Ok(());
            }
        }
        self.current.push(r);
        Ok(())
    }

    /// Whether the current batch is full and the writer's queue has no
    /// room for it (tried now): the next record pushed would be discarded.
    /// In lockstep the receiver then takes nothing more from its buffers.
    pub fn is_full(&mut self) -> Result<bool, WriterGone> {
        if self.current.len() >= self.batch {
            self.hand_off()?;
        }
        Ok(self.current.len() >= self.batch)
    }

    /// Hands the current batch to the writer now if it holds anything and
    /// the writer's queue has room; otherwise keeps it.
    pub fn hand_off(&mut self) -> Result<(), WriterGone> {
        if self.current.is_empty() {
            return Ok(());
        }
        let next = match self.spare.try_recv() {
            Ok(mut v) => {
                v.clear();
                v
            }
            Err(TryRecvError::Empty) | Err(TryRecvError::Disconnected) => Vec::new(),
        };
        let full = std::mem::replace(&mut self.current, next);
        match self.tx.try_send(full) {
            Ok(()) => {
                if self.current.capacity() < self.batch {
                    self.current.reserve_exact(self.batch);
                }
                Ok(())
            }
            Err(TrySendError::Full(full)) => {
                self.current = full;
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(WriterGone),
        }
    }

    /// Hands over the last batch, waiting for room if the writer is behind
    /// (at the end of a run nothing is in a hurry); returns the records
    /// discarded over the run.
    pub fn finish(mut self) -> Result<u64, WriterGone> {
        if !self.current.is_empty() {
            let last = std::mem::take(&mut self.current);
            self.tx.send(last).map_err(|_| WriterGone)?;
        }
        Ok(self.discarded)
    }

    /// Records in the current, not yet handed-over batch.
    pub fn pending(&self) -> usize {
        self.current.len()
    }

    /// Records discarded because the writer was `max_pending` batches behind.
    pub fn discarded(&self) -> u64 {
        self.discarded
    }
}

impl BatchReceiver {
    /// The next batch, waiting at most `timeout`; `Ok(None)` on timeout,
    /// `Err` once the sender is gone and everything was taken.
    pub fn recv(&self, timeout: Duration) -> Result<Option<Vec<Record>>, WriterGone> {
        match self.rx.recv_timeout(timeout) {
            Ok(v) => Ok(Some(v)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(WriterGone),
        }
    }

    /// Returns a written batch for reuse.
    pub fn recycle(&self, v: Vec<Record>) {
        // A full spare queue just frees the batch.
        let _ = self.back.try_send(v);
    }
}

/// The default recording path: `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`.
pub fn default_output(cfg: &RunConfig, unix_s: u64) -> PathBuf {
    cfg.run.output_dir.join(format!(
        "{}-{}-{unix_s}.mcap",
        cfg.run.instance,
        cfg.subject().name
    ))
}

/// The `exo` metadata record of a run (see the recording format).
pub fn run_metadata(cfg: &RunConfig, config_file: &Path) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        m.insert(k.to_string(), v);
    };
    put("subject", cfg.subject().name.clone());
    put("software_version", exo_recording::SOFTWARE.to_string());
    put("config_file", config_file.display().to_string());
    put("arm_inertia_kg_m2", cfg.rig.arm_inertia_kg_m2.to_string());
    put("load_lever_arm_m", cfg.rig.load_lever_arm_m.to_string());
    put("m_h_kg_m2", cfg.subject().inertia_kg_m2.to_string());
    put("rate_hz", cfg.run.rate_hz.to_string());
    put("timing", format!("{:?}", cfg.run.timing).to_lowercase());
    put("instance", cfg.run.instance.clone());
    put("seed", cfg.run.seed.to_string());
    put(
        "protocol_mode",
        format!("{:?}", cfg.protocol.mode).to_lowercase(),
    );
    // The lines a multisine run excites (issue 34: a recording says what
    // was applied). The run file was checked: its design exists.
    if let Some(Ok(design)) = cfg
        .protocol
        .multisine()
        .map(|ms| ms.design(cfg.run.rate_hz))
    {
        exo_recording::excitation::MultisineLines {
            period_samples: design.period_samples(),
            bins: design.lines().iter().map(|l| l.bin).collect(),
            amplitudes: design.lines().iter().map(|l| l.amplitude).collect(),
            phases_rad: design.lines().iter().map(|l| l.phase_rad).collect(),
        }
        .write_to(&mut m);
    }
    m
}

/// A run's recording file as the recorder writes it.
pub type FileWriter = RecordingWriter<std::io::BufWriter<std::fs::File>>;

/// Starts the recording of run `cfg` (read from `config_file`) at `path`:
/// the contract's schemas and channels, the `exo` metadata, and the run's
/// configuration, plant model and subject attached (a file that cannot be
/// attached is a warning, not a failed run). Used by the recorder process
/// and by the in-process simulation alike.
pub fn start_recording(
    path: &Path,
    cfg: &RunConfig,
    config_file: &Path,
) -> Result<FileWriter, RecordingError> {
    let mut w = RecordingWriter::create(path)?;
    w.register_contract()?;
    w.write_metadata("exo", &run_metadata(cfg, config_file))?;
    for (name, file) in [
        ("config.toml", config_file),
        ("plant.toml", cfg.plant_model.as_path()),
        ("subject.toml", cfg.subject_file.as_path()),
    ] {
        match std::fs::read(file) {
            Ok(bytes) => {
                if let Err(e) = w.attach(name, "application/toml", &bytes, 0) {
                    tracing::warn!("recorder: attaching {}: {e}", file.display());
                }
            }
            Err(e) => tracing::warn!("recorder: cannot attach {}: {e}", file.display()),
        }
    }
    w.flush()?;
    Ok(w)
}

/// The `exo.drops` metadata record: per topic, samples missed.
pub fn drops_metadata<'a>(
    counters: impl IntoIterator<Item = (&'a str, &'a DropCounter)>,
) -> BTreeMap<String, String> {
    counters
        .into_iter()
        .map(|(topic, c)| (topic.to_string(), c.dropped.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_counted_and_repeats_are_not_drops() {
        let mut c = DropCounter::default();
        for s in [0, 1, 2, 5, 6, 6, 3, 7, 10] {
            c.see(s);
        }
        assert_eq!(c.received, 9);
        assert_eq!(c.dropped, 2 + 2);
        assert_eq!(c.out_of_order, 2);
        assert_eq!(c.first_missing, Some(3));
    }

    #[test]
    fn the_misses_are_named_per_topic_with_the_first_missing_seq() {
        // A recorder stalled past its buffers (SIGSTOP, a slow disk): what
        // it wrote of exo/sensor jumps from 2300 to 4101, exo/bus/motor
        // from 10 to 12; the metadata names the counts and the first seq
        // missed, and `exo run` reads them back as faults.
        let mut drops = Drops::default();
        for seq in (0..=2300).chain(4101..=4200) {
            drops.see(&sample(seq));
        }
        for seq in [9, 10, 12] {
            drops.see(&Record::BusMotor(BusMotorCommand {
                seq,
                ..Default::default()
            }));
        }
        let m = drops.metadata(0);
        assert_eq!(m["exo/sensor"], "1800");
        assert_eq!(m["exo/sensor.first_missing"], "2301");
        assert_eq!(m["exo/bus/motor.first_missing"], "11");
        assert!(!m.contains_key("exo/command.first_missing"));
        let missed = exo_recording::drops::missed(Path::new("run.mcap"), &m).unwrap();
        let named: Vec<_> = missed
            .iter()
            .map(|x| (x.topic.as_str(), x.count, x.first_seq))
            .collect();
        assert_eq!(
            named,
            [
                ("exo/bus/motor", 1, Some(11)),
                ("exo/sensor", 1800, Some(2301))
            ]
        );
        // Nothing missed: the record is as it always was (no first_missing
        // keys), so `exo sim`'s and `exo run`'s files stay alike.
        let clean = Drops::default().metadata(0);
        assert!(clean.keys().all(|k| !k.ends_with(".first_missing")));
    }

    #[test]
    fn frames_taken_count_a_frame_once_its_answer_is_taken_too() {
        let mut drops = FramesTaken::default();
        assert_eq!(drops.count(), 0);
        let frame = |seq| {
            Record::BusSensor(BusSensorFrame {
                seq,
                ..Default::default()
            })
        };
        let motor = |frame_seq| {
            Record::BusMotor(BusMotorCommand {
                seq: frame_seq,
                frame_seq,
                ..Default::default()
            })
        };
        drops.see(&frame(0));
        assert_eq!(drops.count(), 0, "frame 0's answer not yet taken");
        drops.see(&motor(0));
        drops.see(&frame(1));
        drops.see(&frame(2));
        assert_eq!(drops.count(), 1);
        drops.see(&motor(1));
        drops.see(&motor(2));
        assert_eq!(drops.count(), 3);
        // A re-sent frame (lockstep, a slow answer) does not go back.
        drops.see(&frame(1));
        assert_eq!(drops.count(), 3);
    }

    fn sample(seq: u64) -> Record {
        Record::Sensor(SensorSample {
            seq,
            ..SensorSample::default()
        })
    }

    #[test]
    fn a_gap_the_publisher_owns_to_is_not_a_drop() {
        let mut c = DropCounter::default();
        c.see_flagged(1, false);
        c.see_flagged(4, true); // the driver skipped 2 and 3
        c.see_flagged(7, false); // 5 and 6 missed here
        assert_eq!((c.skipped_upstream, c.dropped), (2, 2));
    }

    #[test]
    fn batches_arrive_whole_and_in_order() {
        let (mut tx, rx) = batch_channel(4, 8);
        for s in 0..10 {
            tx.push(sample(s)).unwrap();
        }
        tx.hand_off().unwrap();
        let mut seen = Vec::new();
        while let Ok(Some(b)) = rx.recv(Duration::from_millis(1)) {
            seen.extend(b.iter().map(|r| match r {
                Record::Sensor(m) => m.seq,
                _ => unreachable!(),
            }));
            rx.recycle(b);
        }
        assert_eq!(seen, (0..10).collect::<Vec<_>>());
        assert_eq!(tx.discarded(), 0);
    }

    #[test]
    fn a_stalled_writer_costs_counted_records_never_a_block() {
        // Two batches of three may wait; the writer takes nothing.
        let (mut tx, rx) = batch_channel(3, 2);
        for s in 0..20 {
            tx.push(sample(s)).unwrap();
        }
        // 2 queued batches + the current full one hold 9; 11 discarded.
        assert_eq!(tx.pending(), 3);
        assert_eq!(tx.discarded(), 11);
        // The writer catches up; later records flow again, and what was
        // written shows the loss as a gap of exactly the discarded ones.
        let mut drops = Drops::default();
        let drain = |drops: &mut Drops| {
            while let Ok(Some(b)) = rx.recv(Duration::from_millis(1)) {
                b.iter().for_each(|r| drops.see(r));
                rx.recycle(b);
            }
        };
        drain(&mut drops);
        for s in 20..23 {
            tx.push(sample(s)).unwrap();
        }
        tx.hand_off().unwrap();
        drain(&mut drops);
        assert_eq!(tx.pending(), 0);
        assert_eq!(drops.sensor.received, 12);
        assert_eq!(drops.sensor.dropped, 11);
        assert_eq!(drops.total(), tx.discarded());
        // The last batch is handed over even into a full queue, by waiting:
        // 23..=28 fill the queue, 29..=31 are the current batch, 32 is
        // discarded.
        for s in 23..33 {
            tx.push(sample(s)).unwrap();
        }
        let writer = std::thread::spawn(move || {
            let mut n = 0;
            while let Ok(b) = rx.recv(Duration::from_secs(5)) {
                n += b.map_or(0, |b| b.len());
            }
            n
        });
        assert_eq!(tx.finish(), Ok(12));
        assert_eq!(writer.join().unwrap(), 9);
    }

    #[test]
    fn a_full_hand_off_says_so_before_it_discards() {
        // One batch of two may wait; the writer takes nothing.
        let (mut tx, rx) = batch_channel(2, 1);
        for s in 0..4 {
            assert!(!tx.is_full().unwrap(), "{s}");
            tx.push(sample(s)).unwrap();
        }
        // 0 and 1 queued, 2 and 3 the current batch: full, nothing lost.
        assert!(tx.is_full().unwrap());
        assert_eq!(tx.discarded(), 0);
        // The writer takes a batch: room again.
        let b = rx.recv(Duration::from_millis(10)).unwrap().unwrap();
        rx.recycle(b);
        assert!(!tx.is_full().unwrap());
    }

    #[test]
    fn the_writer_gone_is_reported() {
        let (mut tx, rx) = batch_channel(1, 1);
        drop(rx);
        tx.push(sample(0)).unwrap();
        assert_eq!(tx.push(sample(1)), Err(WriterGone));
    }

    #[test]
    fn the_run_metadata_names_the_subject_and_the_rig() {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        let m = run_metadata(&cfg, Path::new("configs/default.toml"));
        assert_eq!(m["subject"], "B");
        assert_eq!(m["arm_inertia_kg_m2"], "0.1");
        assert_eq!(m["load_lever_arm_m"], "0.45");
        assert!(default_output(&cfg, 7)
            .to_string_lossy()
            .ends_with("exo-B-7.mcap"));
    }
}
