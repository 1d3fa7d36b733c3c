//! USD export round trips: a synthetic bake (known per-frame displacement, no solver) written
//! as `.usda`/`.usdc`, then read back by usd-core's own API and by Blender.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] fns unwrap too

use serde_json::Value;
use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{DisplayMesh, ImportedScene, Primitive, SourceDocument, UpAxis};
use springbake_core::nalgebra::{Matrix4, Point3, Rotation3, Translation3, Vector3};
use springbake_core::plugin::{
    CacheKind, ExportSettings, Exporter, ImportSettings, Importer, IoErrorKind,
};
use springbake_testkit::{corpus_dir, last_json_line, run_python_client};
use springbake_usd::{UsdExporter, UsdImporter};
use std::path::{Path, PathBuf};

/// The synthetic motion: frame `f` moves a point at local `p` by `0.01·f·(1, p.z, -p.x)`.
fn displaced(p: [f32; 3], f: usize) -> [f32; 3] {
    let s = 0.01 * f as f32;
    [p[0] + s, p[1] + s * p[2], p[2] - s * p[0]]
}

fn bake(scene: &ImportedScene, frames: usize, fps: f64) -> BakedScene {
    BakedScene {
        particles: Vec::new(),
        fps,
        stage: None,
        frame_count: frames,
        meshes: scene
            .meshes
            .iter()
            .enumerate()
            .map(|(i, m)| BakedMesh {
                mesh_index: i,
                frames: (0..frames)
                    .map(|f| {
                        m.primitives
                            .iter()
                            .flat_map(|p| p.positions.iter())
                            .map(|&q| displaced(q, f))
                            .collect()
                    })
                    .collect(),
                lattice: None,
            })
            .collect(),
    }
}

fn import(path: &Path) -> ImportedScene {
    let bytes = std::fs::read(path).unwrap();
    UsdImporter
        .import(path, &bytes, &ImportSettings::default())
        .unwrap()
}

