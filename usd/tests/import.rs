//! USD import against the shared corpus and against usd-core's own answers.

#![allow(clippy::unwrap_used)] // test helpers outside #[test] fns unwrap too

use springbake_core::display::{ImportedScene, UpAxis};
use springbake_core::nalgebra::Point3;
use springbake_core::plugin::{ImportSettings, Importer, IoErrorKind, PluginError};
use springbake_testkit::{corpus_dir, corpus_entries, last_json_line, run_python_client};
use springbake_usd::UsdImporter;
use std::path::Path;

fn import(path: &Path) -> Result<ImportedScene, PluginError> {
    let bytes = std::fs::read(path).unwrap();
    UsdImporter.import(path, &bytes, &ImportSettings::default())
}

#[test]
fn corpus_sweep_usd() {
    let entries = corpus_entries(&["usda", "usdc", "usdz"]);
    assert_eq!(entries.len(), 6, "corpus USD entries changed: {entries:?}");
    for e in entries {
        let result = import(&e.path);
        match (e.expect_ok, result) {
            (true, Ok(scene)) => {
                assert!(!scene.meshes.is_empty(), "{}", e.path.display());
                for m in &scene.meshes {
                    assert!(m.triangle_count() > 0, "{}: {}", e.path.display(), m.name);
                    assert!(m.source_key.starts_with('/'), "{}", m.source_key);
                    assert_eq!(m.source_point_of_vertex.len(), m.vertex_count());
                    assert!(m
                        .source_point_of_vertex
                        .iter()
                        .all(|&p| (p as usize) < m.source_point_count));
                    let n = m.vertex_count() as u32;
                    assert!(m.triangles().iter().flatten().all(|&i| i < n));
                    assert!(m
                        .world_positions()
                        .iter()
                        .all(|p| p.coords.iter().all(|c| c.is_finite())));
                }
                assert_eq!(scene.source.importer, "usd");
            }
            (true, Err(err)) => panic!("{} ({}) must import: {err}", e.path.display(), e.why),
            (false, Ok(_)) => panic!("{} ({}) must be rejected", e.path.display(), e.why),
            (false, Err(err)) => {
                assert_eq!(err.kind, IoErrorKind::Invalid, "{err}");
                assert_eq!(err.path, e.path, "{err}");
                assert!(!err.message.is_empty());
            }
        }
    }
}

#[test]
fn broken_usda_reports_usd_cores_parse_error_with_line() {
    let path = corpus_dir().join("bad/broken.usda");
    let err = import(&path).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("parse error"), "{text}");
    assert!(text.contains("broken.usda:4:1"), "{text}");
    // The C++ noise (function names, source files of usd-core) is stripped.
    assert!(!text.contains("textParserHelpers.h"), "{text}");
}

#[test]
fn stage_without_meshes_is_rejected() {
    let err = import(&corpus_dir().join("bad/no_mesh.usda")).unwrap_err();
    assert!(err.message.contains("no UsdGeomMesh"), "{err}");
}

#[test]
fn cylinder_usdc_is_z_up_metres_with_24_gon_caps() {
    let scene = import(&corpus_dir().join("blender/cylinder.usdc")).unwrap();
    assert_eq!(scene.up_axis, UpAxis::Z);
    assert_eq!(scene.meters_per_unit, 1.0);
    assert_eq!(scene.meshes.len(), 1);
    let m = &scene.meshes[0];
    assert_eq!(m.source_key, "/root/Cylinder/Cylinder");
    assert_eq!(m.source_point_count, 48);
    // 24 side quads (2 triangles each) and two 24-gon caps (22 each).
    assert_eq!(m.triangle_count(), 24 * 2 + 2 * 22);
    let p = &m.primitives[0];
    assert!(p.normals.is_some() && p.uvs.is_some());
    // Every display vertex sits where its source point is.
    let stage = springbake_usd::read_stage(
        &corpus_dir().join("blender/cylinder.usdc"),
        &corpus_dir(),
        false,
    )
    .unwrap();
    for (v, &src) in m.source_point_of_vertex.iter().enumerate() {
        let q = stage.meshes[0].points[src as usize];
        assert_eq!(p.positions[v], q.map(|c| c as f32));
    }
    // Normals are unit length.
    for n in p.normals.as_ref().unwrap() {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-4, "{n:?}");
    }

    let zipped = import(&corpus_dir().join("blender/cylinder.usdz")).unwrap();
    assert_eq!(zipped.meshes[0].triangle_count(), m.triangle_count());
    assert_eq!(zipped.meshes[0].source_point_count, 48);
}

