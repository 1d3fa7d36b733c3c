//! Test-only helpers shared by every crate's integration tests: where the workspace and the
//! corpus are, and how to run the real clients (Blender's `bpy` and `usd-core` in `.venv`,
//! Khronos `gltf-validator` in `node_modules`) installed by `scripts/setup-test-env.sh`.
//!
//! A missing client is a test failure with the command that installs it, never a skip.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace root (the folder holding the top `Cargo.toml`).
pub fn workspace_root() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent()
        .expect("testkit lives one level below the root")
        .to_path_buf()
}

/// `../shared/corpus` beside the checkout.
pub fn corpus_dir() -> PathBuf {
    let dir = workspace_root().join("../shared/corpus");
    assert!(
        dir.join("manifest.json").is_file(),
        "test corpus not found at {}: the project expects ../shared beside the checkout",
        dir.display()
    );
    dir
}

/// One entry of `corpus/manifest.json`.
#[derive(Debug, Clone)]
pub struct CorpusEntry {
    pub path: PathBuf,
    pub format: String,
    pub expect_ok: bool,
    pub why: String,
}

/// Every corpus entry whose format is one of `formats`.
pub fn corpus_entries(formats: &[&str]) -> Vec<CorpusEntry> {
    let dir = corpus_dir();
    let text = std::fs::read_to_string(dir.join("manifest.json")).expect("read manifest.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("manifest.json is JSON");
    json.as_array()
        .expect("manifest is an array")
        .iter()
        .filter(|e| formats.contains(&e["format"].as_str().unwrap_or("")))
        .map(|e| CorpusEntry {
            path: dir.join(e["path"].as_str().expect("path")),
            format: e["format"].as_str().unwrap_or("").to_owned(),
            expect_ok: e["expect"].as_str() == Some("ok"),
            why: e["why"].as_str().unwrap_or("").to_owned(),
        })
        .collect()
}

fn setup_hint() -> &'static str {
    "run `scripts/setup-test-env.sh` (the README's test command does) to install the test clients"
}

/// The `.venv` interpreter that has `bpy` and `usd-core`.
pub fn venv_python() -> PathBuf {
    let py = workspace_root().join(".venv/bin/python");
    assert!(py.is_file(), "{} missing: {}", py.display(), setup_hint());
    py
}

/// Run a Python script from `tests/clients/` with the venv interpreter; returns stdout.
/// Panics with the script's stderr when it exits non-zero.
pub fn run_python_client(script: &str, args: &[&str]) -> String {
    let path = workspace_root().join("tests/clients").join(script);
    let out = Command::new(venv_python())
        .arg(&path)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("start {}: {e}", path.display()));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{script} {args:?} failed ({}):\nstdout:\n{stdout}\nstderr:\n{stderr}",
        out.status
    );
    stdout
}

/// Run a Node.js test client from `tests/clients/` in the workspace root; panics with its output
/// when it fails. Returns its stdout.
pub fn run_node_client(script: &str, args: &[&str]) -> String {
    let root = workspace_root();
    let path = root.join("tests/clients").join(script);
    let out = Command::new("node")
        .arg(&path)
        .args(args)
        .current_dir(&root)
        .output()
        .unwrap_or_else(|e| panic!("start node {}: {e}", path.display()));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{script} {args:?} failed ({}):\nstdout:\n{stdout}\nstderr:\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        setup_hint()
    );
    stdout
}

/// The last line of a client's stdout parsed as JSON (clients print their result last; Blender
/// prints its own chatter before it).
pub fn last_json_line(stdout: &str) -> serde_json::Value {
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| panic!("no JSON line in client output:\n{stdout}"));
    serde_json::from_str(line).unwrap_or_else(|e| panic!("bad JSON from client ({e}): {line}"))
}

/// Validate a .gltf/.glb file with Khronos gltf-validator; returns the report JSON.
pub fn gltf_validate(file: &Path) -> serde_json::Value {
    let root = workspace_root();
    assert!(
        root.join("node_modules/gltf-validator/package.json")
            .is_file(),
        "node_modules/gltf-validator missing: {}",
        setup_hint()
    );
    let out = Command::new("node")
        .arg(root.join("tests/clients/validate_gltf.js"))
        .arg(file)
        .current_dir(&root)
        .output()
        .expect("start node");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "gltf-validator run failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("validator output ({e}): {stdout}"))
}

/// Assert gltf-validator finds no errors, printing the messages when it does.
pub fn assert_gltf_valid(file: &Path) {
    let report = gltf_validate(file);
    let errors = report["issues"]["numErrors"].as_u64().expect("numErrors");
    assert_eq!(
        errors,
        0,
        "gltf-validator errors in {}:\n{}",
        file.display(),
        serde_json::to_string_pretty(&report["issues"]["messages"]).unwrap_or_default()
    );
}
