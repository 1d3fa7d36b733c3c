//! End-to-end bakes through the pipeline, checked by real clients: Khronos gltf-validator and
//! Blender (bpy) playing the baked glTF, plus physics of the default bare-mesh scene.
#![allow(clippy::unwrap_used)]

use serde_json::{json, Value};
use springbake_core::bake::BakedScene;
use springbake_core::nalgebra::Point3;
use springbake_core::scene::CacheSpec;
use springbake_core::solver::FrameDiagnostics;
use springbake_pipeline::{
    default_registry, default_scene_for_mesh, export, prepare, write_outputs, BakeHooks,
    LoadedScene, MeshOverrides, Prepared, Seconds,
};
use std::path::{Path, PathBuf};

fn corpus(name: &str) -> PathBuf {
    springbake_testkit::corpus_dir().join("blender").join(name)
}

/// Bake a bare mesh with the default scene; returns the prepared world, the bake and the files.
fn bake_mesh(
    mesh: &Path,
    out: &Path,
    frames: usize,
    cache: CacheSpec,
) -> (Prepared, BakedScene, Vec<PathBuf>) {
    let (prepared, baked, files, _) = bake_mesh_diagnostics(mesh, out, frames, cache);
    (prepared, baked, files)
}

/// [`bake_mesh`] that also returns the per-frame diagnostics.
fn bake_mesh_diagnostics(
    mesh: &Path,
    out: &Path,
    frames: usize,
    cache: CacheSpec,
) -> (Prepared, BakedScene, Vec<PathBuf>, Vec<FrameDiagnostics>) {
    let registry = default_registry();
    let mut loaded: LoadedScene = default_scene_for_mesh(
        mesh,
        &MeshOverrides {
            output: Some(out.to_path_buf()),
            frames: Some(frames),
            ..Default::default()
        },
    );
    loaded.scene.output.cache = cache;
    let mut prepared = prepare(&registry, &loaded, &mut Seconds::default()).unwrap();
    let (baked, diagnostics) = prepared
        .simulate(&loaded.scene, &mut BakeHooks::default())
        .unwrap();
    assert_eq!(diagnostics.len(), frames);
    // Known weakness (see the core issue note): a boundary cell can fold for a frame on a
    // drop; more than 1 % of the cells would be a regression.
    let cells: usize = prepared.bodies.iter().map(|b| b.lattice.cell_count()).sum();
    for d in &diagnostics {
        assert!(
            d.inverted_cells * 100 <= cells,
            "frame {}: {} of {cells} cells inverted",
            d.frame,
            d.inverted_cells
        );
        assert!(
            d.max_penetration < prepared.world.settings.layer.thickness_m,
            "frame {}: {d:?}",
            d.frame
        );
    }
    let files = export(&registry, &prepared, &baked, out, cache).unwrap();
    write_outputs(&files, &[]).unwrap();
    (
        prepared,
        baked,
        files.into_iter().map(|f| f.path).collect(),
        diagnostics,
    )
}

fn world_frames(
    prepared: &Prepared,
    baked: &BakedScene,
    mesh: usize,
    frames: &[usize],
) -> Vec<Vec<[f64; 3]>> {
    let m = &prepared.export_scene.meshes[baked.meshes[mesh].mesh_index];
    frames
        .iter()
        .map(|&f| {
            baked.meshes[mesh].frames[f]
                .iter()
                .map(|p| {
                    let w = m.world_from_local.transform_point(&Point3::new(
                        p[0] as f64,
                        p[1] as f64,
                        p[2] as f64,
                    ));
                    [w.x, w.y, w.z]
                })
                .collect()
        })
        .collect()
}