#[test]
fn two_objects_hierarchy_places_vertices_like_usd_core() {
    let path = corpus_dir().join("blender/two_objects.usda");
    let scene = import(&path).unwrap();
    let cube = scene
        .meshes
        .iter()
        .find(|m| m.source_key == "/root/Body/Cube")
        .unwrap();
    assert_eq!(cube.primitives[0].material.as_deref(), Some("Red"));
    // By hand: point 0 (-0.3, -0.3, -0.3), scaled (1.5, 1, 1), rotated 30° about Z, moved
    // (0, 0, 1): (-0.45·cos30 + 0.3·sin30, -0.45·sin30 - 0.3·cos30, 0.7).
    let (s, c) = 30f64.to_radians().sin_cos();
    let expected = Point3::new(-0.45 * c + 0.3 * s, -0.45 * s - 0.3 * c, 0.7);
    let v = cube
        .source_point_of_vertex
        .iter()
        .position(|&p| p == 0)
        .unwrap();
    let got = cube.world_positions()[v];
    assert!((got - expected).norm() < 1e-6, "{got} vs {expected}");

    // Every vertex of every mesh agrees with usd-core's own world transform.
    let out = run_python_client("usd_world_points.py", &[path.to_str().unwrap()]);
    let json = last_json_line(&out);
    assert_eq!(json["up_axis"], "Z");
    assert_eq!(
        scene.meshes.len(),
        json["meshes"].as_object().unwrap().len()
    );
    for m in &scene.meshes {
        let pts = json["meshes"][&m.source_key].as_array().unwrap();
        assert_eq!(pts.len(), m.source_point_count);
        for (v, w) in m.world_positions().iter().enumerate() {
            let q = &pts[m.source_point_of_vertex[v] as usize];
            let q = Point3::new(
                q[0].as_f64().unwrap(),
                q[1].as_f64().unwrap(),
                q[2].as_f64().unwrap(),
            );
            assert!(
                (w - q).norm() < 1e-5,
                "{} vertex {v}: {w} vs {q}",
                m.source_key
            );
        }
    }
    let sphere = scene
        .meshes
        .iter()
        .find(|m| m.source_key == "/root/Body/Head/Sphere")
        .unwrap();
    assert_eq!(sphere.source_point_count, 482);
}

#[test]
fn nan_point_is_rejected_with_its_prim_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.usda");
    std::fs::write(
        &path,
        "#usda 1.0\ndef Mesh \"m\" {\n  int[] faceVertexCounts = [3]\n  int[] faceVertexIndices = [0, 1, 2]\n  point3f[] points = [(0, 0, 0), (1, nan, 0), (0, 1, 0)]\n}\n",
    )
    .unwrap();
    let err = import(&path).unwrap_err();
    assert_eq!(err.kind, IoErrorKind::Invalid);
    assert_eq!(err.location.as_deref(), Some("/m.points[1]"), "{err}");
}

