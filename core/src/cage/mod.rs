//! Analysis models besides the auto-fitted lattice (physics §8, Terasawa's "analysis model"):
//! coarse *cages* the display mesh is embedded in. A [`Cage`] is nodes, springs and a
//! tetrahedralisation of its volume:
//!
//! - **Primitive cages** (`box`, `octahedron`, `icosahedron`): the unit shape scaled by the
//!   mesh's half extents about its bounding-box centre (thin axes floored at 5 % of the largest
//!   half extent), then inflated uniformly about the centre just enough to contain every mesh
//!   vertex. One **centre node** is added; the tets are the fan from the centre to each
//!   (triangulated) face; the springs are the tets' edges: the cage's surface edges plus a
//!   spoke from the centre to every surface node (a triangulated closed surface is rigid as a
//!   framework; the spokes add volume stiffness, so the cage is not floppy).
//! - **`plane`**: a slab one cell thick across the mesh's two widest axes (`cells` along the
//!   widest, thickness the mesh's own or 5 % of its width), every hexahedron split into the 6
//!   Kuhn tets around its main diagonal (conforming between neighbours); springs are all tet
//!   edges. For cloth, flags and other sheets.
//! - **`decimated`** ([`decimate`]): the mesh's vertices clustered on a grid to about
//!   `cage_vertices` nodes (cluster mean), its triangles remapped (degenerate ones dropped),
//!   plus a centre node and the fan as above — when that surface is closed and star-shaped
//!   about its centre (every fan tet positively oriented). Otherwise the convex hull of the
//!   clustered nodes is used instead, and [`Cage::note`] says so.
//! - **`explicit`**: the scene's own nodes and springs. The tets for the embedding are a fan
//!   over the nodes' convex hull from an interior node (the one nearest the hull's centroid) or
//!   else from a hull vertex; nodes that are neither on the hull nor the apex carry no
//!   embedding weight (they are still simulated).
//!
//! **Embedding** ([`Cage::embed`]): a point takes barycentric weights in the tet that contains
//! it; a point outside every tet uses the tet whose smallest barycentric coordinate is largest
//! (the least-outside one) and extrapolates. The weights are padded to the lattice's 8 (4 zero
//! weights on the tet's first node), so the display mesh, the contact samples and the skin
//! cache use one [`Embedding`] type. Exact for any affine motion of a tet; across tets the
//! mapping is continuous inside the cage. **Limits**: linear per tet, so a coarse cage bends
//! the mesh along tet faces (visible creases under large deformation of a 13-node icosahedron);
//! a convex cage (hull, primitives) spans concavities, so the parts of a U-shaped mesh cannot
//! move independently; extrapolated points (outside every tet) are continuous only within one
//! tet.
//!
//! **Physics in real units** ([`Cage::body_parameters`]): node masses lump each tet's mass
//! (density × volume) a quarter to each corner, scaled so the body weighs density × the
//! *mesh's* enclosed volume when the mesh is closed (the cage's volume otherwise). A spring of
//! rest length `L` gets `k = 6 E V_e / L²`, `V_e` its share of the tets' volume (a sixth of
//! each tet it is an edge of); for an isotropic network this gives Young's modulus `E` exactly
//! (`E = Σ k L² / 6V`; a central-force network's Poisson ratio is ¼). Explicit models have no
//! tets per spring: every spring gets `k = 6 E V / Σ L²`. Dampers `D = 2ζ sqrt(k μ)` as in the
//! lattice. For comparison, Miyazaki's `k = E·L` on the `both` lattice gives
//! `Σ k L² / 6V = 4.5 E`, so a lattice body is stiffer than a cage of the same material.

pub mod decimate;
pub mod embed;
pub mod explicit;
pub mod hull;
pub mod primitives;

pub use decimate::decimated;
pub use explicit::explicit;
pub use hull::convex_hull;
pub use primitives::{plane, primitive, Primitive};

use crate::lattice::{Embedding, Lattice, Spring};
use crate::material::Material;
use crate::solver::{BodyHandle, World};
use nalgebra::{Point3, Vector3};

