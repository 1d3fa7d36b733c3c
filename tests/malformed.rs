//! The malformed-input suite of issue 17: several hundred bad inputs through the `springbake`
//! binary as a user would run it — the shared corpus's bad files, every truncation class of a
//! GLB, broken glTF JSON, broken OBJ lines, scene files with every out-of-range number, bad
//! arguments and special files. Each must end within 10 s with exit code 2 and a message that
//! names the file, peak memory under 1 GB, and never a panic.
#![allow(clippy::unwrap_used)]

mod support;

use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const PER_CASE: Duration = Duration::from_secs(10);
const MAX_RSS_KB: i64 = 1 << 20;

struct Case {
    name: String,
    args: Vec<String>,
    /// Text the error message must contain (the file's name, a key, a line).
    needle: String,
}

struct Outcome {
    code: Option<i32>,
    stderr: String,
    elapsed: Duration,
    max_rss_kb: i64,
}

/// Runs the binary, killing it after [`PER_CASE`]; peak memory from `wait4`'s rusage.
// The child is reaped by `wait4` (for its rusage), not by `Child::wait`.
#[allow(clippy::zombie_processes)]
fn run(args: &[String], dir: &Path) -> Outcome {
    let started = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_springbake"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut s);
        s
    });
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    #[allow(unsafe_code)]
    // SAFETY: an all-zero rusage is a valid value of this plain C struct.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    loop {
        #[allow(unsafe_code)]
        // SAFETY: `pid` is our child, not yet reaped (std's `Child::wait` is never called);
        // `status` and `usage` are valid for writes.
        let done = unsafe { libc::wait4(pid, &mut status, libc::WNOHANG, &mut usage) };
        if done == pid {
            break;
        }
        if started.elapsed() > PER_CASE {
            let _ = child.kill();
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    Outcome {
        code,
        stderr: reader.join().unwrap(),
        elapsed: started.elapsed(),
        max_rss_kb: usage.ru_maxrss,
    }
}

fn case(name: impl Into<String>, args: &[&str], needle: impl Into<String>) -> Case {
    Case {
        name: name.into(),
        args: args.iter().map(|s| s.to_string()).collect(),
        needle: needle.into(),
    }
}

fn bake_file(cases: &mut Vec<Case>, dir: &Path, name: &str, bytes: &[u8], needle: &str) {
    std::fs::write(dir.join(name), bytes).unwrap();
    cases.push(case(
        name,
        &["bake", name, "-o", "out.glb", "--frames", "2"],
        needle,
    ));
}

/// A valid one-triangle glTF with its buffer as a data URI, as a JSON value to break.
fn triangle_gltf() -> Value {
    let floats: [f32; 9] = [0., 0., 0., 1., 0., 0., 0., 1., 0.];
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    use base64::Engine as _;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": uri}],
    })
}

/// Sets `value` at a `/`-separated JSON pointer (creating nothing: the parent must exist).
fn with(mut doc: Value, pointer: &str, value: Value) -> Value {
    let (parent, key) = pointer.rsplit_once('/').unwrap();
    let target = doc.pointer_mut(parent).unwrap();
    match target {
        Value::Array(a) => a[key.parse::<usize>().unwrap()] = value,
        Value::Object(o) => {
            o.insert(key.to_owned(), value);
        }
        _ => panic!("{pointer}"),
    }
    doc
}

