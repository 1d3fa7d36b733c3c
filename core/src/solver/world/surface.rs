//! The display-surface contact points of the world's bodies (embedded in their lattices).

use super::*;

/// Display-surface contact points (see [`crate::lattice::surface_samples`]), embedded in their
/// body's lattice: a rigid contact at a point pushes its cell's 8 nodes by the trilinear
/// weights (Terasawa eq 3.43–3.47), so the *mesh* rests on the floor and a thin manipulator
/// cannot slip between nodes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfacePoints {
    /// World node indices of each point's cell.
    pub nodes: Vec<[u32; 8]>,
    pub weights: Vec<[f64; 8]>,
    /// The point's area over a cell face (L²): its share of a node's contact stiffness.
    pub share: Vec<f64>,
    /// The body's mass per contact share times the point's share, kg: the mass the point's
    /// contact damper is scaled for, so a body landing on its surface is damped as a whole
    /// (a damper scaled for the point's own tiny mass lets a heavy body bounce almost forever).
    pub body_mass: Vec<f64>,
    /// The body each point belongs to.
    pub body: Vec<u32>,
    /// How far a point can be from its cell's first corner, m (three cell diagonals: cells
    /// stretched by the bounded dispersion stay well inside).
    pub reach: Vec<f64>,
    /// The display surface's unit normal at the point at rest, where it is known (a lattice
    /// body's samples from [`crate::lattice::surface_samples_with_normals`]); zero elsewhere
    /// (a cage's samples, or samples given without). [`SurfacePoints::normal_now`] turns it
    /// with the point's cell.
    pub rest_normal: Vec<Vector3<f64>>,
}

impl SurfacePoints {
    /// Rigid contact of point `i` for node positions in `nodes` and node velocities
    /// `velocities`: (force, depth, force from the manipulators). The point feels the layer at
    /// its share of a node's stiffness, damped for its share of the body's mass or its
    /// effective mass `1 / Σ w²/m` through its cell's nodes, whichever is larger.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn contact(
        &self,
        i: usize,
        nodes: &NodeState,
        velocities: &[Vector3<f64>],
        layer: &ContactLayer,
        planes: &[Plane],
        capsules: &[Capsule],
        dt: f64,
    ) -> (Vector3<f64>, f64, Vector3<f64>) {
        let (w, ids) = (&self.weights[i], &self.nodes[i]);
        let mut x = Vector3::zeros();
        for c in 0..8 {
            x += nodes.position[ids[c] as usize] * w[c];
        }
        // No contact: what node_contacts would give (+0 throughout), without its inputs.
        if !touches_any(planes, capsules, &x) {
            return (Vector3::zeros(), 0.0, Vector3::zeros());
        }
        let (mut v, mut compliance) = (Vector3::zeros(), 0.0);
        for c in 0..8 {
            let n = ids[c] as usize;
            v += velocities[n] * w[c];
            compliance += w[c] * w[c] * nodes.inv_mass[n];
        }
        let share = self.share[i];
        let effective = if compliance > 0.0 {
            share / compliance
        } else {
            0.0
        };
        let point_layer = ContactLayer {
            stiffness: layer.stiffness * share,
            ..*layer
        };
        node_contacts(
            &point_layer,
            planes,
            capsules,
            x,
            v,
            effective.max(self.body_mass[i]),
            dt,
        )
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Point `i`'s surface normal for node positions `x`: its rest normal turned and sheared
    /// with its cell, by the cofactor of the cell's mean edge vectors (a lattice at rest is
    /// axis-aligned, its corners in [`crate::lattice::CORNERS`] order). `None` where the rest
    /// normal is not known or the cell is crushed flat.
    pub(crate) fn normal_now(&self, i: usize, x: &[Vector3<f64>]) -> Option<Vector3<f64>> {
        let rest = *self.rest_normal.get(i)?;
        if rest == Vector3::zeros() {
            return None;
        }
        let c = self.nodes[i].map(|n| x[n as usize]);
        let along_x = (c[1] - c[0]) + (c[3] - c[2]) + (c[5] - c[4]) + (c[7] - c[6]);
        let along_y = (c[2] - c[0]) + (c[3] - c[1]) + (c[6] - c[4]) + (c[7] - c[5]);
        let along_z = (c[4] - c[0]) + (c[5] - c[1]) + (c[6] - c[2]) + (c[7] - c[3]);
        let turned = along_y.cross(&along_z) * rest.x
            + along_z.cross(&along_x) * rest.y
            + along_x.cross(&along_y) * rest.z;
        turned.try_normalize(1e-12)
    }
}
