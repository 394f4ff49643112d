//! Completing a dead writer's file on a full disk (issue 32, item 2):
//! where the completed copy does not fit, `segments::finish_orphans`
//! completes the file in place; where not even the summary fits, the
//! newest chunks make room; where nothing can, the file keeps its partial
//! name. Each test runs again inside a mount namespace of its own
//! (`unshare -rm`) with a tmpfs of a chosen size on its directory; the
//! truth each result is held to is that of `inplace.rs` (the finished
//! file, the `mcap` crate, Python's `make_reader`).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::*;
use crate::inplace::{
    assert_crcs, data_end, full, mcap_indexed_messages, messages_in_whole_chunks,
    python_has_what_was_kept, python_indexed, python_read, Full,
};
use exo_recording::*;

/// Set inside the mount namespace: the tmpfs directory.
const DISK_ENV: &str = "EXO_TEST_TMPFS";
/// The partial file to copy onto the tmpfs.
const PARTIAL_ENV: &str = "EXO_TEST_TMPFS_PARTIAL";
/// Where the inner test leaves what happened (outside the namespace).
const OUT_ENV: &str = "EXO_TEST_TMPFS_OUT";

/// The segment's name on the tmpfs.
const SEGMENT: &str = "run.mcap";

/// In the test: runs `test` (this module's) again under `unshare -rm` with
/// a tmpfs of `size_bytes` (rounded up to pages) on `disk`, `partial`
/// copied onto it as the partial file of `run.mcap`; what the inner run
/// did is left in `out` ([`on_tmpfs`]).
/// `false` (the test skipped, saying why) where a mount namespace with a
/// tmpfs cannot be made and the test does not run as root; as root (as CI
/// runs) that fails the test.
fn rerun_on_tmpfs(test: &str, disk: &Path, size_bytes: u64, partial: &Path, out: &Path) -> bool {
    std::fs::create_dir_all(disk).unwrap();
    std::fs::create_dir_all(out).unwrap();
    let probe = Command::new("unshare")
        .args([
            "-rm",
            "sh",
            "-c",
            r#"mount -t tmpfs -o size=4096 tmpfs "$1""#,
            "sh",
        ])
        .arg(disk)
        .output();
    if !probe.as_ref().is_ok_and(|o| o.status.success()) {
        let why = match &probe {
            Ok(o) => stderr(o),
            Err(e) => e.to_string(),
        };
        let root = std::fs::read_to_string("/proc/self/status")
            .is_ok_and(|s| s.lines().any(|l| l.starts_with("Uid:\t0\t")));
        assert!(
            !root,
            "{test}: `unshare -rm` with a tmpfs failed as root: {why}"
        );
        println!(
            "skipped {test}: it needs a mount namespace of its own with a tmpfs \
             (`unshare -rm`: unprivileged user namespaces, or root), which failed: {why}"
        );
        return false;
    }
    let name = format!("full_disk::{test}");
    let script = r#"mount -t tmpfs -o size="$1" tmpfs "$2" || exit 90
exec "$3" --exact "$4" --nocapture --test-threads=1"#;
    let result = Command::new("unshare")
        .args(["-rm", "sh", "-c", script, "sh"])
        .arg(size_bytes.to_string())
        .arg(disk)
        .arg(std::env::current_exe().unwrap())
        .arg(&name)
        .env(DISK_ENV, disk)
        .env(PARTIAL_ENV, partial)
        .env(OUT_ENV, out)
        .output()
        .unwrap();
    let text = format!("{}\n{}", stdout(&result), stderr(&result));
    assert!(
        result.status.success() && text.contains("1 passed"),
        "{name} on a {size_bytes}-byte tmpfs:\n{text}"
    );
    true
}

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Inside the namespace (when [`DISK_ENV`] is set): copies the partial file
/// onto the tmpfs, runs each of `steps` on it (`complete`, `in_place`,
/// `finish_orphans`), writing `out/<step>` (`ok`, with the messages given
/// up for `in_place`, or the error), then
/// copies every file on the tmpfs to `out/disk/`. `false` outside.
fn on_tmpfs(steps: &[&str]) -> bool {
    let (Some(disk), Some(src), Some(out)) = (
        std::env::var_os(DISK_ENV),
        std::env::var_os(PARTIAL_ENV),
        std::env::var_os(OUT_ENV),
    ) else {
        return false;
    };
    let (disk, out) = (PathBuf::from(disk), PathBuf::from(out));
    let seg = disk.join(SEGMENT);
    let partial = segments::partial_path(&seg);
    std::fs::copy(&src, &partial).unwrap();
    for step in steps {
        let result = match *step {
            "complete" => segments::complete(&partial, &seg)
                .map(|_| "ok".to_string())
                .map_err(|e| e.to_string()),
            "in_place" => segments::complete_in_place(&partial, &seg)
                .map(|d| format!("ok, {} messages given up", d.given_up))
                .map_err(|e| e.to_string()),
            "finish_orphans" => match segments::finish_orphans(&seg) {
                Ok(done) => {
                    assert_eq!(done.len(), 1);
                    assert_eq!(done[0].0, seg);
                    Ok(format!("ok, {} messages given up", done[0].1.given_up))
                }
                Err(e) => Err(e.to_string()),
            },
            other => panic!("no step {other}"),
        };
        let text = result.unwrap_or_else(|e| e);
        std::fs::write(out.join(step), text).unwrap();
    }
    let copy = out.join("disk");
    std::fs::create_dir_all(&copy).unwrap();
    for entry in std::fs::read_dir(&disk).unwrap() {
        let p = entry.unwrap().path();
        std::fs::copy(&p, copy.join(p.file_name().unwrap())).unwrap();
    }
    true
}

