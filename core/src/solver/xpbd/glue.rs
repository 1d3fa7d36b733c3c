//! Glue between parts that interpenetrate at the start (see
//! [`crate::solver::body_contact::overlap`]): where two bodies' solids overlap, each lattice
//! node of one that lies inside the other's mesh becomes a material point of the other's
//! lattice, attached to the cell it lies in at rest. The pair no longer collides; the two
//! move as the one object the artist modelled (a sphere sunk into a box stays sunk in it, eyes
//! stay in the head). The two are also tied where their meshes cross: the corners of each
//! one's cells holding a crossing point are attached to the other's cells. That is all that
//! holds a part thinner than a cell (a rod through a box, no node of its lattice inside the
//! box) or a part through a sheet, which has no inside.
//!
//! An attachment is the zero-length XPBD constraint `C = x_n − Σ_k w_k x_k` (node `n`, the
//! cell's eight nodes `k` at trilinear weights `w`), with no compliance: it is solved exactly
//! each substep, after the cells, and it conserves momentum (`Σ w_k = 1`) and, being between
//! coincident points, angular momentum.

use super::super::body_contact::overlap::{start_overlaps, StartOverlaps};
use super::super::World;
use crate::collide::BoxGrid;
use nalgebra::{Matrix3, Vector3};

type V3 = Vector3<f64>;

/// How far outside its cell (in cell fractions) a node at rest may lie and still be attached
/// to it: rounding on a cell's faces.
const CELL_TOLERANCE: f64 = 1e-9;

/// A node attached to a point of another body's cell.
#[derive(Debug, Clone, PartialEq)]
struct Attachment {
    node: u32,
    cell: [u32; 8],
    weights: [f64; 8],
}

/// The attachments of all glued pairs.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Glue {
    attachments: Vec<Attachment>,
    /// The body pairs `(lower, higher)` that interpenetrate at the start, and whether they are
    /// glued (else they only ignore each other).
    pairs: Vec<((usize, usize), bool)>,
}

impl Glue {
    /// Find the pairs of `world`'s bodies that interpenetrate at rest, make them ignore each
    /// other in the contact pass, and attach the overlapping nodes of the pairs of flexible
    /// lattice bodies (a rigid or particle body is only kept from colliding); `kept` resolves
    /// joint followers to the node that stands for them.
    pub(crate) fn build(world: &mut World, kept: &[u32]) -> Glue {
        let flexible = |b: usize| {
            !world.rigid.iter().any(|r| r.body == b)
                && world.bodies[b].material.is_some()
                && !world.bodies[b].cells.is_empty()
        };
        let StartOverlaps {
            pairs,
            welds,
            touch_welded,
            mut solids,
        } = start_overlaps(world);
        // A rigid or particle part fitted into another, or on a seam, keeps its contact (a
        // dowel in a rigid board is held by the hole's walls); only flexible ones are welded.
        let (pairs, welds): (Vec<_>, Vec<_>) = (pairs.into_iter().zip(welds).zip(touch_welded))
            .filter(|&(((a, b), _), fit)| !fit || (flexible(a) && flexible(b)))
            .map(|(pair_weld, _)| pair_weld)
            .unzip();
        let mut attachments = Vec::new();
        let mut glued = Vec::new();
        for (&(a, b), weld) in pairs.iter().zip(&welds) {
            glued.push(flexible(a) && flexible(b));
            if !(flexible(a) && flexible(b)) {
                continue;
            }
            if !weld.is_empty() {
                for (from, to) in [(a, b), (b, a)] {
                    attach_at_crossings(world, kept, (from, to), weld, &mut attachments);
                }
            }
            for (from, to) in [(a, b), (b, a)] {
                let Some(solid) = solids[to].as_mut() else {
                    continue;
                };
                let mut cells = RestCells::new(world, to);
                for i in world.bodies[from].nodes.clone() {
                    let p = world.rest[i];
                    if world.nodes.mass[i] <= 0.0 || !solid.contains(&p) {
                        continue;
                    }
                    if let Some((cell, weights)) = cells.locate(world, &p) {
                        attachments.push(Attachment {
                            node: kept[i],
                            cell: cell.map(|k| kept[k as usize]),
                            weights,
                        });
                    }
                }
            }
        }
        for &pair in &pairs {
            if !world.body_contact.ignored_pairs.contains(&pair) {
                world.body_contact.ignored_pairs.push(pair);
            }
        }
        let pairs: Vec<_> = pairs.into_iter().zip(glued).collect();
        world.body_contact.assemblies = assemblies(world.bodies.len(), &pairs);
        Glue { attachments, pairs }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.attachments.is_empty()
    }

    /// The body pairs `(lower, higher)` that interpenetrate at the start, and whether they
    /// are glued.
    pub(crate) fn pairs(&self) -> &[((usize, usize), bool)] {
        &self.pairs
    }

