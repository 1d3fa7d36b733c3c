//! Locality: per-region mass and stiffness (physics §9, e.g. a heavy bottom). A region is an
//! axis-aligned box (world metres, rest pose); nodes inside get `mass_scale` × their mass,
//! springs whose midpoint is inside get `stiffness_scale` × their stiffness, and every
//! spring's damper is rescaled by `sqrt(k'μ' / kμ)` so its damping ratio is kept. Regions
//! apply in order; overlapping regions multiply. Call before stepping and before giving the
//! body a contact surface (the surface's damper masses are read from the node masses).

use super::{BodyHandle, World};
use nalgebra::Vector3;

/// A box with its scales.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub min: Vector3<f64>,
    pub max: Vector3<f64>,
    pub mass_scale: f64,
    pub stiffness_scale: f64,
}

/// Why a region cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegionError {
    #[error("{field} must be finite and positive, got {value}")]
    BadScale { field: &'static str, value: f64 },
    #[error("min must not exceed max on any axis")]
    EmptyBox,
    #[error("the box holds no node of body \"{0}\"")]
    NoNodes(String),
    #[error("body {0} does not exist")]
    NoBody(usize),
}

/// What a region changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RegionEffect {
    pub nodes: usize,
    pub springs: usize,
}

/// Apply `region` to `body` (module docs).
pub fn apply_region(
    world: &mut World,
    body: BodyHandle,
    region: &Region,
) -> Result<RegionEffect, RegionError> {
    for (field, value) in [
        ("mass_scale", region.mass_scale),
        ("stiffness_scale", region.stiffness_scale),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(RegionError::BadScale { field, value });
        }
    }
    let ordered = |a: usize| {
        matches!(
            region.min[a].partial_cmp(&region.max[a]),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        )
    };
    if !(0..3).all(ordered) {
        return Err(RegionError::EmptyBox);
    }
    let info = world
        .bodies
        .get(body.0)
        .ok_or(RegionError::NoBody(body.0))?
        .clone();
    let inside = |x: &Vector3<f64>| (0..3).all(|a| x[a] >= region.min[a] && x[a] <= region.max[a]);
    let n = &mut world.nodes;
    let old_mass: Vec<f64> = n.mass.clone();
    let mut nodes = 0;
    for i in info.nodes.clone() {
        if inside(&n.position[i]) {
            n.mass[i] *= region.mass_scale;
            if n.inv_mass[i] > 0.0 {
                n.inv_mass[i] = 1.0 / n.mass[i];
            }
            nodes += 1;
        }
    }
    if nodes == 0 {
        return Err(RegionError::NoNodes(info.name));
    }
    let s = &mut world.springs;
    let mut springs = 0;
    let reduced = |m: &[f64], a: usize, b: usize| {
        if m[a] + m[b] > 0.0 {
            m[a] * m[b] / (m[a] + m[b])
        } else {
            0.0
        }
    };
    for k in info.springs.clone() {
        let (a, b) = (s.a[k] as usize, s.b[k] as usize);
        let k_scale = if inside(&((n.position[a] + n.position[b]) / 2.0)) {
            springs += 1;
            region.stiffness_scale
        } else {
            1.0
        };
        s.stiffness[k] *= k_scale;
        let (mu0, mu1) = (reduced(&old_mass, a, b), reduced(&n.mass, a, b));
        let mu_scale = if mu0 > 0.0 { mu1 / mu0 } else { 1.0 };
        s.damping[k] *= (k_scale * mu_scale).sqrt();
    }
    // The XPBD cells whose centre is inside take the same stiffness factor.
    let body_info = &mut world.bodies[body.0];
    let x = &world.nodes.position;
    body_info.cell_stiffness.resize(body_info.cells.len(), 1.0);
    for (cell, scale) in body_info.cells.iter().zip(&mut body_info.cell_stiffness) {
        let centre = cell.iter().map(|&i| x[i as usize]).sum::<Vector3<f64>>() / 8.0;
        if inside(&centre) {
            *scale *= region.stiffness_scale;
        }
    }
    world.invalidate_prepared();
    Ok(RegionEffect { nodes, springs })
}
