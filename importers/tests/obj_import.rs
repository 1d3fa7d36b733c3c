//! OBJ importer: the corpus sweep and the behaviours the simulation and the point caches rely
//! on (triangulation, relative indices, objects, materials, normals, Blender's point order).

#![allow(clippy::unwrap_used)] // tests: a failed unwrap is a failed test

use springbake_core::display::{DisplayMesh, ImportedScene, UpAxis};
use springbake_core::plugin::{ImportSettings, Importer, PluginError};
use springbake_importers::obj::ObjImporter;
use std::path::Path;

fn import(text: &str) -> Result<ImportedScene, PluginError> {
    ObjImporter.import(
        Path::new("mem/test.obj"),
        text.as_bytes(),
        &ImportSettings::default(),
    )
}

fn import_merged(text: &str) -> ImportedScene {
    let s = ImportSettings {
        merge_objects: true,
        ..ImportSettings::default()
    };
    ObjImporter
        .import(Path::new("mem/test.obj"), text.as_bytes(), &s)
        .unwrap()
}

/// Sum of triangle areas (3-D, unsigned) of a mesh.
fn area(mesh: &DisplayMesh) -> f64 {
    let p = mesh.world_positions();
    mesh.triangles()
        .iter()
        .map(|t| {
            let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
            (b - a).cross(&(c - a)).norm() / 2.0
        })
        .sum()
}

/// Signed area in the XY plane (positive when counter-clockwise seen from +Z).
fn signed_area_xy(mesh: &DisplayMesh) -> f64 {
    let p = mesh.world_positions();
    mesh.triangles()
        .iter()
        .map(|t| {
            let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
            (b - a).cross(&(c - a)).z / 2.0
        })
        .sum()
}

#[test]
fn obj_corpus_sweep() {
    let entries = springbake_testkit::corpus_entries(&["obj"]);
    assert!(
        entries.len() >= 6,
        "corpus lists {} OBJ files",
        entries.len()
    );
    for e in entries {
        let bytes = std::fs::read(&e.path).unwrap();
        let result = ObjImporter.import(&e.path, &bytes, &ImportSettings::default());
        match (e.expect_ok, result) {
            (true, Ok(scene)) => {
                assert!(!scene.meshes.is_empty(), "{}", e.path.display());
                for m in &scene.meshes {
                    assert!(m.triangle_count() > 0, "{} {}", e.path.display(), m.name);
                    assert_eq!(m.source_point_of_vertex.len(), m.vertex_count());
                    assert!(m
                        .source_point_of_vertex
                        .iter()
                        .all(|&p| (p as usize) < m.source_point_count));
                    for prim in &m.primitives {
                        let n = prim.normals.as_ref().expect("normals are always filled");
                        assert_eq!(n.len(), prim.positions.len());
                        for v in n {
                            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                            assert!(
                                (len - 1.0).abs() < 1e-4,
                                "{}: normal {v:?}",
                                e.path.display()
                            );
                        }
                        assert!(prim
                            .indices
                            .iter()
                            .all(|&i| (i as usize) < prim.positions.len()));
                    }
                }
            }
            (false, Err(err)) => {
                let text = err.to_string();
                assert!(text.contains(&*e.path.to_string_lossy()), "{text}");
                assert_eq!(err.kind, springbake_core::plugin::IoErrorKind::Invalid);
                eprintln!("{} rejected: {text}", e.path.display());
            }
            (true, Err(err)) => panic!("{} ({}) must import: {err}", e.path.display(), e.why),
            (false, Ok(_)) => panic!("{} ({}) must be rejected", e.path.display(), e.why),
        }
    }
}

#[test]
fn bad_files_name_the_line() {
    let dir = springbake_testkit::corpus_dir();
    let cases = [
        ("bad/bad_index.obj", Some("line 4"), "vertex 7"),
        ("bad/nan.obj", Some("line 2"), "nan"),
        ("bad/empty.obj", None, "no geometry"),
    ];
    for (file, location, needle) in cases {
        let path = dir.join(file);
        let bytes = std::fs::read(&path).unwrap();
        let err = ObjImporter
            .import(&path, &bytes, &ImportSettings::default())
            .unwrap_err();
        assert_eq!(err.location.as_deref(), location, "{file}: {err}");
        assert!(err.to_string().contains(needle), "{file}: {err}");
        if let Some(l) = location {
            assert!(err.to_string().contains(l), "{err}");
        }
    }
}

