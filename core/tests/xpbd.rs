//! The XPBD solver (issue 16) in motion: rebound per material, no inverted cell in the jelly block
//! swept by the capsule nor in a jelly cube tipped over its stuck edge, spin kept by a free body, a
//! column's sag against ρ g h²/(2E), volume held, pins, the speed cap lifted near a floor, and the
//! same bits with any thread count. Scenes are set up as the product sets up a mesh: display-
//! surface contact sampled at half a cell.
#![allow(clippy::unwrap_used)]

mod support;

use springbake_core::material::Material;
use springbake_core::nalgebra::Vector3;
use springbake_core::shapes::{box_mesh, uv_sphere};
use springbake_core::solver::manipulator::ManipulatorKey;
use springbake_core::solver::{
    BodyHandle, FrameDiagnostics, Integrator, ManipulatorTrack, Plane, World, WorldSettings,
};
use support::{add_part, floored_parts_world, mesh, product_world, rebound_ball, spin_kept, Mesh};

const FRAME: f64 = 1.0 / 24.0;

/// An XPBD world holding `m` in `material` at `velocity`, with a floor at y = 0 when `floor`.
fn world(m: &Mesh, material: &Material, velocity: Vector3<f64>, floor: bool) -> World {
    product_world(m, material, Integrator::Xpbd, velocity, floor)
}

fn frame(w: &mut World, f: usize) -> FrameDiagnostics {
    w.advance_frame(FRAME, f, &|| false).unwrap()
}

/// Highest the bottom of a ball (r 0.1 m) dropped from 1 m gets after its first bounce, and
/// the most cells inverted in any frame.
fn rebound(preset: &str) -> (f64, usize) {
    let material = Material::preset(preset).unwrap();
    let mut w = world(&rebound_ball(), &material, Vector3::zeros(), true);
    let r = support::rebound(&mut w, 40);
    (r.peak, r.inverted)
}

#[test]
fn a_rubber_ball_rebounds_like_rubber_and_jelly_barely_does() {
    let (rubber, inverted) = rebound("rubber");
    assert!((0.4..=0.75).contains(&rubber), "rubber rebounds {rubber} m");
    assert_eq!(inverted, 0);
    let (jelly, inverted) = rebound("jelly");
    assert!(jelly < 0.2, "jelly rebounds {jelly} m");
    assert_eq!(inverted, 0);
}

/// Wood and steel: too stiff for a substep to resolve their impact, they bounce by the
/// restitution of their damping ratio (`xpbd::restitution`) — a steel ball well, a wood ball
/// less — with no cell inverted and no energy gained; a steel box dropped on a corner comes
/// off it turning, and lies still once it has settled.
#[test]
fn stiff_balls_rebound_and_a_steel_box_settles_without_gaining_energy() {
    let (steel, inverted) = rebound("steel");
    assert!((0.5..=0.9).contains(&steel), "steel rebounds {steel} m");
    assert_eq!(inverted, 0);
    let (wood, _) = rebound("wood");
    assert!((0.2..steel).contains(&wood), "wood rebounds {wood} m");

    // A 20 cm steel box tilted 30° about x and z, its corner 0.3 m above the floor.
    let (mut points, triangles) = box_mesh([-0.1, -0.1, -0.1], [0.1, 0.1, 0.1]);
    let tilt = springbake_core::nalgebra::Rotation3::from_euler_angles(0.5, 0.0, 0.5);
    for p in &mut points {
        *p = tilt * *p;
    }
    let low = points.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    for p in &mut points {
        p.y += 0.3 - low;
    }
    let tilted = mesh((points, triangles), 4);
    let mut w = world(
        &tilted,
        &Material::preset("steel").unwrap(),
        Vector3::zeros(),
        true,
    );
    let mut spun = 0.0f64;
    for f in 1..=120 {
        let d = frame(&mut w, f);
        assert!(d.energy_gain.is_none_or(|g| g <= 1e-6), "frame {f}: {d:?}");
        let (x, v) = (&w.nodes.position, &w.nodes.velocity);
        let n = x.len() as f64;
        let com = x.iter().sum::<Vector3<f64>>() / n;
        let vel = v.iter().sum::<Vector3<f64>>() / n;
        let spin = x
            .iter()
            .zip(v)
            .map(|(p, q)| (p - com).cross(&(q - vel)).norm())
            .sum::<f64>();
        spun = spun.max(spin);
    }
    assert!(spun > 1e-3, "the corner impact turns the box ({spun})");
    let fastest = w
        .nodes
        .velocity
        .iter()
        .map(|v| v.norm())
        .fold(0.0, f64::max);
    assert!(
        fastest < 0.02,
        "settled after 3 s: fastest node {fastest} m/s"
    );
    // Its lattice is an axis-aligned grid around the tilted box (nodes outside the mesh may sit
    // below the floor); the box itself lies on a face, its centre half its size up.
    let n = w.nodes.position.len() as f64;
    let com = w.nodes.position.iter().sum::<Vector3<f64>>() / n;
    assert!(
        (com.y - 0.1).abs() < 2e-3,
        "rests on a face: centre at {}",
        com.y
    );
}

