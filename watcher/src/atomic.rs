//! Atomic file replacement for hosts and jobs: [`write_atomically`] writes a temporary file in
//! the target's folder, flushes it to disk and renames it over the target, so readers (and a
//! watch loop whose bake fails half-way) only ever see the old file or the complete new one.

use std::ffi::OsString;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Replaces `path` with `bytes` atomically.
///
/// The bytes go to a temporary file in the same folder (so the final rename never crosses a
/// file system), which is flushed with `fsync` and renamed over `path`; the folder is then
/// synced too where the platform allows. An existing file's permissions are kept. On any error
/// the temporary file is removed and `path` is untouched.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomically_with(path, |file| file.write_all(bytes))
}

/// Like [`write_atomically`], but `write` streams the content into the temporary file (e.g. an
/// exporter writing through a `BufWriter`). If `write` fails, the temporary file is removed,
/// `path` is untouched and the error is returned.
pub fn write_atomically_with(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<()> {
    let file_name = path.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{}: not a file path", path.display()),
        )
    })?;
    let dir = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let (temp_path, mut file) = create_temp(&dir, file_name).map_err(|e| with_path(e, &dir))?;
    let result = (|| {
        if let Ok(meta) = fs::metadata(path) {
            // Keep the mode of the file we replace (e.g. group-readable outputs).
            file.set_permissions(meta.permissions())?;
        }
        write(&mut file)?;
        file.flush()?;
        file.sync_all()?;
        drop(file);
        fs::rename(&temp_path, path)
    })();
    if let Err(error) = result {
        // The temp file may already be closed or renamed; removal is best effort.
        let _ = fs::remove_file(&temp_path);
        return Err(with_path(error, path));
    }
    sync_dir(&dir);
    Ok(())
}

/// Adds the path to an I/O error's message, keeping its kind.
fn with_path(error: io::Error, path: &Path) -> io::Error {
    io::Error::new(error.kind(), format!("{}: {error}", path.display()))
}

/// Creates `.<name>.<pid>.<n>.tmp` next to the target, never reusing an existing name.
fn create_temp(dir: &Path, file_name: &std::ffi::OsStr) -> io::Result<(PathBuf, File)> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    // Keep the temp name well under the usual 255-byte limit on a file name.
    let stem: String = file_name.to_string_lossy().chars().take(64).collect();
    loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut name = OsString::from(".");
        name.push(&stem);
        name.push(format!(".{}.{n}.tmp", std::process::id()));
        let temp_path = dir.join(name);
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp_path)
        {
            Ok(file) => return Ok((temp_path, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Makes the rename itself durable (POSIX needs the directory synced); best effort.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(handle) = File::open(dir) {
        let _ = handle.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names in `dir` other than `keep`.
    fn leftovers(dir: &Path, keep: &[&str]) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !keep.contains(&n.as_str()))
            .collect();
        names.sort();
        names
    }

    #[test]
    fn creates_and_replaces_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.glb");
        write_atomically(&path, b"first").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"first");
        write_atomically(&path, b"second, longer").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"second, longer");
        write_atomically(&path, b"").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"");
        assert!(leftovers(dir.path(), &["out.glb"]).is_empty());
    }

    #[test]
    fn a_failing_writer_leaves_the_old_file_and_no_temp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.pc2");
        fs::write(&path, b"last good").unwrap();
        let err = write_atomically_with(&path, |file| {
            file.write_all(b"half a fram")?;
            Err(io::Error::other("simulated exporter failure"))
        })
        .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::Other);
        assert!(
            err.to_string().contains("simulated exporter failure"),
            "{err}"
        );
        assert!(err.to_string().contains("out.pc2"), "{err}");
        assert_eq!(fs::read(&path).unwrap(), b"last good");
        assert!(leftovers(dir.path(), &["out.pc2"]).is_empty());
    }

    #[test]
    fn a_failing_rename_leaves_the_target_and_no_temp() {
        // Renaming a file over a non-empty directory fails on every platform (even for root,
        // where a read-only folder would not stop the write).
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.usda");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("keep.txt"), b"inside").unwrap();
        assert!(write_atomically(&target, b"new").is_err());
        assert!(target.is_dir());
        assert_eq!(fs::read(target.join("keep.txt")).unwrap(), b"inside");
        assert!(leftovers(dir.path(), &["out.usda"]).is_empty());
    }

    #[test]
    fn a_missing_folder_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no-such-dir").join("out.glb");
        let err = write_atomically(&path, b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(err.to_string().contains("no-such-dir"), "{err}");
        assert!(leftovers(dir.path(), &[]).is_empty());
    }

    #[test]
    fn a_path_without_file_name_is_rejected() {
        let err = write_atomically(Path::new("/"), b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[cfg(unix)]
    #[test]
    fn keeps_the_mode_of_the_replaced_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.mdd");
        fs::write(&path, b"old").unwrap();
        fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
        write_atomically(&path, b"new").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(
            fs::metadata(&path).unwrap().permissions().mode() & 0o777,
            0o640
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_read_only_folder_leaves_the_old_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("ro");
        fs::create_dir(&sub).unwrap();
        let path = sub.join("out.glb");
        fs::write(&path, b"last good").unwrap();
        fs::set_permissions(&sub, fs::Permissions::from_mode(0o555)).unwrap();
        // Root ignores folder permissions, so the write may succeed there; either way the file
        // holds a complete version and no temp file is left behind.
        let result = write_atomically(&path, b"new");
        fs::set_permissions(&sub, fs::Permissions::from_mode(0o755)).unwrap();
        match result {
            Ok(()) => assert_eq!(fs::read(&path).unwrap(), b"new"),
            Err(err) => {
                assert_eq!(err.kind(), io::ErrorKind::PermissionDenied, "{err}");
                assert_eq!(fs::read(&path).unwrap(), b"last good");
            }
        }
        assert!(leftovers(&sub, &["out.glb"]).is_empty());
    }
}
