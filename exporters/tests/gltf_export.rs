//! glTF exporter: synthetic bakes (no solver) of corpus meshes, exported as morph targets and
//! as the lattice skin, then checked by gltf-validator, by evaluating the written animation
//! ourselves, by re-importing, by Blender, and for byte-identical repeats.

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use nalgebra::{Matrix4, Point3, Vector3};
use serde_json::{json, Value};
use springbake_core::bake::{BakedLattice, BakedMesh, BakedScene};
use springbake_core::display::{DisplayMesh, ImportedScene};
use springbake_core::plugin::{CacheKind, ExportSettings, Exporter, ImportSettings, Importer};
use springbake_exporters::gltf::GltfExporter;
use springbake_importers::gltf::accessor::read_floats;
use springbake_importers::gltf::document::{get_usize, load_document, GltfDocument};
use springbake_importers::gltf::{local_matrix, GltfImporter};
use std::path::{Path, PathBuf};

const FPS: f64 = 24.0;
const FRAMES: usize = 10;

fn import(path: &Path) -> ImportedScene {
    let bytes = std::fs::read(path).unwrap();
    GltfImporter
        .import(path, &bytes, &ImportSettings::default())
        .unwrap_or_else(|e| panic!("{e}"))
}

fn corpus(name: &str) -> PathBuf {
    springbake_testkit::corpus_dir().join("blender").join(name)
}

fn local_bbox(mesh: &DisplayMesh) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for p in mesh.primitives.iter().flat_map(|p| &p.positions) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

fn diagonal(mesh: &DisplayMesh) -> f64 {
    let (lo, hi) = local_bbox(mesh);
    (0..3)
        .map(|k| ((hi[k] - lo[k]) as f64).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// A 2×2×2-cell lattice (27 nodes) around the mesh, nodes moving by a smooth function of
/// their position and the frame; vertices follow by trilinear interpolation. The same
/// frames serve the morph cache (positions) and the skin cache (lattice).
fn lattice_bake(mesh_index: usize, mesh: &DisplayMesh) -> BakedMesh {
    let (mut lo, mut hi) = local_bbox(mesh);
    for k in 0..3 {
        let pad = 0.01 * (hi[k] - lo[k]).max(1e-3);
        lo[k] -= pad;
        hi[k] += pad;
    }
    let size: Vec<f32> = (0..3).map(|k| hi[k] - lo[k]).collect();
    let amp = 0.05 * diagonal(mesh) as f32;
    let mut rest = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..3 {
                rest.push([
                    lo[0] + size[0] * i as f32 / 2.0,
                    lo[1] + size[1] * j as f32 / 2.0,
                    lo[2] + size[2] * k as f32 / 2.0,
                ]);
            }
        }
    }
    // Frame 0 is the rest pose, as every bake's first frame is (a re-import of the output
    // starts from its first frame).
    let disp = |p: [f32; 3], f: usize| -> [f32; 3] {
        if f == 0 {
            return [0.0; 3];
        }
        let ph = std::f32::consts::TAU * f as f32 / FRAMES as f32;
        let u: Vec<f32> = (0..3).map(|k| (p[k] - lo[k]) / size[k]).collect();
        [
            amp * (ph + 3.0 * u[1]).sin(),
            amp * 0.5 * (ph + 2.0 * u[0]).cos() * u[1],
            amp * (0.5 * ph).sin() * (u[0] - u[2]),
        ]
    };
    let frames_nodes: Vec<Vec<[f32; 3]>> = (0..FRAMES)
        .map(|f| {
            rest.iter()
                .map(|&r| {
                    let d = disp(r, f);
                    [r[0] + d[0], r[1] + d[1], r[2] + d[2]]
                })
                .collect()
        })
        .collect();
    let mut vertex_nodes = Vec::new();
    let mut vertex_weights = Vec::new();
    for p in mesh.primitives.iter().flat_map(|p| &p.positions) {
        let mut cell = [0usize; 3];
        let mut t = [0f32; 3];
        for k in 0..3 {
            let c = (p[k] - lo[k]) / size[k] * 2.0;
            cell[k] = (c.floor() as usize).min(1);
            t[k] = c - cell[k] as f32;
        }
        let mut ns = [0u32; 8];
        let mut ws = [0f32; 8];
        for corner in 0..8 {
            let d = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            ns[corner] = ((cell[0] + d[0]) + 3 * (cell[1] + d[1]) + 9 * (cell[2] + d[2])) as u32;
            ws[corner] = (0..3)
                .map(|k| if d[k] == 1 { t[k] } else { 1.0 - t[k] })
                .product();
        }
        vertex_nodes.push(ns);
        vertex_weights.push(ws);
    }
    let frames: Vec<Vec<[f32; 3]>> = (0..FRAMES)
        .map(|f| {
            mesh.primitives
                .iter()
                .flat_map(|p| &p.positions)
                .zip(vertex_nodes.iter().zip(&vertex_weights))
                .map(|(v, (ns, ws))| {
                    let mut q = *v;
                    for (&n, &w) in ns.iter().zip(ws) {
                        let a = frames_nodes[f][n as usize];
                        let r = rest[n as usize];
                        for k in 0..3 {
                            q[k] += w * (a[k] - r[k]);
                        }
                    }
                    q
                })
                .collect()
        })
        .collect();
    BakedMesh {
        mesh_index,
        frames,
        lattice: Some(BakedLattice {
            rest,
            frames: frames_nodes,
            vertex_nodes,
            vertex_weights,
        }),
    }
}