/// A jelly cube of edge `size` (`cells` along it) standing on the floor, and a capsule of
/// `(radius, length)` across it, `height` up, moved along x through the `(time, x)` keys.
fn jelly_block_swept(
    size: f64,
    cells: u32,
    (radius, length): (f64, f64),
    height: f64,
    keys: [(f64, f64); 2],
) -> World {
    let half = 0.5 * size;
    let block = mesh(box_mesh([-half, 0.0, -half], [half, size, half]), cells);
    let mut w = world(
        &block,
        &Material::preset("jelly").unwrap(),
        Vector3::zeros(),
        true,
    );
    w.manipulators.push(ManipulatorTrack {
        radius,
        length,
        friction: 0.3,
        smooth: false,
        keys: keys
            .map(|(t, x)| ManipulatorKey {
                t,
                position: Vector3::new(x, height, 0.0),
                yaw_deg: 90.0,
            })
            .to_vec(),
        up: Vector3::y(),
    });
    w
}

/// The mean x of the world's nodes, m.
fn mean_x(w: &World) -> f64 {
    w.nodes.position.iter().map(|p| p.x).sum::<f64>() / w.nodes.len() as f64
}

/// The papers' headline scene: a 30 cm jelly block on the floor swept broadside by a 4 cm
/// capsule at 2 m/s (the spring lattice folds 167 of its 512 cells).
#[test]
fn no_cell_of_a_jelly_block_swept_by_the_capsule_inverts() {
    let mut w = jelly_block_swept(0.3, 8, (0.04, 0.6), 0.15, [(0.0, -0.6), (0.6, 0.6)]);
    let mut pushed = 0.0f64;
    for f in 1..=24 {
        let d = frame(&mut w, f);
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        pushed = pushed.max(d.manipulator_reaction[0].abs());
    }
    // The block was pushed along, and the manipulator felt it.
    let centre_x = mean_x(&w);
    assert!(centre_x > 0.05, "block centre at x = {centre_x}");
    assert!(pushed > 0.1, "reaction {pushed} N");
}

/// The viewer's live case: a 0.5 m jelly cube (15 cells: it sags to 0.42 m) on the floor,
/// pushed broadside by a 5 cm capsule at 1 m/s, 20 cm up, in 1/60 s frames. It tips over its
/// front edge, which friction holds, and the pivot's cells are crushed: at the substeps its
/// speed asks for (10–17 a frame) cells there folded in 7 of the first 45 frames; the frames
/// that start with a corner near collapse now double their substeps.
#[test]
fn a_jelly_cube_tipped_over_its_stuck_edge_does_not_fold() {
    let mut w = jelly_block_swept(0.5, 15, (0.05, 0.8), 0.2, [(0.0, -0.35), (1.5, 1.15)]);
    let (mut fewest, mut most) = (u32::MAX, 0);
    for f in 1..=45 {
        let d = w.advance_frame(1.0 / 60.0, f, &|| false).unwrap();
        assert_eq!(d.inverted_cells, 0, "frame {f}, {} substeps", d.substeps);
        if f > 1 {
            fewest = fewest.min(d.substeps);
            most = most.max(d.substeps);
        }
    }
    // The crushed frames took more substeps than the calm ones, not all of them.
    assert!(most >= 2 * fewest, "substeps {fewest}..{most}");
    let centre_x = mean_x(&w);
    assert!(centre_x > 0.1, "block centre at x = {centre_x}");
}

#[test]
fn a_free_spinning_rubber_cube_keeps_its_spin() {
    let cube = mesh(box_mesh([-0.25, -0.25, -0.25], [0.25, 0.25, 0.25]), 6);
    let mut w = world(
        &cube,
        &Material::preset("rubber").unwrap(),
        Vector3::zeros(),
        false,
    );
    let kept = spin_kept(&mut w);
    assert!(kept >= 0.95, "kept {:.1} % of the spin", kept * 100.0);
}

/// A jelly cube thrown at 2 m/s with no gravity, wobbling from an uneven start (random
/// node velocities about the throw): over two seconds its momentum stays what it was to a
/// billionth. Internal forces exert no net force, whatever the cells' single-precision lanes
/// round (without the torque pass's impulse correction it drifted by 2.4e-7 of itself).
#[test]
fn a_wobbling_body_in_flight_keeps_its_momentum() {
    let cube = mesh(box_mesh([-0.15, 0.0, -0.15], [0.15, 0.3, 0.15]), 6);
    let throw = Vector3::new(2.0, 0.5, -1.0);
    let mut w = world(&cube, &Material::preset("jelly").unwrap(), throw, false);
    w.settings.gravity = Vector3::zeros();
    let mut rng = fastrand::Rng::with_seed(5);
    for v in &mut w.nodes.velocity {
        *v += Vector3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5);
    }
    let momentum = |w: &World| {
        (w.nodes.velocity.iter().zip(&w.nodes.mass)).fold(Vector3::zeros(), |p, (v, m)| p + v * *m)
    };
    let before = momentum(&w);
    for f in 1..=48 {
        frame(&mut w, f);
    }
    let drift = (momentum(&w) - before).norm() / before.norm();
    assert!(drift < 1e-9, "momentum drifted by {drift:e} of itself");
}

