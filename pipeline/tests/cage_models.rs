//! Analysis models, particles, joints and regions from scene files (issue 7): a mesh baked in
//! an icosahedron cage moves with it, explicit node/spring errors name the field, a particle
//! falls as x0 + v0 t − ½ g t² without changing shape, a two-link articulated body pulled at
//! one end drags the other link, and a heavy-bottom region adds mass low down.
#![allow(clippy::unwrap_used)]

use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::scene::CacheSpec;
use springbake_core::shapes::{box_mesh, uv_sphere};
use springbake_pipeline::{
    default_registry, export, load_scene, prepare, write_outputs, BakeHooks, Prepared, Seconds,
};
use std::path::Path;

fn write_obj(path: &Path, points: &[Point3<f64>], triangles: &[[u32; 3]]) {
    let mut obj = String::from("o Mesh\n");
    for p in points {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in triangles {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, obj).unwrap();
}

fn load_and_prepare(
    dir: &Path,
    scene: &str,
) -> Result<(Prepared, springbake_core::scene::SceneFile), String> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let loaded = load_scene(&path).map_err(|e| e.to_string())?;
    let prepared = prepare(&default_registry(), &loaded, &mut Seconds::default())
        .map_err(|e| e.to_string())?;
    Ok((prepared, loaded.scene))
}

fn bake(dir: &Path, scene: &str) -> (Prepared, springbake_core::bake::BakedScene) {
    let (mut prepared, scene) = load_and_prepare(dir, scene).unwrap();
    let (baked, diagnostics) = prepared
        .simulate(&scene, &mut BakeHooks::default())
        .unwrap();
    assert!(diagnostics.iter().all(|d| d.max_speed.is_finite()));
    (prepared, baked)
}

#[test]
fn a_mesh_baked_in_an_icosahedron_moves_with_its_cage() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = uv_sphere([0.0, 0.3, 0.0], 0.15, 8, 16);
    write_obj(&dir.path().join("ball.obj"), &p, &t);
    let scene = "[output]\npath = \"out.glb\"\nframes = 24\ncache = \"skin\"\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"ball.obj\"\nmodel = \"icosahedron\"\nmaterial = \"soft_rubber\"\n";
    let (prepared, baked) = bake(dir.path(), scene);
    let report = &prepared.body_reports()[0];
    assert_eq!((report.nodes, report.springs, report.cells), (13, 42, 20));
    assert_eq!(
        (report.model.as_str(), report.model_note.as_deref()),
        ("icosahedron", None)
    );
    let m = &baked.meshes[0];
    let skin = m.lattice.as_ref().unwrap();
    assert_eq!(skin.rest.len(), 13);
    assert_eq!(skin.frames.len(), 24);
    for (w, n) in skin.vertex_weights.iter().zip(&skin.vertex_nodes) {
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!(
            w.iter().all(|x| *x >= -1e-6),
            "a vertex outside the cage: {w:?}"
        );
        assert!(n.iter().all(|&i| (i as usize) < 13));
    }
    for (f, (verts, nodes)) in m.frames.iter().zip(&skin.frames).enumerate() {
        // Each baked vertex is its weights applied to the cage nodes of the same frame …
        for (i, v) in verts.iter().enumerate() {
            let mut q = [0.0f32; 3];
            for c in 0..8 {
                let node = nodes[skin.vertex_nodes[i][c] as usize];
                for a in 0..3 {
                    q[a] += skin.vertex_weights[i][c] * node[a];
                }
            }
            for a in 0..3 {
                assert!((q[a] - v[a]).abs() < 1e-5, "frame {f} vertex {i}");
            }
        }
        // … so it stays inside the cage's box.
        let (lo, hi) = nodes
            .iter()
            .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), n| {
                (
                    [lo[0].min(n[0]), lo[1].min(n[1]), lo[2].min(n[2])],
                    [hi[0].max(n[0]), hi[1].max(n[1]), hi[2].max(n[2])],
                )
            });
        for v in verts {
            assert!((0..3).all(|a| v[a] >= lo[a] - 1e-5 && v[a] <= hi[a] + 1e-5));
        }
    }
    // It fell 0.15 m onto the floor and its mesh (not the cage) rests on it.
    let lowest = |f: &Vec<[f32; 3]>| f.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
    assert!((lowest(&m.frames[0]) - 0.15).abs() < 1e-5);
    let (f, touch) = m
        .frames
        .iter()
        .map(lowest)
        .enumerate()
        .fold((0, f32::MAX), |b, (i, y)| if y < b.1 { (i, y) } else { b });
    assert!(
        touch > -0.02 && touch < 0.005,
        "mesh bottom reached {touch}"
    );
    let cage_bottom = skin.frames[f].iter().map(|n| n[1]).fold(f32::MAX, f32::min);
    assert!(
        cage_bottom < -0.01,
        "the cage stands off the mesh: {cage_bottom}"
    );
    // The skin cache (cage nodes as joints, 4 of 8 weights used) is valid glTF.
    let out = dir.path().join("out.glb");
    let files = export(
        &default_registry(),
        &prepared,
        &baked,
        &out,
        CacheSpec::Skin,
    )
    .unwrap();
    write_outputs(&files, &[]).unwrap();
    springbake_testkit::assert_gltf_valid(&out);
}