/// Every mesh tumbling (a turn of 0.4 rad a frame about a tilted axis through its centre),
/// falling and drifting, with a small squash along its local y: rigid motion with a little
/// deformation, as a bouncing body's bake is.
fn tumbling_bake(scene: &ImportedScene) -> BakedScene {
    let meshes = scene
        .meshes
        .iter()
        .enumerate()
        .map(|(mesh_index, mesh)| {
            let rest: Vec<[f32; 3]> = mesh
                .primitives
                .iter()
                .flat_map(|p| p.positions.clone())
                .collect();
            let centre = rest.iter().fold(Vector3::zeros(), |a, p| {
                a + Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64)
            }) / rest.len() as f64;
            let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 3.0));
            let frames = (0..FRAMES)
                .map(|f| {
                    let t = f as f64;
                    let turn = nalgebra::UnitQuaternion::from_axis_angle(&axis, 0.4 * t);
                    let squash = 1.0 - 0.02 * t.sin();
                    let moved = Vector3::new(0.1 * t, -0.05 * t * t, 0.03 * t);
                    rest.iter()
                        .map(|p| {
                            let mut v =
                                Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) - centre;
                            v.y *= squash;
                            let x = centre + moved + turn * v;
                            [x.x as f32, x.y as f32, x.z as f32]
                        })
                        .collect()
                })
                .collect();
            BakedMesh {
                mesh_index,
                frames,
                lattice: None,
            }
        })
        .collect();
    BakedScene {
        particles: Vec::new(),
        stage: None,
        fps: FPS,
        frame_count: FRAMES,
        meshes,
    }
}

fn bake_all(scene: &ImportedScene) -> BakedScene {
    BakedScene {
        particles: Vec::new(),
        stage: None,
        fps: FPS,
        frame_count: FRAMES,
        meshes: scene
            .meshes
            .iter()
            .enumerate()
            .map(|(i, m)| lattice_bake(i, m))
            .collect(),
    }
}

/// Export into `dir/name` and write the files there.
fn export_to(
    dir: &Path,
    name: &str,
    scene: &ImportedScene,
    baked: &BakedScene,
    cache: CacheKind,
) -> Vec<springbake_core::plugin::OutputFile> {
    let settings = ExportSettings {
        path: dir.join(name),
        cache,
        axes: Default::default(),
    };
    let files = GltfExporter
        .export(scene, baked, &settings)
        .unwrap_or_else(|e| panic!("{e}"));
    for f in &files {
        std::fs::write(&f.path, &f.bytes).unwrap();
    }
    files
}

fn load(path: &Path) -> GltfDocument {
    load_document(path, &std::fs::read(path).unwrap()).unwrap()
}

fn node_by_name(doc: &GltfDocument, name: &str) -> usize {
    doc.array("nodes")
        .iter()
        .position(|n| n["name"] == name)
        .unwrap_or_else(|| panic!("no node {name}"))
}

/// Value of the (only) channel of animation 0 for `node`/`path` at key `f`.
fn channel_key(doc: &GltfDocument, node: usize, path: &str, f: usize) -> Option<Vec<f32>> {
    let anim = &doc.array("animations")[0];
    let ch =
        anim["channels"].as_array().unwrap().iter().find(|c| {
            get_usize(&c["target"], "node") == Some(node) && c["target"]["path"] == path
        })?;
    let sampler = &anim["samplers"][get_usize(ch, "sampler").unwrap()];
    assert_eq!(sampler["interpolation"], "LINEAR");
    let (times, _) = read_floats(doc, get_usize(sampler, "input").unwrap(), "t").unwrap();
    assert_eq!(times.len(), FRAMES);
    assert!(
        (times[f] as f64 - f as f64 / FPS).abs() < 1e-6,
        "key {f} at {}",
        times[f]
    );
    let (out, comps) = read_floats(doc, get_usize(sampler, "output").unwrap(), "o").unwrap();
    let per = out.len() / times.len();
    let _ = comps;
    Some(out[f * per..(f + 1) * per].to_vec())
}