#[test]
fn more_bad_lines_are_reported_with_their_line_numbers() {
    let cases = [
        (
            "v 0 0 0\nv 1 0 0\nv 0 x 0\nf 1 2 3\n",
            "line 3",
            "`x` is not a number",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n",
            "line 5",
            "at least 3 corners",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "line 4", "index 0"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
            "line 4",
            "relative vertex index -4",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nf 1 2 3\n",
            "line 3",
            "beyond the range of the 32-bit floats",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n", "line 3", "finite"),
        ("v 0 0\n", "line 1", "3 to 7 numbers"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/a 2 3\n",
            "line 4",
            "`a` is not",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1/1 2 3\n",
            "line 4",
            "is not v, v/vt",
        ),
    ];
    for (text, line, needle) in cases {
        let err = import(text).unwrap_err();
        assert_eq!(err.location.as_deref(), Some(line), "{text:?}: {err}");
        assert!(err.message.contains(needle), "{text:?}: {err}");
    }
}

#[test]
fn lines_and_points_only_is_a_no_faces_error() {
    let err = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\np 1\n").unwrap_err();
    assert!(err.message.contains("no faces"), "{err}");
    assert!(err.message.contains("lines/points"), "{err}");
    let err = import("v 0 0 0\n").unwrap_err();
    assert!(err.message.contains("no faces"), "{err}");
}

#[test]
fn unknown_keywords_are_skipped() {
    let s = import(
        "# comment\nmtllib nowhere.mtl\ncurv 0 1 1 2\nv 0 0 0\nv 1 0 0 # trailing\nv 0 1 0\n\
         vp 0.5\ns off\nl 1 2\ncstype bspline\nf 1 2 3\n",
    )
    .unwrap();
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.meshes[0].triangle_count(), 1);
    assert_eq!(s.up_axis, UpAxis::Y);
    assert_eq!(s.meters_per_unit, 1.0);
    assert_eq!(s.source.importer, "obj");
    assert_eq!(s.meshes[0].world_from_local, nalgebra::Matrix4::identity());
}

#[test]
fn mtllib_is_recorded_and_a_missing_mtl_is_fine() {
    let doc = springbake_importers::obj::ObjDocument::parse(
        Path::new("/nonexistent/x.obj"),
        b"mtllib x.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl Red\nf 1 2 3\n",
    )
    .unwrap();
    assert_eq!(doc.mtllibs, vec!["x.mtl".to_string()]);
    assert_eq!(doc.materials, vec!["Red".to_string()]);
}

#[test]
fn quad_triangulation_preserves_area() {
    // A 2 x 3 rectangle in a tilted plane.
    let s = import("v 0 0 0\nv 2 0 0\nv 2 3 3\nv 0 3 3\nf 1 2 3 4\n").unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.triangle_count(), 2);
    let expected = 2.0 * (9.0f64 + 9.0).sqrt();
    assert!(
        (area(m) - expected).abs() < 1e-5,
        "{} vs {expected}",
        area(m)
    );
}