#[test]
fn explicit_models_bake_and_their_errors_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = box_mesh([-0.1, 0.5, -0.1], [0.1, 0.7, 0.1]);
    write_obj(&dir.path().join("cube.obj"), &p, &t);
    let head = "[output]\npath = \"out.glb\"\nframes = 12\n[world]\nfloor = 0.0\n\
                [[body]]\nsource = \"cube.obj\"\nmodel = \"explicit\"\n";
    let nodes = "nodes = [[-0.2, 0.4, -0.2], [0.2, 0.4, -0.2], [-0.2, 0.4, 0.2], [0.2, 0.4, 0.2], \
                 [0.0, 0.9, 0.0], [0.0, 0.6, 0.0]]\n";
    let springs = "springs = [[0, 1], [1, 3], [3, 2], [2, 0], [0, 3], [0, 4], [1, 4], [2, 4], \
                   [3, 4], [5, 0], [5, 1], [5, 2], [5, 3], [5, 4]]\n";
    // Parse errors: the entry is named, with its line.
    for (bad, field) in [
        ("springs = [[0, 1], [2]]\n", "springs[1]"),
        ("springs = [[0, 1], [2, -1]]\n", "springs[1]"),
        ("springs = \"diagonal\"\n", "springs: unknown layout"),
    ] {
        let e = load_and_prepare(dir.path(), &format!("{head}{nodes}{bad}")).unwrap_err();
        assert!(e.contains(field) && e.contains("line 10"), "{e}");
    }
    let e = load_and_prepare(
        dir.path(),
        &format!("{head}nodes = [[0, 0, 0], [1, 2]]\n{springs}"),
    )
    .unwrap_err();
    assert!(e.contains("nodes[1]") && e.contains("line 9"), "{e}");
    // Model errors: the field and the body.
    for (text, field) in [
        (
            format!("{head}{nodes}springs = [[0, 1], [1, 9]]\n"),
            "springs[1]: node 9 out of range",
        ),
        (
            format!("{head}{nodes}"),
            "springs: model = \"explicit\" needs",
        ),
        (
            format!("{head}{springs}"),
            "nodes: model = \"explicit\" needs",
        ),
        (
            format!("{head}{nodes}springs = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]]\n"),
            "nodes[4]: has no spring",
        ),
        (
            head.replace("explicit", "box") + nodes,
            "nodes: only for model = \"explicit\"",
        ),
        (
            head.replace("explicit", "icosahedron") + "cells = 8\n",
            "cells: only for model = \"lattice\" or \"plane\"",
        ),
        (
            head.replace("explicit", "box") + "cell_size = 0.1\n",
            "cell_size: only for model = \"lattice\"",
        ),
    ] {
        let e = load_and_prepare(dir.path(), &text).unwrap_err();
        assert!(e.contains(field) && e.contains("body 0"), "{e}");
    }
    // The good model bakes: the cube drops with its 6 nodes.
    let (prepared, baked) = bake(dir.path(), &format!("{head}{nodes}{springs}"));
    assert_eq!(prepared.body_reports()[0].nodes, 6);
    let first = &baked.meshes[0].frames[0];
    let last = baked.meshes[0].frames.last().unwrap();
    assert!((first[0][1] - 0.5).abs() < 1e-6);
    assert!(last[0][1] < 0.45, "fell: {}", last[0][1]);
}

