//! What the world registers with body–body contact before stepping: each body's display
//! surface as the faces its partners' samples meet (clustered, refined and embedded in its
//! lattice, [`World::add_collision_surface`]), the static colliders, and the contact model.

use super::mesh::refine;
use super::*;

/// The longest edge a body's contact faces keep, in its cells: longer display triangles are
/// halved until none is ([`refine`]), so a face's reaction lands on the cells under
/// the contact (every point of a face lies within this of its corners), not on the corners
/// of a coarse mesh's big triangles. Not the samples' spacing of half a cell: bisection leaves
/// a face's triangles with their longest edge anywhere between half the limit and the limit,
/// and at half a cell a 20 cm cube at 3 cells (6.7 cm cells) was cut into 256 triangles a
/// face, edges of 1.8 and 2.5 cm, where 3/4 of a cell gives 128.
/// The faces' upkeep and search is most of a pile's contact pass: 60 such cubes 1 cm apart
/// baked 24 frames in 11.7–12.0 s instead of 14.1–14.7 s, two 30 cm rubber boxes stacked
/// at 10 cells in 9.4 s instead of 11.7 s, and they swayed as before (docs/benchmarks.md).
const FACE_EDGE_CELLS: f64 = 0.75;

impl World {
    /// Register `body`'s display surface (`positions` in world metres at rest, `triangles`
    /// counter-clockwise from outside) for contact with other bodies: its vertices are
    /// embedded in `lattice` (the body's own), triangles with an edge over
    /// [`FACE_EDGE_CELLS`] refined first. The body's contact samples (see
    /// [`World::add_contact_surface`]) touch the other bodies' triangles and the static
    /// colliders. Call before stepping. A lattice without cells (a cage's view) cannot embed:
    /// use [`World::add_embedded_collision_surface`].
    pub fn add_collision_surface(
        &mut self,
        body: BodyHandle,
        lattice: &Lattice,
        positions: &[Point3<f64>],
        triangles: &[[u32; 3]],
    ) {
        if lattice.cells.is_empty() {
            return;
        }
        // Clustered like the samples' vertices (at half a cell's spacing), then refined.
        let sample_spacing = 0.5 * lattice.cell_size;
        let clustered = simplify::cluster_triangles(
            positions,
            triangles,
            crate::lattice::VERTEX_CLUSTER * sample_spacing,
        );
        let longest = FACE_EDGE_CELLS * lattice.cell_size;
        let (refined, refined_triangles) = refine(positions, &clustered, longest);
        let embedding = Embedding::new(lattice, &refined);
        self.register_mesh(
            body,
            &embedding,
            positions,
            triangles,
            &refined,
            refined_triangles,
            lattice.cell_size,
        );
    }

    /// [`World::add_collision_surface`] for a body whose display vertices are already embedded
    /// in its nodes (`embedding`, body-local node indices, one entry per position; e.g. a cage
    /// model's), with `spacing` its node spacing, m. Triangles are not refined.
    pub fn add_embedded_collision_surface(
        &mut self,
        body: BodyHandle,
        embedding: &Embedding,
        positions: &[Point3<f64>],
        triangles: &[[u32; 3]],
        spacing: f64,
    ) {
        if embedding.len() != positions.len() {
            return;
        }
        let kept: Vec<[u32; 3]> = triangles
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < positions.len()))
            .copied()
            .collect();
        self.register_mesh(
            body, embedding, positions, triangles, positions, kept, spacing,
        );
    }

    /// Store a collision mesh: `display` triangles over `positions` (for edges and the local
    /// radius), `refined` triangles over `refined_positions` (a superset of `positions`, same
    /// leading indices) embedded by `embedding` (body-local nodes).
    #[allow(clippy::too_many_arguments)]
    fn register_mesh(
        &mut self,
        body: BodyHandle,
        embedding: &Embedding,
        positions: &[Point3<f64>],
        display: &[[u32; 3]],
        refined_positions: &[Point3<f64>],
        triangles: Vec<[u32; 3]>,
        spacing: f64,
    ) {
        let Some(info) = self.bodies.get(body.0) else {
            return;
        };
        let base = info.nodes.start as u32;
        let display: Vec<[u32; 3]> = display
            .iter()
            .filter(|t| t.iter().all(|&i| (i as usize) < positions.len()))
            .copied()
            .collect();
        // Display edges (refinement keeps the corners' indices).
        let mut seen = std::collections::BTreeSet::new();
        let mut edges = Vec::new();
        // Samples are at most a node spacing apart along any edge (a triangle up to twice the
        // sample spacing keeps its corners as samples), so an edge crossing a shorter edge
        // passes within half a spacing of a sample, inside the layer: only longer edges take
        // part in edge–edge tests.
        for t in &display {
            for e in 0..3 {
                let (i, j, k) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let long = (positions[i as usize] - positions[j as usize]).norm() > spacing;
                if long && seen.insert((i.min(j), i.max(j))) {
                    edges.push([i, j, k]);
                }
            }
        }
        let mut edge_sum = 0.0;
        for tri in &triangles {
            for e in 0..3 {
                let (i, j) = (tri[e] as usize, tri[(e + 1) % 3] as usize);
                edge_sum += (refined_positions[i] - refined_positions[j]).norm();
            }
        }
        let springs: Vec<hertz::SpringEdge> = info
            .springs
            .clone()
            .filter(|&s| self.springs.rest_length[s] > 0.0 && self.springs.stiffness[s] > 0.0)
            .map(|s| hertz::SpringEdge {
                length_m: self.springs.rest_length[s],
                k_n_per_m: self.springs.stiffness[s],
            })
            .collect();
        let young = hertz::young_from_springs(&springs, hertz::lattice_spring_area_m2(spacing))
            .unwrap_or(f64::INFINITY);
        let mean_edge = if triangles.is_empty() {
            spacing
        } else {
            edge_sum / (3 * triangles.len()) as f64
        };
        let closed = mesh::closed_outward(positions, &display);
        let mut mesh = BodyMesh::new(
            body.0,
            embedding
                .nodes
                .iter()
                .map(|c| c.map(|i| i + base))
                .collect(),
            embedding.weights.clone(),
            triangles,
            edges,
            display,
            (mean_edge, spacing, young),
        );
        mesh.closed = closed;
        let bc = &mut self.body_contact;
        bc.meshes.retain(|m| m.body != body.0);
        bc.meshes.push(mesh);
        bc.built_for = (usize::MAX, 0);
    }

    /// Add a static collider; returns its index (the log's [`ContactPartner::Collider`]).
    pub fn add_collider(&mut self, collider: StaticCollider) -> usize {
        let bc = &mut self.body_contact;
        bc.colliders.push(collider);
        bc.built_for = (usize::MAX, 0);
        bc.colliders.len() - 1
    }

    /// The static colliders.
    pub fn colliders(&self) -> &[StaticCollider] {
        &self.body_contact.colliders
    }

    /// The bodies that start inside a static collider, deeper than the contact layer (which
    /// the collider cannot push out: see [`overlap::inside_colliders`]), as (body, collider)
    /// names.
    pub fn bodies_inside_colliders(&self) -> Vec<(String, String)> {
        overlap::inside_colliders(self)
            .into_iter()
            .map(|(b, c)| {
                let collider = &self.body_contact.colliders[c];
                (self.bodies[b].name.clone(), collider.name.clone())
            })
            .collect()
    }

    /// How bodies push on each other and on colliders (default: the elastic layer).
    pub fn set_contact_model(&mut self, model: ContactModel) {
        self.body_contact.model = model;
    }
}
