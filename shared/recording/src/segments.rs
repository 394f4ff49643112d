//! A run's recording in segments. A recorder restarted during a run never
//! truncates what its predecessor wrote: it continues in the next free
//! segment, `<stem>-part2.mcap`, `<stem>-part3.mcap`, … beside the first
//! (`RUN.mcap`), and the readers ([`crate::read_recording`],
//! [`crate::read_recording_topics`]) take a first segment and its parts as
//! one recording.
//!
//! A segment is written under its partial name, `<segment>.partial`, and
//! renamed to its own name when its writer finishes it
//! ([`crate::RecordingWriter::finish`]): a file at a segment's own name is
//! always complete, and a write that fails (no space, no permission) never
//! touches an earlier file of that name. The writer holds an exclusive lock
//! on its partial file for as long as it writes; a partial file nobody
//! holds is an orphan, left by a writer that died (`kill -9`, a failed
//! write). Its complete chunks are the recording up to that point:
//! [`finish_orphans`] (called by a restarted recorder and by `exo run` at
//! the end of a run) completes it ([`complete`]: what its complete chunks
//! and loose records hold, rewritten with indexes, summary and footer, as
//! `mcap recover` does) under its own name, so that a file at a segment's
//! own name is a complete MCAP any reader opens. On a full disk, where the
//! completed copy does not fit, the partial file is completed in place
//! ([`complete_in_place`]: cut after its last complete record, given the
//! summary and footer, renamed; the newest chunks given up where not even
//! the summary fits). A file that cannot be completed keeps its partial
//! name; the readers read an orphan (or a partial file still being
//! written) in place of a missing segment.

use std::fs::{File, TryLockError};
use std::io;
use std::path::{Path, PathBuf};

use crate::{RecordingError, RecordingWriter, DEFAULT_CHUNK_BYTES};

pub use crate::in_place::complete_in_place;

/// What a segment's name gets while its writer writes it.
pub const PARTIAL_SUFFIX: &str = ".partial";

/// The name `path` is written under until its writer finishes it:
/// `<path>.partial`.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_os_string();
    name.push(PARTIAL_SUFFIX);
    PathBuf::from(name)
}

/// The file holding segment `path`: its own name when it was finished,
/// else its partial file when that exists (a writer still writing it, or
/// one that died); `None` when neither exists.
pub fn on_disk(path: &Path) -> Option<PathBuf> {
    if path.exists() {
        return Some(path.to_path_buf());
    }
    let partial = partial_path(path);
    partial.exists().then_some(partial)
}

/// Whether `path` (a partial file) is held by a live writer right now.
fn held(path: &Path) -> io::Result<bool> {
    let f = File::open(path)?;
    match f.try_lock() {
        Ok(()) => Ok(false),
        Err(TryLockError::WouldBlock) => Ok(true),
        Err(TryLockError::Error(e)) => Err(e),
    }
}

/// Completes every orphaned partial file of `first`'s segments (one no
/// live writer holds, whose segment has no finished file) under its
/// segment's own name ([`complete`]), and returns the segments so
/// finished, each with what it kept ([`Completed`]). Where the completed copy does not fit (a full disk), the
/// partial file is completed in place ([`complete_in_place`], which gives
/// up the newest chunks where not even the summary fits). A file at a
/// segment's own name is thus always a complete MCAP: where neither can be
/// done, the partial file keeps its partial name (exo's readers read it)
/// and the error names it and both failures. A partial file a writer
/// still holds is left alone. Errors name the file.
pub fn finish_orphans(first: &Path) -> io::Result<Vec<(PathBuf, Completed)>> {
    let named = |p: &Path, e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", p.display()));
    let mut finished = Vec::new();
    for part in 1.. {
        let seg = segment_path(first, part);
        let partial = partial_path(&seg);
        if seg.exists() {
            continue;
        }
        if !partial.exists() {
            break;
        }
        if held(&partial).map_err(|e| named(&partial, e))? {
            continue;
        }
        let done = match complete(&partial, &seg) {
            Ok(done) => done,
            Err(copy) => complete_in_place(&partial, &seg).map_err(|in_place| {
                io::Error::other(format!(
                    "{}: not completed, left under its partial name (copying: {copy}; in place: {in_place})",
                    seg.display()
                ))
            })?,
        };
        finished.push((seg, done));
    }
    Ok(finished)
}

/// What [`complete`] copied, or [`complete_in_place`] kept, from a dead
/// writer's file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Completed {
    /// Messages (those of its complete chunks and loose message records).
    pub messages: usize,
    /// Metadata records.
    pub metadata: usize,
    /// Attachments.
    pub attachments: usize,
    /// Messages of complete chunks given up to make room for the summary
    /// on a full disk ([`complete_in_place`]; 0 otherwise).
    pub given_up: usize,
}

