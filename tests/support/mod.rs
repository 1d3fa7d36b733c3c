//! Helpers shared by the CLI's integration tests: run the binary, read its stderr, find the
//! shared corpus, copy the example cube.
#![allow(dead_code)] // each test file uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `springbake` with `args` and waits for it.
pub fn springbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args(args)
        .output()
        .expect("run springbake")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A file of `../shared/corpus`.
pub fn corpus(rel: &str) -> PathBuf {
    springbake_testkit::corpus_dir().join(rel)
}

/// Copies `examples/cube.obj` to `dir/name`.
pub fn cube(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/cube.obj"),
        &path,
    )
    .expect("copy the example cube");
    path
}
