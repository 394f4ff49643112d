//! Completing a dead writer's file in place (issue 32, item 2), where the
//! completed copy [`crate::segments::complete`] writes does not fit (a full
//! disk): the partial file keeps its complete records where they are, is
//! cut after the last of them, and gets what a finished MCAP file has after
//! its data section: the data end record, the summary section, the summary
//! offsets, the footer and the closing magic (MCAP spec, "File Structure").
//! That needs the summary's bytes (about 170 bytes a chunk) less what the
//! cut record held, where a copy needs the whole file again.
//!
//! The records are read one at a time, never past the file's length, each
//! checked before `mcap::parse_record` sees it (as exo's reader does,
//! [`crate::reader`]); chunks are decompressed in memory, so reading needs
//! no room on the disk. The summary's records are serialised by the `mcap`
//! crate's own record types (their `binrw` encoding), framed as the spec's
//! "Records" section says: opcode (u8), body length (u64 LE), body.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{self, BufReader, Read, Seek, SeekFrom, Write};
use std::path::Path;

use binrw::BinWrite;
use crc32fast::Hasher;
use mcap::records::{self, op, Record};

use crate::framing::{chunk_body, lengths_fit, Frame, Framing};
use crate::segments::Completed;
use crate::RecordingError;

/// Bytes of a record's opcode (u8) and body length (u64) (MCAP spec,
/// "Records").
const RECORD_HEAD_BYTES: u64 = 9;

/// Finishes the MCAP file `partial`, which its writer never finished (no
/// summary, no footer, perhaps cut in the middle of a record), in place,
/// and renames it to `dest`.
///
/// What is kept: the file's records up to the last whole one that is not
/// damaged (a chunk that does not decompress or fails its CRC, a record
/// that does not parse, opcode 0x00 or another MCAP does not define),
/// before the first one cut off, of the data section only (reading stops
/// at a data end record or a summary record). A damaged record before it
/// stays in its place, unindexed (exo's reader skips it, with a warning).
/// The last chunk's message indexes (MCAP spec, "Message Index"), when the
/// cut took some of them, are written again from the chunk's messages. The
/// file is cut after the last record kept (which frees what the cut record
/// held), then given the data end record (its CRC of the data section),
/// the summary section (every schema and channel, the statistics, the
/// chunk, attachment and metadata indexes), the summary offsets, the
/// footer (its CRC of the summary) and the magic, in that order, as the
/// `mcap` crate's writer lays them out; synced, then renamed. A file
/// without a complete magic and header record keeps nothing and is written
/// as an empty recording.
///
/// When those bytes do not fit (no space), the newest complete chunks are
/// given up, as few as make room (each frees its bytes, far more than its
/// index takes in the summary; how many bytes of the summary the disk took
/// tells how many): the file is cut at the start of the oldest chunk given
/// up and completed again ([`Completed::given_up`] counts their messages).
/// Where no chunk is left to give up, or on another error, the file is cut
/// back to the complete records the last attempt kept (what exo's readers
/// read of it), nothing half-written remains, it keeps its partial name,
/// and the error names the file. A file another process holds (a live
/// writer's `flock`) is refused, untouched.
pub fn complete_in_place(partial: &Path, dest: &Path) -> Result<Completed, RecordingError> {
    let named = |e: io::Error| RecordingError::io(partial, e);
    let mut file = OpenOptions::new()
        .read(true)
        .write(true)
        .open(partial)
        .map_err(named)?;
    match file.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            return Err(named(io::Error::new(
                io::ErrorKind::ResourceBusy,
                "another process is writing it",
            )))
        }
        Err(TryLockError::Error(e)) => return Err(named(e)),
    }
    let file_bytes = file.metadata().map_err(named)?.len();
    let mut scan = scan(BufReader::new(&file), file_bytes).map_err(named)?;
    let all = scan.completed();
    loop {
        let tail = scan.tail().map_err(|e| RecordingError::Mcap {
            file: partial.display().to_string(),
            message: format!("encoding its summary: {e}"),
        })?;
        let Err(failed) = append(&mut file, scan.cut_bytes, &tail) else {
            break;
        };
        let no_space = matches!(
            failed.error.kind(),
            io::ErrorKind::StorageFull | io::ErrorKind::QuotaExceeded
        );
        let smaller = if no_space {
            scan.smaller_cut(scan.cut_bytes + failed.written, tail.len())
        } else {
            None
        };
        let Some(cut_bytes) = smaller else {
            return Err(named(failed.error));
        };
        // The file as if it ended where that chunk starts.
        file.seek(SeekFrom::Start(0)).map_err(named)?;
        scan = self::scan(BufReader::new(&file), cut_bytes).map_err(named)?;
    }
    std::fs::rename(partial, dest).map_err(|e| {
        RecordingError::io(
            dest,
            io::Error::new(
                e.kind(),
                format!(
                    "renaming the completed {} to it: {e}; the recording stays there",
                    partial.display()
                ),
            ),
        )
    })?;
    if let Some(dir) = dest.parent().filter(|d| !d.as_os_str().is_empty()) {
        // Best effort: makes the rename itself durable.
        let _ = File::open(dir).and_then(|d| d.sync_all());
    }
    let mut done = scan.completed();
    done.given_up = all.messages.saturating_sub(done.messages);
    Ok(done)
}