/// Sag of a column (0.2 × 1 × 0.2 m, E = 1 MPa, ν = 0, 1000 kg/m³) standing on its pinned
/// base after 3 s, with the vertical stiffness scaled by `vertical` (anisotropy), and ρ g h² /
/// (2E).
fn column_sag(vertical: f64) -> (f64, f64) {
    let column = mesh(box_mesh([0.0, 0.0, 0.0], [0.2, 1.0, 0.2]), 10);
    let m = Material::new("column", 1.0e6, 0.0, 1000.0, 0.5).unwrap();
    let mut w = world(&column, &m, Vector3::zeros(), true);
    if vertical != 1.0 {
        w.scale_stiffness_per_axis(BodyHandle(0), Vector3::new(1.0, vertical, 1.0))
            .unwrap();
    }
    let base: Vec<usize> = (0..w.nodes.len())
        .filter(|&i| w.nodes.position[i].y < 1e-9)
        .collect();
    w.pin(&base).unwrap();
    let top = |w: &World| w.nodes.position.iter().map(|p| p.y).fold(0.0, f64::max);
    let top0 = top(&w);
    for f in 1..=72 {
        frame(&mut w, f);
    }
    for &i in &base {
        assert_eq!(
            w.nodes.position[i],
            w.rest_position(i),
            "pinned node {i} moved"
        );
    }
    (
        top0 - top(&w),
        1000.0 * 9.81 * 1.0 / (2.0 * 1.0e6 * vertical),
    )
}

/// A column standing on its pinned base sags by ρ g h² / (2E) (small strain, ν = 0).
#[test]
fn a_column_sags_under_its_own_weight_as_elasticity_says() {
    let (sag, expected) = column_sag(1.0);
    assert!(
        (sag / expected - 1.0).abs() < 0.1,
        "sag {sag} m, elasticity says {expected} m"
    );
}

/// `stiffness_scale` (anisotropy) reaches the cells: four times stiffer vertically, about a
/// quarter of the sag (elasticity: exactly; the stiffer column's wave asks for more substeps
/// than the cap of 30 allows, and an under-resolved sweep is softer: a third, measured).
#[test]
fn a_column_four_times_stiffer_vertically_sags_about_a_quarter() {
    let (plain, _) = column_sag(1.0);
    let (stiff, _) = column_sag(4.0);
    let ratio = stiff / plain;
    assert!((0.2..0.4).contains(&ratio), "sag ratio {ratio}");
}

#[test]
fn a_jelly_ball_thrown_down_keeps_its_volume_and_no_cell_inverts() {
    let ball = mesh(uv_sphere([0.0, 0.52, 0.0], 0.5, 12, 24), 8);
    let jelly = Material::preset("jelly").unwrap();
    let mut w = world(&ball, &jelly, Vector3::new(0.0, -8.0, 0.0), true);
    let h = BodyHandle(0);
    w.preserve_volume(h, 1.0).unwrap();
    let v0 = w.body_volume(h);
    for f in 1..=24 {
        let d = frame(&mut w, f);
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        let v = w.body_volume(h);
        assert!((v / v0 - 1.0).abs() < 0.02, "frame {f}: volume {v} of {v0}");
    }
}

/// A rubber cube dropped onto the floor and hit by the capsule, stepped in pools of 1, 2 and 8
/// threads: the same bits.
#[test]
fn the_same_bits_with_one_two_and_eight_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let cube = mesh(box_mesh([0.0, 0.3, 0.0], [0.5, 0.8, 0.5]), 12);
            let mut w = world(
                &cube,
                &Material::preset("rubber").unwrap(),
                Vector3::zeros(),
                true,
            );
            let key = |t: f64, x: f64| ManipulatorKey {
                t,
                position: Vector3::new(x, 0.2, 0.25),
                yaw_deg: 90.0,
            };
            w.manipulators.push(ManipulatorTrack {
                radius: 0.05,
                length: 0.8,
                friction: 0.3,
                smooth: false,
                keys: vec![key(0.0, -0.4), key(0.5, 0.3)],
                up: Vector3::y(),
            });
            for f in 1..=5 {
                frame(&mut w, f);
            }
            w.nodes.position.clone()
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(8));
}

/// Two rubber cubes (0.5 m, 6 cells) side by side with a gap of `gap` metres (negative:
/// overlapping), no gravity: the fastest node speed over 12 frames and the change of the
/// gap between their centres.
fn neighbours(gap: f64) -> (f64, f64) {
    let (fastest, opened, _) = neighbours_with(gap, Integrator::Xpbd);
    (fastest, opened)
}

