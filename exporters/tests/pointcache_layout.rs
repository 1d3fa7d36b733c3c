//! PC2/MDD byte layouts parsed back, point order through the source map, file naming and the
//! errors a bad bake gets.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::ImportedScene;
use springbake_core::plugin::{ExportSettings, Exporter, ImportSettings, Importer, OutputFile};
use springbake_exporters::pointcache::{MddExporter, Pc2Exporter};
use springbake_importers::obj::ObjImporter;
use std::path::{Path, PathBuf};

fn obj(text: &str) -> ImportedScene {
    ObjImporter
        .import(
            Path::new("t.obj"),
            text.as_bytes(),
            &ImportSettings::default(),
        )
        .unwrap()
}

fn settings(path: &str) -> ExportSettings {
    ExportSettings {
        path: PathBuf::from(path),
        cache: Default::default(),
        axes: Default::default(),
    }
}

/// A bake where display vertex v of frame f sits at its rest position + (f, 10 f, 100 f).
fn shifted_bake(scene: &ImportedScene, frames: usize, fps: f64) -> BakedScene {
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
                        let d = [f as f32, 10.0 * f as f32, 100.0 * f as f32];
                        m.primitives
                            .iter()
                            .flat_map(|p| p.positions.iter())
                            .map(|p| [p[0] + d[0], p[1] + d[1], p[2] + d[2]])
                            .collect()
                    })
                    .collect(),
                lattice: None,
            })
            .collect(),
    }
}