fn gltf_cases(cases: &mut Vec<Case>, dir: &Path) {
    let edits: Vec<(&str, Value)> = vec![
        ("/asset/version", json!("1.0")),
        ("/asset/version", json!(2)),
        ("/accessors/0/count", json!(4_000_000_000u64)),
        ("/accessors/0/count", json!(0)),
        ("/accessors/0/count", json!(-1)),
        ("/accessors/0/count", json!(4)),
        ("/accessors/0/componentType", json!(5121)),
        ("/accessors/0/componentType", json!(1)),
        ("/accessors/0/type", json!("VEC2")),
        ("/accessors/0/type", json!("MAT9")),
        ("/accessors/0/bufferView", json!(7)),
        ("/accessors/0/byteOffset", json!(4)),
        ("/accessors/0/byteOffset", json!(1u64 << 62)),
        ("/bufferViews/0/byteLength", json!(100)),
        ("/bufferViews/0/byteOffset", json!(30)),
        ("/bufferViews/0/byteStride", json!(2)),
        ("/bufferViews/0/buffer", json!(3)),
        ("/buffers/0/byteLength", json!(1000)),
        ("/buffers/0/byteLength", json!(20)),
        (
            "/buffers/0/uri",
            json!("data:application/octet-stream;base64,!!!"),
        ),
        ("/buffers/0/uri", json!("data:text/plain,abc")),
        ("/buffers/0/uri", json!("")),
        ("/buffers/0/uri", json!(".")),
        ("/buffers/0/uri", json!("../outside.bin")),
        ("/buffers/0/uri", json!("/etc/passwd")),
        ("/buffers/0/uri", json!("missing.bin")),
        ("/buffers/0/uri", json!("file:///etc/passwd")),
        ("/meshes/0/primitives/0/attributes/POSITION", json!(5)),
        ("/meshes/0/primitives/0/mode", json!(1)),
        ("/meshes/0/primitives/0/mode", json!(9)),
        ("/meshes/0/primitives/0/indices", json!(0)),
        ("/meshes/0/primitives/0/attributes", json!({})),
        ("/nodes/0/mesh", json!(3)),
        ("/nodes/0/children", json!([0])),
        ("/nodes/0/matrix", json!([1, 0, 0])),
        ("/nodes/0/scale", json!([0, 0, 0])),
        ("/nodes/0/translation", json!(["x", 0, 0])),
        ("/scenes/0/nodes", json!([9])),
        ("/meshes", json!([])),
        ("/extensionsRequired", json!(["KHR_draco_mesh_compression"])),
    ];
    for (i, (pointer, value)) in edits.into_iter().enumerate() {
        let doc = with(triangle_gltf(), pointer, value);
        let name = format!("edit{i:02}.gltf");
        bake_file(cases, dir, &name, &serde_json::to_vec(&doc).unwrap(), &name);
    }
    for (i, text) in [
        "",
        "{",
        "[]",
        "null",
        "{\"asset\":{}}",
        "\u{feff}{}",
        "{\"asset\":{\"version\":\"2.0\"}}",
    ]
    .iter()
    .enumerate()
    {
        let name = format!("json{i}.gltf");
        bake_file(cases, dir, &name, text.as_bytes(), &name);
    }
    // NaN cannot be written in JSON; 1e39 overflows f32 and a position of 3.5e38 is finite
    // but meaningless: both are refused with the accessor named.
    let floats: [f32; 9] = [0., 0., 0., f32::NAN, 0., 0., 0., f32::INFINITY, 0.];
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    use base64::Engine as _;
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&bin)
    );
    let doc = with(triangle_gltf(), "/buffers/0/uri", json!(uri));
    bake_file(
        cases,
        dir,
        "nan.gltf",
        &serde_json::to_vec(&doc).unwrap(),
        "nan.gltf",
    );
}

fn glb_cases(cases: &mut Vec<Case>, dir: &Path) {
    let glb =
        std::fs::read(springbake_testkit::corpus_dir().join("blender/icosphere.glb")).unwrap();
    // Cut it at 40 places across the header, the JSON chunk and the BIN chunk.
    for k in 0..40 {
        let at = if k < 8 { k * 3 } else { glb.len() * k / 41 };
        let name = format!("cut{k:02}.glb");
        bake_file(cases, dir, &name, &glb[..at], &name);
    }
    // Header fields that lie.
    for (k, (offset, value)) in [
        (4usize, 1u32),
        (4, 3),
        (8, 0),
        (8, u32::MAX),
        (12, u32::MAX),
        (16, 0),
    ]
    .into_iter()
    .enumerate()
    {
        let mut bytes = glb.clone();
        bytes[offset..offset + 4].copy_from_slice(&value.to_le_bytes());
        let name = format!("header{k}.glb");
        bake_file(cases, dir, &name, &bytes, &name);
    }
}

/// A face naming a `vt` or `vn` the file lacks is not among these: Blender keeps the face
/// and so does springbake, with a note (`importers/tests/obj_import.rs`).
fn obj_cases(cases: &mut Vec<Case>, dir: &Path) {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let bodies: Vec<String> = vec![
        String::new(),
        "v 0 0 0\n".into(),
        tri.into(),
        format!("{tri}f 1 2\n"),
        format!("{tri}f 1 2 4\n"),
        format!("{tri}f 0 1 2\n"),
        format!("{tri}f -4 -1 -2\n"),
        format!("{tri}f 1 2 99999999999\n"),
        format!("{tri}f a b c\n"),
        format!("{tri}f 1/1/1/1 2 3\n"),
        "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v inf 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v 1e400 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v x y z\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".into(),
        "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n".into(),
        "v 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n".into(),
        format!("{tri}l 1 2\n"),
        format!("{tri}p 1\n"),
        format!("{tri}vn 0 0\nf 1//1 2//1 3//1\n"),
    ];
    for (i, body) in bodies.iter().enumerate() {
        let name = format!("bad{i:02}.obj");
        bake_file(cases, dir, &name, body.as_bytes(), &name);
    }
    let name = "binary.obj";
    bake_file(
        cases,
        dir,
        name,
        &[0xff, 0xfe, 0, 1, 2, 3, 0x80, 0x81],
        name,
    );
}