/// [`neighbours`] with any integrator, and the largest energy gain the frames report.
fn neighbours_with(gap: f64, integrator: Integrator) -> (f64, f64, f64) {
    let rubber = Material::preset("rubber").unwrap();
    let mut w = World::new(WorldSettings {
        gravity: Vector3::zeros(),
        layer: WorldSettings::default_layer(0.5 / 6.0, &rubber, 0.4),
        integrator,
        ..WorldSettings::default()
    });
    let mut cubes = Vec::new();
    for (i, x0) in [0.0, 0.5 + gap].into_iter().enumerate() {
        let m = mesh(box_mesh([x0, 0.0, 0.0], [x0 + 0.5, 0.5, 0.5]), 6);
        cubes.push(add_part(&mut w, &format!("cube{i}"), &m, &rubber));
    }
    let centre_x = |w: &World, h: BodyHandle| {
        let xs = w.body_positions(h);
        xs.iter().map(|p| p.x).sum::<f64>() / xs.len() as f64
    };
    let gap0 = centre_x(&w, cubes[1]) - centre_x(&w, cubes[0]);
    let (mut fastest, mut gain) = (0.0f64, 0.0f64);
    for f in 1..=12 {
        let d = frame(&mut w, f);
        fastest = fastest.max(d.max_speed);
        gain = gain.max(d.energy_gain.unwrap());
    }
    let opened = centre_x(&w, cubes[1]) - centre_x(&w, cubes[0]) - gap0;
    (fastest, opened, gain)
}

/// The report's energy balance flags parts thrown apart by their stored contact push (the
/// papers' integrator, whose layer throws two overlapping cubes apart at metres per second)
/// and stays quiet when they separate slowly (XPBD).
#[test]
fn the_energy_balance_flags_parts_thrown_apart_by_their_contact_layer() {
    let (fastest, _, gain) = neighbours_with(-0.005, Integrator::SymplecticEuler);
    assert!(fastest > 1.0 && gain > 100.0, "{fastest} m/s, {gain} J");
    let (_, _, gain) = neighbours_with(-0.005, Integrator::Xpbd);
    assert_eq!(gain, 0.0);
}

/// Parts that start a centimetre apart (inside each other's contact layer, within the
/// contact pass's reach) do not touch: the contact constraints leave them where they are
/// (the layer pushed them apart). Parts overlapping by 5 mm keep the layer, and separate
/// slowly instead of flying apart (its stored push threw such parts apart at metres per
/// second).
#[test]
fn parts_that_start_close_or_overlapping_separate_without_gaining_speed() {
    let (fastest, opened) = neighbours(0.01);
    assert!(fastest < 1e-9, "gap 0.01: fastest node {fastest} m/s");
    assert!(
        opened.abs() < 1e-9,
        "gap 0.01: the parts moved {opened} m apart"
    );
    let (fastest, opened) = neighbours(-0.005);
    assert!(fastest < 0.2, "overlap: fastest node {fastest} m/s");
    assert!(opened > 0.0, "overlap: the parts moved {opened} m apart");
}

/// The same contact layer still bounces a body that falls onto another: a rubber cube dropped
/// 0.75 m onto a resting one rises again after the impact.
#[test]
fn a_body_falling_onto_another_still_bounces() {
    let rubber = Material::preset("rubber").unwrap();
    let mut w = floored_parts_world(&rubber);
    let mut cubes = Vec::new();
    for (i, y0) in [0.0, 1.25].into_iter().enumerate() {
        let m = mesh(box_mesh([0.0, y0, 0.0], [0.5, y0 + 0.5, 0.5]), 6);
        cubes.push(add_part(&mut w, &format!("cube{i}"), &m, &rubber));
    }
    let bottom = |w: &World| {
        w.body_positions(cubes[1])
            .iter()
            .map(|p| p.y)
            .fold(f64::INFINITY, f64::min)
    };
    let (mut lowest, mut rebound) = (f64::INFINITY, f64::NEG_INFINITY);
    for f in 1..=30 {
        frame(&mut w, f);
        let b = bottom(&w);
        if b < lowest {
            lowest = b;
            rebound = b;
        }
        rebound = rebound.max(b);
    }
    assert!(lowest < 0.6, "the top cube reached {lowest} m");
    assert!(
        rebound > lowest + 0.1,
        "rose to {rebound} m from {lowest} m"
    );
}

/// A static collider is a contact constraint like the floor: a ball dropped on a slab
/// (no floor) rebounds as high as off the floor, rubber by its cells and steel by its
/// restitution, and rests on the slab's top face, not in it.
#[test]
fn a_ball_bounces_off_a_collider_as_off_the_floor() {
    use springbake_core::collide::StaticCollider;
    for preset in ["rubber", "steel"] {
        let (floor, _) = rebound(preset);
        let material = Material::preset(preset).unwrap();
        let mut w = world(&rebound_ball(), &material, Vector3::zeros(), false);
        let (points, triangles) = box_mesh([-1.0, -0.5, -1.0], [1.0, 0.0, 1.0]);
        let slab = StaticCollider::new("slab", &points, &triangles, 0.4).unwrap();
        w.add_collider(slab);
        let r = support::rebound(&mut w, 40);
        assert!(
            (r.peak - floor).abs() <= 0.1 * floor,
            "{preset}: {} m off the collider, {floor} m off the floor",
            r.peak
        );
        assert_eq!(r.inverted, 0);
        for f in 41..=96 {
            frame(&mut w, f);
        }
        // The display surface rests on the slab (the lattice's corner nodes may hang below
        // it): the centre of a 0.1 m ball stays about a radius up.
        let x = &w.nodes.position;
        let centre = x.iter().map(|p| p.y).sum::<f64>() / x.len() as f64;
        assert!(
            (0.085..0.115).contains(&centre),
            "{preset}: centre {centre} m above the slab"
        );
    }
}

