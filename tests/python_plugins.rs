//! Python plug-ins found at run time (issue 22, items 1–4 and 6 in part): the example PLY
//! importer reads a PLY written by Blender and the example JSON exporter writes the bake,
//! both from `plugins/` beside the input, without rebuilding springbake; `springbake plugins`
//! lists them with their files and a broken plug-in with its error while bakes still run; an
//! exception inside a plug-in is a one-line error naming its file and line (exit 2);
//! `--no-plugins` turns discovery off.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_testkit::{last_json_line, workspace_root};
use std::path::Path;
use std::process::Command;
use support::{springbake_in as springbake, succeeded as ok};

/// A folder with Blender's PLY of a UV sphere (r 0.3 m, centre 0.8 m up) and the examples.
fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("plugins")).unwrap();
    for name in ["ply_importer.py", "json_cache_exporter.py"] {
        std::fs::copy(
            workspace_root().join("examples/plugins").join(name),
            d.join("plugins").join(name),
        )
        .unwrap();
    }
    let script = d.join("make_ply.py");
    std::fs::write(
        &script,
        format!(
            "import bpy\nbpy.ops.wm.read_factory_settings(use_empty=True)\n\
             bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(0, 0, 0.8), segments=16, ring_count=8)\n\
             bpy.ops.wm.ply_export(filepath={:?}, ascii_format=False)\n",
            d.join("ball.ply").to_string_lossy()
        ),
    )
    .unwrap();
    run_python_client_path(&script);
    dir
}

/// [`setup`], plus the example plug-in `example` and the corpus icosphere.
fn setup_with_ball(example: &str) -> tempfile::TempDir {
    let dir = setup();
    let d = dir.path();
    let examples = workspace_root().join("examples/plugins");
    std::fs::copy(examples.join(example), d.join("plugins").join(example)).unwrap();
    std::fs::copy(
        springbake_testkit::corpus_dir().join("blender/icosphere.glb"),
        d.join("icosphere.glb"),
    )
    .unwrap();
    dir
}

fn run_python_client_path(script: &Path) -> String {
    let out = Command::new(springbake_testkit::venv_python())
        .arg(script)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn blenders_ply_bakes_through_the_importer_plugin_and_the_json_exporter_writes_it() {
    let dir = setup();
    let d = dir.path();
    ok(&springbake(
        d,
        &[
            "bake",
            "ball.ply",
            "-o",
            "ball.json",
            "--frames",
            "24",
            "--progress",
            "quiet",
        ],
    ));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("ball.json")).unwrap()).unwrap();
    assert_eq!(doc["frame_count"], 24);
    assert_eq!(doc["up_axis"], "Z", "Blender's PLY is Z-up");
    let frames = doc["meshes"][0]["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 24);
    let lowest = |f: &serde_json::Value| {
        f.as_array()
            .unwrap()
            .iter()
            .map(|p| p[2].as_f64().unwrap())
            .fold(f64::INFINITY, f64::min)
    };
    assert!((lowest(&frames[0]) - 0.5).abs() < 1e-4, "starts 0.5 m up");
    let landed = frames.iter().map(lowest).fold(f64::INFINITY, f64::min);
    assert!(landed.abs() < 0.01, "falls onto the floor: {landed}");

    // The same PLY baked to glTF, opened in Blender: the sphere where Blender made it.
    ok(&springbake(
        d,
        &[
            "bake",
            "ball.ply",
            "-o",
            "ball.glb",
            "--frames",
            "12",
            "--progress",
            "quiet",
        ],
    ));
    let script = d.join("open_glb.py");
    std::fs::write(
        &script,
        format!(
            "import bpy, json\nbpy.ops.wm.read_factory_settings(use_empty=True)\n\
             bpy.ops.import_scene.gltf(filepath={:?})\n\
             o = [o for o in bpy.context.scene.objects if o.type == 'MESH'][0]\n\
             bpy.context.scene.frame_set(0)\n\
             e = o.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()\n\
             zs = [(o.matrix_world @ v.co).z for v in e.vertices]\n\
             print(json.dumps({{'name': o.name, 'low': min(zs), 'high': max(zs)}}))\n",
            d.join("ball.glb").to_string_lossy()
        ),
    )
    .unwrap();
    let seen = last_json_line(&run_python_client_path(&script));
    assert_eq!(seen["name"], "ball", "{seen}");
    assert!((seen["low"].as_f64().unwrap() - 0.5).abs() < 1e-3, "{seen}");
    assert!(
        (seen["high"].as_f64().unwrap() - 1.1).abs() < 1e-3,
        "{seen}"
    );
}