fn i32_le(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn f32_le(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn i32_be(b: &[u8], at: usize) -> i32 {
    i32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}
fn f32_be(b: &[u8], at: usize) -> f32 {
    f32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}

/// Vertex 2 carries two UVs, so 5 display vertices map onto 4 source points; vertex 4 (x = 3)
/// is written before vertex 3 in the faces but after it in the `v` list.
const SPLIT_QUAD: &str = "o Q\nv 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
                          f 1/1 2/1 4/2\nf 2/3 3/1 4/2\n";

#[test]
fn pc2_header_and_points_in_source_order() {
    let scene = obj(SPLIT_QUAD);
    assert_eq!(scene.meshes[0].vertex_count(), 5);
    let bake = shifted_bake(&scene, 3, 24.0);
    let files = Pc2Exporter
        .export(&scene, &bake, &settings("out/x.pc2"))
        .unwrap();
    assert_eq!(files.len(), 1);
    assert_eq!(files[0].path, PathBuf::from("out/x.pc2"));
    let b = &files[0].bytes;
    assert_eq!(&b[..12], b"POINTCACHE2\0");
    assert_eq!(i32_le(b, 12), 1, "version");
    assert_eq!(i32_le(b, 16), 4, "points");
    assert_eq!(f32_le(b, 20), 0.0, "start frame");
    assert_eq!(f32_le(b, 24), 1.0, "sample rate");
    assert_eq!(i32_le(b, 28), 3, "samples");
    assert_eq!(b.len(), 32 + 3 * 4 * 12);
    for f in 0..3 {
        for p in 0..4 {
            let at = 32 + (f * 4 + p) * 12;
            let got = [f32_le(b, at), f32_le(b, at + 4), f32_le(b, at + 8)];
            // Source point p is `v` line p: x = p at rest.
            let want = [p as f32 + f as f32, 10.0 * f as f32, 100.0 * f as f32];
            assert_eq!(got, want, "sample {f} point {p}");
        }
    }
}

#[test]
fn mdd_header_times_and_points_big_endian() {
    let scene = obj(SPLIT_QUAD);
    let bake = shifted_bake(&scene, 4, 25.0);
    let files = MddExporter
        .export(&scene, &bake, &settings("x.mdd"))
        .unwrap();
    let b = &files[0].bytes;
    assert_eq!(i32_be(b, 0), 4, "frames");
    assert_eq!(i32_be(b, 4), 4, "points");
    for f in 0..4 {
        assert_eq!(f32_be(b, 8 + 4 * f), f as f32 / 25.0, "time of frame {f}");
    }
    let data = 8 + 4 * 4;
    assert_eq!(b.len(), data + 4 * 4 * 12, "no extra rest frame");
    for f in 0..4 {
        for p in 0..4 {
            let at = data + (f * 4 + p) * 12;
            let got = [f32_be(b, at), f32_be(b, at + 4), f32_be(b, at + 8)];
            assert_eq!(
                got,
                [p as f32 + f as f32, 10.0 * f as f32, 100.0 * f as f32]
            );
        }
    }
}

#[test]
fn several_meshes_get_one_sanitized_file_each() {
    let scene = obj("o My Body/1\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n\
         o Head\nv 5 0 0\nf 4 2 3\no Head\nv 6 0 0\nf 5 2 3\n");
    assert_eq!(scene.meshes.len(), 3);
    let bake = shifted_bake(&scene, 2, 24.0);
    for (exporter, ext) in [
        (&Pc2Exporter as &dyn Exporter, "pc2"),
        (&MddExporter as &dyn Exporter, "mdd"),
    ] {
        let files: Vec<OutputFile> = exporter
            .export(&scene, &bake, &settings(&format!("dir/out.{ext}")))
            .unwrap();
        let names: Vec<String> = files.iter().map(|f| f.path.display().to_string()).collect();
        assert_eq!(
            names,
            vec![
                format!("dir/out_My_Body_1.{ext}"),
                format!("dir/out_Head.{ext}"),
                format!("dir/out_Head_2.{ext}"),
            ]
        );
    }
    let files = Pc2Exporter
        .export(&scene, &bake, &settings("out.pc2"))
        .unwrap();
    // Head's points: the shared v2, v3 (written under the first object) and its own v4.
    assert_eq!(i32_le(&files[1].bytes, 16), 3);
    assert_eq!(f32_le(&files[1].bytes, 32 + 2 * 12), 5.0);
}

#[test]
fn bad_bakes_are_refused_with_a_location() {
    let scene = obj(SPLIT_QUAD);
    let mut bake = shifted_bake(&scene, 2, 24.0);
    bake.meshes[0].frames[1].pop();
    let err = Pc2Exporter
        .export(&scene, &bake, &settings("a.pc2"))
        .unwrap_err();
    assert_eq!(
        err.location.as_deref(),
        Some("baked.meshes[0].frames[1]"),
        "{err}"
    );
    assert!(
        err.message.contains("4 vertices but mesh 'Q' has 5"),
        "{err}"
    );

    let mut bake = shifted_bake(&scene, 2, 24.0);
    bake.meshes[0].frames[0][3][1] = f32::NAN;
    let err = MddExporter
        .export(&scene, &bake, &settings("a.mdd"))
        .unwrap_err();
    assert!(err.message.contains("not finite"), "{err}");

    let mut bake = shifted_bake(&scene, 2, 24.0);
    bake.meshes[0].frames.clear();
    assert!(Pc2Exporter
        .export(&scene, &bake, &settings("a.pc2"))
        .unwrap_err()
        .message
        .contains("no baked frames"));

    let mut bake = shifted_bake(&scene, 2, 24.0);
    bake.meshes[0].mesh_index = 7;
    assert!(Pc2Exporter
        .export(&scene, &bake, &settings("a.pc2"))
        .unwrap_err()
        .message
        .contains("refers to mesh 7"));

    let bake = shifted_bake(&scene, 2, 0.0);
    assert!(MddExporter
        .export(&scene, &bake, &settings("a.mdd"))
        .unwrap_err()
        .message
        .contains("frame rate"));
}

#[test]
fn builtin_plugin_registers_both_extensions() {
    let mut reg = springbake_core::plugin::Registry::new();
    reg.add_plugin(&springbake_exporters::BuiltinExporters);
    assert_eq!(reg.exporter_for(Path::new("a.PC2")).unwrap().name(), "pc2");
    assert_eq!(reg.exporter_for(Path::new("a.mdd")).unwrap().name(), "mdd");
}
