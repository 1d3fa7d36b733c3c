//! Glued assemblies: parts that interpenetrate at the start are glued (`xpbd::glue`), and the
//! parts glued to each other, directly or through others, form one assembly. Found on
//! trimesh's `boolean.glb` (a block and 27 cutters, most sunk into it or each other, some
//! face to face): a contact between two parts of one assembly pushed against the glue that
//! held them, and the parting of an assembly from a part it rested on shifted its parts one
//! by one against their glue; without gravity it gained 4 kJ in its first frame. Parts that
//! fit into each other (a peg in a hole of its own size: trimesh's `pins.glb`, dowels in a
//! board) are welded where they touch.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::material::Material;
use springbake_core::nalgebra::{Point3, Vector3};
use springbake_core::shapes::box_mesh;
use springbake_core::solver::{BodyHandle, FrameDiagnostics, Integrator, World, WorldSettings};
use support::{add_part, mesh};

const FRAME: f64 = 1.0 / 24.0;

fn frame(w: &mut World, f: usize) -> FrameDiagnostics {
    w.advance_frame(FRAME, f, &|| false).unwrap()
}

/// A rubber world without gravity or floor; parts of 0.5 m at 6 cells.
fn weightless_world(rubber: &Material) -> World {
    World::new(WorldSettings {
        gravity: Vector3::zeros(),
        layer: WorldSettings::default_layer(0.5 / 6.0, rubber, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    })
}

/// A rubber world without gravity holding a 0.5 m base with a post sunk 0.25 m into it, and
/// `third`, as parts `part0`, `part1`, `part2`.
fn post_in_base_and(third: ([f64; 3], [f64; 3])) -> (World, Vec<BodyHandle>) {
    let rubber = Material::preset("rubber").unwrap();
    let mut w = weightless_world(&rubber);
    let base = ([0.0, 0.0, 0.0], [0.5, 0.5, 0.5]);
    let post = ([0.15, 0.25, 0.15], [0.35, 0.9, 0.35]);
    let parts = add_boxes(&mut w, &rubber, &[base, post, third]);
    (w, parts)
}

/// Add boxes `[lo, hi]` as parts named after their index.
fn add_boxes(w: &mut World, rubber: &Material, boxes: &[([f64; 3], [f64; 3])]) -> Vec<BodyHandle> {
    boxes
        .iter()
        .enumerate()
        .map(|(i, &(lo, hi))| {
            let m = mesh(box_mesh(lo, hi), 6);
            add_part(w, &format!("part{i}"), &m, rubber)
        })
        .collect()
}

fn centre(w: &World, h: BodyHandle) -> Vector3<f64> {
    let xs = w.body_positions(h);
    xs.iter().sum::<Vector3<f64>>() / xs.len() as f64
}

/// A post sunk into a base and through a cap that lies face to face on the base: the post is
/// glued to both, and the cap touches the base. Nothing moves them, so nothing moves.
#[test]
fn parts_of_one_assembly_touching_at_the_start_stay_where_they_are() {
    // cap on the base, the post through it
    let (mut w, parts) = post_in_base_and(([0.0, 0.5, 0.0], [0.5, 0.7, 0.5]));
    let glued: Vec<_> = w.interpenetrating_parts();
    assert_eq!(glued.len(), 2, "{glued:?}");
    assert!(glued
        .iter()
        .all(|p| p.2 && (p.0 == "part1" || p.1 == "part1")));
    stays_still(&mut w, &parts);
}

/// Over 12 frames no node of `w` moves faster than 1 mm/s, the kinetic and elastic energy
/// stay under a millijoule (87 kg of rubber: a node at a few millimetres a second) and no
/// part's centre moves 0.1 mm.
fn stays_still(w: &mut World, parts: &[BodyHandle]) {
    let start: Vec<_> = parts.iter().map(|&h| centre(w, h)).collect();
    let (mut fastest, mut energy) = (0.0f64, 0.0f64);
    for f in 1..=12 {
        let d = frame(w, f);
        fastest = fastest.max(d.max_speed);
        energy = energy.max(d.kinetic_energy + d.elastic_energy);
        assert_eq!(d.energy_gain, Some(0.0), "frame {f}");
    }
    let moved = (parts.iter().zip(&start))
        .map(|(&h, s)| (centre(w, h) - s).norm())
        .fold(0.0, f64::max);
    assert!(fastest < 1e-3, "fastest node {fastest} m/s");
    assert!(energy < 1e-3, "{energy} J");
    assert!(moved < 1e-4, "a part moved {moved} m");
}

/// The same post and base (glued) lying face to face on a slab they are not glued to: they
/// part from it gently, the post staying in the base (shifted one by one, each glued part
/// was pulled back to the other with speed).
#[test]
fn an_assembly_parts_from_what_it_touches_as_one() {
    // slab under the base, touching it
    let (mut w, parts) = post_in_base_and(([-0.1, -0.3, -0.1], [0.6, 0.0, 0.6]));
    let glued = w.interpenetrating_parts();
    assert_eq!(glued, [("part0".into(), "part1".into(), true)]);
    let offset0 = centre(&w, parts[1]) - centre(&w, parts[0]);
    let (mut fastest, mut drift) = (0.0f64, 0.0f64);
    for f in 1..=24 {
        let d = frame(&mut w, f);
        fastest = fastest.max(d.max_speed);
        assert_eq!(d.energy_gain, Some(0.0), "frame {f}");
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        drift = drift.max((centre(&w, parts[1]) - centre(&w, parts[0]) - offset0).norm());
    }
    assert!(fastest < 0.25, "fastest node {fastest} m/s");
    assert!(drift < 2e-3, "the post moved {drift} m in the base");
    // They did part: the slab's top is below the base's bottom.
    let top = w
        .body_positions(parts[2])
        .iter()
        .map(|p| p.y)
        .fold(f64::MIN, f64::max);
    let bottom = w
        .body_positions(parts[0])
        .iter()
        .map(|p| p.y)
        .fold(f64::MAX, f64::min);
    assert!(bottom - top > 0.0, "gap {} m", bottom - top);
}

/// A closed square ring around the z axis: outer half-width `outer`, a square hole of
/// half-width `inner` through it, from z = 0 to `height`, wound outwards.
fn ring(outer: f64, inner: f64, height: f64) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut points = Vec::new();
    for half in [outer, inner] {
        for z in [0.0, height] {
            points.extend(
                corners
                    .iter()
                    .map(|&(x, y)| Point3::new(x * half, y * half, z)),
            );
        }
    }
    // Outer corner k at z index h is h * 4 + k; inner ones follow at 8.
    let (o, i) = (
        |k: usize, h: u32| h * 4 + (k % 4) as u32,
        |k: usize, h: u32| 8 + h * 4 + (k % 4) as u32,
    );
    let mut triangles = Vec::new();
    let mut quad = |a, b, c, d| triangles.extend([[a, b, c], [a, c, d]]);
    for k in 0..4 {
        quad(o(k, 0), o(k + 1, 0), o(k + 1, 1), o(k, 1));
        quad(i(k, 0), i(k, 1), i(k + 1, 1), i(k + 1, 0));
        quad(o(k, 1), o(k + 1, 1), i(k + 1, 1), i(k, 1));
        quad(o(k, 0), i(k, 0), i(k + 1, 0), o(k + 1, 0));
    }
    (points, triangles)
}