/// World matrices of every node at key `f`, with animated translations and rotations
/// applied.
fn world_matrices(doc: &GltfDocument, f: usize) -> Vec<Matrix4<f64>> {
    let nodes = doc.array("nodes");
    let mut local: Vec<Matrix4<f64>> = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        let mut n = n.clone();
        for path in ["translation", "rotation"] {
            if let Some(key) = channel_key(doc, i, path, f) {
                n[path] = json!(key);
            }
        }
        local.push(local_matrix(doc, &n, "node").unwrap());
    }
    let mut parent = vec![None; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        for c in n["children"].as_array().into_iter().flatten() {
            parent[c.as_u64().unwrap() as usize] = Some(i);
        }
    }
    (0..nodes.len())
        .map(|mut i| {
            let mut m = local[i];
            while let Some(p) = parent[i] {
                m = local[p] * m;
                i = p;
            }
            m
        })
        .collect()
}

/// Positions of `node`'s mesh at key `f` as glTF defines them: morph targets weighted by
/// the weights channel, or skinning by the joints' world matrices; world coordinates.
fn evaluate(doc: &GltfDocument, node: usize, f: usize) -> Vec<Point3<f64>> {
    let n = &doc.array("nodes")[node];
    let mesh = &doc.array("meshes")[get_usize(n, "mesh").unwrap()];
    let worlds = world_matrices(doc, f);
    let mut out = Vec::new();
    for prim in mesh["primitives"].as_array().unwrap() {
        let attrs = &prim["attributes"];
        let (base, _) = read_floats(doc, get_usize(attrs, "POSITION").unwrap(), "p").unwrap();
        let mut pos: Vec<Vector3<f64>> = base
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            .collect();
        if let Some(targets) = prim["targets"].as_array() {
            let w = channel_key(doc, node, "weights", f).unwrap();
            assert_eq!(w.len(), targets.len());
            for (t, &wt) in targets.iter().zip(&w) {
                if wt == 0.0 {
                    continue;
                }
                let (d, _) = read_floats(doc, get_usize(t, "POSITION").unwrap(), "d").unwrap();
                for (p, c) in pos.iter_mut().zip(d.chunks_exact(3)) {
                    *p += wt as f64 * Vector3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                }
            }
        }
        if let Some(skin) = get_usize(n, "skin") {
            let skin = &doc.array("skins")[skin];
            let joints: Vec<usize> = skin["joints"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j.as_u64().unwrap() as usize)
                .collect();
            let (ibm, _) =
                read_floats(doc, get_usize(skin, "inverseBindMatrices").unwrap(), "i").unwrap();
            let joint_mat: Vec<Matrix4<f64>> = joints
                .iter()
                .enumerate()
                .map(|(k, &j)| {
                    let m: Vec<f64> = ibm[k * 16..k * 16 + 16].iter().map(|&x| x as f64).collect();
                    worlds[j] * Matrix4::from_column_slice(&m)
                })
                .collect();
            let mut skinned = vec![Vector3::zeros(); pos.len()];
            for set in 0..2 {
                let (js, _) = read_floats(
                    doc,
                    get_usize(attrs, &format!("JOINTS_{set}")).unwrap(),
                    "j",
                )
                .unwrap();
                let (ws, _) = read_floats(
                    doc,
                    get_usize(attrs, &format!("WEIGHTS_{set}")).unwrap(),
                    "w",
                )
                .unwrap();
                for (v, s) in skinned.iter_mut().enumerate() {
                    for c in 0..4 {
                        let w = ws[v * 4 + c] as f64;
                        assert!(w >= 0.0);
                        let m = joint_mat[js[v * 4 + c] as usize];
                        *s += w * m.transform_point(&Point3::from(pos[v])).coords;
                    }
                }
            }
            out.extend(skinned.into_iter().map(Point3::from));
        } else {
            out.extend(
                pos.iter()
                    .map(|p| worlds[node].transform_point(&Point3::from(*p))),
            );
        }
    }
    out
}

