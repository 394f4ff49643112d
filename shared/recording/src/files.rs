//! How exo creates what it writes: run directories `0750` and output files
//! (recordings, reports, tables) `0640`, so nothing of a run is writable by
//! the group or readable by other users (a subject's recordings are personal
//! data). The one place these modes are set; the process umask can only
//! narrow them further.

use std::fs::{DirBuilder, File, OpenOptions};
use std::io;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::Path;

/// Mode of a directory exo creates for its outputs.
pub const OUTPUT_DIR_MODE: u32 = 0o750;

/// Mode of a file exo writes.
pub const OUTPUT_FILE_MODE: u32 = 0o640;

/// Creates `dir` and its missing parents with [`OUTPUT_DIR_MODE`] (existing
/// ones are left as they are).
pub fn create_output_dir(dir: &Path) -> io::Result<()> {
    DirBuilder::new()
        .recursive(true)
        .mode(OUTPUT_DIR_MODE)
        .create(dir)
}

/// Creates (or truncates) the file at `path` with [`OUTPUT_FILE_MODE`] when
/// it is new.
pub fn create_output_file(path: &Path) -> io::Result<File> {
    OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(OUTPUT_FILE_MODE)
        .open(path)
}

/// Creates (or empties) `path` with [`OUTPUT_FILE_MODE`] when it is new and
/// holds an exclusive lock on it for the life of the returned file: the
/// partial file of a recording segment ([`crate::segments`]). A file
/// another live writer holds is refused, not emptied.
pub fn create_locked_output_file(path: &Path) -> io::Result<File> {
    let f = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .mode(OUTPUT_FILE_MODE)
        .open(path)?;
    match f.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            return Err(io::Error::new(
                io::ErrorKind::ResourceBusy,
                "another process is writing it",
            ))
        }
        Err(std::fs::TryLockError::Error(e)) => return Err(e),
    }
    f.set_len(0)?;
    Ok(f)
}

/// Writes `contents` to `path` atomically: a temporary file (mode
/// [`OUTPUT_FILE_MODE`]) beside it, synced, then renamed over `path`. On
/// any error (no space, no permission) the temporary file is removed and
/// an earlier file at `path` is left as it was; the error names both.
pub fn write_output_file(path: &Path, contents: impl AsRef<[u8]>) -> io::Result<()> {
    use std::io::Write;
    use std::sync::atomic::{AtomicU64, Ordering};
    static SERIAL: AtomicU64 = AtomicU64::new(0);
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} names no file", path.display()),
        )
    })?;
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let tmp = dir.join(format!(
        ".{}.{}-{}.tmp",
        file_name.to_string_lossy(),
        std::process::id(),
        SERIAL.fetch_add(1, Ordering::Relaxed)
    ));
    let written = (|| -> io::Result<()> {
        let mut f = OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(OUTPUT_FILE_MODE)
            .open(&tmp)?;
        f.write_all(contents.as_ref())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)?;
        // The rename is durable once the directory is synced (best effort).
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    written.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io::Error::new(
            e.kind(),
            format!(
                "writing {} (via the temporary file {}): {e}; any earlier {} is left as it was",
                path.display(),
                tmp.display(),
                path.display()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn outputs_are_private_to_their_user_and_group() {
        let root = std::env::temp_dir().join(format!("exo-files-{}", std::process::id()));
        let dir = root.join("a/b");
        create_output_dir(&dir).unwrap();
        let file = dir.join("x.mcap");
        write_output_file(&file, b"abc").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        // The umask may narrow the modes, never widen them.
        assert_eq!(mode(&dir) & !OUTPUT_DIR_MODE, 0, "{:o}", mode(&dir));
        assert_eq!(mode(&file) & !OUTPUT_FILE_MODE, 0, "{:o}", mode(&file));
        assert_eq!(std::fs::read(&file).unwrap(), b"abc");
        // Replaced whole, and no temporary file left beside it.
        write_output_file(&file, b"defg").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"defg");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn a_failed_write_names_the_path_and_leaves_the_earlier_file() {
        let root = std::env::temp_dir().join(format!("exo-files-fail-{}", std::process::id()));
        create_output_dir(&root).unwrap();
        let file = root.join("report.html");
        write_output_file(&file, b"earlier").unwrap();
        // The rename cannot replace a directory with a file: the write fails
        // at its last step, after the temporary file was written.
        let blocked = root.join("blocked");
        std::fs::create_dir_all(blocked.join("inside")).unwrap();
        let e = write_output_file(&blocked, b"new").unwrap_err().to_string();
        assert!(e.contains(&format!("writing {}", blocked.display())), "{e}");
        assert!(e.contains("left as it was"), "{e}");
        assert!(blocked.is_dir());
        assert_eq!(std::fs::read(&file).unwrap(), b"earlier");
        // No temporary file left behind.
        let names: Vec<String> = std::fs::read_dir(&root)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