/// The clause a message about a completed file adds when chunks were
/// given up to make room for its summary (`"; 12 messages of its newest
/// chunks given up: no room for the summary"`), empty when none were.
pub fn given_up_note(done: &Completed) -> String {
    match done.given_up {
        0 => String::new(),
        n => format!("; {n} messages of its newest chunks given up: no room for the summary"),
    }
}

/// Rewrites the MCAP file `partial` that its writer never finished (no
/// summary, no footer, perhaps cut in the middle of a record) as a complete
/// MCAP at `dest`: every message MCAP's own stream reader yields before the
/// first damaged or cut record (the complete chunks, CRC-checked), and the
/// metadata and attachments before it, written by a [`RecordingWriter`]
/// with the recordings' own options, then given indexes, summary and
/// footer. The new file is written as every output file is
/// ([`crate::files::write_output_file`]: beside `dest`, synced, renamed,
/// nothing left on failure), and only then is `partial` removed: a crash
/// on the way leaves `partial` as it was. Errors name the file.
pub fn complete(partial: &Path, dest: &Path) -> Result<Completed, RecordingError> {
    let bytes = std::fs::read(partial).map_err(|e| RecordingError::io(partial, e))?;
    let mut out = io::Cursor::new(Vec::with_capacity(bytes.len() + (bytes.len() >> 4)));
    let mut w = RecordingWriter::new(&mut out, dest, DEFAULT_CHUNK_BYTES)?;
    let mut done = Completed::default();
    let options = || mcap::read::Options::IgnoreEndMagic.into();
    // Metadata and attachments: the records outside chunks, up to the first
    // that does not parse.
    if let Ok(records) = mcap::read::LinearReader::new_with_options(&bytes, options()) {
        for record in records.map_while(Result::ok) {
            match record {
                mcap::records::Record::Metadata(m) => {
                    w.write_metadata(&m.name, &m.metadata)?;
                    done.metadata += 1;
                }
                mcap::records::Record::Attachment { header, data, .. } => {
                    w.attach(&header.name, &header.media_type, &data, header.log_time)?;
                    done.attachments += 1;
                }
                _ => {}
            }
        }
    }
    if let Ok(stream) = mcap::MessageStream::new_with_options(&bytes, options()) {
        for message in stream.map_while(Result::ok) {
            w.copy_message(&message)?;
            done.messages += 1;
        }
    }
    w.finish()?;
    // Atomically, as every output file: beside `dest`, synced, renamed
    // (nothing half-written left on failure); only then the partial goes.
    crate::files::write_output_file(dest, out.into_inner())
        .map_err(|e| RecordingError::io(dest, e))?;
    std::fs::remove_file(partial).map_err(|e| RecordingError::io(partial, e))?;
    Ok(done)
}

/// Path of segment `part` (1-based) of the recording whose first segment
/// is `first`: `first` itself for part 1, `<stem>-part<N>.<ext>` after.
pub fn segment_path(first: &Path, part: u32) -> PathBuf {
    if part <= 1 {
        return first.to_path_buf();
    }
    let stem = first
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match first.extension() {
        Some(ext) => format!("{stem}-part{part}.{}", ext.to_string_lossy()),
        None => format!("{stem}-part{part}"),
    };
    first.with_file_name(name)
}

/// Removes the partial file a failed writer of `path` left (a one-shot
/// writer such as `exo sim`, whose recording is worth nothing half
/// written); a partial file a live writer holds is left alone.
pub fn discard_partial(path: &Path) {
    let partial = partial_path(path);
    if matches!(held(&partial), Ok(false)) {
        let _ = std::fs::remove_file(&partial);
    }
}

/// The segment a (re)started recorder writes: the first of `first`'s
/// segments not on disk yet (neither finished nor partial), with its
/// number.
pub fn next_free_segment(first: &Path) -> (u32, PathBuf) {
    let mut part = 1;
    loop {
        let p = segment_path(first, part);
        if on_disk(&p).is_none() {
            return (part, p);
        }
        part += 1;
    }
}

/// The files of the recording whose first segment is `first`, in order:
/// `first`, then each consecutive `-partN` on disk; each one as
/// [`on_disk`] finds it (its partial file when it was not finished). The
/// first is listed even when missing, so that reading it names it.
pub fn segments(first: &Path) -> Vec<PathBuf> {
    let mut out = vec![on_disk(first).unwrap_or_else(|| first.to_path_buf())];
    for part in 2.. {
        match on_disk(&segment_path(first, part)) {
            Some(p) => out.push(p),
            None => break,
        }
    }
    out
}

