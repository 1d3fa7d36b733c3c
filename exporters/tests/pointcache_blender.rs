//! Blender plays our PC2 and MDD caches: each corpus OBJ is imported by both springbake and
//! `bpy.ops.wm.obj_import`, a synthetic bake (no solver: every display vertex moved by a known
//! function of its rest position and the sample index) is exported, and Blender's Mesh Cache
//! modifier with default axes must reproduce every vertex within 1e-4 m at several frames.
//!
//! Frame mapping (Blender 5.0.1, default "Frame" time mode, frame scale 1): scene frame `f`
//! shows sample `f - frame_start`, clamped to `[0, samples - 1]`; the PC2 start/rate fields and
//! the MDD time table are not consulted. With `frame_start = 1` (Blender's default scene start)
//! frame 1 shows sample 0; with the modifier's default `frame_start = 0`, frame 0 shows sample 0
//! and frame 1 sample 1. The test checks frames before, inside and after the cache.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::ImportedScene;
use springbake_core::plugin::{ExportSettings, Exporter, ImportSettings, Importer};
use springbake_exporters::pointcache::{MddExporter, Pc2Exporter};
use springbake_importers::obj::ObjImporter;
use std::collections::BTreeMap;
use std::path::Path;

const SAMPLES: usize = 6;

/// Faces refer to vertices out of `v` order, object B uses vertices written under A and has a
/// loose vertex from an `l` element and an unused one, C is a concave pentagon plus a
/// degenerate face (Blender drops the face, keeps its vertices): Blender numbers each object's
/// points as the used `v` lines in file order, and so must we.
const SHUFFLED_OBJ: &str = "o A\nv 0 0 0\nv 1 0.2 0\nv 2 0 0.3\nv 3 0.5 0\nv 4 1 0\n\
                            f 5 1 3\nf -1 -4 -2\n\
                            o B\nv 10 0 0\nv 11 1 0\nv 12 0 1\nv 13 1 1\nv 14 2 2\n\
                            f 7 2 6\nf 8 7 6\nl 10 1\n\
                            o C\nv 0 0 5\nv 2 0 5\nv 2 2 5\nv 1 1 5\nv 0 2 5\nv 9 9 9\nv 8 8 8\n\
                            f 15 14 13 12 11\nf 16 17 17\n";
const FPS: f64 = 24.0;

/// Must match `displacement` in tests/clients/pointcache_blender.py.
fn displacement(k: usize, p: [f32; 3]) -> [f64; 3] {
    let (x, y, z) = (p[0] as f64, p[1] as f64, p[2] as f64);
    let k = k as f64;
    [
        0.01 * k * (3.0 * x + 2.0 * y).sin(),
        0.02 * k * (2.0 * z - x).cos(),
        0.005 * k * (x * z + 1.0),
    ]
}

fn synthetic_bake(scene: &ImportedScene) -> BakedScene {
    BakedScene {
        particles: Vec::new(),
        fps: FPS,
        stage: None,
        frame_count: SAMPLES,
        meshes: scene
            .meshes
            .iter()
            .enumerate()
            .map(|(i, m)| BakedMesh {
                mesh_index: i,
                frames: (0..SAMPLES)
                    .map(|k| {
                        // OBJ meshes have world_from_local = identity, so the displacement is
                        // the same in the local frame the bake is written in.
                        m.primitives
                            .iter()
                            .flat_map(|p| p.positions.iter())
                            .map(|&p| {
                                let d = displacement(k, p);
                                [
                                    (p[0] as f64 + d[0]) as f32,
                                    (p[1] as f64 + d[1]) as f32,
                                    (p[2] as f64 + d[2]) as f32,
                                ]
                            })
                            .collect()
                    })
                    .collect(),
                lattice: None,
            })
            .collect(),
    }
}

