//! Issue 32, item 2: every file a dead writer leaves is completed before it
//! takes its segment's name, into one Python's `mcap` `make_reader` reads
//! through its summary (indexed reading), with every message its complete
//! chunks held. Here for a file cut at random points (a power cut: the
//! file ends anywhere) and for a writer killed with SIGKILL (`kill -9`);
//! the full disk is in `inplace.rs`.
//!
//! The count each result is held to is computed without exo's code: from
//! the finished file, the `mcap` crate's reading of each chunk the cut left
//! whole; from the cut file itself, Python's linear reader
//! (`NonSeekingReader`, CRCs checked), which yields a chunk's messages once
//! its whole record is read and stops at the first cut or damaged record.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::*;
use crate::inplace::assert_crcs;
use exo_recording::*;
use serde_json::Value;

/// Python, once for every file: `stream PATH` counts the messages its
/// linear reader yields before the first cut or damaged record;
/// `indexed PATH` opens it with `make_reader` (which reads the footer and
/// the summary) and gives the statistics' message count, the chunk
/// indexes and the messages `iter_messages` reads through them.
const COUNTS: &str = r#"
import json, sys
from mcap.reader import make_reader, NonSeekingReader
def stream(path):
    n = 0
    try:
        with open(path, "rb") as f:
            r = NonSeekingReader(f, validate_crcs=True)
            for _ in r.iter_messages(log_time_order=False):
                n += 1
    except Exception:
        pass
    return n
def indexed(path):
    with open(path, "rb") as f:
        r = make_reader(f)
        s = r.get_summary()
        return {"statistics": s.statistics.message_count,
                "chunks": len(s.chunk_indexes),
                "messages": sum(1 for _ in r.iter_messages())}
a = sys.argv[1:]
print(json.dumps([stream(p) if m == "stream" else indexed(p)
                  for m, p in zip(a[::2], a[1::2])]))
"#;

/// One entry of [`COUNTS`]: how Python reads a file.
enum Read {
    Stream(PathBuf),
    Indexed(PathBuf),
}

/// What [`COUNTS`] gives for each file, in order.
fn python_counts(reads: &[Read]) -> Vec<Value> {
    let mut cmd = Command::new(python());
    cmd.args(["-c", COUNTS]);
    for r in reads {
        match r {
            Read::Stream(p) => cmd.arg("stream").arg(p),
            Read::Indexed(p) => cmd.arg("indexed").arg(p),
        };
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    v.as_array().unwrap().clone()
}

/// A completed file as Python's indexed reader read it: as many messages
/// through the chunk indexes, and in the statistics, as `expected`, from
/// `chunks` chunk indexes.
fn assert_indexed(v: &Value, expected: usize, chunks: Option<usize>, what: &str) {
    assert_eq!(v["messages"], expected, "{what}: {v}");
    assert_eq!(v["statistics"], expected, "{what}: {v}");
    if let Some(c) = chunks {
        assert_eq!(v["chunks"], c, "{what}: {v}");
    }
}

/// A seed from the clock unless `EXO_TEST_SEED` gives one; printed, so
/// that a failure can be run again.
fn seed() -> u64 {
    let s = std::env::var("EXO_TEST_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos() as u64
        });
    println!("EXO_TEST_SEED={s}");
    s | 1
}

/// xorshift64.
fn next(x: &mut u64) -> u64 {
    *x ^= *x << 13;
    *x ^= *x >> 7;
    *x ^= *x << 17;
    *x
}

/// A power cut: a finished recording cut at 32 random bytes (seeded,
/// printed), each left as a dead writer's partial file. Each is completed
/// by `segments::finish_orphans` (the copy) and, from the same bytes, by
/// `segments::complete_in_place`; Python's `make_reader` opens both and
/// reads, through their chunk indexes, exactly the messages of the chunks
/// the cut left whole, counted by the `mcap` crate on the finished file,
/// and as many as Python's linear reader reads from the cut bytes.
#[test]
fn files_cut_at_random_points_are_completed_into_ones_pythons_indexed_reader_reads() {
    let dir = TempDir::new("random-cuts");
    let full = dir.join("full.mcap");
    write_full(&full, 3000, 8192);
    let bytes = std::fs::read(&full).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    // (where each chunk record ends, its messages)
    let chunks: Vec<(usize, usize)> = summary
        .chunk_indexes
        .iter()
        .map(|i| {
            let n = summary.stream_chunk(&bytes, i).unwrap().count();
            ((i.chunk_start_offset + i.chunk_length) as usize, n)
        })
        .collect();
    let total: usize = chunks.iter().map(|c| c.1).sum();
    assert_eq!(total as u64, summary.stats.as_ref().unwrap().message_count);
    assert!(chunks.len() > 20, "{} chunks", chunks.len());
    let mut x = seed();
    let cuts: Vec<usize> = (0..32)
        .map(|_| (next(&mut x) % bytes.len() as u64) as usize)
        .collect();
    let mut reads = Vec::new();
    let mut expected = Vec::new();
    for (k, &cut) in cuts.iter().enumerate() {
        let whole: Vec<_> = chunks.iter().filter(|c| c.0 <= cut).collect();
        let n: usize = whole.iter().map(|c| c.1).sum();
        expected.push((cut, n, whole.len()));
        let raw = dir.join(&format!("cut{k}.bin"));
        std::fs::write(&raw, &bytes[..cut]).unwrap();
        // As a restarted recorder or `exo run` finishes it (disk not full:
        // the completed copy).
        let copied = dir.join(&format!("copied{k}.mcap"));
        std::fs::write(segments::partial_path(&copied), &bytes[..cut]).unwrap();
        assert_eq!(
            segments::finish_orphans(&copied)
                .unwrap()
                .into_iter()
                .map(|(p, _)| p)
                .collect::<Vec<_>>(),
            std::slice::from_ref(&copied),
            "cut at {cut}"
        );
        assert!(!segments::partial_path(&copied).exists());
        // In place, as on a full disk.
        let in_place = dir.join(&format!("in-place{k}.mcap"));
        let partial = segments::partial_path(&in_place);
        std::fs::write(&partial, &bytes[..cut]).unwrap();
        let done = segments::complete_in_place(&partial, &in_place).unwrap();
        assert_eq!((done.messages, done.given_up), (n, 0), "cut at {cut}");
        for p in [&copied, &in_place] {
            assert_crcs(&std::fs::read(p).unwrap(), &format!("cut at {cut}"));
        }
        reads.extend([
            Read::Stream(raw),
            Read::Indexed(copied),
            Read::Indexed(in_place),
        ]);
    }
    let v = python_counts(&reads);
    for (k, (cut, n, whole)) in expected.into_iter().enumerate() {
        let what = format!("cut at byte {cut} of {}", bytes.len());
        assert_eq!(
            v[3 * k],
            n,
            "{what}: Python's linear reading of the cut file"
        );
        // The copy is written in chunks of its own.
        assert_indexed(&v[3 * k + 1], n, None, &format!("{what}, copied"));
        assert_indexed(&v[3 * k + 2], n, Some(whole), &format!("{what}, in place"));
    }
}