fn scene_cases(cases: &mut Vec<Case>, dir: &Path) {
    support::cube(dir, "cube.obj");
    let base = "[output]\npath = \"out.glb\"\nframes = 2\n";
    let body = "[[body]]\nsource = \"cube.obj\"\n";
    // (section text, key the message must name)
    let mut bad: Vec<(String, &str)> = Vec::new();
    // Each key with the bad values for it: NaN, infinity, and a negative, zero or huge value
    // where that is out of the key's range.
    let keys = [
        ("[world]\ngravity = V\nBODY", "gravity", "nan inf -1.0 1e30"),
        (
            "BODYvelocity = [0.0, V, 0.0]\n",
            "velocity",
            "nan inf 1e5 1e30",
        ),
        (
            "BODYoffset = [V, 0.0, 0.0]\n",
            "offset",
            "nan inf 1e30 -1e30",
        ),
        (
            "BODYmaterial = { young = V, density = 1000 }\n",
            "young",
            "nan inf -1.0 1e30",
        ),
        (
            "BODYmaterial = { young = 1e6, density = V }\n",
            "density",
            "nan inf -1.0 1e30",
        ),
        ("[world]\nfriction = V\nBODY", "friction", "nan inf -1.0"),
        (
            "[world]\ncontact_thickness = V\nBODY",
            "contact_thickness",
            "nan inf -1.0 0.0",
        ),
        ("[world]\nfloor = V\nBODY", "floor", "nan inf -inf"),
        ("BODYcell_size = V\n", "cell_size", "nan inf -1.0 0.0"),
    ];
    for (template, key, values) in keys {
        for v in values.split_whitespace() {
            bad.push((template.replace('V', v).replace("BODY", body), key));
        }
    }
    bad.push((
        format!("[world.walls]\nmin = [1.0, 0.0, 0.0]\nmax = [0.0, 1.0, 1.0]\n{body}"),
        "walls",
    ));
    bad.push((format!("[solver]\naccuracy_n = 0.0\n{body}"), "accuracy_n"));
    bad.push((
        format!("[solver]\nsubsteps = 1000000000\n{body}"),
        "substeps",
    ));
    bad.push((format!("[solver]\nintegrator = \"rk4\"\n{body}"), "rk4"));
    bad.push((format!("{body}cells = 0\n"), "cells"));
    bad.push((format!("{body}material = \"unobtainium\"\n"), "unobtainium"));
    bad.push((format!("{body}bogus = 1\n"), "bogus"));
    bad.push(("[[body]]\nsource = \"missing.obj\"\n".into(), "missing.obj"));
    bad.push(("[[body]]\nsource = \"../outside.obj\"\n".into(), "outside"));
    bad.push(("[[body]]\nsource = \"/etc/passwd\"\n".into(), "passwd"));
    bad.push(("[[body]]\nsource = \"cube.xyz\"\n".into(), "cube.xyz"));
    bad.push((String::new(), "body"));
    let key = "keys = [{ t = 0.0, position = [0.0, 0.0, 0.0] }]";
    for (text, needle) in [
        (format!("radius = -1.0\nlength = 0.2\n{key}"), "radius"),
        ("radius = 0.1\nlength = 0.2\nkeys = []".to_owned(), "keys"),
        (format!("radius = 0.1\n{key}"), "length"),
        (format!("radius = 0.1\nlength = nan\n{key}"), "length"),
    ] {
        bad.push((format!("{body}[[manipulator]]\n{text}\n"), needle));
    }
    for (i, (text, key)) in bad.into_iter().enumerate() {
        let name = format!("scene{i:02}.toml");
        std::fs::write(dir.join(&name), format!("{base}{text}")).unwrap();
        cases.push(case(&name, &["bake", &name], key));
    }
    for (i, (text, key)) in [
        ("[output]\nframes = 1e9\n", "line 2"),
        (
            "[output]\nframes = 99999999999\n[[body]]\nsource = \"cube.obj\"\n",
            "frames",
        ),
        (
            "[output]\nfps = 0\n[[body]]\nsource = \"cube.obj\"\n",
            "fps",
        ),
        (
            "[output]\npath = \"o.pc2\"\ncache = \"pca\"\n[[body]]\nsource = \"cube.obj\"\n",
            "for glTF outputs",
        ),
        (
            "[output]\nmax_error = 0.001\n[[body]]\nsource = \"cube.obj\"\n",
            "max_error",
        ),
        (
            "[output]\ncache = \"pca\"\nmax_error = 0.0\n[[body]]\nsource = \"cube.obj\"\n",
            "max_error",
        ),
        (
            "[output]\npath = \"out.xyz\"\n[[body]]\nsource = \"cube.obj\"\n",
            "out.xyz",
        ),
        ("not toml at all [[[", "line"),
        ("\u{0}\u{1}\u{2}", "key with no value"),
    ]
    .into_iter()
    .enumerate()
    {
        let name = format!("raw{i}.toml");
        std::fs::write(dir.join(&name), text).unwrap();
        cases.push(case(&name, &["bake", &name], key));
    }
}

