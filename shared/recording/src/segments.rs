//! A run's recording in segments. A recorder restarted during a run never
//! truncates what its predecessor wrote: it continues in the next free
//! segment, `<stem>-part2.mcap`, `<stem>-part3.mcap`, … beside the first
//! (`RUN.mcap`), and the readers ([`crate::read_recording`],
//! [`crate::read_recording_topics`]) take a first segment and its parts as
//! one recording.

use std::path::{Path, PathBuf};

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

/// The segment a (re)started recorder writes: the first of `first`'s
/// segments not on disk yet, with its number.
pub fn next_free_segment(first: &Path) -> (u32, PathBuf) {
    let mut part = 1;
    loop {
        let p = segment_path(first, part);
        if !p.exists() {
            return (part, p);
        }
        part += 1;
    }
}

/// The segments on disk of the recording whose first segment is `first`,
/// in order: `first`, then each consecutive `-partN` that exists.
pub fn segments(first: &Path) -> Vec<PathBuf> {
    let mut out = vec![first.to_path_buf()];
    for part in 2.. {
        let p = segment_path(first, part);
        if !p.exists() {
            break;
        }
        out.push(p);
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
}