/// Set in the writer process: the recording it writes until it is killed.
const WRITER_ENV: &str = "EXO_TEST_WRITE_UNTIL_KILLED";

/// In the writer process (when [`WRITER_ENV`] is set): writes every tick's
/// sensor sample and command, a little at a time, until it is killed.
/// `false` outside.
fn write_until_killed() -> bool {
    let Some(path) = std::env::var_os(WRITER_ENV) else {
        return false;
    };
    let mut w = RecordingWriter::create(Path::new(&path)).unwrap();
    w.register_contract().unwrap();
    let t0 = Instant::now();
    for k in 0.. {
        w.write(&sample(k)).unwrap();
        w.write(&command(k)).unwrap();
        if k % 20 == 0 {
            std::thread::sleep(Duration::from_micros(200));
            // Never outlives a test that failed without killing it.
            if t0.elapsed() > Duration::from_secs(120) {
                std::process::abort();
            }
        }
    }
    true
}

/// Kills (SIGKILL) the writer process when dropped, whether or not the
/// test got there.
struct Writer(std::process::Child);

impl Drop for Writer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `kill -9`: a writer process killed with SIGKILL once its partial file
/// has grown past 50 kB, 250 kB and 700 kB. Completed by
/// `segments::finish_orphans` (the copy) and, from the same bytes, by
/// `segments::complete_in_place`, each file is one Python's `make_reader`
/// opens, and reads through its chunk indexes every message Python's
/// linear reader reads from the killed writer's bytes (which stops where
/// the kill cut them).
#[test]
fn a_writer_killed_with_sigkill_leaves_a_file_completed_into_one_pythons_indexed_reader_reads() {
    if write_until_killed() {
        return;
    }
    let name = "killed::a_writer_killed_with_sigkill_leaves_a_file_completed_into_one_pythons_indexed_reader_reads";
    let dir = TempDir::new("sigkill");
    let mut reads = Vec::new();
    for (i, kill_at_bytes) in [50_000u64, 250_000, 700_000].into_iter().enumerate() {
        let dest = dir.join(&format!("run{i}.mcap"));
        let partial = segments::partial_path(&dest);
        let mut writer = Writer(
            Command::new(std::env::current_exe().unwrap())
                .args(["--exact", name, "--nocapture", "--test-threads=1"])
                .env(WRITER_ENV, &dest)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        );
        let t0 = Instant::now();
        while std::fs::metadata(&partial).map_or(0, |m| m.len()) < kill_at_bytes {
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "the writer wrote {:?} in 60 s",
                std::fs::metadata(&partial).map(|m| m.len())
            );
            assert!(writer.0.try_wait().unwrap().is_none(), "the writer stopped");
            std::thread::sleep(Duration::from_millis(1));
        }
        drop(writer); // SIGKILL, then waited for
        assert!(!dest.exists(), "the killed writer finished its file");
        let raw = dir.join(&format!("killed{i}.bin"));
        std::fs::copy(&partial, &raw).unwrap();
        let in_place = dir.join(&format!("in-place{i}.mcap"));
        std::fs::copy(&partial, segments::partial_path(&in_place)).unwrap();
        segments::complete_in_place(&segments::partial_path(&in_place), &in_place).unwrap();
        assert_eq!(
            segments::finish_orphans(&dest)
                .unwrap()
                .into_iter()
                .map(|(p, _)| p)
                .collect::<Vec<_>>(),
            std::slice::from_ref(&dest)
        );
        assert!(!partial.exists());
        reads.extend([
            Read::Stream(raw),
            Read::Indexed(dest),
            Read::Indexed(in_place),
        ]);
    }
    let v = python_counts(&reads);
    for i in 0..3 {
        let n = v[3 * i].as_u64().unwrap() as usize;
        assert!(n > 0, "killed writer {i}: no message in complete chunks");
        assert_indexed(
            &v[3 * i + 1],
            n,
            None,
            &format!("killed writer {i}, copied"),
        );
        assert_indexed(
            &v[3 * i + 2],
            n,
            None,
            &format!("killed writer {i}, in place"),
        );
    }
}
