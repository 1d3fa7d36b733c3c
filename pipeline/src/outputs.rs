//! Where a bake writes (issue 17, item 5): the refusals made before any work — an output that
//! is one of the bake's inputs, a report that is the output, a folder that cannot be written —
//! and the write itself, the whole set of files staged before any is renamed into place
//! ([`springbake_watcher::write_set_atomically`]).

use crate::{LoadedScene, PipelineError};
use springbake_core::plugin::OutputFile;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

/// `path` with symlinks resolved; for a file that does not exist yet, its resolved folder
/// joined with its name (so `out/../in.obj` and `in.obj` compare equal before either exists).
fn resolved(path: &Path) -> PathBuf {
    if let Ok(real) = std::fs::canonicalize(path) {
        return real;
    }
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) => {
            let parent = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            resolved(parent).join(name)
        }
        _ => path.to_path_buf(),
    }
}

/// True when `a` and `b` name the same file (after symlinks and `..`).
pub fn same_file(a: &Path, b: &Path) -> bool {
    resolved(a) == resolved(b)
}

/// Refuses writing `output` when it is one of the bake's inputs (the scene file, a source, a
/// collider): a bake never replaces what it read.
pub fn refuse_overwriting_inputs(loaded: &LoadedScene, output: &Path) -> Result<(), PipelineError> {
    match loaded.inputs().into_iter().find(|i| same_file(i, output)) {
        Some(input) => Err(PipelineError::Usage(format!(
            "{}: the output would overwrite the input {}; choose another output path (-o)",
            output.display(),
            input.display()
        ))),
        None => Ok(()),
    }
}

/// Outputs that are folders of files (vertex animation textures, `out.vat/`).
pub fn is_folder_output(output: &Path) -> bool {
    output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vat"))
}

/// Checks, before simulating, that a file can be created where `output` goes: the nearest
/// folder that exists on its path must be a folder we can create files in, and `output`
/// itself must not be a folder. Exit code 2 when not (the user's path).
pub fn check_writable(output: &Path, what: &str) -> Result<(), PipelineError> {
    let refuse = |message: String| {
        Err(PipelineError::Usage(format!(
            "{}: cannot write the {what} there: {message}",
            output.display()
        )))
    };
    let folder_output = is_folder_output(output);
    if output.is_dir() && !folder_output {
        return refuse("it is a folder; give a file name".into());
    }
    if output.exists() && folder_output && !output.is_dir() {
        return refuse("it is a file, and this output is a folder".into());
    }
    let mut folder = if folder_output && output.is_dir() {
        output.to_path_buf()
    } else {
        output.parent().unwrap_or(Path::new("")).to_path_buf()
    };
    loop {
        if folder.as_os_str().is_empty() {
            folder = PathBuf::from(".");
        }
        if folder.exists() {
            break;
        }
        match folder.parent() {
            Some(parent) => folder = parent.to_path_buf(),
            None => break,
        }
    }
    if !folder.is_dir() {
        return refuse(format!("{} is not a folder", folder.display()));
    }
    match tempfile::Builder::new()
        .prefix(".springbake-write-check")
        .tempfile_in(&folder)
    {
        Ok(_probe) => Ok(()), // removed on drop
        Err(e) => refuse(format!(
            "the folder {} is not writable ({e})",
            folder.display()
        )),
    }
}

/// I/O errors caused by the user's paths (exit code 2) rather than by the machine.
fn is_users_fault(kind: ErrorKind) -> bool {
    matches!(
        kind,
        ErrorKind::PermissionDenied
            | ErrorKind::ReadOnlyFilesystem
            | ErrorKind::IsADirectory
            | ErrorKind::NotADirectory
            | ErrorKind::NotFound
            | ErrorKind::InvalidFilename
    )
}

/// Writes every file of a bake as one set: each is staged in a flushed temporary file beside
/// its target and only then renamed into place, the first file (the one that names the others,
/// e.g. the `.gltf` of a `.gltf` + `.bin`) last. A failure while writing leaves every previous
/// file as it was. Files equal to one of `inputs` are refused before anything is written.
pub fn write_outputs(files: &[OutputFile], inputs: &[PathBuf]) -> Result<(), PipelineError> {
    for f in files {
        if let Some(input) = inputs.iter().find(|i| same_file(i, &f.path)) {
            return Err(PipelineError::Usage(format!(
                "{}: the output would overwrite the input {}; choose another output path",
                f.path.display(),
                input.display()
            )));
        }
    }
    for f in files {
        if let Some(dir) = f.path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| io_error(dir, "cannot create the output folder", &e))?;
        }
    }
    let set: Vec<(&Path, &[u8])> = files
        .iter()
        .map(|f| (f.path.as_path(), f.bytes.as_slice()))
        .collect();
    springbake_watcher::write_set_atomically(&set).map_err(|e| {
        let path = files
            .first()
            .map(|f| f.path.as_path())
            .unwrap_or(Path::new(""));
        io_error(path, "cannot write the output", &e)
    })
}

fn io_error(path: &Path, what: &str, e: &std::io::Error) -> PipelineError {
    if is_users_fault(e.kind()) {
        PipelineError::Usage(format!("{}: {what}: {e}", path.display()))
    } else {
        PipelineError::Io {
            path: path.to_path_buf(),
            message: format!("{what}: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_same_file_is_recognised_through_dots_and_links() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.obj");
        std::fs::write(&a, "v 0 0 0\n").unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        assert!(same_file(&a, &dir.path().join("sub/../a.obj")));
        assert!(!same_file(&a, &dir.path().join("b.obj")));
        assert!(same_file(
            &dir.path().join("new.glb"),
            &dir.path().join("sub/../new.glb")
        ));
        #[cfg(unix)]
        {
            let link = dir.path().join("link.obj");
            std::os::unix::fs::symlink(&a, &link).unwrap();
            assert!(same_file(&a, &link));
        }
    }

    #[test]
    fn folders_and_files_in_the_way_are_refused_before_the_bake() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_writable(&dir.path().join("new/deeper/out.glb"), "output").is_ok());
        let err = check_writable(dir.path(), "report")
            .unwrap_err()
            .to_string();
        assert!(err.contains("it is a folder"), "{err}");
        let file = dir.path().join("file");
        std::fs::write(&file, "x").unwrap();
        let err = check_writable(&file.join("out.glb"), "output")
            .unwrap_err()
            .to_string();
        assert!(err.contains("is not a folder"), "{err}");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no probe left"
        );
    }
}