#[test]
fn concave_ngon_triangulation_preserves_area_and_winding() {
    // A star with 5 points (10 corners, concave), counter-clockwise, plus a tilt in z that the
    // best-fit plane must absorb.
    let mut text = String::new();
    let mut expected = 0.0;
    let mut pts = Vec::new();
    for k in 0..10 {
        let r = if k % 2 == 0 { 2.0 } else { 0.8 };
        let a = std::f64::consts::PI * 2.0 * k as f64 / 10.0;
        pts.push((r * a.cos(), r * a.sin()));
    }
    for k in 0..10 {
        let (x0, y0) = pts[k];
        let (x1, y1) = pts[(k + 1) % 10];
        expected += (x0 * y1 - x1 * y0) / 2.0;
        text += &format!("v {x0} {y0} 0\n");
    }
    text += "f 1 2 3 4 5 6 7 8 9 10\n";
    let s = import(&text).unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.triangle_count(), 8);
    assert!(
        (signed_area_xy(m) - expected).abs() < 1e-5,
        "{}",
        signed_area_xy(m)
    );
    // No triangle folds over: every one winds like the polygon, so unsigned == signed.
    assert!(
        (area(m) - expected).abs() < 1e-5,
        "{} vs {expected}",
        area(m)
    );

    // An L-shaped hexagon in the XZ plane (normal -Y for this winding), area 3.
    let s =
        import("v 0 0 0\nv 0 0 2\nv 1 0 2\nv 1 0 1\nv 2 0 1\nv 2 0 0\nf 1 2 3 4 5 6\n").unwrap();
    assert!(
        (area(&s.meshes[0]) - 3.0).abs() < 1e-6,
        "{}",
        area(&s.meshes[0])
    );
}

#[test]
fn negative_indices_equal_positive_ones() {
    let pos = import(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                      f 1/1 2/2 3/3 4/4\n",
    )
    .unwrap();
    let neg = import(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                      f -4/-4 -3/-3 -2/-2 -1/-1\n",
    )
    .unwrap();
    assert_eq!(pos.meshes[0].primitives, neg.meshes[0].primitives);
    assert_eq!(
        pos.meshes[0].source_point_of_vertex,
        neg.meshes[0].source_point_of_vertex
    );
    // The corpus file (one quad by relative indices) imports as two triangles of area 1.
    let path = springbake_testkit::corpus_dir().join("bad/negative_indices.obj");
    let s = ObjImporter
        .import(
            &path,
            &std::fs::read(&path).unwrap(),
            &ImportSettings::default(),
        )
        .unwrap();
    assert_eq!(s.meshes[0].name, "quad");
    assert_eq!(s.meshes[0].triangle_count(), 2);
    assert!((area(&s.meshes[0]) - 1.0).abs() < 1e-6);
}

const TWO_OBJECTS: &str = "o A\nv 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nv 4 1 0\nf 5 1 3\n\
                           o B\nv 10 0 0\nv 11 1 0\nv 12 0 1\nf 7 2 6\nf 8 7 6\n";

#[test]
fn two_objects_give_two_meshes_with_blender_point_order() {
    let s = import(TWO_OBJECTS).unwrap();
    assert_eq!(s.meshes.len(), 2);
    let (a, b) = (&s.meshes[0], &s.meshes[1]);
    assert_eq!((a.name.as_str(), a.source_key.as_str()), ("A", "object:0"));
    assert_eq!((b.name.as_str(), b.source_key.as_str()), ("B", "object:1"));
    // Blender (checked with bpy 5.0.1): A keeps v1, v3, v5 in file order; B keeps v2 (written
    // under A) and v6, v7, v8 in file order.
    assert_eq!(a.source_point_count, 3);
    assert_eq!(b.source_point_count, 4);
    let xs = |m: &DisplayMesh| {
        let p = m.primitives[0].positions.clone();
        m.to_source_points(&p, [f32::NAN; 3])
            .iter()
            .map(|q| q[0])
            .collect::<Vec<_>>()
    };
    assert_eq!(xs(a), vec![0.0, 2.0, 4.0]);
    assert_eq!(xs(b), vec![1.0, 10.0, 11.0, 12.0]);
    assert_eq!(a.triangle_count(), 1);
    assert_eq!(b.triangle_count(), 2);
}

#[test]
fn merge_setting_gives_one_mesh() {
    let s = import_merged(TWO_OBJECTS);
    assert_eq!(s.meshes.len(), 1);
    let m = &s.meshes[0];
    assert_eq!(m.name, "test");
    assert_eq!(m.triangle_count(), 3);
    assert_eq!(m.source_point_count, 7);
}

#[test]
fn faces_before_any_o_and_groups_form_one_object_named_after_the_file() {
    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng G1\nf 1 2 3\ng G2\nf 2 4 3\n").unwrap();
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.meshes[0].name, "test");
    assert_eq!(s.meshes[0].triangle_count(), 2);
}

