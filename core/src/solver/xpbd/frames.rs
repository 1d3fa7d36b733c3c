//! Held and rigid bodies as rigid bodies in the contact passes (body–body, [`super::bodies`];
//! static colliders, [`super::rigid_contacts`]): each such body's frame for one contact pass
//! (its centre, inverse mass and inertia, and the motion the pass's contacts give it), and
//! which frame each node belongs to.

use super::bodies::NO_FRAME;
use super::V3;
use nalgebra::Matrix3;
use std::ops::Range;

/// A held or rigid body as one rigid body in the body–body contacts: a contact moves it as a whole
/// (its translation and a small rotation about its centre, accumulated over the pass and
/// applied to its nodes after it), with the rigid body's inverse mass along the contact,
/// `1/M + (r × n)ᵀ I⁻¹ (r × n)`. Through its nodes, a contact moved only the eight round its
/// point and the shape matching spread that over the body: a steel box moved a tenth of what
/// the contact asked, and one steel box set on another sank through it. A rigid body
/// (`kind = "rigid"`) took the same push as momentum of those nodes, summed into its frame's:
/// two rigid boxes passed through each other.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct RigidFrame {
    pub nodes: Range<usize>,
    pub centre: V3,
    /// 0 for a body that a pin or path holds.
    pub inverse_mass: f64,
    pub inverse_inertia: Matrix3<f64>,
    /// The pass's accumulated translation and rotation (a small-angle vector), m and rad.
    pub translation: V3,
    pub rotation: V3,
}

/// The rigid frames at `position` of the bodies whose nodes are `bodies` (each with whether
/// it may turn: a particle may not), for the body–body contacts ([`super::bodies`]), and per
/// node the index of its frame ([`NO_FRAME`] for nodes of other bodies) into
/// `frame_of` (resized to the node count; emptied when there are none). A body with a pinned
/// or path-bound node does not move in a contact (its inverse mass is zero).
pub(crate) fn rigid_frames(
    bodies: impl Iterator<Item = (Range<usize>, bool)>,
    (position, mass, inv_mass): (&[V3], &[f64], &[f64]),
    frame_of: &mut Vec<u32>,
) -> Vec<RigidFrame> {
    frame_of.clear();
    let mut frames = Vec::new();
    for (range, turns) in bodies {
        if frames.is_empty() {
            frame_of.resize(position.len(), NO_FRAME);
        }
        let free = range.clone().all(|i| inv_mass[i] > 0.0 || mass[i] <= 0.0);
        let total: f64 = range.clone().map(|i| mass[i]).sum();
        let centre = if total > 0.0 {
            range.clone().map(|i| position[i] * mass[i]).sum::<V3>() / total
        } else {
            V3::zeros()
        };
        let mut inertia = Matrix3::zeros();
        for i in range.clone() {
            let r = position[i] - centre;
            inertia += (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * mass[i];
        }
        let inverse = (free && total > 0.0)
            .then(|| inertia.try_inverse())
            .flatten()
            .filter(|m| m.iter().all(|v| v.is_finite()));
        for i in range.clone() {
            frame_of[i] = frames.len() as u32;
        }
        let turning = inverse.filter(|_| turns).unwrap_or_else(Matrix3::zeros);
        frames.push(RigidFrame {
            nodes: range,
            centre,
            inverse_mass: if inverse.is_some() { 1.0 / total } else { 0.0 },
            inverse_inertia: turning,
            translation: V3::zeros(),
            rotation: V3::zeros(),
        });
    }
    frames
}

impl RigidFrame {
    /// Where node position `x` is with the pass's motion so far.
    pub fn moved(&self, x: V3) -> V3 {
        x + self.translation + self.rotation.cross(&(x - self.centre))
    }

    /// The inverse mass of point `p` of the body along unit `n`.
    pub fn inverse_mass_at(&self, p: V3, n: V3) -> f64 {
        let rn = (p - self.centre).cross(&n);
        self.inverse_mass + rn.dot(&(self.inverse_inertia * rn))
    }

    /// Move the body by the positional impulse `impulse` at point `p`.
    pub fn push(&mut self, p: V3, impulse: V3) {
        self.translation += impulse * self.inverse_mass;
        self.rotation += self.inverse_inertia * (p - self.centre).cross(&impulse);
    }
}

/// Move each frame's nodes in `x` by the motion its pass gave it, adding that to `shift` and
/// marking them `moved`.
pub(crate) fn apply_frames(
    frames: &[RigidFrame],
    x: &mut [V3],
    shift: &mut [V3],
    moved: &mut [bool],
) {
    for f in frames {
        if f.translation == V3::zeros() && f.rotation == V3::zeros() {
            continue;
        }
        for k in f.nodes.clone() {
            let to = f.moved(x[k]);
            shift[k] += to - x[k];
            x[k] = to;
            moved[k] = true;
        }
    }
}