/// A cage analysis model in world metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Cage {
    /// What built it: `box`, `octahedron`, `icosahedron`, `plane`, `decimated`, `explicit`.
    pub model: &'static str,
    pub nodes: Vec<Vector3<f64>>,
    /// Node pairs joined by a spring.
    pub springs: Vec<[u32; 2]>,
    /// Positively oriented tetrahedra covering the cage's volume (embedding, masses, stiffness).
    pub tets: Vec<[u32; 4]>,
    /// Set when the model is not what was asked for exactly (e.g. the decimated surface was
    /// replaced by the convex hull).
    pub note: Option<String>,
    /// Explicit models: springs get one stiffness from the total volume instead of per-tet
    /// shares.
    pub uniform_springs: bool,
}

/// A model that cannot be built, with the scene field to blame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct CageError {
    pub field: String,
    pub message: String,
}

impl CageError {
    pub(crate) fn new(field: impl Into<String>, message: impl Into<String>) -> CageError {
        CageError {
            field: field.into(),
            message: message.into(),
        }
    }
}

/// Masses and springs of a cage body, ready for [`World::add_body`].
#[derive(Debug, Clone, PartialEq)]
pub struct BodyParameters {
    pub masses: Vec<f64>,
    /// `(a, b, k, D)` per spring.
    pub springs: Vec<(u32, u32, f64, f64)>,
}

/// Tet `t` as a degenerate lattice cell `[a, b, a, c, a, a, a, d]`: of the 6 Kuhn tets the
/// volume code splits a cell into (around its 0–7 diagonal) only `[0, 1, 3, 7]` = `t` has
/// volume, and the other five contribute exactly zero volume and zero gradient. So a cage
/// body's tets sit in [`crate::solver::BodyInfo::cells`]: volume preservation holds the tets'
/// volume, and the inverted-cell count tests the tet itself ([`is_tet_cell`]).
pub fn tet_cell(t: [u32; 4]) -> [u32; 8] {
    let [a, b, c, d] = t;
    [a, b, a, c, a, a, a, d]
}

/// Whether a cell is a tet stored by [`tet_cell`] (lattice cells have 8 distinct nodes).
pub fn is_tet_cell(c: &[u32; 8]) -> bool {
    c[2] == c[0] && c[4] == c[0] && c[5] == c[0] && c[6] == c[0] && c[1] != c[0]
}

/// Signed volume of tet `t`.
pub fn tet_volume(t: &[u32; 4], x: &[Vector3<f64>]) -> f64 {
    let a = x[t[0] as usize];
    (x[t[1] as usize] - a).dot(&(x[t[2] as usize] - a).cross(&(x[t[3] as usize] - a))) / 6.0
}

/// Enclosed volume of a closed triangle mesh (divergence theorem), m³; about 0 for open sheets.
pub fn mesh_volume(points: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| points[i as usize].coords);
            a.dot(&b.cross(&c)) / 6.0
        })
        .sum()
}

impl Cage {
    /// Total volume of the tets, m³.
    pub fn volume(&self) -> f64 {
        self.tets.iter().map(|t| tet_volume(t, &self.nodes)).sum()
    }

    /// Mean spring rest length, m: the cage's "cell size" for the contact layer and the
    /// surface sample spacing.
    pub fn spacing(&self) -> f64 {
        if self.springs.is_empty() {
            return 0.0;
        }
        self.springs
            .iter()
            .map(|s| (self.nodes[s[0] as usize] - self.nodes[s[1] as usize]).norm())
            .sum::<f64>()
            / self.springs.len() as f64
    }

    /// Longest extent of the nodes' bounding box, m.
    pub fn longest_extent(&self) -> f64 {
        let (lo, hi) = bounds(self.nodes.iter().copied());
        (hi - lo).max()
    }