#[test]
fn material_groups_become_primitives() {
    let s = import(
        "o Box\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n\
         usemtl Red\nf 1 2 3\nusemtl Blue\nf 1 3 4\nusemtl Red\nf 1 4 5\n\
         o Other\nv 5 5 5\nf 3 4 6\n",
    )
    .unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.primitives.len(), 2);
    assert_eq!(m.primitives[0].material.as_deref(), Some("Red"));
    assert_eq!(m.primitives[0].triangle_count(), 2);
    assert_eq!(m.primitives[1].material.as_deref(), Some("Blue"));
    assert_eq!(m.primitives[1].triangle_count(), 1);
    // The material state carries over into the next object, as in Blender.
    assert_eq!(s.meshes[1].primitives[0].material.as_deref(), Some("Red"));
    // Vertex 1 is shared by both primitives: two display vertices, one source point.
    assert_eq!(m.source_point_count, 5);
    assert_eq!(m.vertex_count(), 5 + 3);
}

#[test]
fn missing_normals_are_computed_unit_length() {
    // A tent: two triangles folded along the x axis; no vn lines.
    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 1\nv 0 -1 1\nf 1 2 3\nf 2 1 4\n").unwrap();
    let prim = &s.meshes[0].primitives[0];
    let n = prim.normals.as_ref().unwrap();
    for v in n {
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-5, "{v:?}");
    }
    // The apex of the first triangle (0,1,1) sees only that face: normal (0,-1,1)/sqrt2 ...
    let apex = prim
        .positions
        .iter()
        .position(|p| *p == [0.0, 1.0, 1.0])
        .unwrap();
    let e = std::f32::consts::FRAC_1_SQRT_2;
    let got = n[apex];
    assert!(
        (got[0]).abs() < 1e-5 && (got[1] + e).abs() < 1e-5 && (got[2] - e).abs() < 1e-5,
        "{got:?}"
    );
    // ... and the shared ridge vertices average the two faces: straight up +Z.
    let ridge = prim
        .positions
        .iter()
        .position(|p| *p == [1.0, 0.0, 0.0])
        .unwrap();
    let got = n[ridge];
    assert!((got[2] - 1.0).abs() < 1e-5, "{got:?}");
}

/// A face naming a `vt` or `vn` the file lacks keeps its place (Blender 5.0.1 imports
/// trimesh's cubevt.obj, `f 1/1/1` and no `vt` line, as a 24-vertex box without UVs): the
/// missing index is dropped, the rest of the file's UVs and normals are kept, and a note
/// names the first such line and how many corners there are.
#[test]
fn faces_naming_missing_uvs_or_normals_keep_their_place_with_a_note() {
    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n").unwrap();
    assert_eq!(s.meshes[0].vertex_count(), 3);
    assert!(s.meshes[0].primitives[0].uvs.is_none());
    assert_eq!(s.notes.len(), 1, "{:?}", s.notes);
    let note = &s.notes[0];
    assert!(
        note.contains("mem/test.obj: line 4") && note.contains("texture coordinate 1"),
        "{note}"
    );
    assert!(
        note.contains("has 0 `vt` line(s); 3 face corner(s)"),
        "{note}"
    );

    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 -1\nf 1//1 2//2 3//1\n").unwrap();
    let normals = s.meshes[0].primitives[0].normals.as_ref().unwrap();
    // Two corners keep the file's normal, the third takes the computed one (+z here).
    assert_eq!(
        normals.iter().filter(|n| **n == [0.0, 0.0, -1.0]).count(),
        2
    );
    assert_eq!(normals.iter().filter(|n| **n == [0.0, 0.0, 1.0]).count(), 1);
    assert!(
        s.notes[0].contains("line 5") && s.notes[0].contains("normal 2"),
        "{:?}",
        s.notes
    );

    // A vertex index past the file's `v` lines is still an error: the face has no place.
    let err = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err();
    assert_eq!(err.location.as_deref(), Some("line 4"), "{err}");
}