#[test]
fn a_particle_falls_exactly_and_keeps_its_shape() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = box_mesh([0.0, 1.0, 0.0], [0.3, 1.1, 0.1]);
    write_obj(&dir.path().join("bar.obj"), &p, &t);
    let scene = "[output]\npath = \"out.glb\"\nframes = 10\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"bar.obj\"\nkind = \"particle\"\nvelocity = [0.5, 1.0, 0.0]\n";
    let (_, baked) = bake(dir.path(), scene);
    let frames = &baked.meshes[0].frames;
    let (g, v0) = (9.81, Vector3::new(0.5, 1.0, 0.0));
    for (f, verts) in frames.iter().enumerate() {
        let t = f as f64 / 24.0;
        let shift = v0 * t - Vector3::new(0.0, 0.5 * g * t * t, 0.0);
        for (v, q) in verts.iter().zip(&frames[0]) {
            for a in 0..3 {
                let moved = v[a] as f64 - q[a] as f64;
                assert!(
                    (moved - shift[a]).abs() < 2e-6,
                    "frame {f}: {moved} vs {shift}"
                );
            }
        }
    }
}

#[test]
fn two_linked_bars_pulled_at_one_end_drag_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = box_mesh([0.0, 1.0, 0.0], [0.4, 1.1, 0.1]);
    write_obj(&dir.path().join("upper.obj"), &p, &t);
    let (p, t) = box_mesh([0.4, 1.0, 0.0], [0.8, 1.1, 0.1]);
    write_obj(&dir.path().join("lower.obj"), &p, &t);
    let scene = "[output]\npath = \"out.glb\"\nframes = 36\n[world]\ngravity = 0.0\n\
                 [[body]]\nsource = \"upper.obj\"\nname = \"upper\"\ncells = 8\nmaterial = \"soft_rubber\"\n\
                 [[body]]\nsource = \"lower.obj\"\nname = \"lower\"\ncells = 8\nmaterial = \"soft_rubber\"\n\
                 [[joint]]\nbodies = [\"upper\", \"lower\"]\nat = [0.4, 1.05, 0.05]\n\
                 [[constraint]]\nbody = \"upper\"\nbox = { min = [-0.01, 0.9, -0.1], max = [0.01, 1.2, 0.2] }\n\
                 keys = [ { t = 0.0, position = [0.0, 1.0, 0.0] }, { t = 1.0, position = [-0.3, 1.0, 0.0] } ]\n";
    let (prepared, baked) = bake(dir.path(), scene);
    let w = &prepared.world;
    assert_eq!(w.joints.len(), 1);
    let j = w.joints[0];
    assert_eq!(w.nodes.position[j.kept], w.nodes.position[j.follower]);
    assert!(
        (w.nodes.position[j.kept] - Vector3::new(0.4, 1.05, 0.05)).norm() > 0.2,
        "it moved"
    );
    let centre_x = |f: &Vec<[f32; 3]>| f.iter().map(|v| v[0] as f64).sum::<f64>() / f.len() as f64;
    let lower = &baked.meshes[1].frames;
    let moved = centre_x(lower.last().unwrap()) - centre_x(&lower[0]);
    // The pull is 0.3 m by t = 1 s; 35 frames = 1.46 s.
    assert!(
        moved < -0.2 && moved > -0.4,
        "the lower link's centre moved {moved} m"
    );
    let upper = &baked.meshes[0].frames;
    let pulled = centre_x(upper.last().unwrap()) - centre_x(&upper[0]);
    assert!(pulled < -0.2, "the upper link moved {pulled}");
    // The joint error names the missing body.
    let bad = scene.replace(
        "bodies = [\"upper\", \"lower\"]",
        "bodies = [\"upper\", \"lowr\"]",
    );
    let e = load_and_prepare(dir.path(), &bad).unwrap_err();
    assert!(
        e.contains("joint[0]: bodies: no body named \"lowr\""),
        "{e}"
    );
    // A joint point away from the bodies is refused (it would tie two far nodes together).
    let far = scene.replace("at = [0.4, 1.05, 0.05]", "at = [0.4, 2.0, 0.05]");
    let e = load_and_prepare(dir.path(), &far).unwrap_err();
    assert!(
        e.contains("joint[0]") && e.contains("farther than") && e.contains("\"upper\""),
        "{e}"
    );
}