/// Largest distance between what the file plays at each key and the bake (world frame).
fn max_error(doc: &GltfDocument, scene: &ImportedScene, baked: &BakedScene) -> f64 {
    let mut worst: f64 = 0.0;
    for bm in &baked.meshes {
        let mesh = &scene.meshes[bm.mesh_index];
        let node = node_by_name(doc, &mesh.name);
        for f in 0..FRAMES {
            let got = evaluate(doc, node, f);
            assert_eq!(got.len(), mesh.vertex_count());
            for (g, e) in got.iter().zip(&bm.frames[f]) {
                let e = mesh.world_from_local.transform_point(&Point3::new(
                    e[0] as f64,
                    e[1] as f64,
                    e[2] as f64,
                ));
                worst = worst.max((g - e).norm());
            }
        }
    }
    worst
}

#[test]
fn morph_glb_is_valid_and_plays_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["icosphere.glb", "two_objects.glb"] {
        let scene = import(&corpus(name));
        let baked = bake_all(&scene);
        let files = export_to(
            dir.path(),
            &format!("m_{name}"),
            &scene,
            &baked,
            CacheKind::Morph,
        );
        assert_eq!(files.len(), 1);
        springbake_testkit::assert_gltf_valid(&files[0].path);
        let doc = load(&files[0].path);
        let err = max_error(&doc, &scene, &baked);
        assert!(
            err < 1e-6,
            "{name}: morph playback differs from the bake by {err}"
        );
        // one target per frame on every baked primitive, NORMAL deltas included
        for m in doc.array("meshes") {
            for p in m["primitives"].as_array().unwrap() {
                let t = p["targets"].as_array().unwrap();
                assert_eq!(t.len(), FRAMES);
                assert!(t[3].get("NORMAL").is_some());
            }
            assert_eq!(m["extras"]["targetNames"][9], "frame_0009");
        }
        // the weights at key 4 are one-hot at 4
        let node = node_by_name(&doc, &scene.meshes[0].name);
        let w = channel_key(&doc, node, "weights", 4).unwrap();
        assert_eq!(w.iter().position(|&x| x == 1.0), Some(4));
        assert_eq!(w.iter().sum::<f32>(), 1.0);
    }
}

/// Issue 23 item 3: the compact cache plays the bake within its bound (world metres) with a
/// few targets, is validator-clean, and is smaller than one target per frame.
#[test]
fn pca_cache_plays_the_bake_within_its_bound_in_a_fraction_of_the_size() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["icosphere.glb", "two_objects.glb"] {
        let scene = import(&corpus(name));
        let baked = bake_all(&scene);
        let morph = export_to(
            dir.path(),
            &format!("m_{name}"),
            &scene,
            &baked,
            CacheKind::Morph,
        );
        for bound_um in [1000, 10] {
            let cache = CacheKind::Pca {
                max_error_um: bound_um,
            };
            let files = export_to(
                dir.path(),
                &format!("p{bound_um}_{name}"),
                &scene,
                &baked,
                cache,
            );
            springbake_testkit::assert_gltf_valid(&files[0].path);
            let doc = load(&files[0].path);
            let err = max_error(&doc, &scene, &baked);
            let bound = f64::from(bound_um) * 1e-6;
            // f32 targets and weights add rounding on top of the components' own error.
            assert!(
                err <= bound * 1.01 + 1e-5,
                "{name}: plays {err} m off, bound {bound}"
            );
            for m in doc.array("meshes") {
                let c = &m["extras"]["springbake_cache"];
                assert_eq!(c["kind"], "pca");
                assert!(c["max_error_m"].as_f64().unwrap() <= bound, "{c}");
                let k = c["components"].as_u64().unwrap() as usize;
                assert!(k < FRAMES, "{name}: {k} components for {FRAMES} frames");
            }
            let (pca_size, morph_size) = (files[0].bytes.len(), morph[0].bytes.len());
            assert!(
                pca_size < morph_size,
                "{name}: {pca_size} vs {morph_size} bytes"
            );
        }
    }
}