    /// Node masses (kg) and springs `(a, b, k, D)` for `material`; the total mass is
    /// density × `mass_volume` (pass the mesh's enclosed volume, or `None` for the cage's).
    pub fn body_parameters(&self, material: &Material, mass_volume: Option<f64>) -> BodyParameters {
        let volume = self.volume();
        let target = mass_volume.filter(|v| *v > 0.0).unwrap_or(volume);
        let scale = if volume > 0.0 { target / volume } else { 0.0 };
        let mut masses = vec![0.0; self.nodes.len()];
        let mut edge_volume = std::collections::HashMap::<(u32, u32), f64>::new();
        for t in &self.tets {
            let v = tet_volume(t, &self.nodes);
            for &n in t {
                masses[n as usize] += material.density_kg_m3 * v * scale / 4.0;
            }
            for i in 0..4 {
                for j in i + 1..4 {
                    let key = (t[i].min(t[j]), t[i].max(t[j]));
                    *edge_volume.entry(key).or_insert(0.0) += v / 6.0;
                }
            }
        }
        // Nodes in no tet (explicit models): an equal share of the mean node mass, so nothing
        // is massless (a massless node would be pinned).
        let lumped: f64 = masses.iter().sum();
        let in_tets = masses.iter().filter(|m| **m > 0.0).count().max(1);
        let fallback = if lumped > 0.0 {
            lumped / in_tets as f64
        } else {
            material.density_kg_m3 * target / self.nodes.len().max(1) as f64
        };
        for m in masses.iter_mut().filter(|m| **m <= 0.0) {
            *m = fallback;
        }
        let sum_l2: f64 = self
            .springs
            .iter()
            .map(|s| (self.nodes[s[0] as usize] - self.nodes[s[1] as usize]).norm_squared())
            .sum();
        let springs = self
            .springs
            .iter()
            .map(|&[a, b]| {
                let l2 = (self.nodes[a as usize] - self.nodes[b as usize]).norm_squared();
                let k = if self.uniform_springs {
                    6.0 * material.young_pa * volume / sum_l2
                } else {
                    let ve = edge_volume
                        .get(&(a.min(b), a.max(b)))
                        .copied()
                        .unwrap_or(0.0);
                    6.0 * material.young_pa * ve / l2
                };
                let (ma, mb) = (masses[a as usize], masses[b as usize]);
                let mu = ma * mb / (ma + mb);
                (a, b, k, 2.0 * material.damping_ratio * (k * mu).sqrt())
            })
            .collect();
        BodyParameters { masses, springs }
    }

    /// Add the cage to `world` as a body: masses and springs from [`Self::body_parameters`],
    /// all nodes moving at `velocity`, deformation damping as for a lattice of the same extent,
    /// its tets as the body's cells ([`tet_cell`]).
    pub fn add_to_world(
        &self,
        world: &mut World,
        name: impl Into<String>,
        material: &Material,
        mass_volume: Option<f64>,
        velocity: Vector3<f64>,
    ) -> BodyHandle {
        let p = self.body_parameters(material, mass_volume);
        let handle = world.add_body(name, &self.nodes, &p.masses, &p.springs, velocity);
        let base = world.bodies[handle.0].nodes.start as u32;
        world.bodies[handle.0].cells = self
            .tets
            .iter()
            .map(|t| tet_cell(t.map(|n| n + base)))
            .collect();
        world.bodies[handle.0].material = Some(material.clone());
        world.bodies[handle.0].deformation_damping =
            crate::solver::deformation_damping::damping_rate(
                material.damping_ratio,
                material.young_pa,
                material.density_kg_m3,
                self.longest_extent(),
            );
        handle
    }

    /// Give a cage body a display-surface contact: `points` (rest pose, e.g. from
    /// [`crate::lattice::surface_samples`]) with their areas, embedded in the cage (4 weights
    /// padded to the 8 of [`crate::solver::SurfacePoints`]). From then on the floor, walls and
    /// manipulators touch these points, not the cage nodes (which stand well off the mesh for
    /// a primitive cage). A point's share of a node's layer stiffness is its area over
    /// [`Self::spacing`]².
    pub fn add_contact_surface(
        &self,
        world: &mut World,
        body: BodyHandle,
        points: &[Point3<f64>],
        areas_m2: &[f64],
    ) {
        let embedding = self.embed(points);
        let range = world.bodies[body.0].nodes.clone();
        let base = range.start as u32;
        let h = self.spacing().max(1e-9);
        let shares: Vec<f64> = (0..points.len())
            .map(|i| areas_m2.get(i).copied().unwrap_or(0.0) / (h * h))
            .collect();
        let total_share: f64 = shares.iter().sum();
        let body_mass: f64 = world.nodes.mass[range.clone()].iter().sum();
        let s = std::sync::Arc::make_mut(&mut world.surface);
        for (i, nodes) in embedding.nodes.iter().enumerate() {
            // How far the point may be from its tet's first node: three times its rest
            // distance or the tet's size, whichever is larger.
            let first = self.nodes[nodes[0] as usize];
            let tet_size = nodes[..4]
                .iter()
                .map(|&n| (self.nodes[n as usize] - first).norm())
                .fold(0.0, f64::max);
            let reach = 3.0 * (points[i].coords - first).norm().max(tet_size);
            s.nodes.push(nodes.map(|n| n + base));
            s.weights.push(embedding.weights[i]);
            s.share.push(shares[i]);
            s.body.push(body.0 as u32);
            s.reach.push(reach);
            s.rest_normal.push(Vector3::zeros());
            s.body_mass.push(if total_share > 0.0 {
                body_mass * shares[i] / total_share
            } else {
                0.0
            });
        }
        for n in range {
            world.node_contact[n] = false;
        }
        world.invalidate_prepared();
    }