/// What a step of [`on_tmpfs`] gave.
fn step(out: &Path, name: &str) -> String {
    std::fs::read_to_string(out.join(name)).unwrap()
}

/// The files left on the tmpfs, by name.
fn left_on_disk(out: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(out.join("disk"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

const PAGE_BYTES: u64 = 4096;

fn pages(bytes: u64) -> u64 {
    bytes.div_ceil(PAGE_BYTES) * PAGE_BYTES
}

/// End to end on a full disk: a dead recorder's partial file, cut in a
/// chunk, on a tmpfs with 32 kB free, where the completed copy does not
/// fit (`complete` fails, no space, the partial file untouched):
/// `finish_orphans` completes it in place (its bytes before the cut chunk
/// untouched, the summary after them), under the segment's name, nothing
/// else left on the disk, and Python's indexed reader reads every message
/// of the complete chunks.
#[test]
fn on_a_full_disk_finish_orphans_completes_the_file_in_place() {
    if on_tmpfs(&["complete", "finish_orphans"]) {
        return;
    }
    let dir = TempDir::new("in-place-full-disk");
    let Full { bytes, summary, e } = full(&dir, 1200);
    let c = &summary.chunk_indexes[summary.chunk_indexes.len() - 3];
    let start = c.chunk_start_offset as usize;
    let cut = start + c.chunk_length as usize / 2;
    let src = dir.join("cut.mcap.partial");
    std::fs::write(&src, &bytes[..cut]).unwrap();
    let before = read_recording_bytes("cut.mcap", &bytes[..cut]).unwrap();
    // Room for the summary (the writer's: every chunk's index), not for a
    // second copy of the file.
    let free_bytes = 32 * 1024;
    let summary_bytes = bytes.len() - data_end(&bytes);
    assert!(summary_bytes < free_bytes / 2, "{summary_bytes}");
    assert!(cut > 4 * free_bytes, "{cut}");
    let (disk, out) = (dir.join("disk"), dir.join("out"));
    if !rerun_on_tmpfs(
        "on_a_full_disk_finish_orphans_completes_the_file_in_place",
        &disk,
        pages(cut as u64) + free_bytes as u64,
        &src,
        &out,
    ) {
        return;
    }
    let copy_failed = step(&out, "complete");
    assert!(
        copy_failed.contains("No space left on device"),
        "{copy_failed}"
    );
    assert_eq!(step(&out, "finish_orphans"), "ok, 0 messages given up");
    assert_eq!(left_on_disk(&out), [SEGMENT]);
    let seg = out.join("disk").join(SEGMENT);
    let after = std::fs::read(&seg).unwrap();
    assert_crcs(&after, "full disk");
    assert_eq!(after[..start], bytes[..start]);
    assert_eq!(after[start], mcap::records::op::DATA_END);
    let n = before.message_count();
    assert_eq!(n, messages_in_whole_chunks(&bytes, &summary, cut));
    assert_eq!(mcap_indexed_messages(&after), n);
    let v = python_read(&seg).unwrap();
    python_has_what_was_kept(&v, &before, &e);
    assert_eq!(v["attachments"]["config.toml"], CONFIG.len());
    let p = python_indexed(&seg);
    assert_eq!(p["statistics"], n, "{p}");
    assert_eq!(p["messages"], n, "{p}");
}

/// The fewest bytes a Chunk Index record of a zstd chunk with messages
/// takes (MCAP spec, "Chunk Index"): opcode and length (9), four times and
/// offsets (32), the map's length (4) and one channel's offset (10), the
/// message index length (8), "zstd" with its length (8), two sizes (16).
const ZSTD_CHUNK_INDEX_MIN_BYTES: u64 = 9 + 32 + 4 + 10 + 8 + 8 + 16;

/// Where not even the summary fits (the cut record 100 bytes; the disk
/// full to the last page, or with room for all but two pages of the
/// summary): the copy fails (no space), and completing in place gives up
/// the newest complete chunks, as few as make room: the file keeps its
/// bytes up to the start of the first chunk given up, its summary indexes
/// every chunk before it (the finished file's own indexes), keeping one
/// chunk more would not fit (its bytes and one more chunk index), nothing
/// else is left on the disk, and Python's indexed reader reads every
/// message of the chunks kept, counted by the `mcap` crate on the finished
/// file, as the messages given up are those of the chunks given up.
#[test]
fn where_not_even_the_summary_fits_the_newest_chunks_make_room() {
    if on_tmpfs(&["complete", "in_place"]) {
        return;
    }
    let dir = TempDir::new("in-place-no-room");
    let Full { bytes, summary, .. } = full(&dir, 1200);
    let cut_chunk = summary.chunk_indexes.len() - 3;
    let start = summary.chunk_indexes[cut_chunk].chunk_start_offset as usize;
    let cut = start + 100;
    let src = dir.join("cut.mcap.partial");
    std::fs::write(&src, &bytes[..cut]).unwrap();
    // What cutting frees and the last page's slack hold less than the
    // summary.
    let summary_bytes = (bytes.len() - data_end(&bytes)) as u64;
    assert!(pages(cut as u64) - start as u64 + 1024 < summary_bytes);
    let in_chunks = |r: std::ops::Range<usize>| -> usize {
        summary.chunk_indexes[r]
            .iter()
            .map(|i| summary.stream_chunk(&bytes, i).unwrap().count())
            .sum()
    };
    let short = pages(summary_bytes) - 2 * PAGE_BYTES;
    for (case, free_bytes) in [(0, 0), (1, short)] {
        let (disk, out) = (
            dir.join(&format!("disk{case}")),
            dir.join(&format!("out{case}")),
        );
        let disk_bytes = pages(cut as u64) + free_bytes;
        if !rerun_on_tmpfs(
            "where_not_even_the_summary_fits_the_newest_chunks_make_room",
            &disk,
            disk_bytes,
            &src,
            &out,
        ) {
            return;
        }
        let copy_failed = step(&out, "complete");
        assert!(
            copy_failed.contains("No space left on device"),
            "{copy_failed}"
        );
        assert_eq!(left_on_disk(&out), [SEGMENT]);
        let after = std::fs::read(out.join("disk").join(SEGMENT)).unwrap();
        assert_crcs(&after, "chunks given up");
        let s = mcap::Summary::read(&after).unwrap().unwrap();
        let kept = s.chunk_indexes.len();
        println!("{free_bytes} B free: {kept} of the {cut_chunk} complete chunks kept");
        assert!(kept > 0 && kept < cut_chunk, "{kept} of {cut_chunk} chunks");
        assert_eq!(s.chunk_indexes[..], summary.chunk_indexes[..kept]);
        let kept_to = summary.chunk_indexes[kept].chunk_start_offset as usize;
        assert_eq!(after[..kept_to], bytes[..kept_to]);
        assert_eq!(after[kept_to], mcap::records::op::DATA_END);
        // One chunk more (its bytes, its index and a summary otherwise no
        // smaller) would not fit.
        let next_to = summary.chunk_indexes[kept + 1].chunk_start_offset;
        let tail_bytes = (after.len() - kept_to) as u64;
        assert!(
            pages(next_to + tail_bytes + ZSTD_CHUNK_INDEX_MIN_BYTES) > disk_bytes,
            "{disk_bytes} B disk: {kept} chunks kept, to byte {kept_to}, and a \
             completion of {tail_bytes} B; one chunk more would keep the bytes to {next_to}"
        );
        let n = in_chunks(0..kept);
        assert_eq!(
            step(&out, "in_place"),
            format!("ok, {} messages given up", in_chunks(kept..cut_chunk))
        );
        assert_eq!(mcap_indexed_messages(&after), n);
        let p = python_indexed(&out.join("disk").join(SEGMENT));
        assert_eq!(p["statistics"], n, "{p}");
        assert_eq!(p["messages"], n, "{p}");
        assert_eq!(p["chunks"], kept, "{p}");
    }
}

/// Where nothing can be given up (no chunk, the disk full to the byte):
/// neither the copy nor completing in place fits, and `finish_orphans`
/// fails naming the segment, the file and the lack of space, leaving the
/// file under its partial name with its bytes as they were: no file at
/// the segment's own name that is not a complete MCAP.
#[test]
fn where_nothing_can_make_room_the_file_keeps_its_partial_name() {
    if on_tmpfs(&["finish_orphans"]) {
        return;
    }
    let dir = TempDir::new("in-place-no-chunk");
    let Full { bytes, .. } = full(&dir, 10);
    // The magic and the header, then a record of an application's own
    // (opcode 0x80) filling two pages exactly.
    let header_end = 8 + 9 + u64::from_le_bytes(bytes[9..17].try_into().unwrap()) as usize;
    let body = 2 * PAGE_BYTES as usize - header_end - 9;
    let mut partial_bytes = bytes[..header_end].to_vec();
    partial_bytes.push(0x80);
    partial_bytes.extend_from_slice(&(body as u64).to_le_bytes());
    partial_bytes.resize(2 * PAGE_BYTES as usize, 7);
    let src = dir.join("full-page.mcap.partial");
    std::fs::write(&src, &partial_bytes).unwrap();
    let (disk, out) = (dir.join("disk"), dir.join("out"));
    if !rerun_on_tmpfs(
        "where_nothing_can_make_room_the_file_keeps_its_partial_name",
        &disk,
        2 * PAGE_BYTES,
        &src,
        &out,
    ) {
        return;
    }
    let failed = step(&out, "finish_orphans");
    assert!(
        failed.contains("run.mcap: not completed")
            && failed.contains("run.mcap.partial")
            && failed.contains("No space left on device"),
        "{failed}"
    );
    let partial = format!("{SEGMENT}{}", segments::PARTIAL_SUFFIX);
    assert_eq!(left_on_disk(&out), std::slice::from_ref(&partial));
    assert_eq!(
        std::fs::read(out.join("disk").join(&partial)).unwrap(),
        partial_bytes
    );
}
