//! Shared memory private to its user. iceoryx2 keeps its node and service
//! files under one root directory (by default `/tmp/iceoryx2/`, shared by
//! every user, so any of them could squat or tamper with it) and names its
//! shared-memory objects with one prefix. exo gives each user their own:
//! the root `/tmp/exo-<uid>/iceoryx2/` (the per-user directory created
//! 0700 and refused when another user owns it or others may write it) and
//! the prefix `exo<uid>_`. Every process of the user derives the same
//! configuration from the project's file ([`per_user_config`]), written
//! once under the per-user directory and loaded both for the node and as
//! iceoryx2's global configuration, so no path falls back to iceoryx2's
//! defaults.
//!
//! Assumption: `/tmp` is the machine's temporary directory and not
//! per-process (as under systemd's `PrivateTmp`, which would give each
//! service its own and so keep them apart): all of a user's exo processes
//! must see the same `/tmp`.

use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

use crate::ipc::IpcError;

/// The per-user directory under `base` (normally `/tmp`): `exo-<uid>`.
pub fn user_dir_in(base: &Path) -> PathBuf {
    base.join(format!("exo-{}", uid()))
}

fn uid() -> u32 {
    // SAFETY: getuid has no preconditions and cannot fail.
    unsafe { libc::getuid() }
}

/// Creates `dir` 0700 when missing; refuses it when another user owns it,
/// it is not a directory, or group or others may write to it.
pub fn ensure_private_dir(dir: &Path) -> Result<(), IpcError> {
    let refuse = |message: String| IpcError::Config {
        path: dir.to_path_buf(),
        message,
    };
    match std::fs::DirBuilder::new().mode(0o700).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(refuse(format!("cannot create it: {e}"))),
    }
    let meta = std::fs::symlink_metadata(dir).map_err(|e| refuse(format!("{e}")))?;
    if !meta.is_dir() {
        return Err(refuse(
            "is not a directory (exo's shared-memory root must be one)".into(),
        ));
    }
    if meta.uid() != uid() {
        return Err(refuse(format!(
            "is owned by user {}, not by this user ({}): refusing another user's shared-memory root",
            meta.uid(),
            uid()
        )));
    }
    if meta.permissions().mode() & 0o022 != 0 {
        return Err(refuse(format!(
            "mode {:o} lets other users write to it: refusing a shared-memory root that is not private",
            meta.permissions().mode() & 0o777
        )));
    }
    Ok(())
}

/// The iceoryx2 configuration of this user: the file at `source` with
/// `global.root-path` moved to `<user dir>/iceoryx2/` and `global.prefix`
/// to `exo<uid>_`, written to `<user dir>/iceoryx2-<hash of source>.toml`
/// (through a temporary file and a rename, so processes starting together
/// never read half a file). Returns its path.
pub fn per_user_config(source: &Path, base: &Path) -> Result<PathBuf, IpcError> {
    let err = |message: String| IpcError::Config {
        path: source.to_path_buf(),
        message,
    };
    let dir = user_dir_in(base);
    ensure_private_dir(&dir)?;
    let text = std::fs::read_to_string(source).map_err(|e| err(format!("{e}")))?;
    let mut doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| err(e.message().to_string()))?;
    let global = doc
        .entry("global")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .ok_or_else(|| err("`global` is not a table".into()))?;
    let root = dir.join("iceoryx2");
    global.insert(
        "root-path".into(),
        toml::Value::String(format!("{}/", root.display())),
    );
    global.insert(
        "prefix".into(),
        toml::Value::String(format!("exo{}_", uid())),
    );
    let out_text = toml::to_string(&doc).map_err(|e| err(format!("{e}")))?;
    let name = format!(
        "iceoryx2-{:016x}.toml",
        fnv1a(source.as_os_str().as_encoded_bytes())
    );
    let out = dir.join(name);
    if std::fs::read_to_string(&out).is_ok_and(|t| t == out_text) {
        return Ok(out);
    }
    // Unique per process and call: threads of one process (the tests'
    // collectors) may write it at the same moment.
    static SERIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let serial = SERIAL.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(".iceoryx2.{}-{serial}.tmp", std::process::id()));
    std::fs::write(&tmp, &out_text)
        .and_then(|()| std::fs::rename(&tmp, &out))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            err(format!("writing {}: {e}", out.display()))
        })?;
    Ok(out)
}