    /// Put every attached node back on its point (in attachment order), moving node and cell
    /// by their inverse masses `w`.
    pub(crate) fn solve(&self, x: &mut [V3], w: &[f64]) {
        for a in &self.attachments {
            let n = a.node as usize;
            let mut target = V3::zeros();
            let mut total = w[n];
            for (k, &c) in a.cell.iter().enumerate() {
                target += x[c as usize] * a.weights[k];
                total += a.weights[k] * a.weights[k] * w[c as usize];
            }
            if total <= 0.0 {
                continue;
            }
            let step = (x[n] - target) / total;
            x[n] -= step * w[n];
            for (k, &c) in a.cell.iter().enumerate() {
                x[c as usize] += step * (a.weights[k] * w[c as usize]);
            }
        }
    }
}

/// Per body, its assembly: the bodies glued to it directly or through others share one,
/// numbered in the order of their lowest body; empty when no pair is glued.
fn assemblies(bodies: usize, pairs: &[((usize, usize), bool)]) -> Vec<usize> {
    if !pairs.iter().any(|&(_, glued)| glued) {
        return Vec::new();
    }
    let glued = (pairs.iter()).filter(|&&(_, glued)| glued);
    let edges = glued.map(|&((a, b), _)| (a as u32, b as u32));
    let (assembly, _) = crate::lattice::connected_components(bodies, edges);
    assembly.into_iter().map(|g| g as usize).collect()
}

/// Attach the corners of `from`'s cells that hold a crossing point of the pair at rest
/// (`weld`) to the cells of `to` they lie in: the two meshes pass through each other there
/// and move as one.
fn attach_at_crossings(
    world: &World,
    kept: &[u32],
    (from, to): (usize, usize),
    weld: &[V3],
    attachments: &mut Vec<Attachment>,
) {
    let (mut from_cells, mut to_cells) = (RestCells::new(world, from), RestCells::new(world, to));
    let mut corners = std::collections::BTreeSet::new();
    for p in weld {
        if let Some((cell, _)) = from_cells.locate(world, p) {
            corners.extend(cell);
        }
    }
    for i in corners {
        let i = i as usize;
        if world.nodes.mass[i] <= 0.0 {
            continue;
        }
        if let Some((cell, weights)) = to_cells.locate(world, &world.rest[i]) {
            attachments.push(Attachment {
                node: kept[i],
                cell: cell.map(|k| kept[k as usize]),
                weights,
            });
        }
    }
}

/// A body's cells at rest, found by point.
struct RestCells {
    body: usize,
    grid: BoxGrid,
    found: Vec<u32>,
}

impl RestCells {
    fn new(world: &World, body: usize) -> RestCells {
        let cells = &world.bodies[body].cells;
        let bounds = |cell: &[u32; 8]| {
            cell.iter().fold(
                (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY)),
                |(lo, hi), &i| {
                    (
                        lo.inf(&world.rest[i as usize]),
                        hi.sup(&world.rest[i as usize]),
                    )
                },
            )
        };
        let boxes: Vec<(V3, V3)> = cells.iter().map(bounds).collect();
        let (lo, hi) = boxes.iter().fold(
            (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY)),
            |(lo, hi), (a, b)| (lo.inf(a), hi.sup(b)),
        );
        let size = boxes.first().map_or(1.0, |(a, b)| (b - a).max());
        let mut grid = BoxGrid::default();
        let entries = boxes
            .iter()
            .enumerate()
            .map(|(i, &(a, b))| (i as u32, a, b));
        grid.build(lo, hi, size, cells.len(), entries);
        RestCells {
            body,
            grid,
            found: Vec::new(),
        }
    }

    /// The first cell (in cell order) holding `p` at rest, with `p`'s trilinear weights in
    /// it. A cell is a parallelepiped at rest (corners 1, 2 and 4 span it from corner 0);
    /// cells that are not (a cage's tets, a sheared cell) hold nothing.
    fn locate(&mut self, world: &World, p: &V3) -> Option<([u32; 8], [f64; 8])> {
        self.grid.query(p, p, &mut self.found);
        self.found.sort_unstable();
        let cells = &world.bodies[self.body].cells;
        self.found.iter().find_map(|&c| {
            let cell = cells[c as usize];
            let x = cell.map(|i| world.rest[i as usize]);
            let frame = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[4] - x[0]]);
            let u = frame.try_inverse()? * (p - x[0]);
            let within = |v: f64| (-CELL_TOLERANCE..=1.0 + CELL_TOLERANCE).contains(&v);
            if !u.iter().all(|&v| within(v)) {
                return None;
            }
            let u = u.map(|v| v.clamp(0.0, 1.0));
            let weights: [f64; 8] = std::array::from_fn(|c| {
                (0..3)
                    .map(|k| if (c >> k) & 1 == 1 { u[k] } else { 1.0 - u[k] })
                    .product()
            });
            // A cell that is no parallelepiped at rest would pull the node at the first step.
            let point: V3 = (0..8).map(|c| x[c] * weights[c]).sum();
            let size = frame.column(0).norm();
            ((point - p).norm() <= 1e-9 * size).then_some((cell, weights))
        })
    }
}