/// Small bodies keep their shape (issue 16, "same look at every scale"): a 1 cm box dropped
/// 5 mm, its elastic wave crossing it many times a substep, rests as a box. Left to the
/// contact projection, gravity pressed its bottom cells by `g Δt²` every substep, more than
/// the one sweep carried up, and rubber, wood and steel cubes of 1 cm folded flat within a
/// second; the plane now holds such a body up as a whole (`xpbd::restitution::support`).
#[test]
fn a_one_centimetre_box_lands_and_rests_as_a_box() {
    for preset in ["rubber", "steel", "jelly"] {
        let mut w = world(
            &mesh(box_mesh([-0.005, 0.005, -0.005], [0.005, 0.015, 0.005]), 10),
            &Material::preset(preset).unwrap(),
            Vector3::zeros(),
            true,
        );
        let n = w.nodes.position.len() as f64;
        let centre = |w: &World| w.nodes.position.iter().sum::<Vector3<f64>>() / n;
        let start = centre(&w);
        let mut inverted = 0;
        for f in 1..=48 {
            inverted = inverted.max(frame(&mut w, f).inverted_cells);
        }
        let end = centre(&w);
        let ys = w.nodes.position.iter().map(|p| p.y);
        let height =
            ys.clone().fold(f64::NEG_INFINITY, f64::max) - ys.fold(f64::INFINITY, f64::min);
        assert!(inverted <= 1, "{preset}: {inverted} cells inverted");
        assert!(
            (height - 0.01).abs() < 0.0006,
            "{preset}: box {height} m tall"
        );
        assert!(
            (end.y - 0.005).abs() < 0.0004,
            "{preset}: centre {} m up",
            end.y
        );
        let drift = ((end.x - start.x).powi(2) + (end.z - start.z).powi(2)).sqrt();
        assert!(drift < 0.001, "{preset}: slid {drift} m");
    }
}

/// Substeps do not grow as a body shrinks (issue 16, "real units, same look at every scale"):
/// a box of 1 m, 10 cm and 1 cm (10 cells each) dropped half its size onto the floor takes as
/// many substeps a frame at every size. The travel bound (a tenth of a cell a substep near a
/// surface) asked 60 a frame of the 1 cm box; a body whose wave crosses it within a substep
/// is moved as a whole at an impact (`xpbd::restitution`), so its cells need no such bound,
/// and a body it moves partly needs it only for the share its cells stop.
#[test]
fn substeps_do_not_grow_as_a_body_shrinks() {
    for preset in ["rubber", "steel"] {
        let material = Material::preset(preset).unwrap();
        let most = |size: f64| {
            let lo = [-size / 2.0, size / 2.0, -size / 2.0];
            let hi = [size / 2.0, size * 1.5, size / 2.0];
            let mut w = world(
                &mesh(box_mesh(lo, hi), 10),
                &material,
                Vector3::zeros(),
                true,
            );
            (1..=24).map(|f| frame(&mut w, f).substeps).max().unwrap()
        };
        let sizes = [1.0, 0.1, 0.01].map(most);
        assert!(
            sizes.iter().all(|&n| n == sizes[0]),
            "{preset}: substeps a frame at 1 m, 10 cm, 1 cm: {sizes:?}"
        );
    }
}

/// A cone of radius 1 cm and height 2 cm (32 sides), its base centred on `(0, base, 0)`,
/// turned `tilt` radians about x around its base's centre.
fn cone(base: f64, tilt: f64) -> (Vec<springbake_core::nalgebra::Point3<f64>>, Vec<[u32; 3]>) {
    use springbake_core::nalgebra::{Point3, Rotation3};
    const SIDES: u32 = 32;
    let turn = Rotation3::from_euler_angles(tilt, 0.0, 0.0);
    let mut points = vec![Point3::new(0.0, 0.02, 0.0), Point3::origin()];
    points.extend((0..SIDES).map(|k| {
        let a = std::f64::consts::TAU * f64::from(k) / f64::from(SIDES);
        Point3::new(0.01 * a.cos(), 0.0, 0.01 * a.sin())
    }));
    let mut triangles = Vec::new();
    for k in 0..SIDES {
        let (a, b) = (2 + k, 2 + (k + 1) % SIDES);
        triangles.push([0, b, a]);
        triangles.push([1, a, b]);
    }
    for p in &mut points {
        *p = turn * *p + Vector3::y() * base;
    }
    (points, triangles)
}

