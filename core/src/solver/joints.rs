//! Articulated flexible bodies: two bodies share a joint node (physics §8, Terasawa's
//! articulated models). The World concatenates all bodies' nodes, so a spring of body B can
//! reference a node of body A: joining node `j` (of B) into node `i` (of A) rewires every
//! spring, surface contact point and path constraint of `j` to `i`, gives `i` the mass of
//! both at their mass-weighted mean position and momentum-conserving mean velocity, and
//! recomputes the rest lengths of the springs at `i` there (the joint starts unstressed).
//! `j` stays in B's node range with no mass (so B's node range, its lattice cells, its
//! deformation damping fit and its baked embedding keep working); after every step `j` is
//! set to `i`'s position and velocity ([`sync`]), so the two are the same point exactly.
//!
//! Joined bodies do not collide with each other (their body–body contact is skipped: the
//! links overlap at the joint); they still touch everything else.
//!
//! The joint point must lie within a spring's length of each body's nearest node (inside or
//! on both bodies), or the joint is refused ([`JointError::TooFar`]).
//!
//! What this costs: B's volume correction (if any) cannot move `j` (it has no mass) and does
//! not reach `i`; a rigid or particle body cannot take part (its frame would ignore the
//! springs of the other body), so joining one is refused.

use super::{BodyHandle, World};
use nalgebra::Vector3;

/// Node `follower` is the same point as node `kept` (world indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SharedNode {
    pub kept: usize,
    pub follower: usize,
}

/// Why a joint cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointError {
    #[error("a joint needs two different bodies")]
    SameBody,
    #[error("body {0} does not exist")]
    NoBody(usize),
    #[error("body \"{0}\" has no nodes")]
    Empty(String),
    #[error("body \"{0}\" is rigid or a particle; joints join flexible bodies")]
    Rigid(String),
    #[error("the joint's nodes are already joined by a spring")]
    Connected,
    #[error("the joint's nodes are already the same node")]
    AlreadyShared,
    #[error(
        "body \"{body}\"'s nearest node is {distance_m:.3} m from the joint point, farther than \
         its longest spring there ({reach_m:.3} m): put `at` where the two bodies meet"
    )]
    TooFar {
        body: String,
        /// 0 for the first body of the joint, 1 for the second.
        which: usize,
        distance_m: f64,
        reach_m: f64,
    },
}

/// The node of `body` nearest to `at` (first on ties), world index.
pub fn nearest_body_node(world: &World, body: BodyHandle, at: Vector3<f64>) -> Option<usize> {
    let range = world.bodies.get(body.0)?.nodes.clone();
    super::nearest_node(&world.nodes.position[range.clone()], at).map(|n| n + range.start)
}

/// Join bodies `a` and `b` at the nodes of each nearest to `at`; returns the shared node.
pub fn join_bodies_at(
    world: &mut World,
    a: BodyHandle,
    b: BodyHandle,
    at: Vector3<f64>,
) -> Result<SharedNode, JointError> {
    if a == b {
        return Err(JointError::SameBody);
    }
    for h in [a, b] {
        let info = world.bodies.get(h.0).ok_or(JointError::NoBody(h.0))?;
        if info.nodes.is_empty() {
            return Err(JointError::Empty(info.name.clone()));
        }
        if world.rigid.iter().any(|r| r.body == h.0) {
            return Err(JointError::Rigid(info.name.clone()));
        }
    }
    let i = nearest_body_node(world, a, at).ok_or(JointError::NoBody(a.0))?;
    let j = nearest_body_node(world, b, at).ok_or(JointError::NoBody(b.0))?;
    // A point inside or on a body lies within a spring's length of its nearest node.
    for (which, (h, n)) in [(a, i), (b, j)].into_iter().enumerate() {
        let distance_m = (world.nodes.position[n] - at).norm();
        let s = &world.springs;
        let reach_m = (0..s.len())
            .filter(|&k| s.a[k] as usize == n || s.b[k] as usize == n)
            .map(|k| s.rest_length[k])
            .fold(0.0, f64::max);
        if distance_m > reach_m {
            return Err(JointError::TooFar {
                body: world.bodies[h.0].name.clone(),
                which,
                distance_m,
                reach_m,
            });
        }
    }
    let shared = join_nodes(world, i, j)?;
    // Linked parts overlap at the joint: they do not collide with each other.
    let pair = (a.0.min(b.0), a.0.max(b.0));
    let ignored = &mut world.body_contact.ignored_pairs;
    if !ignored.contains(&pair) {
        ignored.push(pair);
    }
    Ok(shared)
}

/// The node `n` stands for (itself, or the node it was joined into).
pub fn resolve(world: &World, mut n: usize) -> usize {
    while let Some(s) = world.joints.iter().find(|s| s.follower == n) {
        n = s.kept;
    }
    n
}

/// Make node `j` the same point as node `i` (module docs).
pub fn join_nodes(world: &mut World, i: usize, j: usize) -> Result<SharedNode, JointError> {
    let (i, j) = (resolve(world, i), resolve(world, j));
    if i == j {
        return Err(JointError::AlreadyShared);
    }
    let s = &world.springs;
    if (0..s.len()).any(|k| {
        let (a, b) = (s.a[k] as usize, s.b[k] as usize);
        (a == i && b == j) || (a == j && b == i)
    }) {
        return Err(JointError::Connected);
    }
    let n = &mut world.nodes;
    let (mi, mj) = (n.mass[i], n.mass[j]);
    let m = mi + mj;
    if m > 0.0 {
        n.position[i] = (n.position[i] * mi + n.position[j] * mj) / m;
        n.velocity[i] = (n.velocity[i] * mi + n.velocity[j] * mj) / m;
    }
    let pinned = n.inv_mass[i] == 0.0 || n.inv_mass[j] == 0.0;
    n.mass[i] = m;
    n.inv_mass[i] = if pinned || m <= 0.0 { 0.0 } else { 1.0 / m };
    n.mass[j] = 0.0;
    n.inv_mass[j] = 0.0;
    n.position[j] = n.position[i];
    n.velocity[j] = n.velocity[i];
    let (i32_, j32) = (i as u32, j as u32);
    let s = &mut world.springs;
    for k in 0..s.len() {
        if s.a[k] == j32 {
            s.a[k] = i32_;
        }
        if s.b[k] == j32 {
            s.b[k] = i32_;
        }
        if s.a[k] == i32_ || s.b[k] == i32_ {
            let (a, b) = (s.a[k] as usize, s.b[k] as usize);
            s.rest_length[k] = (world.nodes.position[a] - world.nodes.position[b]).norm();
        }
    }
    for ids in &mut std::sync::Arc::make_mut(&mut world.surface).nodes {
        for id in ids.iter_mut().filter(|id| **id == j32) {
            *id = i32_;
        }
    }
    for c in &mut world.constraints {
        for id in c.nodes.iter_mut().filter(|id| **id == j) {
            *id = i;
        }
    }
    world.node_contact[i] |= world.node_contact[j];
    world.node_contact[j] = false;
    for follower in world.joints.iter_mut().filter(|s| s.kept == j) {
        follower.kept = i;
    }
    let shared = SharedNode {
        kept: i,
        follower: j,
    };
    world.joints.push(shared);
    world.invalidate_prepared();
    Ok(shared)
}

/// Put every follower on its kept node (after each step).
pub(crate) fn sync(joints: &[SharedNode], nodes: &mut super::NodeState) {
    for s in joints {
        nodes.position[s.follower] = nodes.position[s.kept];
        nodes.velocity[s.follower] = nodes.velocity[s.kept];
    }
}