/// The first segment of `path` when `path` is a later segment
/// (`<stem>-partN.<ext>` with N ≥ 2), whether or not it exists.
pub fn first_segment_of(path: &Path) -> Option<PathBuf> {
    let stem = path.file_stem()?.to_str()?;
    let (base, n) = stem.rsplit_once("-part")?;
    let n: u32 = n.parse().ok()?;
    if n < 2 || base.is_empty() {
        return None;
    }
    let name = match path.extension() {
        Some(ext) => format!("{base}.{}", ext.to_string_lossy()),
        None => base.to_string(),
    };
    Some(path.with_file_name(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths(finished: Vec<(PathBuf, Completed)>) -> Vec<PathBuf> {
        finished.into_iter().map(|(p, _)| p).collect()
    }

    #[test]
    fn the_messages_given_up_are_named_only_when_there_are_some() {
        assert_eq!(given_up_note(&Completed::default()), "");
        let done = Completed {
            messages: 900,
            given_up: 12,
            ..Completed::default()
        };
        assert_eq!(
            given_up_note(&done),
            "; 12 messages of its newest chunks given up: no room for the summary"
        );
    }

    #[test]
    fn segments_are_numbered_beside_the_first_and_found_in_order() {
        let dir = std::env::temp_dir().join(format!("exo-seg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let first = dir.join("run-B-1.mcap");
        assert_eq!(segment_path(&first, 1), first);
        assert_eq!(segment_path(&first, 3), dir.join("run-B-1-part3.mcap"));
        assert_eq!(next_free_segment(&first), (1, first.clone()));
        std::fs::write(&first, b"x").unwrap();
        assert_eq!(
            next_free_segment(&first),
            (2, dir.join("run-B-1-part2.mcap"))
        );
        std::fs::write(dir.join("run-B-1-part2.mcap"), b"x").unwrap();
        // A part after a missing one is not part of the run.
        std::fs::write(dir.join("run-B-1-part4.mcap"), b"x").unwrap();
        assert_eq!(
            segments(&first),
            [first.clone(), dir.join("run-B-1-part2.mcap")]
        );
        assert_eq!(next_free_segment(&first).0, 3);
        assert_eq!(
            first_segment_of(&dir.join("run-B-1-part2.mcap")),
            Some(first.clone())
        );
        assert_eq!(first_segment_of(&first), None);
        assert_eq!(first_segment_of(&dir.join("x-part1.mcap")), None);
        assert_eq!(first_segment_of(&dir.join("-part2.mcap")), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn partial_files_take_their_segment_and_orphans_are_finished() {
        let dir = std::env::temp_dir().join(format!("exo-seg-partial-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let first = dir.join("run.mcap");
        let p1 = dir.join("run.mcap.partial");
        let (s2, p2) = (
            dir.join("run-part2.mcap"),
            dir.join("run-part2.mcap.partial"),
        );
        assert_eq!(partial_path(&first), p1);
        assert_eq!(on_disk(&first), None);
        // A missing first segment is still listed, so reading it names it.
        assert_eq!(segments(&first), std::slice::from_ref(&first));
        // Segment 1 being written (held), segment 2 an orphan.
        let live = crate::files::create_locked_output_file(&p1).unwrap();
        std::fs::write(&p2, b"x").unwrap();
        assert_eq!(on_disk(&first), Some(p1.clone()));
        assert_eq!(segments(&first), [p1.clone(), p2.clone()]);
        assert_eq!(next_free_segment(&first).0, 3);
        // The live writer's file is left alone; the orphan gets its name.
        assert_eq!(
            paths(finish_orphans(&first).unwrap()),
            std::slice::from_ref(&s2)
        );
        assert!(p1.exists() && s2.exists() && !p2.exists());
        assert_eq!(segments(&first), [p1.clone(), s2.clone()]);
        // A live writer's file is not removed as a failed one's would be.
        discard_partial(&first);
        assert!(p1.exists());
        // Once its writer is gone, it is an orphan too.
        drop(live);
        assert_eq!(
            paths(finish_orphans(&first).unwrap()),
            std::slice::from_ref(&first)
        );
        assert_eq!(segments(&first), [first.clone(), s2.clone()]);
        assert_eq!(
            paths(finish_orphans(&first).unwrap()),
            Vec::<PathBuf>::new()
        );
        // A partial file beside a finished segment (a failed rewrite) is
        // never renamed over it; a failed one-shot writer's is discarded.
        std::fs::write(&p1, b"half").unwrap();
        assert_eq!(
            paths(finish_orphans(&first).unwrap()),
            Vec::<PathBuf>::new()
        );
        assert_eq!(on_disk(&first), Some(first.clone()));
        discard_partial(&first);
        assert!(!p1.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