/// Why [`append`] failed, and how many bytes of the tail it had written
/// when it did (what the disk had room for).
struct AppendError {
    error: io::Error,
    written: u64,
}

/// Cuts `file` at `cut_bytes` (freeing what the cut record held) and
/// appends `tail` there, synced. When that fails (no space) the file is cut
/// back to `cut_bytes`, its complete records.
fn append(file: &mut File, cut_bytes: u64, tail: &[u8]) -> Result<(), AppendError> {
    let mut written = 0u64;
    let result = (|| {
        file.set_len(cut_bytes)?;
        file.seek(SeekFrom::Start(cut_bytes))?;
        let mut rest = tail;
        while !rest.is_empty() {
            match file.write(rest) {
                Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
                Ok(n) => {
                    written += n as u64;
                    rest = &rest[n..];
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        file.sync_all()
    })();
    let Err(e) = result else {
        return Ok(());
    };
    let back = file.set_len(cut_bytes).and_then(|()| file.sync_all());
    let after = match back {
        Ok(()) => "the file is left as it was up to that record".to_string(),
        Err(b) => format!("cutting it back there failed too: {b}"),
    };
    Err(AppendError {
        error: io::Error::new(
            e.kind(),
            format!(
                "appending the summary and footer ({} bytes) after its last complete record (byte {cut_bytes}): {e}; {after}",
                tail.len()
            ),
        ),
        written,
    })
}

/// Records read one after the other from a file of `file_bytes` bytes, with
/// the running CRC-32 of every byte read.
struct Records<R> {
    r: R,
    /// Where the next record starts (bytes from the file's start).
    pos_bytes: u64,
    file_bytes: u64,
    /// CRC-32 of the bytes before `pos_bytes`.
    crc: Hasher,
    /// The body of the record last read.
    body: Vec<u8>,
}

impl<R: Read> Records<R> {
    /// Whether the file starts with the MCAP magic (MCAP spec, "Magic").
    fn magic(&mut self) -> io::Result<bool> {
        let mut magic = [0u8; 8];
        if self.file_bytes < magic.len() as u64 {
            return Ok(false);
        }
        self.r.read_exact(&mut magic)?;
        self.pos_bytes = magic.len() as u64;
        self.crc.update(&magic);
        Ok(magic[..] == mcap::MAGIC[..])
    }

    /// The next record's opcode and start (its body in `self.body`), or
    /// `None` where the file ends or its next record is cut off.
    fn next(&mut self) -> io::Result<Option<(u8, u64)>> {
        let left_bytes = self.file_bytes - self.pos_bytes;
        if left_bytes < RECORD_HEAD_BYTES {
            return Ok(None);
        }
        let mut head = [0u8; RECORD_HEAD_BYTES as usize];
        self.r.read_exact(&mut head)?;
        let [opcode, len @ ..] = head;
        let body_bytes = u64::from_le_bytes(len);
        let Some(n) = usize::try_from(body_bytes)
            .ok()
            .filter(|_| body_bytes <= left_bytes - RECORD_HEAD_BYTES)
        else {
            return Ok(None);
        };
        self.body.clear();
        self.body.resize(n, 0);
        self.r.read_exact(&mut self.body)?;
        self.crc.update(&head);
        self.crc.update(&self.body);
        let start = self.pos_bytes;
        self.pos_bytes += RECORD_HEAD_BYTES + body_bytes;
        Ok(Some((opcode, start)))
    }
}

/// What the records kept hold: the content of the summary section (MCAP
/// spec, "Summary Section").
#[derive(Default)]
struct Kept {
    /// Schema records' bodies by schema id, the first of each id.
    schemas: BTreeMap<u16, Vec<u8>>,
    /// Channel records' bodies by channel id, the first of each id.
    channels: BTreeMap<u16, Vec<u8>>,
    chunk_indexes: Vec<records::ChunkIndex>,
    attachment_indexes: Vec<records::AttachmentIndex>,
    metadata_indexes: Vec<records::MetadataIndex>,
    /// Messages per channel id.
    message_counts: BTreeMap<u16, u64>,
    /// Earliest and latest message log time (ns).
    log_time_bounds_ns: Option<(u64, u64)>,
}

impl Kept {
    fn message(&mut self, channel_id: u16, log_time_ns: u64) {
        *self.message_counts.entry(channel_id).or_default() += 1;
        self.log_time_bounds_ns = Some(match self.log_time_bounds_ns {
            None => (log_time_ns, log_time_ns),
            Some((a, b)) => (a.min(log_time_ns), b.max(log_time_ns)),
        });
    }

    /// The Statistics record (MCAP spec, "Statistics").
    fn statistics(&self) -> records::Statistics {
        let (start_ns, end_ns) = self.log_time_bounds_ns.unwrap_or((0, 0));
        let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
        records::Statistics {
            message_count: self.message_counts.values().sum(),
            schema_count: u16::try_from(self.schemas.len()).unwrap_or(u16::MAX),
            channel_count: count(self.channels.len()),
            attachment_count: count(self.attachment_indexes.len()),
            metadata_count: count(self.metadata_indexes.len()),
            chunk_count: count(self.chunk_indexes.len()),
            message_start_time: start_ns,
            message_end_time: end_ns,
            channel_message_counts: self.message_counts.clone(),
        }
    }
}

/// The last chunk read, while the message indexes after it are read.
struct OpenChunk {
    /// Its Chunk Index record (MCAP spec, "Chunk Index"), the message
    /// indexes read so far in it.
    index: records::ChunkIndex,
    /// Where the chunk record ends (its message indexes follow).
    end_bytes: u64,
    /// CRC-32 of the file before `end_bytes`.
    crc_to_end: Hasher,
    /// Its messages' index entries by channel id (log time, offset in its
    /// uncompressed records), in the order written.
    entries: BTreeMap<u16, Vec<records::MessageIndexEntry>>,
}

impl OpenChunk {
    /// Whether a message index was read for every channel with messages
    /// in the chunk.
    fn indexed(&self) -> bool {
        self.entries
            .keys()
            .all(|c| self.index.message_index_offsets.contains_key(c))
    }
}

/// A file's records up to the first cut or damaged one.
#[derive(Default)]
struct Scan {
    /// Where the records kept end: the file is cut there.
    cut_bytes: u64,
    /// CRC-32 of the file before `cut_bytes`.
    crc_to_cut: Hasher,
    /// No complete magic and header: nothing is kept (`cut_bytes` 0).
    headless: bool,
    kept: Kept,
    /// The last chunk, whose message indexes the cut took: they are written
    /// again after it.
    reindex: Option<OpenChunk>,
}

/// Reads the records of a file of `file_bytes` bytes up to the first one
/// cut off, or the end of its data section: the records kept end with the
/// last whole one that is not damaged (a damaged one before it stays where
/// it is, unindexed, as exo's reader skips it).
fn scan<R: Read>(r: R, file_bytes: u64) -> io::Result<Scan> {
    let mut recs = Records {
        r,
        pos_bytes: 0,
        file_bytes,
        crc: Hasher::new(),
        body: Vec::new(),
    };
    let mut scan = Scan {
        headless: true,
        ..Scan::default()
    };
    if !recs.magic()? {
        return Ok(scan);
    }
    match recs.next()? {
        Some((op::HEADER, _)) if lengths_fit(op::HEADER, &recs.body) => {
            if mcap::parse_record(op::HEADER, &recs.body).is_err() {
                return Ok(scan);
            }
        }
        _ => return Ok(scan),
    }
    scan.headless = false;
    scan.commit(&recs);
    let mut open: Option<OpenChunk> = None;
    while let Some((opcode, start_bytes)) = recs.next()? {
        if let (op::MESSAGE_INDEX, Some(chunk)) = (opcode, open.as_mut()) {
            // A damaged one is skipped.
            if let Some(channel_id) = message_index_channel(&recs.body) {
                chunk
                    .index
                    .message_index_offsets
                    .insert(channel_id, start_bytes);
                chunk.index.message_index_length = recs.pos_bytes - chunk.end_bytes;
                scan.commit(&recs);
            }
            continue;
        }
        let end_bytes = recs.pos_bytes;
        let step = scan.keep(opcode, start_bytes, end_bytes, &recs.body);
        match step {
            Step::End => break,
            Step::Damaged if opcode != op::CHUNK => continue,
            _ => {}
        }
        // Another record kept, or another chunk (damaged or not): the
        // writer had written the open chunk's indexes.
        if let Some(chunk) = open.take() {
            scan.kept.chunk_indexes.push(chunk.index);
        }
        match step {
            Step::Chunk(c) => {
                open = Some(OpenChunk {
                    crc_to_end: recs.crc.clone(),
                    ..c
                })
            }
            Step::Damaged => continue,
            _ => {}
        }
        scan.commit(&recs);
    }
    if let Some(chunk) = open {
        if chunk.indexed() {
            scan.kept.chunk_indexes.push(chunk.index);
        } else {
            // The cut took some of its message indexes: cut after the
            // chunk and write them all again.
            scan.cut_bytes = chunk.end_bytes;
            scan.crc_to_cut = chunk.crc_to_end.clone();
            scan.reindex = Some(chunk);
        }
    }
    Ok(scan)
}

/// The channel id of a Message Index record's body, when it parses (its
/// entries are read one by one: a damaged length allocates nothing).
fn message_index_channel(body: &[u8]) -> Option<u16> {
    match mcap::parse_record(op::MESSAGE_INDEX, body) {
        Ok(Record::MessageIndex(i)) => Some(i.channel_id),
        _ => None,
    }
}

/// What a record of the data section is.
enum Step {
    /// Kept.
    Keep,
    /// A chunk, kept, whose message indexes may follow.
    Chunk(OpenChunk),
    /// Damaged (or no record): skipped, not indexed.
    Damaged,
    /// Past the data section: the records kept end before it.
    End,
}

impl Scan {
    /// The records read so far are kept.
    fn commit<R>(&mut self, recs: &Records<R>) {
        self.cut_bytes = recs.pos_bytes;
        self.crc_to_cut = recs.crc.clone();
    }

    /// One record of the data section (opcode, start, end, body), outside
    /// chunks.
    fn keep(&mut self, opcode: u8, start_bytes: u64, end_bytes: u64, body: &[u8]) -> Step {
        let parsed = || {
            lengths_fit(opcode, body)
                .then(|| mcap::parse_record(opcode, body).ok())
                .flatten()
        };
        match opcode {
            op::CHUNK => {
                return self
                    .chunk(start_bytes, end_bytes, body)
                    .map_or(Step::Damaged, Step::Chunk)
            }
            op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                let Some(r) = parsed() else {
                    return Step::Damaged;
                };
                self.content(r, body);
            }
            op::METADATA => {
                let Some(Record::Metadata(m)) = parsed() else {
                    return Step::Damaged;
                };
                // MCAP spec, "Metadata Index".
                self.kept.metadata_indexes.push(records::MetadataIndex {
                    offset: start_bytes,
                    length: end_bytes - start_bytes,
                    name: m.name,
                });
            }
            op::ATTACHMENT => {
                // Its CRC is checked by the parser.
                let Some(Record::Attachment { header, data, .. }) = parsed() else {
                    return Step::Damaged;
                };
                // MCAP spec, "Attachment Index".
                self.kept.attachment_indexes.push(records::AttachmentIndex {
                    offset: start_bytes,
                    length: end_bytes - start_bytes,
                    log_time: header.log_time,
                    create_time: header.create_time,
                    data_size: data.len() as u64,
                    name: header.name,
                    media_type: header.media_type,
                });
            }
            // The end of the data section (a data end record, the summary),
            // or a second header: nothing after it is data.
            op::HEADER
            | op::FOOTER
            | op::DATA_END
            | op::CHUNK_INDEX
            | op::ATTACHMENT_INDEX
            | op::METADATA_INDEX
            | op::STATISTICS
            | op::SUMMARY_OFFSET => return Step::End,
            // A message index after no chunk, kept as written, or a record
            // of an application's own (opcodes 0x80 to 0xff, MCAP spec,
            // "Opcodes"), which readers skip.
            op::MESSAGE_INDEX | 0x80..=0xff => {}
            // Opcode 0x00 (zeros where a power cut left the file's length
            // ahead of its data) or one MCAP has not defined: no record of
            // this file.
            _ => return Step::Damaged,
        }
        Step::Keep
    }

    /// A schema, channel or message record, in a chunk or not.
    fn content(&mut self, r: Record<'_>, body: &[u8]) {
        match r {
            Record::Schema { header, .. } => {
                self.kept
                    .schemas
                    .entry(header.id)
                    .or_insert_with(|| body.to_vec());
            }
            Record::Channel(c) => {
                self.kept
                    .channels
                    .entry(c.id)
                    .or_insert_with(|| body.to_vec());
            }
            Record::Message { header, .. } => self.kept.message(header.channel_id, header.log_time),
            _ => {}
        }
    }

    /// A chunk record (`body`, from `start_bytes` to `end_bytes`) whose
    /// records decompress, pass the CRC and parse: its schemas, channels
    /// and messages are kept, its index started. `None` for a damaged one,
    /// of which nothing is kept.
    fn chunk(&mut self, start_bytes: u64, end_bytes: u64, body: &[u8]) -> Option<OpenChunk> {
        if !lengths_fit(op::CHUNK, body) {
            return None;
        }
        let Ok(Record::Chunk { header, data }) = mcap::parse_record(op::CHUNK, body) else {
            return None;
        };
        let inner = chunk_body(&header, &data).ok()?;
        let mut found = Vec::new();
        let mut entries: BTreeMap<u16, Vec<records::MessageIndexEntry>> = BTreeMap::new();
        let mut framing = Framing::new(&inner, 0);
        loop {
            let offset = framing.position() as u64;
            match framing.next() {
                Frame::Record(o @ (op::SCHEMA | op::CHANNEL | op::MESSAGE), b) => {
                    if !lengths_fit(o, b) {
                        return None;
                    }
                    let r = mcap::parse_record(o, b).ok()?;
                    if let Record::Message { header: m, .. } = &r {
                        entries
                            .entry(m.channel_id)
                            .or_default()
                            .push(records::MessageIndexEntry {
                                log_time: m.log_time,
                                offset,
                            });
                    }
                    found.push((r, b));
                }
                // Records readers skip.
                Frame::Record(..) => {}
                Frame::End => break,
                Frame::Cut(_) => return None,
            }
        }
        for (r, b) in found {
            self.content(r, b);
        }
        Some(OpenChunk {
            // MCAP spec, "Chunk Index": the times and sizes its header
            // gives; the message indexes as they are read.
            index: records::ChunkIndex {
                message_start_time: header.message_start_time,
                message_end_time: header.message_end_time,
                chunk_start_offset: start_bytes,
                chunk_length: end_bytes - start_bytes,
                message_index_offsets: BTreeMap::new(),
                message_index_length: 0,
                compression: header.compression,
                compressed_size: header.compressed_size,
                uncompressed_size: header.uncompressed_size,
            },
            end_bytes,
            crc_to_end: Hasher::new(),
            entries,
        })
    }

    /// Where to cut the file instead, so that its completion fits in
    /// `room_bytes` (the file's length the disk had room for), the
    /// completion at `cut_bytes` having taken `tail_bytes`: the start of the
    /// newest chunk kept whose start leaves room for that completion less
    /// the indexes of the chunks given up (at least one); where none does,
    /// the oldest chunk's start. `None` when no chunk is kept.
    fn smaller_cut(&self, room_bytes: u64, tail_bytes: usize) -> Option<u64> {
        let mut need_bytes = tail_bytes as u64;
        let mut oldest = None;
        for index in self.kept.chunk_indexes.iter().rev() {
            let mut b = Vec::new();
            let index_bytes = put(&mut b, op::CHUNK_INDEX, index).map_or(0, |()| b.len());
            need_bytes = need_bytes.saturating_sub(index_bytes as u64);
            let start_bytes = index.chunk_start_offset;
            if start_bytes + need_bytes <= room_bytes {
                return Some(start_bytes);
            }
            oldest = Some(start_bytes);
        }
        oldest
    }

    /// What was kept, counted.
    fn completed(&self) -> Completed {
        let n = |c: u64| usize::try_from(c).unwrap_or(usize::MAX);
        Completed {
            messages: n(self.kept.message_counts.values().sum()),
            metadata: self.kept.metadata_indexes.len(),
            attachments: self.kept.attachment_indexes.len(),
            given_up: 0,
        }
    }

    /// The bytes that follow the records kept (from `cut_bytes` on), as the
    /// MCAP spec's "File Structure" lays them out: the magic and header
    /// when none were kept, the last chunk's message indexes when the cut
    /// took some, the data end record, the summary section (schemas,
    /// channels, statistics, chunk indexes, attachment indexes, metadata
    /// indexes, each a group), the summary offsets (one per group), the
    /// footer and the magic.
    fn tail(&mut self) -> binrw::BinResult<Vec<u8>> {
        let base_bytes = self.cut_bytes;
        let mut out = Vec::new();
        let at = |out: &Vec<u8>| base_bytes + out.len() as u64;
        if self.headless {
            out.extend_from_slice(mcap::MAGIC);
            put(
                &mut out,
                op::HEADER,
                &records::Header {
                    profile: crate::schema::PROFILE.to_string(),
                    library: crate::SOFTWARE.to_string(),
                },
            )?;
        }
        if let Some(chunk) = self.reindex.take() {
            // MCAP spec, "Message Index": one per channel with messages in
            // the chunk, right after it.
            let mut index = chunk.index;
            index.message_index_offsets.clear();
            let start = at(&out);
            for (channel_id, entries) in chunk.entries {
                index.message_index_offsets.insert(channel_id, at(&out));
                put(
                    &mut out,
                    op::MESSAGE_INDEX,
                    &records::MessageIndex {
                        channel_id,
                        records: entries,
                    },
                )?;
            }
            index.message_index_length = at(&out) - start;
            self.kept.chunk_indexes.push(index);
        }
        // MCAP spec, "Data End": the CRC-32 of every byte before it.
        let mut data_crc = self.crc_to_cut.clone();
        data_crc.update(&out);
        put(
            &mut out,
            op::DATA_END,
            &records::DataEnd {
                data_section_crc: data_crc.finalize(),
            },
        )?;
        let summary_start = out.len();
        let mut offsets = Vec::new();
        let mut group = |out: &Vec<u8>, opcode: u8, start: usize| {
            if out.len() > start {
                // MCAP spec, "Summary Offset".
                offsets.push(records::SummaryOffset {
                    group_opcode: opcode,
                    group_start: base_bytes + start as u64,
                    group_length: (out.len() - start) as u64,
                });
            }
        };
        let start = out.len();
        for body in self.kept.schemas.values() {
            frame(&mut out, op::SCHEMA, body);
        }
        group(&out, op::SCHEMA, start);
        let start = out.len();
        for body in self.kept.channels.values() {
            frame(&mut out, op::CHANNEL, body);
        }
        group(&out, op::CHANNEL, start);
        let start = out.len();
        put(&mut out, op::STATISTICS, &self.kept.statistics())?;
        group(&out, op::STATISTICS, start);
        let start = out.len();
        for index in &self.kept.chunk_indexes {
            put(&mut out, op::CHUNK_INDEX, index)?;
        }
        group(&out, op::CHUNK_INDEX, start);
        let start = out.len();
        for index in &self.kept.attachment_indexes {
            put(&mut out, op::ATTACHMENT_INDEX, index)?;
        }
        group(&out, op::ATTACHMENT_INDEX, start);
        let start = out.len();
        for index in &self.kept.metadata_indexes {
            put(&mut out, op::METADATA_INDEX, index)?;
        }
        group(&out, op::METADATA_INDEX, start);
        let summary_offset_start = at(&out);
        for offset in &offsets {
            put(&mut out, op::SUMMARY_OFFSET, offset)?;
        }
        // MCAP spec, "Footer": its CRC covers the summary section, the
        // summary offsets and the footer up to the CRC itself.
        put(
            &mut out,
            op::FOOTER,
            &records::Footer {
                summary_start: base_bytes + summary_start as u64,
                summary_offset_start,
                summary_crc: 0,
            },
        )?;
        let crc_at = out.len() - 4;
        let summary_crc = crc32fast::hash(&out[summary_start..crc_at]);
        out[crc_at..].copy_from_slice(&summary_crc.to_le_bytes());
        out.extend_from_slice(mcap::MAGIC);
        Ok(out)
    }
}

/// Appends one record: `opcode`, the body's length (u64 LE), the body
/// (MCAP spec, "Records").
fn frame(out: &mut Vec<u8>, opcode: u8, body: &[u8]) {
    out.push(opcode);
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
}

/// Appends one record whose body is `body` serialised as the `mcap` crate
/// serialises it.
fn put<T>(out: &mut Vec<u8>, opcode: u8, body: &T) -> binrw::BinResult<()>
where
    T: for<'a> BinWrite<Args<'a> = ()>,
{
    let mut b = io::Cursor::new(Vec::new());
    body.write_options(&mut b, binrw::Endian::Little, ())?;
    frame(out, opcode, b.get_ref());
    Ok(())
}
