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

/// Writes `contents` to a new file at `path` ([`create_output_file`]).
pub fn write_output_file(path: &Path, contents: impl AsRef<[u8]>) -> io::Result<()> {
    use std::io::Write;
    let mut f = create_output_file(path)?;
    f.write_all(contents.as_ref())?;
    f.flush()
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
        let _ = std::fs::remove_dir_all(&root);
    }
}