/// 64-bit FNV-1a: a stable name for each source file's derived copy.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Makes this user's iceoryx2 management segments in `/dev/shm` (iceoryx2
/// creates `…global_mgmt` readable and writable by everyone) accessible to
/// this user only. Returns how many were changed.
pub fn restrict_shm(prefix: &str) -> usize {
    let Ok(entries) = std::fs::read_dir("/dev/shm") else {
        return 0;
    };
    let mut changed = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        if !(name.starts_with(prefix) && name.ends_with("global_mgmt")) {
            continue;
        }
        let Ok(meta) = e.metadata() else { continue };
        if meta.uid() == uid()
            && meta.permissions().mode() & 0o077 != 0
            && std::fs::set_permissions(e.path(), std::fs::Permissions::from_mode(0o600)).is_ok()
        {
            changed += 1;
        }
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("exo-access-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn the_root_is_private_and_a_shared_one_is_refused() {
        let base = scratch("root");
        let dir = user_dir_in(&base);
        ensure_private_dir(&dir).unwrap();
        let mode = std::fs::metadata(&dir).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o700);
        // Opened to others (a squatter's directory, or a careless chmod): refused.
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        let e = ensure_private_dir(&dir).unwrap_err().to_string();
        assert!(e.contains("lets other users write"), "{e}");
        // A file in its place: refused.
        std::fs::remove_dir(&dir).unwrap();
        std::fs::write(&dir, b"x").unwrap();
        let e = ensure_private_dir(&dir).unwrap_err().to_string();
        assert!(e.contains("is not a directory"), "{e}");
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn another_users_root_is_refused() {
        if uid() != 0 {
            return; // only root can make a directory another user owns
        }
        let base = scratch("foreign");
        let dir = user_dir_in(&base);
        std::fs::DirBuilder::new().mode(0o700).create(&dir).unwrap();
        let c = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid C string; we are root.
        assert_eq!(unsafe { libc::chown(c.as_ptr(), 4242, 4242) }, 0);
        let e = ensure_private_dir(&dir).unwrap_err().to_string();
        assert!(e.contains("is owned by user 4242"), "{e}");
        std::fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn the_per_user_configuration_moves_root_and_prefix_and_keeps_the_rest() {
        let base = scratch("cfg");
        let source = base.join("iceoryx2.toml");
        std::fs::write(
            &source,
            "[global]\nroot-path = \"/tmp/iceoryx2/\"\nprefix = \"exo_\"\n\n[global.node]\ndirectory = \"nodes\"\n",
        )
        .unwrap();
        let out = per_user_config(&source, &base).unwrap();
        assert!(out.starts_with(user_dir_in(&base)));
        let doc: toml::Table = std::fs::read_to_string(&out).unwrap().parse().unwrap();
        let g = doc["global"].as_table().unwrap();
        assert_eq!(
            g["root-path"].as_str().unwrap(),
            format!("{}/iceoryx2/", user_dir_in(&base).display())
        );
        assert_eq!(g["prefix"].as_str().unwrap(), format!("exo{}_", uid()));
        assert_eq!(g["node"]["directory"].as_str(), Some("nodes"));
        // The same source gives the same file (every process agrees), also
        // from threads writing it at once.
        assert_eq!(per_user_config(&source, &base).unwrap(), out);
        std::fs::remove_file(&out).unwrap();
        let paths: Vec<PathBuf> = std::thread::scope(|sc| {
            let h: Vec<_> = (0..8)
                .map(|_| sc.spawn(|| per_user_config(&source, &base).unwrap()))
                .collect();
            h.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(paths.iter().all(|p| *p == out));
        let leftovers = std::fs::read_dir(user_dir_in(&base))
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".tmp")
            })
            .count();
        assert_eq!(leftovers, 0);
        std::fs::remove_dir_all(&base).unwrap();
    }
}
