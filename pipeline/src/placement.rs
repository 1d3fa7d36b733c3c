//! Bodies that start through the floor or a wall are lifted out of it before the bake.
//!
//! A solver that keeps points out of a plane puts a point found behind it back onto it in one
//! substep, and that correction is speed: a 30 cm rubber cube set 1 cm into the floor left it
//! at 0.75 m/s, and one centred on the floor (a DCC's default cube at the origin, `floor = 0`)
//! flew 7.5 m up with 142 of its cells inverted. An artist who puts a model through the
//! ground means it to stand on it, so the model is moved out along the plane's normal, as a
//! group with the bodies it touches (a stack on a block, a chess set on its board: their node
//! boxes overlap), before frame 1. The bake's log names what moved and how far.

use crate::simulate::PreparedBody;
use springbake_core::nalgebra::Vector3;
use springbake_core::procedures::{lowest_over, translate_body};
use springbake_core::solver::{Plane, World};

/// Depths below this share of a group's size are rounding, not placement (a model resting on
/// the ground at 0 reads a few ulps below it), and are left alone.
const ROUNDING: f64 = 1e-4;

/// A group of bodies moved out of a plane before the bake.
#[derive(Debug, Clone, PartialEq)]
pub struct Lift {
    /// Indices into the prepared bodies, in order.
    pub bodies: Vec<usize>,
    /// How far it was moved, metres.
    pub distance: f64,
    /// Whether the plane faces up (a floor) rather than sideways or down (a wall).
    pub floor: bool,
}

/// Move each group of touching bodies that starts through a plane out of it, plane by plane
/// in the world's order; what moved, in group then plane order. A group that cannot be
/// clear of every plane at once (wider than the room) is left where it was.
pub fn lift_out_of_planes(world: &mut World, bodies: &[PreparedBody]) -> Vec<Lift> {
    let planes: Vec<Plane> = world.settings.planes.clone();
    if planes.is_empty() || bodies.is_empty() {
        return Vec::new();
    }
    let boxes: Vec<NodeBox> = (bodies.iter())
        .map(|b| node_box(world.body_positions(b.handle).iter()))
        .collect();
    let mut lifts = Vec::new();
    for group in touching_groups(&boxes) {
        let (lo, hi) = node_box(group.iter().flat_map(|&b| [&boxes[b].0, &boxes[b].1]));
        let size = (hi - lo).max();
        let depth = |world: &World, plane: &Plane| {
            let deepest = (group.iter())
                .map(|&b| -lowest_over(world, bodies[b].handle, plane))
                .fold(f64::NEG_INFINITY, f64::max);
            Some(deepest).filter(|d| *d > ROUNDING * size)
        };
        let mut moved = Vec::new();
        for plane in &planes {
            if let Some(distance) = depth(world, plane) {
                move_group(world, bodies, &group, plane.normal * distance);
                moved.push((plane.normal, distance));
            }
        }
        if planes.iter().any(|plane| depth(world, plane).is_some()) {
            let back: Vector3<f64> = moved.iter().map(|(n, d)| -n * *d).sum();
            move_group(world, bodies, &group, back);
            continue;
        }
        let up = world.settings.up;
        lifts.extend(moved.into_iter().map(|(normal, distance)| Lift {
            bodies: group.clone(),
            distance,
            floor: normal.dot(&up) > 0.9,
        }));
    }
    lifts
}

fn move_group(world: &mut World, bodies: &[PreparedBody], group: &[usize], shift: Vector3<f64>) {
    for &b in group {
        // Only a rigid body's floating frame can refuse, and it was made from these nodes:
        // moved together, it is rebuilt the same.
        let _ = translate_body(world, bodies[b].handle, shift);
    }
}

/// A node box: its lowest and highest corners.
type NodeBox = (Vector3<f64>, Vector3<f64>);

/// The bodies whose node `boxes` overlap or touch, joined into groups (in body order).
fn touching_groups(boxes: &[NodeBox]) -> Vec<Vec<usize>> {
    let mut root: Vec<usize> = (0..boxes.len()).collect();
    fn find(root: &mut [usize], mut i: usize) -> usize {
        while root[i] != i {
            root[i] = root[root[i]];
            i = root[i];
        }
        i
    }
    for a in 0..boxes.len() {
        for b in a + 1..boxes.len() {
            let (lo_a, hi_a) = &boxes[a];
            let (lo_b, hi_b) = &boxes[b];
            if (0..3).all(|k| lo_a[k] <= hi_b[k] && lo_b[k] <= hi_a[k]) {
                let (ra, rb) = (find(&mut root, a), find(&mut root, b));
                root[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; boxes.len()];
    for b in 0..boxes.len() {
        let r = find(&mut root, b);
        if slot[r] == usize::MAX {
            slot[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[r]].push(b);
    }
    groups
}

/// The box of `points`.
fn node_box<'a>(points: impl Iterator<Item = &'a Vector3<f64>>) -> NodeBox {
    let empty = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    points.fold(empty, |(lo, hi), x| (lo.inf(x), hi.sup(x)))
}