#[test]
fn plugins_are_listed_with_their_files_and_a_broken_one_with_its_error() {
    let dir = setup();
    let d = dir.path();
    std::fs::write(
        d.join("plugins/broken.py"),
        "SPRINGBAKE_PLUGIN = {\n  'kind': \n",
    )
    .unwrap();
    let listing = ok(&springbake(d, &["plugins", "."]));
    assert!(
        listing.contains("ply") && listing.contains("ply_importer.py"),
        "{listing}"
    );
    assert!(listing.contains("jsoncache") && listing.contains("json_cache_exporter.py"));
    assert!(
        listing.contains("not loaded") && listing.contains("broken.py") && listing.contains("line"),
        "{listing}"
    );
    // `inspect` reads through the plug-in too.
    let shown = ok(&springbake(d, &["inspect", "ball.ply"]));
    assert!(
        shown.contains("(ply, Z-up") && shown.contains("151 vertices"),
        "{shown}"
    );
    // A bake that does not use the broken plug-in runs.
    ok(&springbake(
        d,
        &[
            "bake",
            "ball.ply",
            "-o",
            "ball.glb",
            "--frames",
            "6",
            "--progress",
            "quiet",
        ],
    ));
    let off = springbake(d, &["bake", "ball.ply", "--no-plugins", "--frames", "6"]);
    assert_eq!(
        off.status.code(),
        Some(2),
        "no importer for .ply without plug-ins"
    );
}

