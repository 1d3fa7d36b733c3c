//! Fuzz targets (issue 17, item 7): each takes arbitrary bytes and runs one reader of user
//! input the way a bake does, then fits the analysis model to what it read, so a panic, an
//! abort or a runaway allocation anywhere on that path is a finding. A target returns normally
//! for every input, whether it was accepted or refused with an error.
//!
//! The same functions serve the AFL binaries (`fuzz/afl`, `scripts/fuzz.sh`) and the replay
//! of the minimised corpora in CI (`tests/replay.rs`).

use springbake_core::display::ImportedScene;
use springbake_core::lattice::{fit_lattice, surface_samples, Embedding, FitSettings, Resolution};
use springbake_core::nalgebra::Point3;
use springbake_core::plugin::{ImportSettings, Importer};
use springbake_core::scene::SceneFile;
use springbake_usd::mesh::{build_display_mesh, Interpolation, RawMesh, RawPrimvar};
use std::path::Path;

/// A fuzz target: any bytes in, no panic out.
pub type Target = fn(&[u8]);

/// Every target, by name (the corpus folder's name).
pub const TARGETS: &[(&str, Target)] = &[
    ("gltf", gltf),
    ("obj", obj),
    ("scene", scene),
    ("usd_mesh", usd_mesh),
];

/// Fits a coarse lattice to every imported mesh, embeds it and samples its surface, as
/// `prepare` does; errors are fine, panics are not.
fn fit_all(scene: &ImportedScene) {
    for mesh in &scene.meshes {
        let points: Vec<Point3<f64>> = mesh
            .world_positions()
            .iter()
            .map(|p| p * scene.meters_per_unit)
            .collect();
        let triangles = mesh.triangles();
        let settings = FitSettings {
            resolution: Resolution::CellsAlongLongest(4),
            // Small enough that a fuzzer's memory limit is never the finding.
            memory_limit_bytes: 64 << 20,
            ..FitSettings::default()
        };
        if let Ok(lattice) = fit_lattice(&points, &triangles, &settings) {
            let _ = Embedding::new(&lattice, &points);
            let _ = surface_samples(&points, &triangles, lattice.cell_size);
        }
    }
}

/// glTF (JSON) or GLB bytes; external URIs resolve beside a file that does not exist.
pub fn gltf(data: &[u8]) {
    let name = if data.starts_with(b"glTF") {
        "fuzz.glb"
    } else {
        "fuzz.gltf"
    };
    let importer = springbake_importers::gltf::GltfImporter;
    if let Ok(scene) = importer.import(Path::new(name), data, &ImportSettings::default()) {
        fit_all(&scene);
    }
}

/// OBJ text (any bytes).
pub fn obj(data: &[u8]) {
    let importer = springbake_importers::obj::ObjImporter;
    if let Ok(scene) = importer.import(Path::new("fuzz.obj"), data, &ImportSettings::default()) {
        fit_all(&scene);
    }
}

/// A scene file: parsed, then checked as `springbake bake` checks it before any work.
pub fn scene(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scene) = SceneFile::parse(text) {
        let _ = springbake_pipeline::validate_scene(&scene);
    }
}

/// The Rust half of the USD importer: face counts, indices, points and primvars as usd-core
/// hands them over, decoded from the bytes, triangulated and split into display vertices.
/// (usd-core's own text parser is C++ and is not instrumented by AFL; the corpus replay
/// runs real `.usda` files through it.)
pub fn usd_mesh(data: &[u8]) {
    let mut bytes = data.iter().copied();
    let mut next = || bytes.next().unwrap_or(0);
    let n_points = usize::from(next() % 32);
    let n_faces = usize::from(next() % 16);
    let points: Vec<[f64; 3]> = (0..n_points)
        .map(|_| [0, 1, 2].map(|_| f64::from(next() as i8) / 8.0))
        .collect();
    let counts: Vec<i32> = (0..n_faces).map(|_| i32::from(next() as i8)).collect();
    let corners: usize = counts.iter().map(|&c| c.clamp(0, 12) as usize).sum();
    let indices: Vec<i32> = (0..corners + usize::from(next() % 3))
        .map(|_| i32::from(next() as i8))
        .collect();
    let mut primvar = |comps: usize| {
        let interpolation = match next() % 5 {
            0 => return None,
            1 => Interpolation::Constant,
            2 => Interpolation::Uniform,
            3 => Interpolation::Vertex,
            _ => Interpolation::FaceVarying,
        };
        let len = usize::from(next() % 64) * comps / 2;
        let values = (0..len).map(|_| f64::from(next() as i8) / 16.0).collect();
        Some(RawPrimvar {
            interpolation,
            values,
        })
    };
    let normals = primvar(3);
    let st = primvar(2);
    let raw = RawMesh {
        path: "/Fuzz".into(),
        name: "Fuzz".into(),
        points,
        counts,
        indices,
        normals,
        normals_source: None,
        st,
        left_handed: next() & 1 == 1,
        material: None,
        // Some faces (possibly out of range) bound to a second material.
        subsets: {
            let n = next() % 4;
            let faces: Vec<i32> = (0..n).map(|_| i32::from(next()) - 8).collect();
            if faces.is_empty() {
                Vec::new()
            } else {
                vec![("Subset".into(), faces)]
            }
        },
        world_gf: [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
        ],
    };
    let _ = build_display_mesh(&raw, Path::new("fuzz.usda"));
}