    /// The cage as a cell-less [`Lattice`] (nodes and springs, `cell_size` = [`Self::spacing`]),
    /// for hosts that show or report an analysis lattice.
    pub fn lattice_view(&self) -> Lattice {
        let (lo, _) = bounds(self.nodes.iter().copied());
        Lattice::from_parts(
            lo,
            self.spacing(),
            [0, 0, 0],
            Vec::new(),
            Vec::new(),
            self.nodes.iter().map(|p| Point3::from(*p)).collect(),
            self.springs
                .iter()
                .map(|&[a, b]| Spring {
                    a,
                    b,
                    rest_length: (self.nodes[a as usize] - self.nodes[b as usize]).norm(),
                })
                .collect(),
        )
    }

    /// Embed `points` (rest pose) in the cage (module docs).
    pub fn embed(&self, points: &[Point3<f64>]) -> Embedding {
        embed::embed(&self.nodes, &self.tets, points)
    }

    /// A fan cage: `surface` nodes and triangles (outward), plus a centre node at `centre`;
    /// tets are the fan, springs the tets' edges. Degenerate tets are dropped.
    pub(crate) fn fan(
        model: &'static str,
        mut nodes: Vec<Vector3<f64>>,
        surface: &[[u32; 3]],
        centre: Vector3<f64>,
    ) -> Cage {
        let c = nodes.len() as u32;
        nodes.push(centre);
        let scale = {
            let (lo, hi) = bounds(nodes.iter().copied());
            (hi - lo).max().max(1e-12)
        };
        let mut tets = Vec::new();
        for f in surface {
            let t = [f[0], f[1], f[2], c];
            let v = tet_volume(&t, &nodes);
            if v > 1e-12 * scale.powi(3) {
                tets.push(t);
            } else if v < -1e-12 * scale.powi(3) {
                tets.push([f[0], f[2], f[1], c]);
            }
        }
        let springs = tet_edges(&tets);
        Cage {
            model,
            nodes,
            springs,
            tets,
            note: None,
            uniform_springs: false,
        }
    }

    /// Scale the nodes about node `centre` so every point lies inside a fan tet (by the radial
    /// coordinate), with 1 % to spare; no change when all are inside already.
    pub(crate) fn inflate_to_contain(&mut self, centre: u32, points: &[Point3<f64>]) {
        let c = self.nodes[centre as usize];
        let mut worst: f64 = 0.0;
        let inverses = embed::inverses(&self.nodes, &self.tets);
        for p in points {
            // The tet whose face the ray from the centre crosses: largest smallest face weight.
            let mut best: Option<(f64, f64)> = None;
            for (t, inv) in self.tets.iter().zip(&inverses) {
                let Some(inv) = inv else { continue };
                let l = embed::barycentric(&self.nodes, t, inv, &p.coords);
                let apex = t.iter().position(|&n| n == centre);
                let Some(apex) = apex else { continue };
                let face_min = (0..4)
                    .filter(|&k| k != apex)
                    .map(|k| l[k])
                    .fold(f64::INFINITY, f64::min);
                if best.is_none_or(|(m, _)| face_min > m) {
                    best = Some((face_min, 1.0 - l[apex]));
                }
            }
            if let Some((_, radial)) = best {
                worst = worst.max(radial);
            }
        }
        if worst > 1.0 {
            let s = worst * 1.01;
            for x in &mut self.nodes {
                *x = c + (*x - c) * s;
            }
        }
    }
}

/// Unique edges of `tets`, sorted.
pub(crate) fn tet_edges(tets: &[[u32; 4]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = tets
        .iter()
        .flat_map(|t| {
            let mut e = Vec::with_capacity(6);
            for i in 0..4 {
                for j in i + 1..4 {
                    e.push([t[i].min(t[j]), t[i].max(t[j])]);
                }
            }
            e
        })
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Axis-aligned bounds of `points`.
pub(crate) fn bounds(points: impl Iterator<Item = Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    points.fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(&p), hi.sup(&p)),
    )
}
