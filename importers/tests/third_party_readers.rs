//! Why springbake reads glTF and OBJ itself rather than through the `gltf` and `tobj` crates
//! (issue 17, item 8; ARCHITECTURE.md, "Readers"): on the same files, each crate does
//! something a bake must not — read outside the asset's folder, misread silently, or let NaN
//! and infinity through — where springbake's importers refuse with the file, line or JSON
//! path. If one of these assertions starts failing, the crate has changed: look again.
#![allow(clippy::unwrap_used)]

use springbake_core::plugin::{ImportSettings, Importer};
use springbake_importers::gltf::GltfImporter;
use springbake_importers::obj::ObjImporter;
use std::path::Path;

fn triangle_gltf(uri: &str, count: u64) -> String {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": uri}],
    })
    .to_string()
}

#[test]
fn the_gltf_crate_reads_outside_the_folder_and_misreads_a_short_buffer_silently() {
    let outer = tempfile::tempdir().unwrap();
    let folder = outer.path().join("asset");
    std::fs::create_dir(&folder).unwrap();
    std::fs::write(outer.path().join("secret.bin"), [0u8; 36]).unwrap();
    // A buffer URI that leaves the folder.
    let escape = folder.join("escape.gltf");
    std::fs::write(&escape, triangle_gltf("../secret.bin", 3)).unwrap();
    let (_, buffers, _) = gltf::import(&escape).expect("the gltf crate follows ../");
    assert_eq!(buffers[0].len(), 36, "it read the file outside the folder");
    let ours = GltfImporter.import(
        &escape,
        &std::fs::read(&escape).unwrap(),
        &ImportSettings::default(),
    );
    assert!(ours.unwrap_err().message.contains("leaves the folder"));

    // An accessor of 1000 elements over 36 bytes: the crate yields no positions at all.
    std::fs::write(folder.join("tri.bin"), [0u8; 36]).unwrap();
    let short = folder.join("short.gltf");
    std::fs::write(&short, triangle_gltf("tri.bin", 1000)).unwrap();
    let (doc, buffers, _) = gltf::import(&short).expect("accepted");
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|b| Some(&buffers[b.index()]));
    let read = reader.read_positions().map_or(0, Iterator::count);
    assert_eq!(read, 0, "silently empty instead of an error");
    let ours = GltfImporter
        .import(
            &short,
            &std::fs::read(&short).unwrap(),
            &ImportSettings::default(),
        )
        .unwrap_err();
    assert_eq!(ours.location.as_deref(), Some("accessors[0]"), "{ours}");
}

#[test]
fn tobj_lets_nan_and_infinity_through_and_a_byte_order_mark_breaks_the_file() {
    let load = |text: &str| {
        let mut reader = std::io::BufReader::new(text.as_bytes());
        tobj::load_obj_buf(&mut reader, &tobj::GPU_LOAD_OPTIONS, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
    };
    let ours = |text: &str| {
        ObjImporter.import(
            Path::new("t.obj"),
            text.as_bytes(),
            &ImportSettings::default(),
        )
    };
    let tri = "v 1 0 0\nv 0 1 0\nf 1 2 3\n";
    for bad in ["nan", "1e39"] {
        let text = format!("v {bad} 0 0\n{tri}");
        let (models, _) = load(&text).expect("tobj accepts it");
        assert!(
            !models[0].mesh.positions[0].is_finite(),
            "{bad} became a non-finite coordinate"
        );
        let err = ours(&text).unwrap_err();
        assert_eq!(err.location.as_deref(), Some("line 1"), "{err}");
    }
    // A UTF-8 byte-order mark hides the first vertex from tobj; the face then fails, with no line.
    let text = format!("\u{feff}v 0 0 0\n{tri}");
    assert!(load(&text).is_err());
    assert_eq!(ours(&text).unwrap().meshes[0].triangle_count(), 1);
}