#[test]
fn indexed_and_vertex_primvars_resolve_and_concave_faces_triangulate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("l.usda");
    // An L-shaped hexagon (concave) with an indexed vertex st and vertex normals.
    std::fs::write(
        &path,
        r#"#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 0.01
)
def Mesh "L" {
    int[] faceVertexCounts = [6]
    int[] faceVertexIndices = [0, 1, 2, 3, 4, 5]
    point3f[] points = [(0,0,0), (2,0,0), (2,1,0), (1,1,0), (1,2,0), (0,2,0)]
    normal3f[] normals = [(0,0,1), (0,0,1), (0,0,1), (0,0,1), (0,0,1), (0,0,1)] (
        interpolation = "vertex"
    )
    texCoord2f[] primvars:st = [(0, 0), (1, 1)] (
        interpolation = "vertex"
    )
    int[] primvars:st:indices = [0, 1, 1, 0, 1, 0]
}
"#,
    )
    .unwrap();
    let scene = import(&path).unwrap();
    assert_eq!(scene.up_axis, UpAxis::Y);
    assert_eq!(scene.meters_per_unit, 0.01);
    let m = &scene.meshes[0];
    let p = &m.primitives[0];
    assert_eq!(
        p.positions.len(),
        6,
        "vertex primvars must not split vertices"
    );
    assert_eq!(p.uvs.as_ref().unwrap()[2], [1.0, 1.0]);
    assert_eq!(p.uvs.as_ref().unwrap()[3], [0.0, 0.0]);
    assert_eq!(m.triangle_count(), 4);
    // Ear clipping covers exactly the L's area (3), no triangle reaches outside.
    let area: f32 = p
        .indices
        .chunks(3)
        .map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| p.positions[i as usize]);
            ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) / 2.0
        })
        .sum();
    assert!((area - 3.0).abs() < 1e-6, "{area}");
}

#[test]
fn unreadable_file_is_an_io_error_and_bytes_alone_still_import() {
    let missing = Path::new("/nonexistent/folder/x.usda");
    let err = UsdImporter
        .import(missing, &[], &ImportSettings::default())
        .unwrap_err();
    assert_eq!(err.kind, IoErrorKind::Io, "{err}");
    assert_eq!(err.path, missing);

    // Bytes handed over from memory for a path that is not on disk.
    let bytes = std::fs::read(corpus_dir().join("blender/grid_open.usda")).unwrap();
    let scene = UsdImporter
        .import(
            Path::new("memory/grid.usda"),
            &bytes,
            &ImportSettings::default(),
        )
        .unwrap();
    assert_eq!(scene.source.path, Path::new("memory/grid.usda"));
    assert!(scene.meshes[0].triangle_count() > 0);
}

/// A mesh layer with one triangle, for composition tests.
const TRIANGLE_LAYER: &str = "#usda 1.0\n(\n    defaultPrim = \"Tri\"\n)\ndef Mesh \"Tri\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}\n";

/// Issue 17, item 4: subLayers, references and payloads resolve only inside the folder the
/// host allows (the scene's), symlinks followed; inside it they compose as before.
#[test]
fn layers_outside_the_allowed_folder_are_refused_before_they_are_read() {
    let outer = tempfile::tempdir().unwrap();
    let scene = outer.path().join("scene");
    std::fs::create_dir_all(scene.join("assets")).unwrap();
    std::fs::write(outer.path().join("outside.usda"), TRIANGLE_LAYER).unwrap();
    std::fs::write(scene.join("assets/inside.usda"), TRIANGLE_LAYER).unwrap();
    let arcs = [
        ("subLayer", "(\n    subLayers = [@REF@]\n)\n"),
        (
            "reference",
            "def \"A\" (\n    prepend references = @REF@\n)\n{\n}\n",
        ),
        (
            "payload",
            "def \"A\" (\n    prepend payload = @REF@\n)\n{\n}\n",
        ),
    ];
    let settings = ImportSettings {
        root: Some(scene.clone()),
        ..ImportSettings::default()
    };
    let absolute = outer.path().join("outside.usda");
    for (kind, arc) in arcs {
        for target in [
            "../../outside.usda",
            absolute.to_str().unwrap(),
            "./inside.usda",
        ] {
            let file = scene.join(format!("assets/{kind}.usda"));
            let text = format!("#usda 1.0\n{}", arc.replace("REF", target));
            std::fs::write(&file, &text).unwrap();
            let result = UsdImporter.import(&file, text.as_bytes(), &settings);
            if target.contains("inside") {
                let scene = result.unwrap_or_else(|e| panic!("{kind} {target}: {e}"));
                assert_eq!(scene.meshes.len(), 1, "{kind} {target}");
            } else {
                let err = result.expect_err(kind).to_string();
                assert!(err.contains("outside the folder"), "{kind} {target}: {err}");
            }
        }
    }
    // A symlink inside the folder that points out is caught too.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(outer.path().join("outside.usda"), scene.join("link.usda"))
            .unwrap();
        let file = scene.join("linked.usda");
        let text = "#usda 1.0\n(\n    subLayers = [@./link.usda@]\n)\n";
        std::fs::write(&file, text).unwrap();
        let err = UsdImporter
            .import(&file, text.as_bytes(), &settings)
            .expect_err("symlink out")
            .to_string();
        assert!(err.contains("outside the folder"), "{err}");
    }
}