#[test]
fn file_normals_and_uvs_are_kept_and_split_vertices() {
    let s = import(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvt 0.5 0.5\n\
         vn 0 0 2\nf 1/1/1 2/2/1 3/3/1\nf 2/5/1 4/4/1 3/3/1\n",
    )
    .unwrap();
    let m = &s.meshes[0];
    let p = &m.primitives[0];
    // Vertex 2 appears with two different UVs: 5 display vertices over 4 points.
    assert_eq!(m.vertex_count(), 5);
    assert_eq!(m.source_point_count, 4);
    assert!(p
        .normals
        .as_ref()
        .unwrap()
        .iter()
        .all(|n| *n == [0.0, 0.0, 1.0]));
    let uvs = p.uvs.as_ref().unwrap();
    assert!(uvs.contains(&[0.5, 0.5]) && uvs.contains(&[1.0, 0.0]));
    let points: Vec<u32> = m.source_point_of_vertex.clone();
    assert_eq!(points.iter().filter(|&&q| q == 1).count(), 2, "{points:?}");
}

#[test]
fn blender_corpus_files_have_the_point_counts_blender_reports() {
    // Counts checked with bpy 5.0.1's obj_import: Body 8, Head 482, Cylinder 48.
    let dir = springbake_testkit::corpus_dir();
    for (file, expected) in [
        (
            "blender/two_objects.obj",
            vec![("Body", 8usize), ("Head", 482)],
        ),
        ("blender/cylinder.obj", vec![("Cylinder", 48)]),
    ] {
        let path = dir.join(file);
        let s = ObjImporter
            .import(
                &path,
                &std::fs::read(&path).unwrap(),
                &ImportSettings::default(),
            )
            .unwrap();
        let got: Vec<(&str, usize)> = s
            .meshes
            .iter()
            .map(|m| (m.name.as_str(), m.source_point_count))
            .collect();
        assert_eq!(got, expected, "{file}");
    }
    // The cylinder: 24 side quads and two 24-gon caps.
    let path = dir.join("blender/cylinder.obj");
    let s = ObjImporter
        .import(
            &path,
            &std::fs::read(&path).unwrap(),
            &ImportSettings::default(),
        )
        .unwrap();
    assert_eq!(s.meshes[0].triangle_count(), 24 * 2 + 2 * 22);
}

#[test]
fn line_vertices_are_loose_points_and_p_is_ignored_as_in_blender() {
    // Blender 5.0.1 imports this as 5 vertices (the face's 3 and the line's 2), not the `p` one.
    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv 6 6 6\nv 7 7 7\nf 1 2 3\nl 4 5\np 6\n")
        .unwrap();
    let m = &s.meshes[0];
    assert_eq!(m.source_point_count, 5);
    assert_eq!(m.triangle_count(), 1);
    assert_eq!(m.vertex_count(), 5);
    let xs: Vec<f32> = m
        .to_source_points(&m.primitives[0].positions, [f32::NAN; 3])
        .iter()
        .map(|p| p[0])
        .collect();
    assert_eq!(xs, vec![0.0, 1.0, 0.0, 5.0, 6.0]);
    // An out-of-range line index is an error on its line.
    let err = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nl 1 9\n").unwrap_err();
    assert_eq!(err.location.as_deref(), Some("line 5"), "{err}");
}

#[test]
fn degenerate_faces_keep_their_points() {
    // Blender drops `f 4 5 5` but keeps vertices 4 and 5: 5 points.
    let s = import("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv 6 6 6\nf 1 2 3\nf 4 5 5\n").unwrap();
    assert_eq!(s.meshes[0].source_point_count, 5);
}

/// Issue 17 silent misreads: a UTF-8 byte-order mark hid the first vertex (shifting every
/// index), and a number too large for f32 was called "not finite".
#[test]
fn a_byte_order_mark_is_skipped_and_huge_numbers_say_why() {
    let plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let with_bom = format!("\u{feff}{plain}");
    let a = import(plain).unwrap();
    let b = import(&with_bom).unwrap();
    assert_eq!(
        a.meshes[0].primitives[0].positions,
        b.meshes[0].primitives[0].positions
    );
    let err = import("v 1e308 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap_err();
    assert_eq!(err.location.as_deref(), Some("line 1"));
    assert!(err.message.contains("beyond the range"), "{err}");
}
