//! `render_screenshot` end to end: a scene with a falling cube renders to a PNG of the asked
//! size, the object's pixels differ from the background (and from the floor) and the corners
//! do not, the cube moves down the picture as it falls, and a baked glb's frame N (morph
//! weights applied) matches the simulation's frame N. Also the live-reload watcher and the argument errors.

#![allow(clippy::unwrap_used)]

use springbake_viewer::raster::{DrawMesh, BACKGROUND};
use springbake_viewer::source::ViewSource;
use springbake_viewer::{render_screenshot, Overlays, ScreenshotArgs, ViewerError};
use std::path::Path;

const CUBE_OBJ: &str = "o Cube
v -0.25 -0.25 -0.25
v  0.25 -0.25 -0.25
v -0.25  0.25 -0.25
v  0.25  0.25 -0.25
v -0.25 -0.25  0.25
v  0.25 -0.25  0.25
v -0.25  0.25  0.25
v  0.25  0.25  0.25
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
f 3 7 8 4
f 1 5 7 3
f 2 4 8 6
";

/// A 0.5 m rubber cube whose bottom is 0.55 m above the floor, 6 cells, no manipulator.
fn write_scene(dir: &Path, output: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("cube.obj"), CUBE_OBJ).unwrap();
    let scene = format!(
        "[output]\npath = \"{output}\"\nfps = 24\nframes = 12\n\n[world]\nfloor = 0.0\n\n\
         [[body]]\nsource = \"cube.obj\"\ncells = 6\nmaterial = \"rubber\"\noffset = [0.0, 0.8, 0.0]\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    path
}

struct Decoded {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

impl Decoded {
    fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = ((y * self.width + x) * 4) as usize;
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Pixels of the (orange) body, not the background nor the grey-blue floor: count and
    /// mean row.
    fn object(&self) -> (usize, f64) {
        let (mut n, mut rows) = (0usize, 0.0);
        for y in 0..self.height {
            for x in 0..self.width {
                let p = self.pixel(x, y);
                if p[0] as i32 > p[2] as i32 + 30 {
                    n += 1;
                    rows += y as f64;
                }
            }
        }
        (n, if n > 0 { rows / n as f64 } else { f64::NAN })
    }
}

fn decode(path: &Path) -> Decoded {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    buf.truncate(info.buffer_size());
    Decoded {
        width: info.width,
        height: info.height,
        rgba: buf,
    }
}

fn shot(input: &Path, output: &Path, frame: usize) -> Decoded {
    let args = ScreenshotArgs {
        input: input.to_path_buf(),
        frame,
        output: output.to_path_buf(),
        width: 160,
        height: 120,
        // One camera for every frame, so the motion shows as motion in the picture.
        frame_all: true,
        camera: None,
        overlays: Default::default(),
    };
    render_screenshot(&args).unwrap();
    decode(output)
}

#[test]
fn scene_screenshot_has_the_object_on_a_clean_background_and_falls() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    let first = shot(&scene, &dir.path().join("shots/f1.png"), 1);
    assert_eq!((first.width, first.height), (160, 120));
    let bg = [BACKGROUND[0], BACKGROUND[1], BACKGROUND[2], 255];
    for (x, y) in [(0, 0), (159, 0), (0, 119), (159, 119)] {
        assert_eq!(first.pixel(x, y), bg, "corner ({x}, {y}) is background");
    }
    let centre = first.pixel(80, 60);
    assert_ne!(centre, bg, "the cube is in the middle of the frame");
    assert!(
        centre[0] as i32 > centre[2] as i32 + 30,
        "body colour: {centre:?}"
    );
    let (n1, row1) = first.object();
    // The framing puts the bounding sphere in 1/1.2 of the height: the cube covers a real area,
    // but not the whole picture.
    assert!(n1 > 1500 && n1 < 160 * 120 / 2, "object pixels: {n1}");
    // The view frames the cube and the floor it falls to, so at frame 1 the cube sits in the
    // upper half of the picture.
    assert!(
        row1 > 10.0 && row1 < 60.0,
        "in the upper half: mean row {row1}"
    );

    // Frame 8 (t = 0.29 s): free fall of about 0.41 m, not yet on the floor (0.55 m below).
    let falling = shot(&scene, &dir.path().join("f8.png"), 8);
    let (n8, row8) = falling.object();
    assert!(n8 > 1000, "still visible: {n8}");
    assert!(
        row8 > row1 + 15.0,
        "the cube moved down the picture: row {row1:.1} -> {row8:.1}"
    );
    for (x, y) in [(0, 0), (159, 0), (0, 119), (159, 119)] {
        assert_eq!(falling.pixel(x, y), bg);
    }
    // Deterministic: the same frame renders the same bytes.
    let again = shot(&scene, &dir.path().join("f8b.png"), 8);
    assert_eq!(again.rgba, falling.rgba);
}

