//! Vertex animation textures decoded back to positions (issue 23 item 2): a synthetic bake
//! (no solver) of a two-part Blender glTF, declared Z-up in centimetres so the axes and units
//! conversion is exercised, written by the VAT exporter; the rest mesh plus the float EXR
//! offsets give every baked vertex to 1e-5 m, the 8-bit PNG pair to its quantisation (the
//! offsets' range / 51 000), the (float16) rotation texture turns +Y into the deformed normal to 4e-3; the
//! mesh's lookup UVs and the JSON agree with the layout; the same bake gives the same bytes.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use nalgebra::{Point3, UnitQuaternion, Vector3};
use springbake_core::bake::{BakedMesh, BakedScene};
use springbake_core::display::{vertex_normals, ImportedScene, UpAxis};
use springbake_core::plugin::{CacheKind, ExportSettings, Exporter, ImportSettings, Importer};
use springbake_exporters::vat::{join_ldr, VatExporter};
use springbake_importers::gltf::GltfImporter;
use std::path::Path;

const FRAMES: usize = 12;

fn import(path: &Path) -> ImportedScene {
    let bytes = std::fs::read(path).unwrap();
    GltfImporter
        .import(path, &bytes, &ImportSettings::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A wobble and a drop, in source units (centimetres).
fn displaced(p: [f32; 3], f: usize) -> [f32; 3] {
    let t = f as f32 * 0.3;
    [
        p[0] * (1.0 + 0.1 * t.sin()),
        p[1] + 3.0 * (p[2] * 0.05 + t).cos(),
        p[2] - 4.0 * f as f32,
    ]
}

fn synthetic_bake(scene: &ImportedScene) -> BakedScene {
    BakedScene {
        particles: Vec::new(),
        stage: None,
        fps: 24.0,
        frame_count: FRAMES,
        meshes: scene
            .meshes
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let rest: Vec<[f32; 3]> = m
                    .primitives
                    .iter()
                    .flat_map(|p| p.positions.clone())
                    .collect();
                BakedMesh {
                    mesh_index: i,
                    frames: (0..FRAMES)
                        .map(|f| rest.iter().map(|&p| displaced(p, f)).collect())
                        .collect(),
                    lattice: None,
                }
            })
            .collect(),
    }
}

/// The expected world positions (Y-up metres) of every vertex, meshes one after the other.
fn expected(scene: &ImportedScene, baked: &BakedScene, f: usize) -> Vec<[f32; 3]> {
    let to_y_up = scene.y_up_metres_from_world();
    let mut out = Vec::new();
    for bm in &baked.meshes {
        let m = to_y_up * scene.meshes[bm.mesh_index].world_from_local;
        for p in &bm.frames[f] {
            let q = m.transform_point(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            out.push([q.x as f32, q.y as f32, q.z as f32]);
        }
    }
    out
}

fn read_exr(path: &Path) -> (usize, Vec<[f32; 4]>) {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![[0.0f32; 4]; resolution.area()]),
        |(w, texels), p, (r, g, b, a): (f32, f32, f32, f32)| {
            texels[p.y() * *w + p.x()] = [r, g, b, a];
        },
    )
    .unwrap();
    image.layer_data.channel_data.pixels
}

fn read_png(path: &Path) -> Vec<[u8; 4]> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf[..info.buffer_size()]
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}

fn export(dir: &Path, scene: &ImportedScene, baked: &BakedScene) -> Vec<(String, Vec<u8>)> {
    let settings = ExportSettings {
        path: dir.join("wobble.vat"),
        cache: CacheKind::Morph,
        axes: Default::default(),
    };
    let files = VatExporter.export(scene, baked, &settings).unwrap();
    for f in &files {
        std::fs::create_dir_all(f.path.parent().unwrap()).unwrap();
        std::fs::write(&f.path, &f.bytes).unwrap();
    }
    files
        .into_iter()
        .map(|f| {
            (
                f.path.strip_prefix(dir).unwrap().display().to_string(),
                f.bytes,
            )
        })
        .collect()
}

