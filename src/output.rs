//! Output files, written whole or not at all, and checked before any work is done.
//!
//! Every file raypack writes (images, ray and hit files, OBJ exports, JSON reports) goes
//! through [`write_atomic`]: the bytes go to a hidden temporary file beside the target,
//! which is synced and renamed over it, so a crash or a full disk never leaves half a
//! file under the target's name. [`check_writable`] lets a command refuse a bad output
//! path before a long render or build rather than after it.

use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

/// The hidden sibling `.NAME.PID.SUFFIX` of `path`, in the same folder so a rename
/// over `path` stays within one file system.
fn sibling(path: &Path, suffix: &str) -> io::Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let mut tmp = std::ffi::OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".{}.{suffix}", std::process::id()));
    Ok(path.with_file_name(tmp))
}

/// Writes through `f` into a temporary file beside `path`, then renames it to `path`;
/// on any failure the temporary file is removed and `path` is left as it was. I/O
/// failures reach the caller through `io_err`, so each caller keeps its own error type.
pub fn write_atomic<E>(
    path: &Path,
    io_err: impl Fn(io::Error) -> E,
    f: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
) -> Result<(), E> {
    let tmp = sibling(path, "tmp").map_err(&io_err)?;
    let result = File::create(&tmp).map_err(&io_err).and_then(|file| {
        let mut w = BufWriter::new(file);
        f(&mut w)?;
        let file = w.into_inner().map_err(|e| io_err(e.into_error()))?;
        file.sync_all().map_err(&io_err)
    });
    let result = result.and_then(|()| std::fs::rename(&tmp, path).map_err(&io_err));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`write_atomic`] of a byte slice.
pub fn write_bytes_atomic<E>(
    path: &Path,
    bytes: &[u8],
    io_err: impl Fn(io::Error) -> E,
) -> Result<(), E> {
    write_atomic(path, &io_err, |w| {
        io::Write::write_all(w, bytes).map_err(&io_err)
    })
}

/// Succeeds when [`write_atomic`] can create a file beside `path` and `path` is not a
/// folder: the folder exists and is writable. Creates and removes a probe file, the one
/// check that answers for permissions, read-only mounts and missing folders alike.
pub fn check_writable(path: &Path) -> io::Result<()> {
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            "is a directory",
        ));
    }
    let probe = sibling(path, "probe")?;
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)?;
    std::fs::remove_file(&probe)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("raypack-output-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn writes_whole_files_and_leaves_nothing_on_failure() {
        let dir = temp_dir("atomic");
        let target = dir.join("a.bin");
        write_bytes_atomic(&target, b"abc", |e| e).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"abc");
        // A writer that fails half way leaves the old file as it was.
        let err = write_atomic(
            &target,
            |e| e,
            |w| {
                io::Write::write_all(w, b"half")?;
                Err(io::Error::other("disk full"))
            },
        )
        .unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        assert_eq!(std::fs::read(&target).unwrap(), b"abc");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.bin")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn check_writable_refuses_missing_folders_and_directories() {
        let dir = temp_dir("check");
        check_writable(&dir.join("x.png")).unwrap();
        let missing = check_writable(&dir.join("missing").join("x.png")).unwrap_err();
        assert_eq!(missing.kind(), io::ErrorKind::NotFound);
        let is_dir = check_writable(&dir).unwrap_err();
        assert_eq!(is_dir.kind(), io::ErrorKind::IsADirectory);
        assert!(
            std::fs::read_dir(&dir).unwrap().next().is_none(),
            "probe left behind"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