/// A peg modelled in a hole of its own size, sticking out of it: the two are welded where
/// they touch and, with nothing moving them, stay where they are (the contact pushed the peg
/// in from all round, squeezing it and pumping energy into both). A block lying on the ring
/// touches it but does not fit into it, and stays a contact.
#[test]
fn a_peg_in_a_hole_of_its_size_is_welded_to_it() {
    let rubber = Material::preset("rubber").unwrap();
    let mut w = weightless_world(&rubber);
    let ring_mesh = mesh(ring(0.3, 0.1, 0.2), 6);
    let board = add_part(&mut w, "board", &ring_mesh, &rubber);
    let peg_mesh = mesh(box_mesh([-0.1, -0.1, 0.0], [0.1, 0.1, 0.5]), 6);
    let peg = add_part(&mut w, "peg", &peg_mesh, &rubber);
    assert_eq!(
        w.interpenetrating_parts(),
        [("board".into(), "peg".into(), true)]
    );
    stays_still(&mut w, &[board, peg]);

    let mut w = weightless_world(&rubber);
    add_part(&mut w, "board", &ring_mesh, &rubber);
    let lid = mesh(box_mesh([-0.3, -0.3, 0.2], [0.3, 0.3, 0.3]), 6);
    add_part(&mut w, "lid", &lid, &rubber);
    assert!(w.interpenetrating_parts().is_empty());
}
