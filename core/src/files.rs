//! Reading the user's files, bounded and contained (issue 17, items 3 and 4).
//!
//! - [`read_source`]: a file must be regular (after symlinks) and no larger than
//!   [`max_source_bytes`]; directories, FIFOs and devices are refused before anything is read
//!   (a FIFO blocked the bake, `/dev/zero` ate memory), and the read itself stops at the limit
//!   should the file grow meanwhile.
//! - [`contained`]: a path is read only when, with every symlink resolved, it lies inside the
//!   folder tree the user handed over (the scene's folder, or a glTF file's own folder for its
//!   buffers), so `../`, absolute paths and links pointing out are refused by one rule.

use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest source file by default, bytes (2 GiB).
pub const DEFAULT_MAX_SOURCE_BYTES: u64 = 2 << 30;

/// The largest source file a bake reads: `SPRINGBAKE_MAX_SOURCE_BYTES` when set to a
/// number, else [`DEFAULT_MAX_SOURCE_BYTES`].
pub fn max_source_bytes() -> u64 {
    std::env::var("SPRINGBAKE_MAX_SOURCE_BYTES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(DEFAULT_MAX_SOURCE_BYTES)
}

/// The bytes of the source file at `path`, or why it cannot be read (a sentence naming the
/// problem; the caller names the file).
pub fn read_source(path: &Path) -> Result<Vec<u8>, String> {
    read_bounded(path, max_source_bytes())
}

/// [`read_source`] with the limit `limit` bytes.
pub fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read the source file: {e}"))?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a FIFO, socket or device)"
        };
        return Err(format!(
            "the source is {kind}: springbake reads mesh files only"
        ));
    }
    let too_big = |size: u64| {
        format!(
            "the source file is {size} bytes, over the {limit}-byte limit for a source (set \
             SPRINGBAKE_MAX_SOURCE_BYTES to raise it)"
        )
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let file =
        std::fs::File::open(path).map_err(|e| format!("cannot read the source file: {e}"))?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read the source file: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// `path` with every symlink resolved, when it lies inside `root`'s folder tree (also resolved);
/// otherwise why not, naming both. A path that does not exist is refused too: there is nothing
/// to read, and the caller's message for a missing file is clearer than a containment one.
pub fn contained(root: &Path, path: &Path) -> Result<PathBuf, String> {
    let root_real = std::fs::canonicalize(if root.as_os_str().is_empty() {
        Path::new(".")
    } else {
        root
    })
    .map_err(|e| format!("cannot resolve the folder {}: {e}", root.display()))?;
    let real =
        std::fs::canonicalize(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if real.starts_with(&root_real) {
        Ok(real)
    } else {
        Err(format!(
            "{} resolves to {}, outside the folder {}: springbake reads only files inside it \
             (a scene file's folder, or a bare mesh's own: to read both, bake a scene file \
             placed in a folder that holds them)",
            path.display(),
            real.display(),
            root_real.display()
        ))
    }
}

/// [`read_source`] of `path` after [`contained`] in `root`.
pub fn read_contained(root: &Path, path: &Path) -> Result<Vec<u8>, String> {
    let real = contained(root, path)?;
    read_source(&real)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_fifos_and_oversized_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_bounded(dir.path(), 100).unwrap_err();
        assert!(err.contains("a directory"), "{err}");
        let file = dir.path().join("m.obj");
        std::fs::write(&file, "v 0 0 0\n").unwrap();
        assert_eq!(read_bounded(&file, 100).unwrap(), b"v 0 0 0\n");
        let err = read_bounded(&file, 4).unwrap_err();
        assert!(err.contains("over the 4-byte limit"), "{err}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("pipe.obj");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let err = read_bounded(&fifo, 100).unwrap_err();
                assert!(err.contains("not a regular file"), "{err}");
            }
            let err = read_bounded(Path::new("/dev/zero"), 100).unwrap_err();
            assert!(err.contains("not a regular file"), "{err}");
        }
    }

    #[test]
    fn paths_are_read_only_inside_the_root_after_symlinks() {
        let outer = tempfile::tempdir().unwrap();
        let root = outer.path().join("scene");
        std::fs::create_dir_all(root.join("sub")).unwrap();
        std::fs::write(root.join("sub/in.obj"), "v 0 0 0\n").unwrap();
        std::fs::write(outer.path().join("secret.obj"), "v 1 1 1\n").unwrap();
        assert!(contained(&root, &root.join("sub/in.obj")).is_ok());
        assert!(contained(&root, &root.join("sub/../sub/in.obj")).is_ok());
        let err = contained(&root, &root.join("../secret.obj")).unwrap_err();
        assert!(err.contains("outside the folder"), "{err}");
        assert!(contained(&root, &root.join("missing.obj")).is_err());
        #[cfg(unix)]
        {
            let link = root.join("link.obj");
            std::os::unix::fs::symlink(outer.path().join("secret.obj"), &link).unwrap();
            let err = read_contained(&root, &link).unwrap_err();
            assert!(err.contains("outside the folder"), "{err}");
            // A link that stays inside is fine.
            let inner = root.join("inner.obj");
            std::os::unix::fs::symlink(root.join("sub/in.obj"), &inner).unwrap();
            assert_eq!(read_contained(&root, &inner).unwrap(), b"v 0 0 0\n");
        }
    }
}