#[test]
fn an_exception_in_a_plugin_names_its_file_and_line_and_keeps_the_old_output() {
    let dir = setup();
    let d = dir.path();
    std::fs::write(
        d.join("plugins/ply_importer.py"),
        "SPRINGBAKE_PLUGIN = {'kind': 'importer', 'name': 'ply', 'extensions': ['ply']}\n\n\
         def import_file(path):\n    raise ValueError('cannot read ' + path)\n",
    )
    .unwrap();
    std::fs::write(d.join("ball.json"), "old").unwrap();
    let out = springbake(d, &["bake", "ball.ply", "-o", "ball.json", "--frames", "6"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("ply_importer.py") && err.contains("line 4") && err.contains("ValueError"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert_eq!(std::fs::read_to_string(d.join("ball.json")).unwrap(), "old");
}

/// The vortex example (a force field called every substep) makes a floating ball orbit the
/// axis; a field that raises stops the bake with its file and line.
#[test]
fn the_vortex_field_plugin_makes_a_body_orbit() {
    let dir = setup_with_ball("vortex_field.py");
    let d = dir.path();
    let scene = "[output]\npath = \"orbit.json\"\nframes = 49\n\n[world]\ngravity = 0.0\n\n\
                 [[body]]\nname = \"ball\"\nsource = \"icosphere.glb\"\ncells = 5\n\
                 offset = [1.0, -1.0, 0.0]\n\n[[force_field]]\nfield = \"vortex\"\n";
    std::fs::write(d.join("orbit.toml"), scene).unwrap();
    assert!(ok(&springbake(d, &["plugins", "."])).contains("every substep"));
    ok(&springbake(
        d,
        &["bake", "orbit.toml", "--progress", "quiet"],
    ));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("orbit.json")).unwrap()).unwrap();
    let centre = |f: usize| {
        let frame = doc["meshes"][0]["frames"][f].as_array().unwrap();
        let n = frame.len() as f64;
        let sum = |k: usize| frame.iter().map(|p| p[k].as_f64().unwrap()).sum::<f64>() / n;
        (sum(0), sum(2))
    };
    let mut swept = 0.0;
    let mut last = 0.0f64;
    for f in 1..49 {
        let (x, z) = centre(f);
        let angle = (-z).atan2(x);
        let mut step = angle - last;
        if step < -std::f64::consts::PI {
            step += std::f64::consts::TAU;
        }
        swept += step;
        last = angle;
        let r = x.hypot(z);
        assert!((0.7..1.05).contains(&r), "frame {f}: radius {r}");
    }
    assert!(swept.to_degrees() > 150.0, "swept {}°", swept.to_degrees());

    std::fs::write(
        d.join("plugins/vortex_field.py"),
        "SPRINGBAKE_PLUGIN = {'kind': 'force_field', 'name': 'vortex'}\n\n\
         def force(x, v, t):\n    return x[:, :2]\n",
    )
    .unwrap();
    let out = springbake(d, &["bake", "orbit.toml", "--progress", "quiet"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("vortex_field.py") && err.contains("shape"),
        "{err}"
    );
}

/// The "squash on landing" example flattens the ball it runs on: fired in mid-air (where the
/// plain ball stays round; on the floor the ball's own squash would hide it), the ball becomes
/// wider than tall.
#[test]
fn the_squash_procedure_plugin_flattens_the_ball() {
    let dir = setup_with_ball("squash_procedure.py");
    let d = dir.path();
    let scene = |squash: bool, out: &str| {
        let event = if squash {
            "[[event]]\nname = \"squash\"\nbody = \"ball\"\non = { time = 0.05 }\n\
             procedure = { plugin = { name = \"squash\", args = { rate = 6.0 } } }\n"
        } else {
            ""
        };
        format!(
            "[output]\npath = \"{out}\"\nframes = 7\n\n[world]\nfloor = 0.0\n\n\
             [[body]]\nname = \"ball\"\nsource = \"icosphere.glb\"\ncells = 6\n\
             material = \"soft_rubber\"\n\n{event}"
        )
    };
    let flatness = |file: &str| {
        let doc: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join(file)).unwrap()).unwrap();
        let frames = doc["meshes"][0]["frames"].as_array().unwrap();
        frames
            .iter()
            .map(|f| {
                let f = f.as_array().unwrap();
                let extent = |k: usize| {
                    let c = f.iter().map(|p| p[k].as_f64().unwrap());
                    c.clone().fold(f64::NEG_INFINITY, f64::max) - c.fold(f64::INFINITY, f64::min)
                };
                extent(0) / extent(1)
            })
            .fold(0.0, f64::max)
    };
    for (squash, out) in [(false, "plain.json"), (true, "squash.json")] {
        std::fs::write(d.join(format!("{out}.toml")), scene(squash, out)).unwrap();
        let file = format!("{out}.toml");
        ok(&springbake(d, &["bake", &file, "--progress", "quiet"]));
    }
    assert!(ok(&springbake(d, &["plugins", "."])).contains("squash"));
    let (plain, squashed) = (flatness("plain.json"), flatness("squash.json"));
    assert!(
        plain < 1.02 && squashed > 1.1,
        "widest/tallest: {squashed} with the squash, {plain} without"
    );
}

/// Issue 22 item 1: plug-ins of installed packages, found through their `springbake.plugins`
/// entry points. The package here is installed as pip would lay it out (a module and its
/// `*.dist-info` with `entry_points.txt`) in a folder on `$PYTHONPATH`; one of its entry
/// points names a module that raises on import.
#[test]
fn installed_packages_add_plugins_through_their_entry_points() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let site = d.join("site");
    let info = site.join("sbk_cache-1.0.dist-info");
    std::fs::create_dir_all(&info).unwrap();
    std::fs::write(
        info.join("METADATA"),
        "Metadata-Version: 2.1\nName: sbk-cache\nVersion: 1.0\n",
    )
    .unwrap();
    std::fs::write(
        info.join("entry_points.txt"),
        "[springbake.plugins]\njson_cache = sbk_cache_plugin\nbroken = sbk_broken\n",
    )
    .unwrap();
    std::fs::copy(
        workspace_root().join("examples/plugins/json_cache_exporter.py"),
        site.join("sbk_cache_plugin.py"),
    )
    .unwrap();
    std::fs::write(
        site.join("sbk_broken.py"),
        "import os\n\nraise RuntimeError('not configured')\n",
    )
    .unwrap();
    std::fs::copy(
        springbake_testkit::corpus_dir().join("blender/icosphere.glb"),
        d.join("icosphere.glb"),
    )
    .unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_springbake"))
            .args(args)
            .current_dir(d)
            .env("PYTHONPATH", &site)
            .env("XDG_CONFIG_HOME", d.join("no-config"))
            .output()
            .unwrap()
    };
    let listing = ok(&run(&["plugins"]));
    let module = site.join("sbk_cache_plugin.py");
    assert!(
        listing.contains("jsoncache") && listing.contains(module.to_str().unwrap()),
        "{listing}"
    );
    assert!(
        listing.contains("not loaded")
            && listing.contains("entry point broken = sbk_broken")
            && listing.contains("sbk_broken.py, line 3")
            && listing.contains("not configured"),
        "{listing}"
    );
    ok(&run(&[
        "bake",
        "icosphere.glb",
        "-o",
        "cache.json",
        "--frames",
        "4",
        "--progress",
        "quiet",
    ]));
    let cache: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("cache.json")).unwrap()).unwrap();
    assert!(cache.to_string().contains("Icosphere"), "{cache}");
    let off = ok(&run(&["plugins", "--no-plugins"]));
    assert!(!off.contains("jsoncache"), "{off}");
}

