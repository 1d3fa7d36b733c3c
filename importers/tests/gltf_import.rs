//! glTF importer: the corpus sweep plus in-memory files for each feature the importer claims.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use base64::Engine as _;
use serde_json::{json, Value};
use springbake_core::plugin::{ImportSettings, Importer, IoErrorKind};
use springbake_importers::gltf::GltfImporter;
use std::path::Path;

fn import_bytes(
    name: &str,
    bytes: &[u8],
) -> Result<springbake_core::display::ImportedScene, springbake_core::plugin::PluginError> {
    GltfImporter.import(Path::new(name), bytes, &ImportSettings::default())
}

fn import_file(path: &Path) -> springbake_core::display::ImportedScene {
    let bytes = std::fs::read(path).unwrap();
    GltfImporter
        .import(path, &bytes, &ImportSettings::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A .gltf with one node/mesh/primitive whose buffer is `bin` as a data URI.
/// `accessors`, `views` and `primitive` are spliced in as given.
fn doc(bin: &[u8], views: Value, accessors: Value, primitive: Value) -> Vec<u8> {
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bin)
    );
    serde_json::to_vec(&json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "N"}],
        "meshes": [{"primitives": [primitive]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
    }))
    .unwrap()
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Four vertices of a unit square in z=0.
const SQUARE: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.];