/// How far `w`'s only body is turned from its rest pose, radians: the rotation of the best
/// rigid fit of its nodes (polar decomposition of their covariance with the rest pose).
fn turned(w: &World, rest: &[Vector3<f64>]) -> f64 {
    let r = best_rotation(w, rest);
    ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

/// The rotation of the best rigid fit of `w`'s nodes to their rest pose `rest`.
fn best_rotation(w: &World, rest: &[Vector3<f64>]) -> springbake_core::nalgebra::Matrix3<f64> {
    use springbake_core::nalgebra::Matrix3;
    let x = &w.nodes.position;
    let n = x.len() as f64;
    let (c, c0) = (
        x.iter().sum::<Vector3<f64>>() / n,
        rest.iter().sum::<Vector3<f64>>() / n,
    );
    let a: Matrix3<f64> = x
        .iter()
        .zip(rest)
        .map(|(p, q)| (p - c) * (q - c0).transpose())
        .sum();
    let svd = a.svd(true, true);
    svd.u.unwrap() * svd.v_t.unwrap()
}

/// A stiff small body landing on a face bounces off it as a whole (`xpbd::restitution`): a
/// 2 cm cone (Blender's, as in the corpus) dropped 4 cm onto its base, flat or 2° off, stays
/// on its base in every material. One impulse at the contact points' centre let the points
/// farther down keep approaching: a cone landing 1.5° off flat left spinning at 19 rad/s,
/// flipped over and ended on its side.
#[test]
fn a_small_cone_dropped_on_its_base_lands_on_its_base() {
    for preset in ["steel", "wood", "rubber"] {
        for tilt_deg in [0.0f64, 2.0] {
            let m = mesh(cone(0.04, tilt_deg.to_radians()), 10);
            let material = Material::preset(preset).unwrap();
            let mut w = world(&m, &material, Vector3::zeros(), true);
            let rest = w.nodes.position.clone();
            let (mut most, mut bottom_peak, mut landed) = (0.0f64, 0.0f64, false);
            for f in 1..=36 {
                frame(&mut w, f);
                most = most.max(turned(&w, &rest).to_degrees() - tilt_deg);
                let low = w
                    .nodes
                    .position
                    .iter()
                    .map(|p| p.y)
                    .fold(f64::INFINITY, f64::min);
                landed |= w.nodes.velocity.iter().map(|v| v.y).sum::<f64>() > 0.0;
                if landed {
                    bottom_peak = bottom_peak.max(low);
                }
            }
            // On its base at the end: its axis upright (the tilted cone lands flat, so how far
            // it turned from its start is its tilt and any turn about its axis).
            let axis = best_rotation(&w, &rest)
                * springbake_core::nalgebra::Rotation3::from_euler_angles(
                    tilt_deg.to_radians(),
                    0.0,
                    0.0,
                )
                * Vector3::y();
            let off_upright = axis.angle(&Vector3::y()).to_degrees();
            assert!(most < 10.0, "{preset} at {tilt_deg}°: turned {most}° more");
            assert!(
                off_upright < 3.0,
                "{preset} at {tilt_deg}°: ends {off_upright}° off upright"
            );
            if preset == "steel" {
                assert!(bottom_peak > 0.01, "steel rebounds {bottom_peak} m");
            }
        }
    }
}

/// A steel ball dropped straight leaves the floor without turning: its first bounce's
/// impulses spread over the cap of points that meet the floor in the impact's substep (a
/// ball of 0.5 × 0.4 × 0.45 m, turned 30° about the vertical, as Blender's two-object test
/// scene's head). Sequential impulses alone, sixteen passes over that cap, left it turning at
/// 1.9 rad/s, and it tumbled from then on.
#[test]
fn a_steel_ball_dropped_straight_bounces_without_turning() {
    use springbake_core::nalgebra::Rotation3;
    let (mut points, triangles) = uv_sphere([0.0, 0.0, 0.0], 1.0, 16, 32);
    let turn = Rotation3::from_euler_angles(0.0, 0.5, 0.0);
    for p in &mut points {
        *p = turn * springbake_core::nalgebra::Point3::new(0.25 * p.x, 0.2 * p.y, 0.225 * p.z);
        p.y += 1.2;
    }
    let m = mesh((points, triangles), 8);
    let mut w = world(
        &m,
        &Material::preset("steel").unwrap(),
        Vector3::zeros(),
        true,
    );
    let mut peak_spin = 0.0f64;
    let mut risen = false;
    for f in 1..=24 {
        frame(&mut w, f);
        let all = 0..w.nodes.len();
        let rigid = springbake_core::solver::deformation_damping::rigid_motion(&w.nodes, all);
        risen |= rigid.velocity.y > 0.0;
        peak_spin = peak_spin.max(rigid.angular_velocity.norm());
    }
    assert!(risen, "the ball bounced");
    assert!(peak_spin < 0.05, "turning at {peak_spin} rad/s");
}

#[test]
fn the_reported_elastic_energy_at_an_impact_is_near_the_energy_the_ball_had() {
    // The cells' energy at a frame's end is read as the last elastic solve left them, not
    // after the contact projection that the next solve relaxes. Read after it, the rubber
    // ball's cells held 3.4 times all the energy it had at its impact (254 J of 76 J dropped,
    // 445 J of 132 J thrown down at 4 m/s). What is left over (1.3 and 1.7 times) is the
    // residual of one Gauss–Seidel sweep a substep, which stiff cells read as energy.
    for drop_speed in [0.0, 4.0] {
        let material = Material::preset("rubber").unwrap();
        let m = rebound_ball();
        let v = Vector3::new(0.0, -drop_speed, 0.0);
        let mut w = product_world(&m, &material, Integrator::Xpbd, v, true);
        let available = w.total_energy();
        let mut most = 0.0f64;
        for f in 1..=30 {
            most = most.max(frame(&mut w, f).elastic_energy);
        }
        assert!(most > 0.1 * available, "{drop_speed} m/s: {most} J");
        assert!(
            most < 2.0 * available,
            "{drop_speed} m/s: {most} J of {available} J"
        );
    }
}

/// A kitbash: a ball sunk halfway into the top of a rubber cube, dropped 0.3 m onto the floor.
/// The layer cannot push out a part that deep (it threw such a ball off at 10 m/s); the two
/// are glued where they overlap, fall and bounce as one, and gain no energy. Parts apart by
/// a few centimetres are not glued.
#[test]
fn parts_that_interpenetrate_at_the_start_are_glued_and_move_as_one() {
    let rubber = Material::preset("rubber").unwrap();
    let build = |ball_y: f64| {
        let mut w = floored_parts_world(&rubber);
        let parts = [
            ("cube", mesh(box_mesh([0.0, 0.3, 0.0], [0.5, 0.8, 0.5]), 6)),
            (
                "ball",
                mesh(uv_sphere([0.25, ball_y, 0.25], 0.15, 12, 16), 6),
            ),
        ];
        let handles: Vec<BodyHandle> = parts
            .iter()
            .map(|(name, m)| add_part(&mut w, name, m, &rubber))
            .collect();
        (w, handles)
    };
    let centre = |w: &World, h: BodyHandle| {
        let xs = w.body_positions(h);
        xs.iter().sum::<Vector3<f64>>() / xs.len() as f64
    };
    let (mut w, parts) = build(0.8);
    let pair = ("cube".to_string(), "ball".to_string(), true);
    assert_eq!(w.interpenetrating_parts(), [pair]);
    let offset0 = centre(&w, parts[1]) - centre(&w, parts[0]);
    let (mut fastest, mut gain, mut drift) = (0.0f64, 0.0f64, 0.0f64);
    for f in 1..=36 {
        let d = frame(&mut w, f);
        fastest = fastest.max(d.max_speed);
        gain = gain.max(d.energy_gain.unwrap());
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        drift = drift.max((centre(&w, parts[1]) - centre(&w, parts[0]) - offset0).norm());
    }
    // 0.3 m of fall is 2.4 m/s; the glued ball stays in the cube (its deformation aside).
    assert!(fastest < 3.0, "fastest node {fastest} m/s");
    assert_eq!(gain, 0.0);
    assert!(
        drift < 0.02,
        "the ball moved {drift} m relative to the cube"
    );
    // A ball 5 cm above the cube's top is a contact, not a glued part.
    let (mut apart, _) = build(1.0);
    assert!(apart.interpenetrating_parts().is_empty());
    // A rigid cube is not glued; the pair only stops colliding, and is not thrown apart (the
    // ball falls through the cube: 0.65 m of fall to the floor is 3.6 m/s).
    let (mut w, parts) = build(0.8);
    w.make_rigid(parts[0]).unwrap();
    let pair = ("cube".to_string(), "ball".to_string(), false);
    assert_eq!(w.interpenetrating_parts(), [pair]);
    for f in 1..=12 {
        let d = frame(&mut w, f);
        assert!(
            d.max_speed < 4.0,
            "rigid cube, frame {f}: {} m/s",
            d.max_speed
        );
    }
}

/// Three rubber cubes stacked touching on the floor, or a centimetre apart, start inside
/// each other's contact layers: they rest on each other within 3 s (the dropped stack's
/// rubber rings for a second or two: its damping ratio is 0.05). Pushed into the floor by that parting, the bottom one jumped the
/// stack at 1 m/s (105 J gained), and a node free for a substep met the layer again at full
/// push (3 m/s); a stack a centimetre apart slid and wobbled for good.
#[test]
fn a_stack_of_boxes_touching_at_the_start_parts_gently_and_rests() {
    let rubber = Material::preset("rubber").unwrap();
    for gap in [0.0, 0.01] {
        let mut w = floored_parts_world(&rubber);
        let mut cubes = Vec::new();
        for i in 0..3 {
            let y0 = gap + i as f64 * (0.5 + gap);
            let m = mesh(box_mesh([0.0, y0, 0.0], [0.5, y0 + 0.5, 0.5]), 6);
            cubes.push(add_part(&mut w, &format!("cube{i}"), &m, &rubber));
        }
        let top_x = |w: &World| {
            let xs = w.body_positions(cubes[2]);
            xs.iter().map(|p| p.x).sum::<f64>() / xs.len() as f64
        };
        let x0 = top_x(&w);
        // Touching, they do not move apart; a centimetre apart, each falls onto the one
        // below (the top one three centimetres in all: 0.77 m/s), and no faster.
        let fall = (2.0 * 9.81 * 3.0 * gap).sqrt();
        let mut last: Option<f64> = None;
        for f in 1..=72 {
            let d = frame(&mut w, f);
            assert!(
                d.max_speed < 0.5f64.max(1.25 * fall),
                "gap {gap}, frame {f}: {} m/s",
                d.max_speed
            );
            assert_eq!(d.energy_gain, Some(0.0), "gap {gap}, frame {f}");
            if f > 60 {
                last = Some(last.map_or(d.kinetic_energy, |k| k.max(d.kinetic_energy)));
            }
        }
        // At rest: at most 0.15 J over the last half second (2.7 cm/s for the stack's 410 kg;
        // a dropped stack keeps a jitter of a few cm/s at its nodes, see issue 16's notes:
        // 0.092 J with one sweep a substep, 0.130 J with the second sweep behind the contacts,
        // `xpbd::sweep_behind_contacts`, whose second pass over the contacts adds to it).
        let kinetic = last.unwrap();
        assert!(kinetic < 0.15, "gap {gap}: still {kinetic} J after 2.5 s");
        let slid = (top_x(&w) - x0).abs();
        assert!(slid < 0.01, "gap {gap}: the top cube slid {slid} m");
    }
}

/// A tower of four 20 cm rubber cubes a centimetre apart on the floor settles and stands,
/// each cube resting on the one below, not floating on a contact layer: as elastic layers
/// the contacts held the cubes 2.5 cm apart, and at 2 s the tower slid apart and fell (3.6
/// m/s at 2.5 s).
#[test]
fn a_tower_of_cubes_a_centimetre_apart_settles_and_stands() {
    let rubber = Material::preset("rubber").unwrap();
    let (size, gap, cells) = (0.2, 0.01, 6);
    let mut w = World::new(WorldSettings {
        planes: vec![Plane {
            normal: Vector3::y(),
            offset: 0.0,
        }],
        layer: WorldSettings::default_layer(size / cells as f64, &rubber, 0.4),
        integrator: Integrator::Xpbd,
        ..WorldSettings::default()
    });
    let mut cubes = Vec::new();
    for i in 0..4 {
        let y0 = i as f64 * (size + gap);
        let m = mesh(box_mesh([0.0, y0, 0.0], [size, y0 + size, size]), cells);
        cubes.push(add_part(&mut w, &format!("cube{i}"), &m, &rubber));
    }
    // A cube's bottom and top: the mean height of its four lowest and four highest corners.
    let bounds = |w: &World, h: BodyHandle| {
        let xs = w.body_positions(h);
        let mut ys: Vec<f64> = xs.iter().map(|p| p.y).collect();
        ys.sort_by(f64::total_cmp);
        let low = ys[..4].iter().sum::<f64>() / 4.0;
        let high = ys[ys.len() - 4..].iter().sum::<f64>() / 4.0;
        let centre = xs.iter().sum::<Vector3<f64>>() / xs.len() as f64;
        (low, high, centre)
    };
    let start = bounds(&w, cubes[3]).2;
    for f in 1..=64 {
        let d = frame(&mut w, f);
        assert_eq!(d.inverted_cells, 0, "frame {f}");
        // Settled: no node faster than 0.3 m/s (the contacts' jitter, a few mm a frame).
        if f > 24 {
            assert!(d.max_speed < 0.3, "frame {f}: {} m/s", d.max_speed);
        }
    }
    let layer = w.settings.layer.thickness_m;
    for i in 1..4 {
        let below = bounds(&w, cubes[i - 1]).1;
        let above = bounds(&w, cubes[i]).0;
        let apart = above - below;
        assert!(
            (-0.1 * layer..0.25 * layer).contains(&apart),
            "cube {i} rests {apart} m above the one below (layer {layer} m)"
        );
    }
    let moved = bounds(&w, cubes[3]).2 - start;
    let sideways = (moved.x * moved.x + moved.z * moved.z).sqrt();
    assert!(sideways < 0.01, "the top cube moved {sideways} m sideways");
}

/// A fast body's substeps are held by the speed cap (60 a frame at 24) only while it cannot
/// reach the floor within the frame: a 10 cm rubber box of 15 cells thrown down at 5 m/s gets
/// more once the floor is within reach. Held at 60, a 1 m rubber cube dropped 1 m on 64³
/// nodes inverted a cell as it landed (0.19 of a cell a substep), on 128³ 11 000.
#[test]
fn the_speed_cap_does_not_hold_a_body_about_to_hit_the_floor() {
    let material = Material::preset("rubber").unwrap();
    let thrown_from = |height: f64| {
        let lo = [-0.05, height, -0.05];
        let hi = [0.05, height + 0.1, 0.05];
        let box_ = mesh(box_mesh(lo, hi), 15);
        world(&box_, &material, Vector3::new(0.0, -5.0, 0.0), true)
    };
    let far = thrown_from(3.0).choose_substeps(FRAME);
    assert_eq!((far.substeps, far.limited_by), (60, "speed cap"), "{far:?}");
    let mut w = thrown_from(0.001);
    let near = w.choose_substeps(FRAME);
    assert!(near.substeps > 100, "{near:?}");
    assert_eq!(near.limited_by, "speed");
    for f in 1..=6 {
        assert_eq!(frame(&mut w, f).inverted_cells, 0, "frame {f}");
    }
}