#[test]
fn blender_mesh_cache_plays_pc2_and_mdd_on_its_obj_import() {
    let tmp = tempfile::tempdir().unwrap();
    let corpus = springbake_testkit::corpus_dir();
    let mut cases = Vec::new();
    let mut point_counts: BTreeMap<String, usize> = BTreeMap::new();
    let shuffled = tmp.path().join("shuffled.obj");
    std::fs::write(&shuffled, SHUFFLED_OBJ).unwrap();
    for file in [
        "blender/two_objects.obj",
        "blender/cylinder.obj",
        "shuffled.obj",
    ] {
        let obj = if file == "shuffled.obj" {
            shuffled.clone()
        } else {
            corpus.join(file)
        };
        let scene = ObjImporter
            .import(
                &obj,
                &std::fs::read(&obj).unwrap(),
                &ImportSettings::default(),
            )
            .unwrap();
        for m in &scene.meshes {
            point_counts.insert(m.name.clone(), m.source_point_count);
        }
        if file == "shuffled.obj" {
            let counts: Vec<usize> = scene.meshes.iter().map(|m| m.source_point_count).collect();
            assert_eq!(counts, vec![5, 6, 7]);
        }
        let bake = synthetic_bake(&scene);
        let stem = Path::new(file)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        for (exporter, format, ext) in [
            (&Pc2Exporter as &dyn Exporter, "PC2", "pc2"),
            (&MddExporter as &dyn Exporter, "MDD", "mdd"),
        ] {
            let out = tmp.path().join(format!("{stem}.{ext}"));
            let settings = ExportSettings {
                path: out,
                cache: Default::default(),
                axes: Default::default(),
            };
            let files = exporter.export(&scene, &bake, &settings).unwrap();
            assert_eq!(files.len(), scene.meshes.len());
            let mut by_object = serde_json::Map::new();
            for (m, f) in scene.meshes.iter().zip(&files) {
                std::fs::write(&f.path, &f.bytes).unwrap();
                by_object.insert(m.name.clone(), f.path.display().to_string().into());
            }
            for frame_start in [1, 0] {
                cases.push(serde_json::json!({
                    "obj": obj.display().to_string(),
                    "format": format,
                    "frame_start": frame_start,
                    "frames": [0, 1, 2, 4, 6, 7, 10],
                    "files": by_object,
                }));
            }
        }
    }
    let spec = tmp.path().join("spec.json");
    std::fs::write(
        &spec,
        serde_json::json!({"fps": FPS, "samples": SAMPLES, "cases": cases}).to_string(),
    )
    .unwrap();
    let stdout =
        springbake_testkit::run_python_client("pointcache_blender.py", &[spec.to_str().unwrap()]);
    let report = springbake_testkit::last_json_line(&stdout);
    let results = report["cases"].as_array().unwrap();
    assert_eq!(results.len(), 12);
    let mut seen = Vec::new();
    for case in results {
        let objects = case["objects"].as_array().unwrap();
        assert!(!objects.is_empty(), "{case}");
        assert_eq!(case["modifier_defaults"][0], "FRAME", "{case}");
        for o in objects {
            let name = o["name"].as_str().unwrap();
            seen.push(name.to_owned());
            // Blender's vertex count equals our source point count (else "Vertex count
            // mismatch" and no deformation at all).
            assert_eq!(
                o["verts"].as_u64().unwrap() as usize,
                point_counts[name],
                "{name}: {case}"
            );
            let max_err = o["max_err"].as_f64().unwrap();
            eprintln!(
                "{} frame_start {}: {name} {} verts, max error {max_err:.2e} m, max displacement {:.4} m",
                case["format"], case["frame_start"], o["verts"], o["max_disp"]
            );
            assert!(
                max_err < 1e-4,
                "{} {name}: max error {max_err} m\n{o}",
                case["format"]
            );
            // Not vacuous: the cache really moved the vertices (sample 5 moves some by > 2 cm).
            assert!(o["max_disp"].as_f64().unwrap() > 0.02, "{o}");
            // Frame → sample mapping as documented above, for the frames checked.
            let start = case["frame_start"].as_i64().unwrap();
            for fr in o["frames"].as_array().unwrap() {
                let f = fr["frame"].as_i64().unwrap();
                let expected = (f - start).clamp(0, SAMPLES as i64 - 1);
                assert_eq!(fr["sample"].as_i64().unwrap(), expected);
            }
        }
    }
    seen.sort();
    seen.dedup();
    assert_eq!(seen, vec!["A", "B", "Body", "C", "Cylinder", "Head"]);
}