fn square_with_indices(mode: u32, idx_bytes: &[u8], component: u32, count: usize) -> Vec<u8> {
    let mut bin = f32s(&SQUARE);
    bin.extend_from_slice(idx_bytes);
    doc(
        &bin,
        json!([{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": idx_bytes.len()}]),
        json!([
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": component, "count": count, "type": "SCALAR"}
        ]),
        json!({"attributes": {"POSITION": 0}, "indices": 1, "mode": mode}),
    )
}

#[test]
fn corpus_sweep_matches_the_manifest() {
    let entries = springbake_testkit::corpus_entries(&["gltf", "glb"]);
    assert!(
        entries.len() >= 15,
        "expected the glTF corpus, got {}",
        entries.len()
    );
    for e in entries {
        let bytes = std::fs::read(&e.path).unwrap();
        let result = GltfImporter.import(&e.path, &bytes, &ImportSettings::default());
        match (e.expect_ok, result) {
            (true, Ok(scene)) => {
                assert!(!scene.meshes.is_empty(), "{}", e.path.display());
                for m in &scene.meshes {
                    assert!(m.triangle_count() > 0, "{}: {}", e.path.display(), m.name);
                }
            }
            (true, Err(err)) => panic!("{} should import ({}): {err}", e.path.display(), e.why),
            (false, Ok(_)) => panic!("{} should be rejected ({})", e.path.display(), e.why),
            (false, Err(err)) => {
                assert!(!err.message.is_empty());
                assert_eq!(err.path, e.path, "error names the file");
            }
        }
    }
}

#[test]
fn corpus_errors_say_what_and_where() {
    let dir = springbake_testkit::corpus_dir();
    let err = |p: &str| {
        let path = dir.join(p);
        let bytes = std::fs::read(&path).unwrap();
        GltfImporter
            .import(&path, &bytes, &ImportSettings::default())
            .unwrap_err()
    };
    let lines = err("bad/lines_only.gltf");
    assert_eq!(
        lines.location.as_deref(),
        Some("meshes[0].primitives[0].mode")
    );
    assert!(lines.message.contains("LINES"), "{lines}");
    assert_eq!(lines.kind, IoErrorKind::Invalid);

    let huge = err("bad/huge_count.gltf");
    assert_eq!(huge.location.as_deref(), Some("accessors[0]"), "{huge}");
    assert!(huge.message.contains("4000000000"), "{huge}");

    let escape = err("bad/uri_escape.gltf");
    assert_eq!(escape.location.as_deref(), Some("buffers[0].uri"));
    assert!(escape.message.contains("leaves the folder"), "{escape}");

    let missing = err("bad/missing_bin.gltf");
    assert!(missing.message.contains("missing.bin"), "{missing}");
    assert!(
        missing
            .message
            .contains(&dir.join("bad").display().to_string()),
        "{missing}"
    );

    let nan = err("bad/nan_position.gltf");
    assert_eq!(nan.location.as_deref(), Some("accessors[0]"));
    assert!(nan.message.contains("NaN"), "{nan}");

    let draco = err("blender/icosphere_draco.glb");
    assert!(
        draco.message.contains("KHR_draco_mesh_compression"),
        "{draco}"
    );

    assert_eq!(err("bad/wrong_magic.glb").kind, IoErrorKind::Incompatible);
    assert!(err("bad/truncated.glb").message.contains("cut short"));
    assert!(err("bad/zero.glb").message.contains("empty"));
    assert!(err("bad/garbage.gltf").message.contains("line 1"));
}

#[test]
fn blender_icosphere_imports_with_normals_uvs_and_placement() {
    let scene = import_file(&springbake_testkit::corpus_dir().join("blender/icosphere.glb"));
    assert_eq!(scene.meshes.len(), 1);
    let m = &scene.meshes[0];
    assert_eq!(m.name, "Icosphere");
    assert_eq!(m.source_key, "node:0");
    assert_eq!(m.vertex_count(), 960);
    let p = &m.primitives[0];
    assert_eq!(p.normals.as_ref().unwrap().len(), 960);
    assert_eq!(p.uvs.as_ref().unwrap().len(), 960);
    // node translation (0, 1, 0)
    assert_eq!(m.world_from_local[(1, 3)], 1.0);
    let ys: Vec<f64> = m.world_positions().iter().map(|q| q.y).collect();
    let (lo, hi) = ys
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &y| (a.min(y), b.max(y)));
    assert!(
        (lo - 0.5).abs() < 1e-6 && (hi - 1.5).abs() < 1e-6,
        "{lo} {hi}"
    );
}

#[test]
fn external_buffer_gltf_matches_the_glb() {
    let dir = springbake_testkit::corpus_dir().join("blender");
    let a = import_file(&dir.join("icosphere.glb"));
    let b = import_file(&dir.join("icosphere_separate.gltf"));
    assert_eq!(a.meshes[0].primitives, b.meshes[0].primitives);
}

#[test]
fn node_hierarchy_world_matrix_on_two_objects() {
    let scene = import_file(&springbake_testkit::corpus_dir().join("blender/two_objects.glb"));
    assert_eq!(scene.meshes.len(), 2);
    let head = scene.meshes.iter().find(|m| m.name == "Head").unwrap();
    let body = scene.meshes.iter().find(|m| m.name == "Body").unwrap();
    assert_eq!(head.source_key, "node:0");
    assert_eq!(body.primitives[0].material.as_deref(), Some("Red"));
    assert_eq!(head.primitives[0].material, None);
    // Body: T=(0,1,0), R = 30° about +Y (quaternion (0, sin15°, 0, cos15°)), S=(1.5,1,1).
    // Head (child of Body): T=(0.8,1.5,0). World = T_b R_b S_b (T_h v), computed by hand.
    let v = head.primitives[0].positions[0];
    let local = [v[0] as f64 + 0.8, v[1] as f64 + 1.5, v[2] as f64];
    let scaled = [local[0] * 1.5, local[1], local[2]];
    let (s, c) = 30f64.to_radians().sin_cos();
    let expected = [
        c * scaled[0] + s * scaled[2],
        scaled[1] + 1.0,
        -s * scaled[0] + c * scaled[2],
    ];
    let got = head.world_positions()[0];
    for k in 0..3 {
        assert!(
            (got[k] - expected[k]).abs() < 1e-6,
            "axis {k}: {got:?} vs {expected:?}"
        );
    }
    // The child's centre lands at T_b R_b S_b (0.8, 1.5, 0) = (1.2 cos30, 2.5, -1.2 sin30).
    let centre = head
        .world_from_local
        .transform_point(&nalgebra::Point3::origin());
    assert!((centre.x - 1.2 * c).abs() < 1e-6 && (centre.y - 2.5).abs() < 1e-6);
    assert!((centre.z + 1.2 * s).abs() < 1e-6, "{centre:?}");
}

#[test]
fn triangle_strip_and_fan_are_triangulated_with_spec_winding() {
    let idx: Vec<u8> = [0u16, 1, 2, 3]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let strip = import_bytes("s.gltf", &square_with_indices(5, &idx, 5123, 4)).unwrap();
    assert_eq!(
        strip.meshes[0].primitives[0].indices,
        vec![0, 1, 2, 2, 1, 3]
    );
    // a fan walks the square's rim: 0, 1, 3, 2
    let rim: Vec<u8> = [0u16, 1, 3, 2]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let fan = import_bytes("f.gltf", &square_with_indices(6, &rim, 5123, 4)).unwrap();
    assert_eq!(fan.meshes[0].primitives[0].indices, vec![1, 3, 0, 3, 2, 0]);
    // both windings face +Z, like the list 0,1,2 / 2,1,3
    for scene in [&strip, &fan] {
        let p = &scene.meshes[0].primitives[0];
        for n in springbake_core::display::vertex_normals(&p.positions, &p.indices) {
            assert!((n[2] - 1.0).abs() < 1e-6, "{n:?}");
        }
    }
}

#[test]
fn u8_and_u32_indices() {
    let idx8 = [0u8, 1, 2, 2, 1, 3];
    let s = import_bytes("a.gltf", &square_with_indices(4, &idx8, 5121, 6)).unwrap();
    assert_eq!(s.meshes[0].primitives[0].indices, vec![0, 1, 2, 2, 1, 3]);
    let idx32: Vec<u8> = [3u32, 1, 0].iter().flat_map(|i| i.to_le_bytes()).collect();
    let s = import_bytes("b.gltf", &square_with_indices(4, &idx32, 5125, 3)).unwrap();
    assert_eq!(s.meshes[0].primitives[0].indices, vec![3, 1, 0]);
}

#[test]
fn index_beyond_the_vertices_is_an_error() {
    let idx8 = [0u8, 1, 9];
    let err = import_bytes("a.gltf", &square_with_indices(4, &idx8, 5121, 3)).unwrap_err();
    assert_eq!(
        err.location.as_deref(),
        Some("meshes[0].primitives[0].indices")
    );
    assert!(err.message.contains('9'), "{err}");
}

#[test]
fn missing_indices_mean_sequential_vertices() {
    let bin = f32s(&[
        0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0., 0., 1., 0., 1., 0., 0.,
    ]);
    let bytes = doc(
        &bin,
        json!([{"buffer": 0, "byteLength": 72}]),
        json!([{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let s = import_bytes("n.gltf", &bytes).unwrap();
    assert_eq!(s.meshes[0].primitives[0].indices, vec![0, 1, 2, 3, 4, 5]);
    assert_eq!(s.meshes[0].primitives[0].positions[3], [1., 1., 0.]);
}

#[test]
fn sparse_accessor_replaces_listed_elements() {
    // base: the square; sparse: vertex 1 → (5, 6, 7), vertex 3 → (8, 9, 10)
    let mut bin = f32s(&SQUARE); // 0..48
    bin.extend([1u8, 0, 3, 0]); // sparse indices u16 at 48..52
    bin.extend(f32s(&[5., 6., 7., 8., 9., 10.])); // values at 52..76
    let bytes = doc(
        &bin,
        json!([
            {"buffer": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 4},
            {"buffer": 0, "byteOffset": 52, "byteLength": 24}
        ]),
        json!([{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                "min": [0,0,0], "max": [8,9,10],
                "sparse": {"count": 2, "indices": {"bufferView": 1, "componentType": 5123},
                           "values": {"bufferView": 2}}}]),
        json!({"attributes": {"POSITION": 0}, "mode": 5}),
    );
    let s = import_bytes("sp.gltf", &bytes).unwrap();
    let p = &s.meshes[0].primitives[0].positions;
    assert_eq!(
        p,
        &vec![[0., 0., 0.], [5., 6., 7.], [0., 1., 0.], [8., 9., 10.]]
    );
}

#[test]
fn sparse_accessor_without_buffer_view_starts_from_zeros() {
    let mut bin = vec![2u8, 0, 0, 0];
    bin.extend(f32s(&[1., 2., 3.]));
    let bytes = doc(
        &bin,
        json!([{"buffer": 0, "byteLength": 1}, {"buffer": 0, "byteOffset": 4, "byteLength": 12}]),
        json!([{"componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,2,3],
                "sparse": {"count": 1, "indices": {"bufferView": 0, "componentType": 5121},
                           "values": {"bufferView": 1}}}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let s = import_bytes("z.gltf", &bytes).unwrap();
    assert_eq!(
        s.meshes[0].primitives[0].positions,
        vec![[0.; 3], [0.; 3], [1., 2., 3.]]
    );
}

#[test]
fn quantized_attributes_are_decoded_to_f32() {
    // KHR_mesh_quantization: POSITION as normalized u16 (padded to 8 bytes per element),
    // NORMAL as normalized i8 (padded to 4), TEXCOORD_0 as normalized u16.
    let pos: [[u16; 4]; 3] = [[0, 0, 0, 0], [65535, 0, 0, 0], [0, 32768, 65535, 0]];
    let nrm: [[i8; 4]; 3] = [[0, 0, 127, 0], [0, -127, 0, 0], [-128, 0, 0, 0]];
    let uv: [[u16; 2]; 3] = [[0, 0], [65535, 0], [0, 65535]];
    let mut bin: Vec<u8> = pos.iter().flatten().flat_map(|c| c.to_le_bytes()).collect(); // 24
    bin.extend(nrm.iter().flatten().map(|&c| c as u8)); // 12 → 36
    bin.extend(uv.iter().flatten().flat_map(|c| c.to_le_bytes())); // 12 → 48
    let mut bytes: Value = serde_json::from_slice(&doc(
        &bin,
        json!([
            {"buffer": 0, "byteLength": 24, "byteStride": 8},
            {"buffer": 0, "byteOffset": 24, "byteLength": 12, "byteStride": 4},
            {"buffer": 0, "byteOffset": 36, "byteLength": 12}
        ]),
        json!([
            {"bufferView": 0, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC3",
             "min": [0,0,0], "max": [65535,32768,65535]},
            {"bufferView": 1, "componentType": 5120, "normalized": true, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "normalized": true, "count": 3, "type": "VEC2"}
        ]),
        json!({"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}),
    ))
    .unwrap();
    bytes["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    bytes["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    bytes["nodes"][0]["scale"] = json!([2.0, 2.0, 2.0]); // dequantization lives on the node
    let s = import_bytes("q.gltf", &serde_json::to_vec(&bytes).unwrap()).unwrap();
    let p = &s.meshes[0].primitives[0];
    assert_eq!(p.positions[0], [0., 0., 0.]);
    assert_eq!(p.positions[1], [1., 0., 0.]);
    assert!((p.positions[2][1] - 32768.0 / 65535.0).abs() < 1e-7);
    assert_eq!(p.positions[2][2], 1.0);
    let n = p.normals.as_ref().unwrap();
    assert_eq!(n[0], [0., 0., 1.]);
    assert_eq!(n[1], [0., -1., 0.]);
    assert_eq!(n[2], [-1., 0., 0.], "-128 clamps to -1");
    assert_eq!(p.uvs.as_ref().unwrap()[2], [0., 1.]);
    assert_eq!(s.meshes[0].world_positions()[1].x, 2.0);
}

#[test]
fn quantized_integer_positions_are_converted() {
    // non-normalized i16 positions (KHR_mesh_quantization allows them)
    let pos: [[i16; 4]; 3] = [[-3, 0, 0, 0], [7, 0, 0, 0], [0, 100, -2, 0]];
    let bin: Vec<u8> = pos.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
    let bytes = doc(
        &bin,
        json!([{"buffer": 0, "byteLength": 24, "byteStride": 8}]),
        json!([{"bufferView": 0, "componentType": 5122, "count": 3, "type": "VEC3",
                "min": [-3,0,-2], "max": [7,100,0]}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let mut v: Value = serde_json::from_slice(&bytes).unwrap();
    v["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    v["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    let s = import_bytes("i.gltf", &serde_json::to_vec(&v).unwrap()).unwrap();
    assert_eq!(
        s.meshes[0].primitives[0].positions,
        vec![[-3., 0., 0.], [7., 0., 0.], [0., 100., -2.]]
    );
}

#[test]
fn data_uri_buffer_and_material_names() {
    let mut v: Value =
        serde_json::from_slice(&square_with_indices(4, &[0u8, 1, 2, 2, 1, 3], 5121, 6)).unwrap();
    assert!(v["buffers"][0]["uri"]
        .as_str()
        .unwrap()
        .starts_with("data:"));
    v["materials"] = json!([{"name": "Rubber"}]);
    v["meshes"][0]["primitives"][0]["material"] = json!(0);
    v["meshes"][0]["name"] = json!("MeshName");
    v["nodes"][0].as_object_mut().unwrap().remove("name");
    let s = import_bytes("d.gltf", &serde_json::to_vec(&v).unwrap()).unwrap();
    assert_eq!(s.meshes[0].name, "MeshName", "falls back to the mesh name");
    assert_eq!(
        s.meshes[0].primitives[0].material.as_deref(),
        Some("Rubber")
    );
    assert_eq!(s.meshes[0].primitives[0].positions[3], [1., 1., 0.]);
    assert_eq!(s.up_axis, springbake_core::display::UpAxis::Y);
    assert_eq!(s.meters_per_unit, 1.0);
    assert_eq!(s.source.importer, "gltf");
}

#[test]
fn stride_running_past_the_view_is_an_error() {
    let bin = f32s(&SQUARE);
    let bytes = doc(
        &bin,
        json!([{"buffer": 0, "byteLength": 48, "byteStride": 16}]),
        json!([{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let err = import_bytes("s.gltf", &bytes).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("accessors[0]"));
    assert!(err.message.contains("stride 16"), "{err}");
}

#[test]
fn buffer_view_running_past_the_buffer_is_an_error() {
    let bin = f32s(&SQUARE);
    let bytes = doc(
        &bin,
        json!([{"buffer": 0, "byteOffset": 40, "byteLength": 48}]),
        json!([{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let err = import_bytes("s.gltf", &bytes).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("bufferViews[0]"));
}

#[test]
fn points_primitive_is_refused_by_its_data_path() {
    let bytes = square_with_indices(0, &[0u8, 1, 2], 5121, 3);
    let err = import_bytes("p.gltf", &bytes).unwrap_err();
    assert_eq!(
        err.location.as_deref(),
        Some("meshes[0].primitives[0].mode")
    );
    assert!(err.message.contains("POINTS"), "{err}");
}

#[test]
fn meshopt_extension_is_refused_by_name() {
    let mut v: Value =
        serde_json::from_slice(&square_with_indices(4, &[0u8, 1, 2], 5121, 3)).unwrap();
    v["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
    let err = import_bytes("m.gltf", &serde_json::to_vec(&v).unwrap()).unwrap_err();
    assert!(err.message.contains("EXT_meshopt_compression"), "{err}");
}

/// A GLB of `json` and `bin`, each chunk's length as written (`pad`: the JSON padded with
/// spaces to 4 bytes first, as the spec asks).
fn glb(json: &Value, bin: &[u8], pad: bool) -> Vec<u8> {
    let mut json = serde_json::to_vec(json).unwrap();
    while pad && !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(bin);
    glb
}

/// Two nodes sharing one triangle, the second 5 m up; `pad_to` spaces make the JSON's length.
fn two_triangles_json(pad_to: usize) -> Value {
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "nodes": [{"mesh": 0, "children": [1]}, {"mesh": 0, "translation": [0, 0, 5]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36}],
    });
    let len = serde_json::to_vec(&doc).unwrap().len();
    doc["asset"]["generator"] = json!("x".repeat(pad_to.saturating_sub(len + 16)));
    doc
}

#[test]
fn glb_written_by_hand_imports() {
    let glb = glb(&two_triangles_json(0), &f32s(&SQUARE[..9]), true);
    // no scenes: every root node and its children are imported
    let s = import_bytes("h.glb", &glb).unwrap();
    assert_eq!(s.meshes.len(), 2);
    assert_eq!(s.meshes[1].source_key, "node:1");
    assert_eq!(s.meshes[1].name, "node_1");
    let q = s.meshes[1].world_positions()[1];
    assert_eq!([q.x, q.y, q.z], [1., 0., 5.]);
}

/// trimesh (up to 3.x) writes the JSON chunk's unpadded length and the BIN chunk right after
/// it (its test models cube.glb and pins.glb); Blender's importer reads them, and so does
/// springbake, for every length the JSON can have.
#[test]
fn glb_whose_json_chunk_is_not_padded_imports() {
    let bin = f32s(&SQUARE[..9]);
    let base = serde_json::to_vec(&two_triangles_json(0)).unwrap().len() + 40;
    let mut remainders = Vec::new();
    for extra in 0..4 {
        let json = two_triangles_json(base + extra);
        let bytes = glb(&json, &bin, false);
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap());
        remainders.push(json_len % 4);
        let s = import_bytes("trimesh.glb", &bytes)
            .unwrap_or_else(|e| panic!("JSON chunk of {json_len} bytes: {e}"));
        assert_eq!(s.meshes.len(), 2, "JSON chunk of {json_len} bytes");
        let q = s.meshes[1].world_positions()[1];
        assert_eq!([q.x, q.y, q.z], [1., 0., 5.]);
    }
    remainders.sort_unstable();
    assert_eq!(remainders, [0, 1, 2, 3]);
}

/// Issue 17, items 4 and 6: a buffer URI is read only inside the glTF file's folder after
/// symlinks are resolved, must be a regular file (`""` and `.` name the folder itself), and
/// every such refusal is the user's error (exit 2), with the JSON path.
#[test]
fn buffer_uris_that_leave_the_folder_through_links_or_name_folders_are_refused() {
    let outer = tempfile::tempdir().unwrap();
    let folder = outer.path().join("asset");
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::write(outer.path().join("secret.bin"), [0u8; 36]).unwrap();
    let gltf = |uri: &str| {
        json!({
            "asset": {"version": "2.0"},
            "buffers": [{"uri": uri, "byteLength": 36}],
        })
        .to_string()
    };
    let mut uris = vec!["", ".", "./"];
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(outer.path().join("secret.bin"), folder.join("link.bin"))
            .unwrap();
        uris.push("link.bin");
    }
    for uri in uris {
        let path = folder.join("m.gltf");
        let text = gltf(uri);
        std::fs::write(&path, &text).unwrap();
        let err = GltfImporter
            .import(&path, text.as_bytes(), &ImportSettings::default())
            .expect_err(uri);
        assert_eq!(err.kind, IoErrorKind::Invalid, "{uri}: {err}");
        assert_eq!(err.location.as_deref(), Some("buffers[0].uri"), "{uri}");
        let expected = if uri == "link.bin" {
            "outside the folder"
        } else {
            "a directory"
        };
        assert!(err.message.contains(expected), "{uri}: {err}");
    }
}

/// Issue 17 silent misreads: integer POSITION without KHR_mesh_quantization, and buffer
/// views that fit the bytes present but not the buffer's declared byteLength.
#[test]
fn integer_positions_and_views_past_the_declared_buffer_are_refused() {
    let bytes: Vec<u8> = vec![0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0];
    let u8_doc = doc(
        &bytes,
        json!([{"buffer": 0, "byteLength": 12, "byteStride": 4}]),
        json!([{"bufferView": 0, "componentType": 5121, "count": 3, "type": "VEC3"}]),
        json!({"attributes": {"POSITION": 0}}),
    );
    let err = import_bytes("u8.gltf", &u8_doc).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("accessors[0].componentType"));
    assert!(err.message.contains("KHR_mesh_quantization"), "{err}");
    // With the extension declared, the same file is valid (unnormalized integers).
    let mut quantized: Value = serde_json::from_slice(&u8_doc).unwrap();
    quantized["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let scene = import_bytes("q.gltf", &serde_json::to_vec(&quantized).unwrap()).unwrap();
    assert_eq!(scene.meshes[0].primitives[0].positions[2], [0.0, 1.0, 0.0]);

    // byteLength says 40 bytes but the view wants the 48 that are there.
    let mut short: Value =
        serde_json::from_slice(&square_with_indices(4, &[0, 1, 2, 1, 3, 2], 5121, 6)).unwrap();
    short["buffers"][0]["byteLength"] = json!(40);
    let err = import_bytes("short.gltf", &serde_json::to_vec(&short).unwrap()).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("bufferViews[0]"), "{err}");
    assert!(
        err.message.contains("runs past buffers[0] (40 bytes)"),
        "{err}"
    );
}

#[test]
fn a_mesh_moved_by_an_animation_is_named_in_a_note() {
    // Node 0 (no mesh) is animated and carries mesh node 1; node 2 stands still.
    let mut bin = f32s(&SQUARE);
    bin.extend(f32s(&[0.0, 1.0]));
    bin.extend(f32s(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]));
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let file = serde_json::to_vec(&json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"name": "Mover", "children": [1]},
            {"mesh": 0, "name": "Carried"},
            {"mesh": 0, "name": "Still", "translation": [3, 0, 0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "animations": [{
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
            "samplers": [{"input": 1, "output": 2}]
        }],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC3"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 8},
            {"buffer": 0, "byteOffset": 56, "byteLength": 24}
        ],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
    }))
    .unwrap();
    let scene = import_bytes("moved.gltf", &file).unwrap();
    let animated: Vec<&String> = scene
        .notes
        .iter()
        .filter(|n| n.contains("is animated in the source"))
        .collect();
    assert_eq!(animated.len(), 1, "{:?}", scene.notes);
    assert!(animated[0].starts_with("\"Carried\""), "{}", animated[0]);
}

#[test]
fn a_skin_without_joints_is_refused_by_its_data_path() {
    // A glTF 1.0 skin (`jointNames`) in a file marked 2.0, as an old COLLADA2GLTF wrote.
    let mut bin = f32s(&SQUARE);
    bin.extend([0u8; 12]);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let file = serde_json::to_vec(&json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "skin": 0}],
        "skins": [{"jointNames": ["a", "b"]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}
        ],
        "bufferViews": [{"buffer": 0, "byteLength": 60}],
        "buffers": [{"byteLength": bin.len(), "uri": uri}],
    }))
    .unwrap();
    let err = import_bytes("old_skin.gltf", &file)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("skins[0].joints") && err.contains("jointNames"),
        "{err}"
    );
}
