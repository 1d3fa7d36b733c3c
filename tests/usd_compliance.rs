//! Every USD file springbake writes passes usd-core's validators (what `usdchecker` runs) and
//! carries what DCC importers rely on (issue 23 item 4; `tests/clients/usd_check.py` lists the
//! rules): new stages baked from glTF and OBJ (with its materials), and flattened source stages
//! (`.usda`, `.usdc`, `.usdz` sources; Z-up; a hierarchy; an open surface).
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{corpus_dir, last_json_line, run_python_client};
use support::{springbake_in, succeeded};

#[test]
fn every_usd_we_write_passes_the_validators_and_the_dcc_rules() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases = [
        ("icosphere.glb", "from_gltf.usda"),
        ("two_objects.obj", "from_obj.usdc"),
        ("two_objects.usda", "from_usd_hierarchy.usda"),
        ("cylinder.usdc", "from_usdc.usdc"),
        ("cylinder.usdz", "from_usdz.usda"),
        ("grid_open.usda", "from_open_surface.usd"),
    ];
    std::fs::copy(
        corpus_dir().join("blender/two_objects.mtl"),
        d.join("two_objects.mtl"),
    )
    .unwrap();
    let mut outputs = Vec::new();
    for (source, output) in cases {
        std::fs::copy(corpus_dir().join("blender").join(source), d.join(source)).unwrap();
        succeeded(&springbake_in(
            d,
            &[
                "bake",
                source,
                "-o",
                output,
                "--frames",
                "12",
                "--cells",
                "5",
                "--progress",
                "quiet",
            ],
        ));
        outputs.push(d.join(output).to_string_lossy().into_owned());
    }
    let args: Vec<&str> = outputs.iter().map(String::as_str).collect();
    let report = last_json_line(&run_python_client("usd_check.py", &args));
    for path in &outputs {
        assert_eq!(report[path], serde_json::json!([]), "{path}: {report}");
    }
}