#[test]
fn a_bare_mesh_falls_lands_on_the_floor_and_settles() {
    // A ball hanging below 0: the default scene puts the floor just under it, so it drops a
    // little, lands, wobbles and settles within the default 72 frames.
    let dir = tempfile::tempdir().unwrap();
    let (points, triangles) = springbake_core::shapes::uv_sphere([0.0, 0.0, 0.0], 0.5, 16, 32);
    let mut obj = String::from("o Ball\n");
    for p in &points {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &triangles {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let mesh = dir.path().join("ball.obj");
    std::fs::write(&mesh, obj).unwrap();
    let (prepared, baked, _, diagnostics) =
        bake_mesh_diagnostics(&mesh, &dir.path().join("ball.glb"), 72, CacheSpec::Morph);
    let floor = prepared.floor.expect("the default scene has a floor");
    assert!(
        floor < -0.5 && floor > -0.6,
        "just under the lowest point: {floor}"
    );
    let layer = prepared.world.settings.layer.thickness_m;
    let frames = world_frames(&prepared, &baked, 0, &[0, 71]);
    let min_y = |f: &Vec<[f64; 3]>| f.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    let (start, end) = (min_y(&frames[0]), min_y(&frames[1]));
    assert!(
        start > floor + 0.02,
        "starts above the floor: lowest {start}, floor {floor}"
    );
    assert!(
        (end - floor).abs() < layer,
        "the mesh rests on the floor, within a layer thickness: lowest {end}, floor {floor}, layer {layer}"
    );
    // Settled: over the last half second the lowest point stays within half a layer (no more
    // bounces; a ball may still roll).
    let tail: Vec<usize> = (60..72).collect();
    let heights: Vec<f64> = world_frames(&prepared, &baked, 0, &tail)
        .iter()
        .map(min_y)
        .collect();
    let spread = heights.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - heights.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        spread < 0.5 * layer,
        "still bouncing: lowest point varies by {spread} m in the last half second"
    );
    assert!(diagnostics.iter().all(|d| d.max_penetration < layer));
}

#[test]
fn baked_gltf_passes_the_validator_and_plays_in_blender() {
    let dir = tempfile::tempdir().unwrap();
    let frames = [0usize, 5, 12, 23];
    let mut specs = Vec::new();
    // The compact cache plays within its default bound (1 mm) instead of exactly.
    let caches = [
        ("morph.glb", CacheSpec::Morph, 1e-4),
        ("skin.glb", CacheSpec::Skin, 1e-4),
        ("pca.glb", CacheSpec::Pca, 1e-3 + 1e-4),
    ];
    for (name, cache, _) in caches {
        let out = dir.path().join(name);
        let (prepared, baked, files) = bake_mesh(&corpus("two_objects.glb"), &out, 24, cache);
        assert_eq!(files, vec![out.clone()]);
        springbake_testkit::assert_gltf_valid(&out);
        let objects: Vec<Value> = (0..baked.meshes.len())
            .map(|i| {
                let m = &prepared.export_scene.meshes[baked.meshes[i].mesh_index];
                let uvs: Vec<[f32; 2]> = m.primitives.iter().flat_map(|p| p.uvs.clone().unwrap_or_default()).collect();
                let materials: Vec<String> = m.primitives.iter().filter_map(|p| p.material.clone()).collect();
                let mesh_name = if m.name == "Body" { "Cube" } else { m.name.as_str() };
                json!({"name": m.name, "mesh_name": mesh_name, "vertex_count": m.vertex_count(),
                       "frames": world_frames(&prepared, &baked, i, &frames), "uvs": uvs, "materials": materials})
            })
            .collect();
        specs.push(json!({"file": out, "fps": baked.fps, "frames": frames, "objects": objects}));
    }
    let spec_path = dir.path().join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&json!(specs)).unwrap()).unwrap();
    let out =
        springbake_testkit::run_python_client("gltf_roundtrip.py", &[spec_path.to_str().unwrap()]);
    let report = springbake_testkit::last_json_line(&out);
    for (r, (_, _, tolerance)) in report["files"].as_array().unwrap().iter().zip(caches) {
        assert_eq!(r["frame_offset"], 0, "{r}");
        assert_eq!(r["visible_mesh_objects"], 2, "{r}");
        for o in r["objects"].as_array().unwrap() {
            let err = o["max_error"].as_f64().unwrap();
            assert!(
                err <= tolerance,
                "{}: Blender differs from our bake by {err} m",
                o["name"]
            );
            assert_eq!(o["vertex_count"], o["expected_vertex_count"], "{o}");
            assert_eq!(o["uv_missing"], 0, "{o}");
            assert_eq!(o["materials_ok"], true, "{o}");
        }
    }
}

#[test]
fn same_inputs_give_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.glb");
    let b = dir.path().join("b.glb");
    bake_mesh(&corpus("icosphere.glb"), &a, 12, CacheSpec::Morph);
    bake_mesh(&corpus("icosphere.glb"), &b, 12, CacheSpec::Morph);
    assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
}

/// The lowest vertex height along the source's own up axis (index 1 for Y-up, 2 for Z-up),
/// first and last frame, and whether the other horizontal coordinates stayed put.
fn fall_along(mesh: &Path, up_index: usize) -> (f64, f64) {
    let dir = tempfile::tempdir().unwrap();
    let (prepared, baked, _) = bake_mesh(mesh, &dir.path().join("out.pc2"), 24, CacheSpec::Morph);
    let frames = world_frames(&prepared, &baked, 0, &[0, 23]);
    let lowest = |f: &Vec<[f64; 3]>| f.iter().map(|p| p[up_index]).fold(f64::INFINITY, f64::min);
    (lowest(&frames[0]), lowest(&frames[1]))
}

#[test]
fn z_up_usd_falls_along_minus_z_and_y_up_gltf_along_minus_y() {
    let (z0, z1) = fall_along(&corpus("cylinder.usdc"), 2);
    assert!(
        z1 < z0 - 0.05,
        "Z-up USD falls along −Z: lowest z {z0} → {z1}"
    );
    let (y0, y1) = fall_along(&corpus("icosphere.glb"), 1);
    assert!(
        y1 < y0 - 0.05,
        "Y-up glTF falls along −Y: lowest y {y0} → {y1}"
    );
}
