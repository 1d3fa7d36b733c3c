//! A missing usd-core is a `MissingDependency` error with the install hint, not a panic.
//!
//! This file holds exactly one test on purpose: integration-test files run as their own process,
//! so setting `SPRINGBAKE_VENV` here, before the first USD call, decides which venv the embedded
//! interpreter sees (none: an empty folder) without affecting other tests. The machine's base
//! CPython has no `pxr` (were it there, the import would succeed and the test fail).

use springbake_core::plugin::{ImportSettings, Importer, IoErrorKind};
use springbake_testkit::corpus_dir;
use springbake_usd::UsdImporter;

#[test]
fn empty_venv_gives_missing_dependency_with_install_hint() {
    let empty = tempfile::tempdir().unwrap();
    std::env::set_var(springbake_usd::python::VENV_ENV, empty.path());
    let path = corpus_dir().join("blender/grid_open.usda");
    let bytes = std::fs::read(&path).unwrap();
    let err = UsdImporter
        .import(&path, &bytes, &ImportSettings::default())
        .unwrap_err();
    assert_eq!(err.kind, IoErrorKind::MissingDependency, "{err}");
    assert_eq!(err.path, path);
    assert!(err.message.contains("No module named 'pxr'"), "{err}");
    assert!(err.message.contains("scripts/setup-test-env.sh"), "{err}");
    assert!(err.message.contains("pip install usd-core"), "{err}");
    assert!(
        err.message.contains(&empty.path().display().to_string()),
        "the message names where it looked: {err}"
    );
    // A second call fails the same way (the failure is not cached as success).
    let again = UsdImporter
        .import(&path, &bytes, &ImportSettings::default())
        .unwrap_err();
    assert_eq!(again.kind, IoErrorKind::MissingDependency);
}