/// The compact cache takes a tumbling body's rigid motion out as its node's translation and
/// rotation keys: a body that turns, falls and squashes a little needs two components at
/// most, 16-bit ones, and the file is a fraction of one target per frame. A node with children keeps
/// its transform (the children would move with it).
#[test]
fn pca_cache_plays_rigid_motion_as_node_keys() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["icosphere.glb", "two_objects.glb"] {
        let scene = import(&corpus(name));
        let baked = tumbling_bake(&scene);
        let morph = export_to(dir.path(), "m.glb", &scene, &baked, CacheKind::Morph);
        let cache = CacheKind::Pca { max_error_um: 100 };
        let files = export_to(dir.path(), "p.glb", &scene, &baked, cache);
        springbake_testkit::assert_gltf_valid(&files[0].path);
        let doc = load(&files[0].path);
        let err = max_error(&doc, &scene, &baked);
        assert!(err <= 1e-4, "{name}: plays {err} m off, bound 0.1 mm");
        for bm in &baked.meshes {
            let node = node_by_name(&doc, &scene.meshes[bm.mesh_index].name);
            let json = &doc.array("nodes")[node];
            let mesh = &doc.array("meshes")[get_usize(json, "mesh").unwrap()];
            let c = &mesh["extras"]["springbake_cache"];
            let parent = json.get("children").is_some();
            if parent {
                assert_eq!(c["rigid"], "none", "{name}: {c}");
                assert!(channel_key(&doc, node, "rotation", 1).is_none());
            } else {
                assert_eq!(c["rigid"], "rotation and translation", "{name}: {c}");
                assert!(c["components"].as_u64().unwrap() <= 2, "{name}: {c}");
                assert_eq!(c["quantised"], true, "{name}: {c}");
                assert!(channel_key(&doc, node, "rotation", 1).is_some());
            }
        }
        let (pca_size, morph_size) = (files[0].bytes.len(), morph[0].bytes.len());
        eprintln!("{name}: pca {pca_size} bytes, morph {morph_size} bytes");
        if name == "icosphere.glb" {
            // 10 frames: the rest mesh is most of the file (a quarter of the morph cache's)
            assert!(pca_size * 4 < morph_size, "{pca_size} vs {morph_size}");
        }
    }
}

#[test]
fn skin_cache_is_valid_and_matches_the_morph_bake() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["icosphere.glb", "two_objects.glb"] {
        let scene = import(&corpus(name));
        let baked = bake_all(&scene);
        let skin = export_to(
            dir.path(),
            &format!("s_{name}"),
            &scene,
            &baked,
            CacheKind::Skin,
        );
        let morph = export_to(
            dir.path(),
            &format!("m_{name}"),
            &scene,
            &baked,
            CacheKind::Morph,
        );
        springbake_testkit::assert_gltf_valid(&skin[0].path);
        let doc = load(&skin[0].path);
        for m in doc.array("meshes") {
            for p in m["primitives"].as_array().unwrap() {
                assert!(p.get("targets").is_none(), "no morph targets in skin mode");
                assert!(p["attributes"].get("JOINTS_1").is_some());
            }
        }
        assert_eq!(doc.array("skins").len(), scene.meshes.len());
        assert_eq!(
            doc.array("skins")[0]["joints"].as_array().unwrap().len(),
            27
        );
        let err = max_error(&doc, &scene, &baked);
        let diag = scene.meshes.iter().map(diagonal).fold(0.0, f64::max);
        assert!(
            err <= 1e-5 * diag,
            "{name}: skin playback differs from the bake by {err} (diagonal {diag})"
        );
        eprintln!(
            "{name}: {} vertices × {FRAMES} frames: morph {} bytes, skin {} bytes, skin error {err:.2e} (diag {diag:.3})",
            scene.meshes.iter().map(|m| m.vertex_count()).sum::<usize>(),
            morph[0].bytes.len(),
            skin[0].bytes.len()
        );
    }
}

#[test]
fn gltf_plus_bin_output_is_valid_and_self_contained() {
    let dir = tempfile::tempdir().unwrap();
    // source with an external buffer: the output must not point back at it
    let scene = import(&corpus("icosphere_separate.gltf"));
    let baked = bake_all(&scene);
    let files = export_to(dir.path(), "my bake.gltf", &scene, &baked, CacheKind::Morph);
    assert_eq!(files.len(), 2);
    assert_eq!(files[1].path, dir.path().join("my bake.bin"));
    let json: Value = serde_json::from_slice(&files[0].bytes).unwrap();
    assert_eq!(json["buffers"].as_array().unwrap().len(), 1);
    assert_eq!(json["buffers"][0]["uri"], "my%20bake.bin");
    assert_eq!(
        json["buffers"][0]["byteLength"].as_u64().unwrap() as usize,
        files[1].bytes.len()
    );
    springbake_testkit::assert_gltf_valid(&files[0].path);
    let doc = load(&files[0].path);
    assert!(max_error(&doc, &scene, &baked) < 1e-6);
    let skin = export_to(dir.path(), "skin.gltf", &scene, &baked, CacheKind::Skin);
    springbake_testkit::assert_gltf_valid(&skin[0].path);
}

