//! `springbake plugins`: the built-in importers and exporters, then the Python plug-ins found
//! for a scene (see `springbake_usd::python_plugins`), each with its file, and the files that
//! failed to load with why.

use std::path::Path;

/// Prints the listing for the scene file or folder `scene` (default: the current folder).
pub fn list(scene: Option<&Path>, with_plugins: bool) {
    let folder = match scene {
        Some(p) if p.is_dir() => p.to_path_buf(),
        Some(p) => p.parent().map(Path::to_path_buf).unwrap_or_default(),
        None => std::env::current_dir().unwrap_or_default(),
    };
    let (registry, found) = springbake_pipeline::registry_with_plugins(Some(&folder), with_plugins);
    let origin = |kind: &str, name: &str| {
        found
            .loaded
            .iter()
            .find(|p| p.kind == kind && p.name == name)
            .map(|p| format!("  ({})", p.file.display()))
            .unwrap_or_else(|| "  (built in)".to_owned())
    };
    println!("importers:");
    for i in registry.importers() {
        let exts = i.extensions().join(", ");
        println!(
            "  {:<8} {:<24}{}",
            i.name(),
            exts,
            origin("importer", i.name())
        );
    }
    println!("exporters:");
    for e in registry.exporters() {
        let exts = e.extensions().join(", ");
        println!(
            "  {:<8} {:<24}{}",
            e.name(),
            exts,
            origin("exporter", e.name())
        );
    }
    if !registry.force_fields().is_empty() {
        println!("force fields:");
        for f in registry.force_fields() {
            let every = if f.per_substep() {
                "every substep"
            } else {
                "every frame"
            };
            println!(
                "  {:<8} {:<24}{}",
                f.name(),
                every,
                origin("force_field", f.name())
            );
        }
    }
    let procedures: Vec<_> = found
        .loaded
        .iter()
        .filter(|p| p.kind == "procedure")
        .collect();
    if !procedures.is_empty() {
        println!("procedures:");
        for p in procedures {
            println!("  {:<8} {:<24}  ({})", p.name, "", p.file.display());
        }
    }
    if !found.failed.is_empty() {
        println!("not loaded:");
        for (file, why) in &found.failed {
            println!("  {}: {why}", file.display());
        }
    }
}