#[test]
fn a_heavy_bottom_region_adds_mass_low_down() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = box_mesh([0.0, 0.0, 0.0], [0.3, 0.3, 0.3]);
    write_obj(&dir.path().join("cube.obj"), &p, &t);
    let head =
        "[output]\npath = \"out.glb\"\nframes = 2\n[[body]]\nsource = \"cube.obj\"\ncells = 3\n";
    let region =
        "[[body.region]]\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 0.04, 1.0]\nmass_scale = 3.0\n";
    let com = |pr: &Prepared| {
        let n = &pr.world.nodes;
        let m: f64 = n.mass.iter().sum();
        (
            m,
            (0..n.len())
                .map(|i| n.position[i].y * n.mass[i])
                .sum::<f64>()
                / m,
        )
    };
    let (plain, _) = load_and_prepare(dir.path(), head).unwrap();
    let (heavy, _) = load_and_prepare(dir.path(), &format!("{head}{region}")).unwrap();
    let ((m0, y0), (m1, y1)) = (com(&plain), com(&heavy));
    // The bottom layer holds 1/6 of the mass (4.5 of 27 cells' corners): ×3 adds 2/6.
    assert!((m1 / m0 - 4.0 / 3.0).abs() < 1e-12, "{m1} vs {m0}");
    assert!((y1 - y0 * m0 / m1).abs() < 1e-12 && y1 < y0);
    assert!((heavy.body_reports()[0].mass_kg - m1).abs() < 1e-12);
    let e = load_and_prepare(
        dir.path(),
        &format!(
            "{head}{}",
            region.replace("mass_scale = 3.0", "mass_scale = -1.0")
        ),
    )
    .unwrap_err();
    assert!(
        e.contains("region[0]: mass_scale must be finite and positive"),
        "{e}"
    );
}

#[test]
fn a_flag_in_a_plane_cage_waves_from_its_pole() {
    // A 1 m × 0.6 m flag (10 × 6 quads, x–y plane) in a plane cage of 8 cells, its pole edge
    // (x = 0) pinned, in gravity and a gusting wind along +z, for 2 s.
    let dir = tempfile::tempdir().unwrap();
    let (nx, ny) = (10u32, 6u32);
    let mut p = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            p.push(Point3::new(i as f64 * 0.1, 1.0 + j as f64 * 0.1, 0.0));
        }
    }
    let mut t = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let a = j * (nx + 1) + i;
            t.push([a, a + 1, a + nx + 2]);
            t.push([a, a + nx + 2, a + nx + 1]);
        }
    }
    write_obj(&dir.path().join("flag.obj"), &p, &t);
    let scene = "[output]\npath = \"out.glb\"\nframes = 48\ncache = \"skin\"\n\
                 [world]\nwind = { velocity = [0.0, 0.0, 4.0], gust = [0.0, 0.0, 2.0], gust_hz = 1.5 }\n\
                 [[body]]\nsource = \"flag.obj\"\nname = \"flag\"\nmodel = \"plane\"\ncells = 8\nmaterial = \"soft_rubber\"\n\
                 [[constraint]]\nbody = \"flag\"\nbox = { min = [-0.01, 0.0, -1.0], max = [0.01, 2.0, 1.0] }\n";
    let (prepared, baked) = bake(dir.path(), scene);
    // 9 × 6 nodes per sheet (8 cells along x, 5 along y), two sheets; the pole's 12 pinned.
    assert_eq!(prepared.body_reports()[0].nodes, 108);
    assert_eq!(prepared.world.constraints[0].nodes.len(), 12);
    let frames = &baked.meshes[0].frames;
    let (first, last) = (&frames[0], frames.last().unwrap());
    // Every spring of the cage within 2× its rest length in every frame.
    let cage = &prepared.bodies[0].lattice;
    let mut longest: f64 = 0.0;
    for nodes in &baked.meshes[0].lattice.as_ref().unwrap().frames {
        for s in &cage.springs {
            let (a, b) = (nodes[s.a as usize], nodes[s.b as usize]);
            let l = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            longest = longest.max(l as f64 / s.rest_length);
        }
    }
    assert!(longest < 2.0, "a spring at {longest} × its rest length");
    for (v, q) in last.iter().zip(first) {
        if q[0] < 0.01 {
            for a in 0..3 {
                assert!(
                    (v[a] - q[a]).abs() < 1e-5,
                    "the pole edge moved: {v:?} vs {q:?}"
                );
            }
        }
    }
    // The free edge blows downwind and sags.
    let tip: Vec<&[f32; 3]> = last
        .iter()
        .zip(first)
        .filter(|(_, q)| q[0] > 0.85)
        .map(|(v, _)| v)
        .collect();
    assert_eq!(tip.len(), 14, "the two last columns of vertices");
    let z = tip.iter().map(|v| v[2] as f64).sum::<f64>() / tip.len() as f64;
    println!("flag: longest spring {longest:.3} × rest, tip z {z:.3} m");
    assert!(z > 0.3, "the tip blew {z} m downwind");
    assert!(frames
        .iter()
        .all(|f| f.iter().all(|v| v.iter().all(|x| x.is_finite()))));
}