#[test]
fn baked_glb_frames_play_back_their_morph_weights() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    let registry = springbake_pipeline::default_registry();
    let loaded = springbake_pipeline::load_scene(&scene).unwrap();
    springbake_pipeline::bake(&registry, &loaded, &mut Default::default()).unwrap();
    let glb = dir.path().join("baked.glb");

    // The baked file's frame N (morph weights applied) is the simulation's frame N: compare
    // the vertex bounds and centroid (f32 deltas against f64 positions).
    let mut sim = ViewSource::open(&registry, &scene).unwrap();
    let mut baked = ViewSource::open(&registry, &glb).unwrap();
    assert!(
        matches!(baked, ViewSource::Baked(_)),
        "a glb with morph targets plays back"
    );
    assert_eq!(baked.frame_count(), 12);
    assert!(
        (baked.fps() - 24.0).abs() < 1e-9,
        "fps from the key times: {}",
        baked.fps()
    );
    let summary = |meshes: Vec<DrawMesh>| {
        let points: Vec<_> = meshes
            .iter()
            .flat_map(|m| m.positions.iter().copied())
            .collect();
        let (lo, hi) = springbake_viewer::raster::bounds_of(points.iter()).unwrap();
        let centroid = points
            .iter()
            .sum::<springbake_core::nalgebra::Vector3<f64>>()
            / points.len() as f64;
        (lo, hi, centroid)
    };
    let start = summary(baked.meshes_at(1).unwrap());
    for frame in [1, 8, 12] {
        let (slo, shi, sc) = summary(sim.meshes_at(frame).unwrap());
        let (blo, bhi, bc) = summary(baked.meshes_at(frame).unwrap());
        for (s, b) in [(slo, blo), (shi, bhi), (sc, bc)] {
            assert!(
                (s - b).norm() < 1e-4,
                "frame {frame}: simulated {s:?} vs baked {b:?}"
            );
        }
    }
    let fallen = summary(baked.meshes_at(8).unwrap());
    assert!(
        start.2.y - fallen.2.y > 0.3,
        "the baked cube falls: {:?} -> {:?}",
        start.2,
        fallen.2
    );

    // And through the screenshot path: frames 1 and 8 differ, asking past the end is an error.
    let rest = shot(&glb, &dir.path().join("baked1.png"), 1);
    let later = shot(&glb, &dir.path().join("baked8.png"), 8);
    let differing = rest
        .rgba
        .chunks(4)
        .zip(later.rgba.chunks(4))
        .filter(|(p, q)| p != q)
        .count();
    assert!(differing > 500, "frame 1 and frame 8 differ: {differing}");
    let err = render_screenshot(&ScreenshotArgs {
        frame: 13,
        ..ScreenshotArgs::new(&glb, dir.path().join("x.png"))
    })
    .unwrap_err();
    assert!(
        err.is_user_error() && err.to_string().contains("the file has 12 frames"),
        "{err}"
    );
}

