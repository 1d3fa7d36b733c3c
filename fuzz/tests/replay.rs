//! The fuzzers' minimised corpora (`fuzz/corpus/<target>/`, kept by `scripts/fuzz.sh`) and the
//! shared corpus's files replayed through the fuzz targets: no input may panic, and each
//! must finish within the per-case bound of issue 17 (10 s).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const PER_CASE: Duration = Duration::from_secs(10);

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    out.sort();
    out
}

/// Seeds from `../shared/corpus` by extension, for each target that reads such files.
fn shared_seeds(target: &str) -> Vec<PathBuf> {
    let exts: &[&str] = match target {
        "gltf" => &["gltf", "glb"],
        "obj" => &["obj"],
        "scene" => &["toml"],
        _ => &[],
    };
    let root = springbake_testkit::corpus_dir();
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(dir) = stack.pop() {
        for path in files_in(&dir) {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            if exts.contains(&ext) {
                out.push(path);
            }
        }
        if let Ok(entries) = std::fs::read_dir(&dir) {
            stack.extend(
                entries
                    .filter_map(Result::ok)
                    .map(|e| e.path())
                    .filter(|p| p.is_dir()),
            );
        }
    }
    out.sort();
    out
}

#[test]
fn every_kept_case_runs_without_panic_in_bounded_time() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus");
    let mut failures = Vec::new();
    let mut ran = 0;
    for &(name, target) in springbake_fuzz::TARGETS {
        let mut cases = files_in(&corpus.join(name));
        cases.extend(shared_seeds(name));
        for case in cases {
            let Ok(bytes) = std::fs::read(&case) else {
                continue;
            };
            let started = Instant::now();
            if std::panic::catch_unwind(|| target(&bytes)).is_err() {
                failures.push(format!("{name}: {} panicked", case.display()));
            }
            if started.elapsed() > PER_CASE {
                failures.push(format!(
                    "{name}: {} took {:?}",
                    case.display(),
                    started.elapsed()
                ));
            }
            ran += 1;
        }
    }
    println!("replayed {ran} cases");
    assert!(ran > 0, "no fuzz cases found under {}", corpus.display());
    assert!(
        failures.is_empty(),
        "{ran} cases, failures:\n{}",
        failures.join("\n")
    );
}