fn export(scene: &ImportedScene, baked: &BakedScene, out: &Path) {
    let files = UsdExporter
        .export(
            scene,
            baked,
            &ExportSettings {
                path: out.to_path_buf(),
                cache: CacheKind::Morph,
                axes: Default::default(),
            },
        )
        .unwrap();
    assert_eq!(files.len(), 1);
    assert_eq!(files[0].path, out);
    std::fs::write(out, &files[0].bytes).unwrap();
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn readback(file: &Path) -> Value {
    last_json_line(&run_python_client(
        "usd_readback.py",
        &[file.to_str().unwrap()],
    ))
}

#[test]
fn usd_source_round_trips_through_usd_core_as_usda_and_usdc() {
    let dir = tempfile::tempdir().unwrap();
    let frames = 5;
    for (source, out_name) in [
        ("blender/cylinder.usdc", "cylinder_baked.usda"),
        ("blender/cylinder.usdc", "cylinder_baked.usdc"),
        ("blender/two_objects.usda", "two_baked.usdc"),
        ("blender/two_objects.usda", "two_baked.usda"),
        ("blender/cylinder.usdz", "cylinder_from_usdz.usda"),
    ] {
        let source = corpus_dir().join(source);
        let scene = import(&source);
        let baked = bake(&scene, frames, 30.0);
        let out = dir.path().join(out_name);
        export(&scene, &baked, &out);
        let head = std::fs::read(&out).unwrap();
        if out_name.ends_with(".usda") {
            assert!(head.starts_with(b"#usda 1.0"), "{out_name}");
        } else {
            assert!(head.starts_with(b"PXR-USDC"), "{out_name}");
        }
        let raw = springbake_usd::read_stage(&source, source.parent().unwrap(), false).unwrap();
        let json = readback(&out);
        assert_eq!(json["up_axis"], "Z", "{out_name}");
        assert_eq!(json["meters_per_unit"], 1.0);
        assert_eq!(json["time_codes_per_second"], 30.0);
        assert_eq!(json["frames_per_second"], 30.0);
        assert_eq!(json["start"], 0.0);
        assert_eq!(json["end"], (frames - 1) as f64);
        // The flattened source keeps every mesh, baked or not.
        assert_eq!(json["meshes"].as_object().unwrap().len(), raw.meshes.len());
        for m in &raw.meshes {
            let got = &json["meshes"][&m.path];
            assert_eq!(
                f64s(&got["times"]),
                (0..frames).map(|f| f as f64).collect::<Vec<_>>(),
                "{out_name} {}",
                m.path
            );
            assert_eq!(f64s(&got["extent_times"]).len(), frames);
            // The untimed value is still the source's rest shape.
            let rest = got["rest_points"].as_array().unwrap();
            assert_eq!(rest.len(), m.points.len());
            for (i, p) in m.points.iter().enumerate() {
                let r = f64s(&rest[i]);
                assert!((0..3).all(|k| (r[k] - p[k]).abs() < 1e-6));
            }
            // Each sample: every point where the synthetic motion put it, in source order.
            for f in 0..frames {
                let pts = got["points"][f].as_array().unwrap();
                assert_eq!(pts.len(), m.points.len());
                for (i, p) in m.points.iter().enumerate() {
                    let want = displaced(p.map(|c| c as f32), f);
                    let have = f64s(&pts[i]);
                    for k in 0..3 {
                        assert!(
                            (have[k] - want[k] as f64).abs() < 1e-6,
                            "{out_name} {} frame {f} point {i}: {have:?} vs {want:?}",
                            m.path
                        );
                    }
                }
            }
            // Blender's face-varying normals become face-varying samples, one per frame.
            assert_eq!(f64s(&got["normal_times"]).len(), frames);
            assert_eq!(got["normals_interpolation"], "faceVarying");
            for c in got["normal_counts"].as_array().unwrap() {
                assert_eq!(c.as_u64().unwrap() as usize, m.indices.len());
            }
            assert_eq!(got["has_primvar_normals"], false);
        }
        if out_name.starts_with("two") {
            // Frame 0 is the rest shape: the hard-edged cube's recomputed normals equal the
            // authored ones (smoothing groups kept).
            let cube = raw
                .meshes
                .iter()
                .find(|m| m.path == "/root/Body/Cube")
                .unwrap();
            let authored = &cube.normals.as_ref().unwrap().values;
            let first = json["meshes"]["/root/Body/Cube"]["first_normals"]
                .as_array()
                .unwrap();
            for (i, n) in first.iter().enumerate() {
                let n = f64s(n);
                for k in 0..3 {
                    assert!((n[k] - authored[3 * i + k]).abs() < 1e-6, "cube normal {i}");
                }
            }
        }
    }
}

fn synthetic_gltf_scene() -> ImportedScene {
    let tri = |z: f32| Primitive {
        positions: vec![[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]],
        normals: Some(vec![[0.0, 0.0, 1.0]; 3]),
        uvs: Some(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
        indices: vec![0, 1, 2],
        material: None,
    };
    let world = Translation3::new(1.0, 2.0, 3.0).to_homogeneous()
        * Rotation3::from_axis_angle(&Vector3::y_axis(), 0.5).to_homogeneous()
        * Matrix4::new_nonuniform_scaling(&Vector3::new(2.0, 1.0, 1.0));
    ImportedScene {
        materials: Vec::new(),
        notes: Vec::new(),
        meshes: vec![DisplayMesh {
            name: "Blob.001".into(),
            source_key: "node:0".into(),
            world_from_local: world,
            primitives: vec![tri(0.0), tri(0.5)],
            source_point_of_vertex: Vec::new(),
            source_point_count: 6,
        }],
        up_axis: UpAxis::Y,
        meters_per_unit: 0.5,
        source: SourceDocument {
            path: PathBuf::from("blob.glb"),
            importer: "gltf".into(),
            read_root: None,
        },
    }
}

#[test]
fn non_usd_source_builds_a_new_stage_with_world_matrix_and_samples() {
    let dir = tempfile::tempdir().unwrap();
    let scene = synthetic_gltf_scene();
    let frames = 4;
    let baked = bake(&scene, frames, 24.0);
    for name in ["new.usda", "new.usdc"] {
        let out = dir.path().join(name);
        export(&scene, &baked, &out);
        let json = readback(&out);
        assert_eq!(json["up_axis"], "Y");
        assert_eq!(json["meters_per_unit"], 0.5);
        assert_eq!(json["time_codes_per_second"], 24.0);
        assert_eq!(json["end"], 3.0);
        let meshes = json["meshes"].as_object().unwrap();
        assert_eq!(meshes.len(), 1);
        let (path, m) = meshes.iter().next().unwrap();
        assert_eq!(path, "/root/Blob_001/Blob_001");
        // usd-core's world transform (transposed to column vectors) equals ours.
        let world = f64s(&m["world"]);
        let ours = scene.meshes[0].world_from_local;
        for r in 0..4 {
            for c in 0..4 {
                assert!((world[r * 4 + c] - ours[(r, c)]).abs() < 1e-12, "{r},{c}");
            }
        }
        assert_eq!(
            m["face_vertex_counts"].as_array().unwrap().len(),
            2,
            "two triangles"
        );
        assert_eq!(m["face_vertex_index_count"], 6);
        assert_eq!(m["st_count"], 6);
        assert_eq!(m["normals_interpolation"], "vertex");
        assert_eq!(f64s(&m["normal_times"]).len(), frames);
        for f in 0..frames {
            let pts = m["points"][f].as_array().unwrap();
            for (v, want) in baked.meshes[0].frames[f].iter().enumerate() {
                let have = f64s(&pts[v]);
                assert!((0..3).all(|k| (have[k] - want[k] as f64).abs() < 1e-6));
            }
        }
    }
}

#[test]
fn bad_bakes_are_rejected_before_writing() {
    let scene = synthetic_gltf_scene();
    let mut baked = bake(&scene, 2, 24.0);
    baked.meshes[0].mesh_index = 3;
    let settings = ExportSettings {
        path: PathBuf::from("x.usda"),
        cache: CacheKind::Morph,
        axes: Default::default(),
    };
    let err = UsdExporter.export(&scene, &baked, &settings).unwrap_err();
    assert_eq!(err.kind, IoErrorKind::Invalid);
    assert!(err.message.contains("mesh 3"), "{err}");

    let mut baked = bake(&scene, 2, 24.0);
    baked.meshes[0].frames[1].pop();
    let err = UsdExporter.export(&scene, &baked, &settings).unwrap_err();
    assert!(err.message.contains("frame 1"), "{err}");

    let baked = bake(&scene, 2, 24.0);
    let other = ExportSettings {
        path: PathBuf::from("x.usdx"),
        cache: CacheKind::Morph,
        axes: Default::default(),
    };
    assert!(UsdExporter.export(&scene, &baked, &other).is_err());
}

/// A stage made from a glTF source opens in Blender with the artist's object names (the
/// glTF nodes', as prim names), not one `mesh`, `mesh.001`, … per body.
#[test]
fn blender_names_the_objects_of_a_stage_made_from_gltf_as_the_source_did() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = synthetic_gltf_scene();
    let mut ball = scene.meshes[0].clone();
    (ball.name, ball.source_key) = ("Ball".into(), "node:1".into());
    scene.meshes.push(ball);
    let baked = bake(&scene, 2, 24.0);
    let out = dir.path().join("two.usda");
    export(&scene, &baked, &out);
    let spec = serde_json::json!({ "files": [{ "path": out.to_str().unwrap(), "frames": [0] }] });
    let spec_path = dir.path().join("spec.json");
    std::fs::write(&spec_path, spec.to_string()).unwrap();
    let json = last_json_line(&run_python_client(
        "usd_blender_frames.py",
        &[spec_path.to_str().unwrap()],
    ));
    let mut blender: Vec<String> = json["files"][0]["objects"]
        .as_object()
        .unwrap()
        .keys()
        .cloned()
        .collect();
    blender.sort();
    assert_eq!(blender, ["Ball", "Blob_001"]);
}

#[test]
fn blender_plays_the_exported_points_at_our_baked_positions() {
    let dir = tempfile::tempdir().unwrap();
    let frames = 5;
    let checked = [0usize, 2, 4];
    let mut cases = Vec::new();
    for (source, out_name) in [
        ("blender/cylinder.usdc", "cyl.usdc"),
        ("blender/two_objects.usda", "two.usda"),
    ] {
        let scene = import(&corpus_dir().join(source));
        let baked = bake(&scene, frames, 24.0);
        let out = dir.path().join(out_name);
        export(&scene, &baked, &out);
        cases.push((scene, baked, out));
    }
    let spec = serde_json::json!({
        "files": cases.iter().map(|(_, _, out)| serde_json::json!({
            "path": out.to_str().unwrap(),
            "frames": checked,
        })).collect::<Vec<_>>()
    });
    let spec_path = dir.path().join("spec.json");
    std::fs::write(&spec_path, spec.to_string()).unwrap();
    let json = last_json_line(&run_python_client(
        "usd_blender_frames.py",
        &[spec_path.to_str().unwrap()],
    ));
    let mut compared = 0;
    for (i, (scene, baked, out)) in cases.iter().enumerate() {
        let result = &json["files"][i];
        let objects = result["objects"].as_object().unwrap();
        assert_eq!(objects.len(), scene.meshes.len(), "{}", out.display());
        for bm in &baked.meshes {
            let mesh = &scene.meshes[bm.mesh_index];
            let name = mesh.source_key.rsplit('/').next().unwrap();
            let ob = &objects
                .get(name)
                .unwrap_or_else(|| panic!("Blender has no object {name}: {objects:?}"))["frames"];
            for &f in &checked {
                let verts = ob[f.to_string()].as_array().unwrap();
                assert_eq!(verts.len(), mesh.source_point_count, "{name}");
                for (v, &point) in mesh.source_point_of_vertex.iter().enumerate() {
                    let q = bm.frames[f][v];
                    // Source is Z-up metres already: world = world_from_local · local.
                    let want = mesh.world_from_local.transform_point(&Point3::new(
                        q[0] as f64,
                        q[1] as f64,
                        q[2] as f64,
                    ));
                    let have = f64s(&verts[point as usize]);
                    let have = Point3::new(have[0], have[1], have[2]);
                    assert!(
                        (have - want).norm() < 1e-4,
                        "{} {name} frame {f} point {point}: Blender {have} vs ours {want}",
                        out.display()
                    );
                    compared += 1;
                }
            }
        }
    }
    assert!(compared > 1000, "{compared}");
}

#[test]
fn old_points_samples_of_an_animated_source_are_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let source = dir.path().join("animated.usda");
    std::fs::write(
        &source,
        r#"#usda 1.0
(
    upAxis = "Z"
)
def Mesh "tri" {
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    point3f[] points.timeSamples = {
        10: [(0, 0, 5), (1, 0, 5), (0, 1, 5)],
        20: [(0, 0, 9), (1, 0, 9), (0, 1, 9)],
    }
}
"#,
    )
    .unwrap();
    let scene = import(&source);
    // The rest shape is the untimed value.
    assert_eq!(scene.meshes[0].primitives[0].positions[1], [1.0, 0.0, 0.0]);
    let baked = bake(&scene, 3, 24.0);
    let out = dir.path().join("out.usda");
    export(&scene, &baked, &out);
    let json = readback(&out);
    let m = &json["meshes"]["/tri"];
    assert_eq!(f64s(&m["times"]), vec![0.0, 1.0, 2.0]);
    let p = f64s(&m["points"][2][1]);
    let want = [1.02, 0.0, -0.02];
    assert!((0..3).all(|k| (p[k] - want[k]).abs() < 1e-6), "{p:?}");
    // No normals were authored, none are invented.
    assert_eq!(f64s(&m["normal_times"]).len(), 0);
}