/// A DCC asset whose looks are MaterialX files (usd-wg's OpenChessSet: `references =
/// @./Knight_mat.mtlx@`) opens: usd-core from PyPI has no `.mtlx` reader, so the stage is
/// composed without those layers, as Blender's importer composes it, and one note names them.
/// usd-core's own warnings (a reference it cannot open) come back as one note, not as C++
/// lines on stderr.
#[test]
fn materialx_layers_usd_core_cannot_read_are_left_out_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("look.mtlx"),
        "<?xml version=\"1.0\"?>\n<materialx version=\"1.38\"></materialx>\n",
    )
    .unwrap();
    let file = dir.path().join("asset.usda");
    let text = TRIANGLE_LAYER.to_owned()
        + "def Scope \"Materials\" (\n    prepend references = @./look.mtlx@</MaterialX>\n)\n{\n}\n\
           def Scope \"Gone\" (\n    prepend references = @./missing.usda@\n)\n{\n}\n";
    std::fs::write(&file, &text).unwrap();
    let scene = import(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.meshes.len(), 1);
    let notes = scene.notes.join("\n");
    assert!(
        notes.contains("1 layer(s) in a format usd-core cannot read were left out (./look.mtlx)"),
        "{notes}"
    );
    assert!(
        notes.contains("usd-core composed the stage with 1 warning(s)")
            && notes.contains("missing.usda")
            && !notes.contains("stage.cpp"),
        "{notes}"
    );
}

