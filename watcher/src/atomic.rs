//! Atomic file replacement for hosts and jobs: [`write_atomically`] writes a temporary file in
//! the target's folder, flushes it to disk and renames it over the target, so readers (and a
//! watch loop whose bake fails half-way) only ever see the old file or the complete new one;
//! [`write_set_atomically`] does the same for a set of files that belong together (`.gltf` and
//! its `.bin`): every file is staged before any is renamed.

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
    stage_with(path, write)?.commit()
}

/// Replaces several files so that a failure while writing (disk full, a folder that cannot be
/// written) leaves every old file as it was: all contents go to flushed temporary files first,
/// and only then are they renamed into place, the first file last. Put the file that refers to
/// the others first (a `.gltf` before its `.bin`), so that it is the last to change. Between
/// two renames (no data is written there) a crash can still leave a new `.bin` beside an old
/// `.gltf`; the renames are the only step not covered.
pub fn write_set_atomically(files: &[(&Path, &[u8])]) -> io::Result<()> {
    let mut staged = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        staged.push(stage_with(path, |file| file.write_all(bytes))?);
    }
    if staged.is_empty() {
        return Ok(());
    }
    // On an error, dropping what is left removes its temporary files.
    let first = staged.remove(0);
    for file in staged {
        file.commit()?;
    }
    first.commit()
}

/// A complete, flushed temporary file waiting to be renamed over its target; dropped without
/// [`commit`](Self::commit), it is removed and the target stays as it was.
#[derive(Debug)]
pub struct StagedFile {
    temp: PathBuf,
    target: PathBuf,
    dir: PathBuf,
    committed: bool,
}

impl StagedFile {
    /// Renames the temporary file over the target and syncs the folder.
    pub fn commit(mut self) -> io::Result<()> {
        fs::rename(&self.temp, &self.target).map_err(|e| with_path(e, &self.target))?;
        self.committed = true;
        sync_dir(&self.dir);
        Ok(())
    }
}

impl Drop for StagedFile {
    fn drop(&mut self) {
        if !self.committed {
            // Best effort: the file may already be gone.
            let _ = fs::remove_file(&self.temp);
        }
    }
}

/// Writes a temporary file beside `path` with `write`, keeping an existing target's
/// permissions, flushed to disk; the target is not touched yet.
pub fn stage_with(
    path: &Path,
    write: impl FnOnce(&mut File) -> io::Result<()>,
) -> io::Result<StagedFile> {
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
    let (temp, mut file) = create_temp(&dir, file_name).map_err(|e| with_path(e, &dir))?;
    let staged = StagedFile {
        temp,
        target: path.to_path_buf(),
        dir,
        committed: false,
    };
    let result = (|| {
        if let Ok(meta) = fs::metadata(path) {
            // Keep the mode of the file we replace (e.g. group-readable outputs).
            file.set_permissions(meta.permissions())?;
        }
        write(&mut file)?;
        file.flush()?;
        file.sync_all()
    })();
    result.map_err(|e| with_path(e, path))?;
    Ok(staged)
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
    fn a_set_is_written_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let gltf = dir.path().join("out.gltf");
        let bin = dir.path().join("out.bin");
        write_set_atomically(&[(&gltf, b"json 1"), (&bin, b"bin 1")]).unwrap();
        assert_eq!(fs::read(&gltf).unwrap(), b"json 1");
        assert_eq!(fs::read(&bin).unwrap(), b"bin 1");
        // The second file cannot be staged (its target's folder does not exist): neither file
        // changes and no temporary file is left.
        let bad = dir.path().join("missing-folder").join("out.bin");
        assert!(write_set_atomically(&[(&gltf, b"json 2"), (&bad, b"bin 2")]).is_err());
        assert_eq!(fs::read(&gltf).unwrap(), b"json 1");
        assert!(leftovers(dir.path(), &["out.gltf", "out.bin"]).is_empty());
        // A rename that fails (a folder in the way of the second file) leaves the first file
        // old: it is renamed last.
        let blocked = dir.path().join("blocked.bin");
        fs::create_dir(&blocked).unwrap();
        fs::write(blocked.join("keep"), b"x").unwrap();
        assert!(write_set_atomically(&[(&gltf, b"json 3"), (&blocked, b"bin 3")]).is_err());
        assert_eq!(fs::read(&gltf).unwrap(), b"json 1");
        assert!(leftovers(dir.path(), &["out.gltf", "out.bin", "blocked.bin"]).is_empty());
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