#[test]
fn bad_arguments_are_user_errors_that_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    let out = dir.path().join("never.png");
    let cases = [
        ScreenshotArgs {
            input: dir.path().join("missing.toml"),
            ..ScreenshotArgs::new(&scene, &out)
        },
        ScreenshotArgs {
            frame: 0,
            ..ScreenshotArgs::new(&scene, &out)
        },
        ScreenshotArgs {
            width: 0,
            ..ScreenshotArgs::new(&scene, &out)
        },
        ScreenshotArgs {
            height: 100_000,
            ..ScreenshotArgs::new(&scene, &out)
        },
    ];
    for args in cases {
        let err = render_screenshot(&args).unwrap_err();
        assert!(
            matches!(err, ViewerError::Usage(_)) && err.is_user_error(),
            "{err}"
        );
    }
    std::fs::write(dir.path().join("broken.toml"), "[output]\nfps = \"fast\"\n").unwrap();
    let err =
        render_screenshot(&ScreenshotArgs::new(dir.path().join("broken.toml"), &out)).unwrap_err();
    assert!(
        err.is_user_error() && err.to_string().contains("broken.toml"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn reloader_signals_when_a_watched_source_changes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    let watched = springbake_viewer::reload::watched_inputs(&scene);
    assert_eq!(watched.len(), 2, "{watched:?}");
    assert!(watched.iter().any(|p| p.ends_with("cube.obj")));
    let reloader = springbake_viewer::reload::Reloader::start(&scene, Box::new(|| {}));
    // No run at start.
    std::thread::sleep(std::time::Duration::from_millis(700));
    assert!(!reloader.changed());
    std::fs::write(dir.path().join("cube.obj"), CUBE_OBJ.replace("0.25", "0.3")).unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while !reloader.changed() {
        assert!(
            std::time::Instant::now() < deadline,
            "no reload signal within 10 s of editing the source"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// The compact cache (`cache = "pca"`) moves its node with translation and rotation keys:
/// the viewer plays them, so each frame sits where the morph cache's does (within the
/// cache's 1 mm bound).
#[test]
fn a_pca_cache_plays_its_rigid_keys_as_the_morph_cache_does() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "morph.glb");
    let registry = springbake_pipeline::default_registry();
    let mut loaded = springbake_pipeline::load_scene(&scene).unwrap();
    springbake_pipeline::bake(&registry, &loaded, &mut Default::default()).unwrap();
    let text = std::fs::read_to_string(&scene)
        .unwrap()
        .replace("morph.glb\"", "pca.glb\"\ncache = \"pca\"");
    std::fs::write(&scene, text).unwrap();
    loaded = springbake_pipeline::load_scene(&scene).unwrap();
    springbake_pipeline::bake(&registry, &loaded, &mut Default::default()).unwrap();
    let doc: serde_json::Value = {
        let bytes = std::fs::read(dir.path().join("pca.glb")).unwrap();
        let n = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        serde_json::from_slice(&bytes[20..20 + n]).unwrap()
    };
    let channels = doc["animations"][0]["channels"].as_array().unwrap();
    assert!(
        channels
            .iter()
            .any(|c| c["target"]["path"] == "translation"),
        "the pca cache has rigid keys: {channels:?}"
    );
    let mut morph = ViewSource::open(&registry, &dir.path().join("morph.glb")).unwrap();
    let mut pca = ViewSource::open(&registry, &dir.path().join("pca.glb")).unwrap();
    for frame in [1, 6, 12] {
        let (a, b) = (
            morph.meshes_at(frame).unwrap(),
            pca.meshes_at(frame).unwrap(),
        );
        let worst = a[0]
            .positions
            .iter()
            .zip(&b[0].positions)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1.1e-3, "frame {frame}: {worst} m apart");
    }
}

/// A simulated body is drawn in its material's base colour (issue 21: "the mesh's own base
/// colour"): the cube with a blue `.mtl` material renders blue where the plain one renders
/// springbake's orange.
#[test]
fn a_simulated_body_takes_its_materials_colour() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    let obj = format!("mtllib cube.mtl\nusemtl Blue\n{CUBE_OBJ}");
    std::fs::write(dir.path().join("cube.obj"), obj).unwrap();
    std::fs::write(
        dir.path().join("cube.mtl"),
        "newmtl Blue\nKd 0.05 0.1 0.8\n",
    )
    .unwrap();
    let blue = shot(&scene, &dir.path().join("blue.png"), 1);
    let centre = blue.pixel(80, 60);
    assert!(
        centre[2] as i32 > centre[0] as i32 + 60,
        "blue body: {centre:?}"
    );
    assert_eq!(blue.object().0, 0, "no orange body pixels");
}

/// `--overlay lattice,contacts` (issue 21 item 1's overlays): the lattice's springs in green
/// over the body, and yellow markers where the floor holds the cube once it has landed, none
/// while it is in the air; without overlays, neither colour.
#[test]
fn overlays_draw_the_lattice_and_the_contacts() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "baked.glb");
    // 24 frames: the cube lands near frame 10 and bounces (rubber).
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&scene, text.replace("frames = 12", "frames = 24")).unwrap();
    let render = |frame: usize, lattice: bool, contacts: bool| {
        let out = dir.path().join(format!("o{frame}{lattice}{contacts}.png"));
        let args = ScreenshotArgs {
            frame,
            width: 320,
            height: 240,
            overlays: Overlays { lattice, contacts },
            ..ScreenshotArgs::new(&scene, &out)
        };
        render_screenshot(&args).unwrap();
        let image = decode(&out);
        let count = |test: &dyn Fn([u8; 4]) -> bool| {
            image
                .rgba
                .chunks_exact(4)
                .filter(|p| test([p[0], p[1], p[2], p[3]]))
                .count()
        };
        let green = count(&|p| p[1] as i32 > p[0] as i32 + 50 && p[1] as i32 > p[2] as i32 + 30);
        let yellow = count(&|p| p[0] > 200 && p[1] > 150 && p[2] < 120);
        (green, yellow)
    };
    let (green, _) = render(1, true, false);
    assert!(green > 300, "lattice pixels: {green}");
    let (_, airborne) = render(1, false, true);
    assert_eq!(airborne, 0, "no contact in the air");
    let landed: Vec<usize> = (8..=24).map(|f| render(f, false, true).1).collect();
    assert!(
        landed.iter().any(|&n| n > 20),
        "contact markers once landed, frames 8 to 24: {landed:?}"
    );
    assert_eq!(render(12, false, false), (0, 0), "no overlay asked for");
}