#[test]
fn reimport_keeps_names_materials_uvs_and_hierarchy() {
    let dir = tempfile::tempdir().unwrap();
    let scene = import(&corpus("two_objects.glb"));
    let baked = bake_all(&scene);
    for cache in [CacheKind::Morph, CacheKind::Skin] {
        let files = export_to(dir.path(), "r.glb", &scene, &baked, cache);
        let again = import(&files[0].path);
        let names: Vec<&str> = again.meshes.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["Head", "Body"], "{cache:?}");
        for (a, b) in again.meshes.iter().zip(&scene.meshes) {
            assert_eq!(a.source_key, b.source_key);
            assert_eq!(a.primitives.len(), b.primitives.len());
            for (pa, pb) in a.primitives.iter().zip(&b.primitives) {
                assert_eq!(pa.material, pb.material);
                assert_eq!(pa.uvs, pb.uvs);
                // a skin cache's re-import is skinned at its first key: the rest, to rounding
                for (x, y) in pa.positions.iter().zip(&pb.positions) {
                    assert!((0..3).all(|c| (x[c] - y[c]).abs() < 1e-6), "{x:?} vs {y:?}");
                }
                assert_eq!(pa.indices, pb.indices);
            }
            assert!((a.world_from_local - b.world_from_local).abs().max() < 1e-12);
        }
        assert_eq!(
            again.meshes[1].primitives[0].material.as_deref(),
            Some("Red")
        );
    }
}

#[test]
fn export_is_deterministic() {
    let scene = import(&corpus("two_objects.glb"));
    let baked = bake_all(&scene);
    for cache in [CacheKind::Morph, CacheKind::Skin] {
        for name in ["d.glb", "d.gltf"] {
            let settings = ExportSettings {
                path: PathBuf::from(name),
                cache,
                axes: Default::default(),
            };
            let a = GltfExporter.export(&scene, &baked, &settings).unwrap();
            let b = GltfExporter.export(&scene, &baked, &settings).unwrap();
            assert_eq!(a, b, "{name} {cache:?}");
        }
    }
}

#[test]
fn shared_mesh_gets_a_copy_per_baked_node() {
    // two nodes instancing one mesh, both simulated
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("inst.gltf");
    let tri: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    std::fs::write(dir.path().join("inst.bin"), &tri).unwrap();
    std::fs::write(
        &src,
        serde_json::to_vec(&json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [{"mesh": 0, "name": "A"}, {"mesh": 0, "name": "B", "translation": [3, 0, 0]}],
            "meshes": [{"name": "Tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": 36, "uri": "inst.bin"}],
        }))
        .unwrap(),
    )
    .unwrap();
    let scene = import(&src);
    let mut baked = BakedScene {
        particles: Vec::new(),
        fps: FPS,
        frame_count: FRAMES,
        meshes: vec![],
        stage: None,
    };
    for (i, m) in scene.meshes.iter().enumerate() {
        let frames = (0..FRAMES)
            .map(|f| {
                m.primitives[0]
                    .positions
                    .iter()
                    .map(|p| [p[0], p[1], p[2] + (f * (i + 1)) as f32 * 0.01])
                    .collect()
            })
            .collect();
        baked.meshes.push(BakedMesh {
            mesh_index: i,
            frames,
            lattice: None,
        });
    }
    let files = export_to(dir.path(), "out.glb", &scene, &baked, CacheKind::Morph);
    springbake_testkit::assert_gltf_valid(&files[0].path);
    let doc = load(&files[0].path);
    assert_eq!(doc.array("meshes").len(), 2);
    let a = get_usize(&doc.array("nodes")[0], "mesh");
    let b = get_usize(&doc.array("nodes")[1], "mesh");
    assert_ne!(a, b);
    assert!(max_error(&doc, &scene, &baked) < 1e-6);
}

/// A scene as the OBJ importer would hand it over: a fresh document is built.
fn obj_like_scene() -> ImportedScene {
    let mut scene = import(&corpus("two_objects.glb"));
    scene.source.importer = "obj".into();
    scene.source.path = PathBuf::from("two_objects.obj");
    for (i, m) in scene.meshes.iter_mut().enumerate() {
        m.source_key = format!("object:{i}");
    }
    scene
}