/// Issue 22 item 2: a plug-in procedure acts through the host's small API as well as on the
/// velocities: an impulse on the whole body, a material change and a pin, applied in that
/// order after it runs. A ball floating (no gravity) is kicked up at 2 m/s and made steel at
/// 0.1 s and pinned at 0.3 s: it rises 0.4 m, then stays. A material that does not exist is
/// an error naming the plug-in and the material (exit 2).
#[test]
fn a_plugin_procedure_gives_an_impulse_changes_the_material_and_pins() {
    let dir = setup_with_ball("squash_procedure.py");
    let d = dir.path();
    std::fs::write(
        d.join("plugins/kick.py"),
        "SPRINGBAKE_PLUGIN = {'kind': 'procedure', 'name': 'kick'}\n\n\n\
         def run(body, args):\n    if args.get('hold'):\n        return {'pin': True}\n    \
         m = body['masses'].sum()\n    \
         return {'impulse': [0.0, 2.0 * m, 0.0], 'material': args.get('material', 'steel')}\n",
    )
    .unwrap();
    let scene = |material: &str| {
        format!(
            "[output]\npath = \"kick.json\"\nframes = 13\nfps = 20\n\n[world]\ngravity = 0.0\n\n\
             [[body]]\nname = \"ball\"\nsource = \"icosphere.glb\"\ncells = 5\nmaterial = \"rubber\"\n\n\
             [[event]]\nname = \"kick\"\nbody = \"ball\"\non = {{ time = 0.1 }}\n\
             procedure = {{ plugin = {{ name = \"kick\", args = {{ material = \"{material}\" }} }} }}\n\n\
             [[event]]\nname = \"hold\"\nbody = \"ball\"\non = {{ time = 0.3 }}\n\
             procedure = {{ plugin = {{ name = \"kick\", args = {{ hold = true }} }} }}\n"
        )
    };
    std::fs::write(d.join("kick.toml"), scene("steel")).unwrap();
    ok(&springbake(
        d,
        &["bake", "kick.toml", "--progress", "quiet"],
    ));
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("kick.json")).unwrap()).unwrap();
    let heights: Vec<f64> = doc["meshes"][0]["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let f = f.as_array().unwrap();
            f.iter().map(|p| p[1].as_f64().unwrap()).sum::<f64>() / f.len() as f64
        })
        .collect();
    let rise = |a: usize, b: usize| heights[b] - heights[a];
    // frames at 0.05 s: kicked at frame 2 (0.1 s), pinned at frame 6 (0.3 s)
    assert!(
        rise(0, 2).abs() < 1e-6,
        "still before the kick: {heights:?}"
    );
    assert!(
        (rise(2, 6) - 0.4).abs() < 0.02,
        "2 m/s for 0.2 s: {heights:?}"
    );
    assert!(rise(6, 12).abs() < 1e-6, "pinned: {heights:?}");
    std::fs::write(
        d.join("bad.toml"),
        scene("unobtanium").replace("kick.json", "bad.json"),
    )
    .unwrap();
    let bad = springbake(d, &["bake", "bad.toml", "--progress", "quiet"]);
    assert_eq!(bad.status.code(), Some(2), "{}", support::stderr(&bad));
    let e = support::stderr(&bad);
    assert!(e.contains("kick") && e.contains("unobtanium"), "{e}");
}
