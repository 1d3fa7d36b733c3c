//! OBJ materials survive a bake (issue 19 items 1 and 2): Blender writes an OBJ with a `.mtl`
//! (a textured material and a plain blue one), springbake bakes it to glTF and to USD, and
//! Blender sees the same objects, materials, base colours (within 1/255), textures and UV
//! layers in the bakes as in the OBJ. A missing `.mtl` is a note, not a failure.
#![allow(clippy::unwrap_used)]

use springbake_testkit::{assert_gltf_valid, last_json_line, run_python_client};
use std::process::Command;

fn bake(obj: &std::path::Path, glb: &std::path::Path, frames: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args([
            "bake",
            obj.to_str().unwrap(),
            "-o",
            glb.to_str().unwrap(),
            "--frames",
            frames,
        ])
        .output()
        .unwrap()
}

fn look(file: &std::path::Path) -> serde_json::Value {
    last_json_line(&run_python_client(
        "obj_materials_blender.py",
        &["look", file.to_str().unwrap()],
    ))
}

#[test]
fn blender_sees_the_objs_materials_in_the_baked_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_python_client("obj_materials_blender.py", &["make", d.to_str().unwrap()]);
    let obj = d.join("props.obj");
    let glb = d.join("props.glb");
    let baked_once = bake(&obj, &glb, "6");
    assert!(
        baked_once.status.success(),
        "{}",
        String::from_utf8_lossy(&baked_once.stderr)
    );
    assert_gltf_valid(&glb);
    let source = look(&obj);
    let baked = look(&glb);
    assert_eq!(source["objects"], 2, "{source}");
    assert_eq!(baked["objects"], source["objects"], "{baked}");
    assert_eq!(baked["uv_layers"], source["uv_layers"], "{baked}");
    let (want, got) = (
        source["materials"].as_object().unwrap(),
        baked["materials"].as_object().unwrap(),
    );
    assert_eq!(got.len(), want.len(), "{baked}");
    for (name, w) in want {
        let g = &got[name];
        assert_eq!(g["textured"], w["textured"], "{name}: {baked}");
        match (w["colour"].as_array(), g["colour"].as_array()) {
            (Some(w), Some(g)) => {
                for (a, b) in w.iter().zip(g) {
                    let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
                    assert!((a - b).abs() <= 1.0 / 255.0, "{name}: {w:?} vs {g:?}");
                }
            }
            (None, None) => {}
            other => panic!("{name}: {other:?}"),
        }
    }
    assert_eq!(
        want["Brick"]["textured"], true,
        "the test's source has a texture"
    );

    // Without its .mtl the OBJ still bakes, grey, and says why.
    std::fs::remove_file(d.join("props.mtl")).unwrap();
    let bare = bake(&obj, &glb, "2");
    let err = String::from_utf8_lossy(&bare.stderr);
    assert!(bare.status.success(), "{err}");
    assert!(
        err.contains("props.mtl") && err.contains("left grey"),
        "{err}"
    );
}

/// A glTF's materials reach a USD bake too: Blender's glTF of the same props, baked to USD
/// (a layer with its images beside it, and a .usdz package holding them), shows the texture
/// and the blue as Blender's import of the glTF does.
#[test]
fn a_gltfs_materials_reach_a_usd_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_python_client("obj_materials_blender.py", &["make", d.to_str().unwrap()]);
    for name in ["from_gltf.usda", "packed.usdz"] {
        a_gltfs_materials_reach(d, name);
    }
    assert!(
        d.join("from_gltf_textures").is_dir(),
        "a layer's images beside it"
    );
    assert!(
        !d.join("packed_textures").exists(),
        "a package holds its images"
    );
}

/// glTF → `name` (USD), then that USD → glTF again (its textures read from the layer's
/// folder or the package): Blender sees the texture and the colours at both steps.
fn a_gltfs_materials_reach(d: &std::path::Path, name: &str) {
    let usda = d.join(name);
    let o = bake(&d.join("props.glb"), &usda, "4");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back = d.join(format!("{name}.glb"));
    let o = bake(&usda, &back, "2");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_gltf_valid(&back);
    for file in [&usda, &back] {
        same_look(&look(&d.join("props.glb")), &look(file));
    }
}