#[test]
fn fresh_document_for_other_sources() {
    let dir = tempfile::tempdir().unwrap();
    let scene = obj_like_scene();
    let baked = bake_all(&scene);
    for cache in [CacheKind::Morph, CacheKind::Skin] {
        let files = export_to(dir.path(), "fresh.glb", &scene, &baked, cache);
        springbake_testkit::assert_gltf_valid(&files[0].path);
        let doc = load(&files[0].path);
        let err = max_error(&doc, &scene, &baked);
        assert!(err < 1e-5 * 4.0, "{cache:?}: {err}");
        let again = import(&files[0].path);
        assert_eq!(again.meshes.len(), 2);
        assert_eq!(again.meshes[1].name, "Body");
        assert_eq!(
            again.meshes[1].primitives[0].material.as_deref(),
            Some("Red")
        );
        assert_eq!(
            again.meshes[1].primitives[0].uvs,
            scene.meshes[1].primitives[0].uvs
        );
    }
    // Z-up sources get a root node turning them Y-up
    let mut zup = obj_like_scene();
    zup.up_axis = springbake_core::display::UpAxis::Z;
    let files = export_to(
        dir.path(),
        "zup.glb",
        &zup,
        &bake_all(&zup),
        CacheKind::Morph,
    );
    springbake_testkit::assert_gltf_valid(&files[0].path);
    let again = import(&files[0].path);
    let p = again.meshes[0].world_positions()[0];
    let q = zup.meshes[0].world_positions()[0];
    assert!((p.x - q.x).abs() < 1e-6 && (p.y - q.z).abs() < 1e-6 && (p.z + q.y).abs() < 1e-6);
}

#[test]
fn bad_bakes_are_refused_with_a_location() {
    let scene = import(&corpus("icosphere.glb"));
    let mut baked = bake_all(&scene);
    baked.meshes[0].frames[3].pop();
    let settings = ExportSettings {
        path: PathBuf::from("x.glb"),
        cache: CacheKind::Morph,
        axes: Default::default(),
    };
    let err = GltfExporter.export(&scene, &baked, &settings).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("baked.meshes[0].frames[3]"));
    let mut baked = bake_all(&scene);
    baked.meshes[0].lattice = None;
    let settings = ExportSettings {
        path: PathBuf::from("x.glb"),
        cache: CacheKind::Skin,
        axes: Default::default(),
    };
    let err = GltfExporter.export(&scene, &baked, &settings).unwrap_err();
    assert_eq!(err.location.as_deref(), Some("baked.meshes[0].lattice"));
}

/// Expected world positions per frame, in glTF coordinates, for the Blender client.
fn blender_spec(file: &Path, scene: &ImportedScene, baked: &BakedScene, frames: &[usize]) -> Value {
    let doc = load(file);
    let objects: Vec<Value> = baked
        .meshes
        .iter()
        .map(|bm| {
            let m = &scene.meshes[bm.mesh_index];
            let per_frame: Vec<Vec<[f64; 3]>> = frames
                .iter()
                .map(|&f| {
                    bm.frames[f]
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
                .collect();
            let uvs: Vec<[f32; 2]> = m
                .primitives
                .iter()
                .flat_map(|p| p.uvs.clone().unwrap_or_default())
                .collect();
            let materials: Vec<String> = m
                .primitives
                .iter()
                .filter_map(|p| p.material.clone())
                .collect();
            let node = &doc.array("nodes")[node_by_name(&doc, &m.name)];
            let mesh_name = &doc.array("meshes")[get_usize(node, "mesh").unwrap()]["name"];
            json!({"name": m.name, "mesh_name": mesh_name, "vertex_count": m.vertex_count(), "frames": per_frame,
                   "uvs": uvs, "materials": materials})
        })
        .collect();
    json!({"file": file, "fps": baked.fps, "frames": frames, "objects": objects})
}

#[test]
fn blender_plays_morph_skin_and_pca_caches() {
    let dir = tempfile::tempdir().unwrap();
    let scene = import(&corpus("two_objects.glb"));
    let baked = bake_all(&scene);
    let frames = [0usize, 1, 4, 9];
    let mut specs = Vec::new();
    for (name, cache) in [
        ("morph.glb", CacheKind::Morph),
        ("skin.glb", CacheKind::Skin),
        ("pca.glb", CacheKind::Pca { max_error_um: 1000 }),
    ] {
        let files = export_to(dir.path(), name, &scene, &baked, cache);
        specs.push(blender_spec(&files[0].path, &scene, &baked, &frames));
    }
    // A tumbling icosphere: the pca cache's rotation keys, as Blender plays them.
    let sphere = import(&corpus("icosphere.glb"));
    let tumbling = tumbling_bake(&sphere);
    let cache = CacheKind::Pca { max_error_um: 1000 };
    let files = export_to(dir.path(), "tumble.glb", &sphere, &tumbling, cache);
    specs.push(blender_spec(&files[0].path, &sphere, &tumbling, &frames));
    let spec_path = dir.path().join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&json!(specs)).unwrap()).unwrap();
    let out =
        springbake_testkit::run_python_client("gltf_roundtrip.py", &[spec_path.to_str().unwrap()]);
    let report = springbake_testkit::last_json_line(&out);
    eprintln!("REPORT {report}");
    let files = report["files"].as_array().unwrap();
    assert_eq!(files.len(), 4, "{report}");
    for (file, r) in ["morph", "skin", "pca", "tumble"].iter().zip(files) {
        // Measured with Blender 5.0.1: its glTF importer puts key time t at frame t·fps (not
        // t·fps + 1), so baked frame i is Blender frame i (at fps = the scene's 24). The client
        // measures both candidates; the other one is off by centimetres.
        assert_eq!(r["frame_offset"], 0, "{file}: {r}");
        let objects = if *file == "tumble" { 1 } else { 2 };
        assert_eq!(r["visible_mesh_objects"], objects, "{file}: {r}");
        if *file == "skin" {
            // Blender turns the skinned node "Body" (it has a child) into an empty of that
            // name plus a mesh object named after the glTF mesh, "Cube".
            assert_eq!(r["objects"][1]["blender_object"], "Cube", "{r}");
        }
        for o in r["objects"].as_array().unwrap() {
            let err = o["max_error"].as_f64().unwrap();
            // the pca cache's bound is 1 mm (its 16-bit targets and rigid keys included)
            let bound = if matches!(*file, "pca" | "tumble") {
                1.001e-3
            } else {
                1e-4
            };
            assert!(err <= bound, "{file} {}: max error {err} m", o["name"]);
            assert_eq!(o["vertex_count"], o["expected_vertex_count"], "{file}: {o}");
            assert_eq!(o["uv_missing"], 0, "{file}: {o}");
            assert_eq!(o["materials_ok"], true, "{file}: {o}");
        }
    }
}