fn argument_cases(cases: &mut Vec<Case>, dir: &Path) {
    std::fs::create_dir_all(dir.join("folder.obj")).unwrap();
    let c = |a: &[&str], n: &str| case(a.join(" "), a, n);
    cases.extend([
        c(&["bake", "cube.obj", "--frames", "0"], "frames"),
        c(
            &["bake", "cube.obj", "--frames", "18446744073709551615"],
            "frames",
        ),
        c(&["bake", "cube.obj", "--fps", "-1"], "-1"),
        c(&["bake", "cube.obj", "--fps=-1"], "fps"),
        c(&["bake", "cube.obj", "--fps", "nan"], "fps"),
        c(&["bake", "cube.obj", "--cells", "0"], "cells"),
        c(
            &["bake", "cube.obj", "--material", "unobtainium"],
            "unobtainium",
        ),
        c(&["bake", "cube.obj", "-o", "out.xyz"], "out.xyz"),
        c(&["bake", "nothing.obj"], "nothing.obj"),
        c(&["bake", "folder.obj"], "folder.obj"),
        c(&["bake", "/dev/null"], "/dev/null"),
        c(&["bake", "/dev/zero", "-o", "x.glb"], "/dev/zero"),
        c(&["inspect", "nothing.glb"], "nothing.glb"),
        c(&["inspect", "cube.obj", "--cells", "0"], "cells"),
        c(&["bake"], "INPUT"),
        c(&["bake", "cube.obj", "--report", "."], "folder"),
    ]);
}

fn corpus_bad_cases(cases: &mut Vec<Case>, dir: &Path) {
    let bad = springbake_testkit::corpus_dir().join("bad");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&bad)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_none_or(|e| e != "bin"))
        .collect();
    names.sort();
    for path in names {
        if path.ends_with("negative_indices.obj") {
            continue; // valid: the manifest expects it to import
        }
        let name = path.file_name().unwrap().to_str().unwrap().to_owned();
        // Copied with the buffers it may name.
        for entry in std::fs::read_dir(&bad).unwrap() {
            let from = entry.unwrap().path();
            std::fs::copy(&from, dir.join(from.file_name().unwrap())).unwrap();
        }
        cases.push(case(
            format!("corpus bad/{name}"),
            &["bake", &name, "-o", "out.glb", "--frames", "2"],
            name.clone(),
        ));
    }
}

#[test]
fn every_malformed_input_is_a_clear_exit_2_in_bounded_time_and_memory() {
    let dir = tempfile::tempdir().unwrap();
    let mut cases = Vec::new();
    gltf_cases(&mut cases, dir.path());
    glb_cases(&mut cases, dir.path());
    obj_cases(&mut cases, dir.path());
    scene_cases(&mut cases, dir.path());
    argument_cases(&mut cases, dir.path());
    corpus_bad_cases(&mut cases, dir.path());
    assert!(cases.len() >= 200, "only {} cases", cases.len());
    let mut failures = Vec::new();
    let mut slowest = (Duration::ZERO, String::new());
    let mut largest = (0, String::new());
    for c in &cases {
        let o = run(&c.args, dir.path());
        let mut why = Vec::new();
        if o.code != Some(2) {
            why.push(format!("exit {:?}", o.code));
        }
        if o.stderr.contains("panicked") || o.stderr.contains("internal error") {
            why.push("panic".into());
        }
        if !o.stderr.contains(&c.needle) {
            why.push(format!("message lacks \"{}\"", c.needle));
        }
        if o.elapsed > PER_CASE {
            why.push(format!("took {:?}", o.elapsed));
        }
        if o.max_rss_kb > MAX_RSS_KB {
            why.push(format!("peak {} MB", o.max_rss_kb >> 10));
        }
        if o.elapsed > slowest.0 {
            slowest = (o.elapsed, c.name.clone());
        }
        if o.max_rss_kb > largest.0 {
            largest = (o.max_rss_kb, c.name.clone());
        }
        if !why.is_empty() {
            failures.push(format!(
                "{}: {}\n    {}",
                c.name,
                why.join(", "),
                o.stderr.trim()
            ));
        }
    }
    eprintln!(
        "{} malformed cases; slowest {:?} ({}), largest {} MB ({})",
        cases.len(),
        slowest.0,
        slowest.1,
        largest.0 >> 10,
        largest.1
    );
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