#[test]
fn textures_decode_to_the_baked_positions_and_normals() {
    let source = springbake_testkit::corpus_dir().join("blender/two_objects.glb");
    let mut scene = import(&source);
    assert!(scene.meshes.len() >= 2);
    scene.up_axis = UpAxis::Z;
    scene.meters_per_unit = 0.01;
    let baked = synthetic_bake(&scene);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().join("wobble.vat");
    let files = export(dir.path(), &scene, &baked);
    assert_eq!(
        files,
        export(dir.path(), &scene, &baked),
        "same bake, same bytes"
    );

    let data: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("data/wobble_data.json")).unwrap()).unwrap();
    let sb = &data[0]["springbake"];
    let (width, height) = (
        sb["texture_width"].as_u64().unwrap() as usize,
        sb["texture_height"].as_u64().unwrap() as usize,
    );
    assert_eq!(sb["frame_count"], FRAMES);
    let rest_scene = import(&d.join("geo/wobble_mesh.glb"));
    let rest: Vec<[f32; 3]> = rest_scene.meshes[0].primitives[0].positions.clone();
    let lookup = rest_scene.meshes[0].primitives[0].uvs.is_some();
    assert!(lookup, "the rest mesh keeps the source's UVs as TEXCOORD_0");
    assert_eq!(rest.len(), sb["vertex_count"].as_u64().unwrap() as usize);
    for (v, (r, e)) in rest.iter().zip(expected(&scene, &baked, 0)).enumerate() {
        let err = (0..3).map(|c| (r[c] - e[c]).abs()).fold(0.0, f32::max);
        assert!(err < 1e-5, "rest vertex {v}: {r:?} vs {e:?}");
    }

    let (w, pos) = read_exr(&d.join("tex/wobble_pos.exr"));
    let (_, rot) = read_exr(&d.join("tex/wobble_rot.exr"));
    assert_eq!((w, pos.len()), (width, width * height));
    let pos8 = read_png(&d.join("tex/wobble_pos.png"));
    let pos8_low = read_png(&d.join("tex/wobble_pos2.png"));
    let bound = |key: &str| data[0][key].as_f64().unwrap() as f32;
    let lo = [
        bound("Bound Min X"),
        bound("Bound Min Y"),
        bound("Bound Min Z"),
    ];
    let hi = [
        bound("Bound Max X"),
        bound("Bound Max Y"),
        bound("Bound Max Z"),
    ];
    let rows = sb["rows_per_frame"].as_u64().unwrap() as usize;
    let triangles: Vec<u32> = rest_scene.meshes[0].primitives[0].indices.clone();
    for f in 0..FRAMES {
        let want = expected(&scene, &baked, f);
        let normals = vertex_normals(&want, &triangles);
        for (v, e) in want.iter().enumerate() {
            let t = (f * rows + v / width) * width + v % width;
            for c in 0..3 {
                let float = rest[v][c] + pos[t][c];
                assert!((float - e[c]).abs() < 1e-5, "EXR frame {f} vertex {v}");
                let unit = join_ldr(pos8[t][c], pos8_low[t][c]);
                let ldr = rest[v][c] + lo[c] + unit * (hi[c] - lo[c]);
                let step = (hi[c] - lo[c]) / 51_000.0 + 1e-6;
                assert!(
                    (ldr - e[c]).abs() <= step,
                    "PNG frame {f} vertex {v}: {ldr} vs {}",
                    e[c]
                );
            }
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                rot[t][3] as f64,
                rot[t][0] as f64,
                rot[t][1] as f64,
                rot[t][2] as f64,
            ));
            let n = q * Vector3::y();
            let want_n = Vector3::new(normals[v][0], normals[v][1], normals[v][2]).cast::<f64>();
            // float16 quaternions: the normal to a few thousandths.
            assert!((n - want_n).norm() < 4e-3, "normal frame {f} vertex {v}");
        }
    }
    // The lookup UV of a vertex is its frame-0 texel's centre, v from the top.
    let mesh_json = std::fs::read(d.join("geo/wobble_mesh.glb")).unwrap();
    assert!(mesh_json.windows(10).any(|w| w == b"TEXCOORD_1"));
}