#[test]
fn textures_referenced_by_uri_are_embedded() {
    use base64::Engine as _;
    let dir = tempfile::tempdir().unwrap();
    let png = base64::engine::general_purpose::STANDARD
        .decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==")
        .unwrap();
    std::fs::create_dir(dir.path().join("tex")).unwrap();
    std::fs::write(dir.path().join("tex/checker.png"), &png).unwrap();
    let mut bin: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .chain(&[0f32, 0., 1., 0., 0., 1.])
        .flat_map(|x| x.to_le_bytes())
        .collect();
    bin.resize(60, 0);
    std::fs::write(dir.path().join("tri.bin"), &bin).unwrap();
    let src = dir.path().join("textured.gltf");
    std::fs::write(
        &src,
        serde_json::to_vec(&json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "name": "Tri"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
            "materials": [{"name": "Checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0, "sampler": 0}],
            "samplers": [{}],
            "images": [{"uri": "tex/checker.png"}],
            "accessors": [
                {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
                {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}
            ],
            "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
            "buffers": [{"byteLength": 60, "uri": "tri.bin"}],
        }))
        .unwrap(),
    )
    .unwrap();
    let scene = import(&src);
    let frames = (0..FRAMES)
        .map(|f| {
            scene.meshes[0].primitives[0]
                .positions
                .iter()
                .map(|p| [p[0], p[1], p[2] + f as f32 * 0.01])
                .collect()
        })
        .collect();
    let baked = BakedScene {
        particles: Vec::new(),
        stage: None,
        fps: FPS,
        frame_count: FRAMES,
        meshes: vec![BakedMesh {
            mesh_index: 0,
            frames,
            lattice: None,
        }],
    };
    let out = tempfile::tempdir().unwrap(); // elsewhere: the output must not need tex/
    let files = export_to(out.path(), "t.glb", &scene, &baked, CacheKind::Morph);
    springbake_testkit::assert_gltf_valid(&files[0].path);
    let doc = load(&files[0].path);
    let image = &doc.array("images")[0];
    assert!(image.get("uri").is_none(), "{image}");
    assert_eq!(image["mimeType"], "image/png");
    let view = &doc.array("bufferViews")[get_usize(image, "bufferView").unwrap()];
    let start = get_usize(view, "byteOffset").unwrap();
    assert_eq!(&doc.buffers[0][start..start + png.len()], &png[..]);
    assert_eq!(doc.array("materials")[0]["name"], "Checker");
    let again = import(&files[0].path);
    assert_eq!(
        again.meshes[0].primitives[0].uvs,
        scene.meshes[0].primitives[0].uvs
    );
    assert!(max_error(&doc, &scene, &baked) < 1e-6);
}