/// What a renderer does not draw is not simulated (invisible prims, their children, proxy and
/// guide purpose), and UVs come from any texCoord2f[] primvar when there is no `st`.
#[test]
fn invisible_and_guide_meshes_are_left_out_and_any_texcoord_primvar_is_the_uvs() {
    let quad = |name: &str, extra: &str| {
        format!(
            "    def Mesh \"{name}\" {{\n{extra}\
             \x20       int[] faceVertexCounts = [4]\n\
             \x20       int[] faceVertexIndices = [0, 1, 2, 3]\n\
             \x20       point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]\n    }}\n"
        )
    };
    let uvs = "        texCoord2f[] primvars:st_faceVarying = [(0, 0), (1, 0), (1, 1), (0, 1)] (\n\
               \x20           interpolation = \"faceVarying\"\n        )\n";
    let text = format!(
        "#usda 1.0\n(\n    upAxis = \"Y\"\n)\ndef Xform \"World\" {{\n{}{}{}\
         \x20   def Xform \"Off\" {{\n        token visibility = \"invisible\"\n{}    }}\n}}\n",
        quad("Shown", uvs),
        quad("Hidden", "        token visibility = \"invisible\"\n"),
        quad("Guide", "        uniform token purpose = \"guide\"\n"),
        quad("Child", ""),
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("layers.usda");
    std::fs::write(&path, &text).unwrap();
    let scene = import(&path).unwrap();
    let names: Vec<&str> = scene.meshes.iter().map(|m| m.source_key.as_str()).collect();
    assert_eq!(names, ["/World/Shown"], "{text}");
    let uv = scene.meshes[0].primitives[0]
        .uvs
        .as_ref()
        .expect("UVs from st_faceVarying");
    assert_eq!(uv.len(), scene.meshes[0].vertex_count());

    // Nothing visible at all: an error that says why.
    let only_hidden = text.replace(
        "def Mesh \"Shown\" {\n",
        "def Mesh \"Shown\" {\n        token visibility = \"invisible\"\n",
    );
    std::fs::write(&path, only_hidden).unwrap();
    let err = import(&path).unwrap_err().to_string();
    assert!(err.contains("every UsdGeomMesh is invisible"), "{err}");
    assert!(err.contains("/World/Guide (purpose guide)"), "{err}");
}

/// Materials bound per face through GeomSubsets become one primitive per material (faces in
/// no subset keep the mesh's own binding); a subset naming a face the mesh lacks is an error.
#[test]
fn geom_subset_materials_split_the_mesh_into_primitives() {
    let cube = |subset_b: &str| {
        format!(
            "#usda 1.0\ndef Xform \"World\" {{\n\
             \x20   def Material \"Red\" {{}}\n    def Material \"Blue\" {{}}\n\
             \x20   def Mesh \"Box\" (prepend apiSchemas = [\"MaterialBindingAPI\"]) {{\n\
             \x20       int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n\
             \x20       int[] faceVertexIndices = [0,2,3,1, 4,5,7,6, 0,1,5,4, 2,6,7,3, 0,4,6,2, 1,3,7,5]\n\
             \x20       point3f[] points = [(0,0,0),(1,0,0),(0,1,0),(1,1,0),(0,0,1),(1,0,1),(0,1,1),(1,1,1)]\n\
             \x20       def GeomSubset \"a\" (prepend apiSchemas = [\"MaterialBindingAPI\"]) {{\n\
             \x20           uniform token elementType = \"face\"\n\
             \x20           uniform token familyName = \"materialBind\"\n\
             \x20           int[] indices = [0, 1, 2]\n\
             \x20           rel material:binding = </World/Red>\n        }}\n\
             \x20       def GeomSubset \"b\" (prepend apiSchemas = [\"MaterialBindingAPI\"]) {{\n\
             \x20           uniform token elementType = \"face\"\n\
             \x20           uniform token familyName = \"materialBind\"\n\
             \x20           int[] indices = [{subset_b}]\n\
             \x20           rel material:binding = </World/Blue>\n        }}\n    }}\n}}\n"
        )
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.usda");
    std::fs::write(&path, cube("3, 4, 5")).unwrap();
    let scene = import(&path).unwrap();
    let m = &scene.meshes[0];
    let materials: Vec<_> = m.primitives.iter().map(|p| p.material.as_deref()).collect();
    assert_eq!(materials, [Some("Red"), Some("Blue")]);
    assert!(m.primitives.iter().all(|p| p.triangle_count() == 6));
    assert_eq!(m.source_point_count, 8);
    assert_eq!(m.source_point_of_vertex.len(), m.vertex_count());
    // Faces 4 and 5 in no subset: a third primitive without a material.
    std::fs::write(&path, cube("3")).unwrap();
    let scene = import(&path).unwrap();
    let materials: Vec<_> = scene.meshes[0]
        .primitives
        .iter()
        .map(|p| p.material.clone())
        .collect();
    assert_eq!(materials, [Some("Red".into()), Some("Blue".into()), None]);
    std::fs::write(&path, cube("3, 9")).unwrap();
    let err = import(&path).unwrap_err().to_string();
    assert!(
        err.contains("face 9, the mesh has 6") && err.contains("/World/Box"),
        "{err}"
    );
}