#[test]
fn a_decimated_cage_bakes_a_falling_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = uv_sphere([0.0, 0.5, 0.0], 0.2, 12, 24);
    write_obj(&dir.path().join("ball.obj"), &p, &t);
    let scene = "[output]\npath = \"out.glb\"\nframes = 12\n[world]\nfloor = 0.0\n\
                 [[body]]\nsource = \"ball.obj\"\nmodel = \"decimated\"\ncage_vertices = 24\nmaterial = \"rubber\"\n";
    let (prepared, baked) = bake(dir.path(), scene);
    let nodes = prepared.body_reports()[0].nodes;
    assert!(
        (10..=25).contains(&nodes),
        "{nodes} nodes for cage_vertices = 24"
    );
    let f = &baked.meshes[0].frames;
    let lowest = |f: &Vec<[f32; 3]>| f.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
    // 11 frames at 24 fps: ½ g t² = 1.03 m of fall, so it reached the floor (0.3 m below).
    assert!((lowest(&f[0]) - 0.3).abs() < 1e-5);
    let touch = f.iter().map(lowest).fold(f32::MAX, f32::min);
    assert!(touch < 0.01 && touch > -0.05, "{touch}");
    let e = load_and_prepare(
        dir.path(),
        &scene.replace("cage_vertices = 24", "cage_vertices = 3"),
    )
    .unwrap_err();
    assert!(e.contains("cage_vertices: must be at least 4"), "{e}");
}

#[test]
fn a_lattice_body_weighs_its_mesh_not_its_cells() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = uv_sphere([0.0, 0.0, 0.0], 0.5, 16, 32);
    write_obj(&dir.path().join("ball.obj"), &p, &t);
    let enclosed = springbake_core::cage::mesh_volume(&p, &t);
    let head = "[output]\npath = \"out.glb\"\nframes = 2\n[[body]]\nsource = \"ball.obj\"\ncells = 8\nmaterial = \"rubber\"\n";
    let mass = |pr: &Prepared| pr.world.nodes.mass.iter().sum::<f64>();
    let (xpbd, _) = load_and_prepare(dir.path(), head).unwrap();
    let ratio = mass(&xpbd) / (1100.0 * enclosed);
    assert!((ratio - 1.0).abs() < 1e-5, "{ratio}");
    assert!((xpbd.body_reports()[0].mass_kg - mass(&xpbd)).abs() < 1e-9);
    // The papers' spring lattice keeps its whole cells.
    let papers = format!("{head}[solver]\nintegrator = \"symplectic_euler\"\n");
    let (springs, _) = load_and_prepare(dir.path(), &papers).unwrap();
    let cells = springs.body_reports()[0].cells as f64;
    let h = springs.body_reports()[0].cell_size;
    assert!((mass(&springs) / (1100.0 * cells * h.powi(3)) - 1.0).abs() < 1e-9);
    assert!(mass(&springs) > 1.25 * mass(&xpbd));
}