fn same_look(want: &serde_json::Value, got: &serde_json::Value) {
    assert_eq!(got["objects"], want["objects"], "{got}");
    assert_eq!(got["materials"]["Brick"]["textured"], true, "{got}");
    let (w, g) = (
        &want["materials"]["Blue"]["colour"],
        &got["materials"]["Blue"]["colour"],
    );
    for (a, b) in w.as_array().unwrap().iter().zip(g.as_array().unwrap()) {
        assert!(
            (a.as_f64().unwrap() - b.as_f64().unwrap()).abs() <= 1.0 / 255.0,
            "{w} vs {g}"
        );
    }
}

/// One OBJ object with two materials bakes to one USD mesh with a GeomSubset per material:
/// Blender sees one object with both materials and their colours; baked again from that USD
/// to glTF (the subsets read back as primitives), Blender sees the same.
#[test]
fn an_objects_materials_become_usd_geom_subsets() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("two.mtl"),
        "newmtl A\nKd 1 0 0\nnewmtl B\nKd 0 0 1\n",
    )
    .unwrap();
    std::fs::write(
        d.join("two.obj"),
        "mtllib two.mtl\no Box\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\n\
         v 0 1 1\nusemtl A\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nusemtl B\nf 2 3 7 6\nf 3 4 8 7\n\
         f 4 1 5 8\n",
    )
    .unwrap();
    let usda = d.join("two.usda");
    let o = bake(&d.join("two.obj"), &usda, "3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&usda).unwrap();
    assert_eq!(text.matches("def GeomSubset").count(), 2, "{text}");
    let seen = look(&usda);
    assert_eq!(seen["objects"], 1, "{seen}");
    assert_eq!(
        seen["materials"]["A"]["colour"],
        serde_json::json!([1.0, 0.0, 0.0, 1.0])
    );
    assert_eq!(
        seen["materials"]["B"]["colour"],
        serde_json::json!([0.0, 0.0, 1.0, 1.0])
    );
}

/// An OBJ material's normal map (`map_Bump`) and opacity map (`map_d`) reach a USD bake as
/// UsdUVTexture inputs of its UsdPreviewSurface: the normal read raw and mapped to [-1, 1]
/// (scale 2, bias -1), the opacity from the image's red channel; every file resolves.
#[test]
fn normal_and_opacity_maps_reach_a_usd_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_python_client("obj_materials_blender.py", &["make", d.to_str().unwrap()]);
    let mtl = std::fs::read_to_string(d.join("props.mtl")).unwrap();
    let with_maps = mtl.replace(
        "map_Kd bricks.png",
        "map_Kd bricks.png\nmap_Bump bricks.png\nmap_d bricks.png",
    );
    assert_ne!(
        with_maps, mtl,
        "the test's .mtl names its base-colour image:\n{mtl}"
    );
    std::fs::write(d.join("props.mtl"), with_maps).unwrap();
    for name in ["maps.usda", "maps.usdz"] {
        let out = d.join(name);
        let o = bake(&d.join("props.obj"), &out, "2");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let maps = last_json_line(&run_python_client(
            "usd_material_maps.py",
            &[out.to_str().unwrap()],
        ));
        let brick = &maps["Brick"];
        for input in ["diffuseColor", "normal", "opacity"] {
            assert_eq!(brick[input]["resolves"], true, "{name} {input}: {maps}");
        }
        assert_eq!(brick["normal"]["colour_space"], "raw", "{maps}");
        assert_eq!(
            brick["normal"]["scale"],
            serde_json::json!([2.0, 2.0, 2.0, 1.0])
        );
        assert_eq!(
            brick["normal"]["bias"],
            serde_json::json!([-1.0, -1.0, -1.0, 0.0])
        );
        assert_eq!(brick["opacity"]["output"], "r", "{maps}");
        assert!(maps["Blue"].as_object().unwrap().is_empty(), "{maps}");
    }
    // A USD source baked into another folder: its maps are named relative to the new layer
    // (flattening made them absolute), and resolve.
    std::fs::create_dir(d.join("again")).unwrap();
    let again = d.join("again").join("again.usda");
    let o = bake(&d.join("maps.usda"), &again, "2");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let maps = last_json_line(&run_python_client(
        "usd_material_maps.py",
        &[again.to_str().unwrap()],
    ));
    for input in ["diffuseColor", "normal", "opacity"] {
        let map = &maps["Brick"][input];
        assert_eq!(map["resolves"], true, "{input}: {maps}");
        assert!(map["file"].as_str().unwrap().starts_with("../"), "{maps}");
    }
}
