//! Atomic file writes: every file Nimbus writes (images, previews, parts, statistics, charts, checkpoints) is
//! written to a temporary file in the same folder, flushed to disk, and renamed over its final name. A process
//! killed while writing, or a full disk, leaves the final name holding either nothing (or the file it held
//! before) or the complete new file, never a torn one; a farm scheduler that takes an existing output as a
//! finished task is never fooled.
//!
//! The temporary file is `.<name>.nimbus-tmp-<pid>-<n>` beside the final one (hidden, in the same folder so that
//! the rename stays on one file system). A write that fails removes it; a process killed by SIGKILL leaves it
//! behind, under its hidden name.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes the temporary files of one process.
static NEXT: AtomicU64 = AtomicU64::new(0);

/// The temporary path a write to `path` goes through.
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.nimbus-tmp-{}-{n}", std::process::id()))
}

/// Writes `bytes` to `path` atomically (see the module docs). On error `path` is untouched and the temporary
/// file removed.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let temporary = temporary_path(path);
    let written = (|| {
        let mut file = std::fs::File::create(&temporary)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&temporary, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("nimbus-atomic-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn writes_replace_the_file_and_leave_no_temporary() {
        let dir = folder("replace");
        let path = dir.join("out.exr");
        write_atomically(&path, b"first").unwrap();
        write_atomically(&path, b"second, longer").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second, longer");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert_eq!(names.len(), 1, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_old_file() {
        let dir = folder("failed");
        let path = dir.join("out.exr");
        write_atomically(&path, b"old").unwrap();
        // A final name that is a folder cannot be renamed over: the old contents elsewhere stay, and the
        // temporary file is gone.
        let folder_path = dir.join("taken");
        std::fs::create_dir(&folder_path).unwrap();
        std::fs::write(folder_path.join("x"), b"x").unwrap();
        assert!(write_atomically(&folder_path, b"new").is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        let count = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(count, 2, "no temporary file left");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
