//! What the papers' integrators derive from a world once (adjacency, colouring, stencil,
//! step bounds) and the buffers their steps reuse; rebuilt when bodies change.

use super::*;

/// Derived data rebuilt when bodies change, and scratch buffers reused every step.
#[derive(Debug, Clone)]
pub(super) struct Prepared {
    pub(super) adjacency: Adjacency,
    pub(super) colouring: SpringColouring,
    pub(super) spring_force: Vec<Vector3<f64>>,
    /// Per fixed node chunk: deepest penetration and the sum of the manipulators' forces.
    pub(super) chunk_contact: Vec<(f64, Vector3<f64>)>,
    /// Per fixed node chunk: the largest |v − c|² after the velocity update (c: node 0's
    /// velocity before it), for the dispersion's uniform-motion test.
    pub(super) chunk_spread: Vec<f64>,
    /// Per spring: 1 where the dispersion must test it exactly (see `SpringHints`).
    pub(super) exceptional: Vec<u8>,
    /// Per fixed spring chunk: the smallest dispersion speed floor².
    pub(super) chunk_floor: Vec<f64>,
    /// Pass the spring hints to the dispersion (always, except in the test comparing with
    /// the hint-free path).
    pub(super) hints_enabled: bool,
    /// Later dispersion sweeps visit only the springs at changed nodes (always, except in the
    /// test comparing with the stamp-only sweeps).
    pub(super) active_set_enabled: bool,
    pub(super) dispersion_scratch: DispersionScratch,
    /// Partial sums of the deformation damping's rigid-motion fit.
    pub(super) rigid_scratch: RigidScratch,
    pub(super) capsules: Vec<Capsule>,
    /// Per surface point: contact force, depth, force from the manipulators.
    pub(super) point_contact: Vec<(Vector3<f64>, f64, Vector3<f64>)>,
    /// Per node: the surface points' contact forces spread onto it.
    pub(super) surface_force: Vec<Vector3<f64>>,
    /// Per body: whether its nodes' box reaches a rigid surface this step.
    pub(super) body_may_touch: Vec<bool>,
    /// Per block of [`CONTACT_BLOCK`] nodes: whether its nodes' box reaches a rigid surface
    /// this step (computed when some node takes contacts itself).
    pub(super) block_near: Vec<bool>,
    /// Skip what cannot touch a rigid surface (node blocks, the log's second look at points
    /// the surface pass found free); always, except in the test comparing with the full path.
    pub(super) rigid_broad_phase: bool,
    pub(super) static_step: SubstepChoice,
    pub(super) shortest_spring: f64,
    /// The lattice bodies' springs by stencil (see [`crate::solver::stencil`]), and the node → spring
    /// lists of the other springs, which the node pass gathers.
    pub(super) stencil: Option<StencilPlan>,
    pub(super) residual_adjacency: Adjacency,
    /// Use the stencil (always, except in the test comparing with the index lists).
    pub(super) stencil_enabled: bool,
}

impl Prepared {
    pub(super) fn bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.adjacency.offsets)
            + b(&self.adjacency.links)
            + b(&self.colouring.order)
            + b(&self.colouring.offsets)
            + b(&self.spring_force)
            + b(&self.chunk_contact)
            + b(&self.chunk_spread)
            + b(&self.exceptional)
            + b(&self.chunk_floor)
            + b(&self.dispersion_scratch.corrections)
            + b(&self.dispersion_scratch.changed)
            + b(&self.colouring.colour)
            + b(&self.dispersion_scratch.log)
            + b(&self.dispersion_scratch.candidates)
            + b(&self.capsules)
            + b(&self.block_near)
            + b(&self.point_contact)
            + b(&self.surface_force)
            + b(&self.body_may_touch)
            + self.stencil.as_ref().map_or(0, StencilPlan::bytes)
            + b(&self.residual_adjacency.offsets)
            + b(&self.residual_adjacency.links)
    }
}

impl World {
    pub(super) fn prepare(&mut self) -> &mut Prepared {
        if self.prepared.is_none() {
            let n = self.nodes.len();
            let adjacency = Adjacency::new(n, &self.springs);
            let colouring = SpringColouring::new(n, &self.springs);
            let stencil = StencilPlan::build(&self.nodes, &self.springs, &self.bodies);
            let residual_adjacency = match &stencil {
                Some(plan) => Adjacency::filtered(n, &self.springs, |s| !plan.covers(s)),
                None => Adjacency::default(),
            };
            let static_step = self.static_step();
            let shortest_spring = self
                .springs
                .rest_length
                .iter()
                .cloned()
                .fold(f64::INFINITY, f64::min);
            self.prepared = Some(Prepared {
                adjacency,
                colouring,
                // Not needed when the stencil takes every spring.
                spring_force: match &stencil {
                    Some(plan) if plan.covers_all() => Vec::new(),
                    _ => vec![Vector3::zeros(); self.springs.len()],
                },
                chunk_contact: vec![(0.0, Vector3::zeros()); n.div_ceil(PAR_CHUNK)],
                chunk_spread: vec![0.0; n.div_ceil(PAR_CHUNK)],
                exceptional: vec![0; self.springs.len()],
                chunk_floor: vec![0.0; self.springs.len().div_ceil(PAR_CHUNK)],
                hints_enabled: true,
                active_set_enabled: true,
                dispersion_scratch: DispersionScratch::default(),
                rigid_scratch: RigidScratch::default(),
                capsules: Vec::with_capacity(self.manipulators.len() + self.live_capsules.len()),
                point_contact: vec![(Vector3::zeros(), 0.0, Vector3::zeros()); self.surface.len()],
                body_may_touch: Vec::with_capacity(self.bodies.len()),
                block_near: vec![false; n.div_ceil(CONTACT_BLOCK)],
                rigid_broad_phase: true,
                surface_force: vec![Vector3::zeros(); if self.surface.is_empty() { 0 } else { n }],
                static_step,
                shortest_spring,
                stencil,
                residual_adjacency,
                stencil_enabled: true,
            });
        }
        self.prepared.as_mut().expect("prepared above")
    }

    /// Largest step allowed by the accuracy bound (stiffest spring, lighter end; the contact
    /// layer on the lightest node) and by symplectic-Euler stability.
    pub(super) fn static_step(&self) -> SubstepChoice {
        let n_acc = self.settings.accuracy_n;
        let s = &self.springs;
        let nodes = &self.nodes;
        let mut k_over_m: f64 = 0.0;
        let mut max_zeta: f64 = 0.0;
        let mut node_k = vec![0.0; nodes.len()];
        for i in 0..s.len() {
            let (a, b) = (s.a[i] as usize, s.b[i] as usize);
            let m = nodes.mass[a].min(nodes.mass[b]);
            if m > 0.0 {
                k_over_m = k_over_m.max(s.stiffness[i] / m);
            }
            let mu = nodes.mass[a] * nodes.mass[b] / (nodes.mass[a] + nodes.mass[b]);
            if mu > 0.0 && s.stiffness[i] > 0.0 {
                max_zeta = max_zeta.max(s.damping[i] / (2.0 * (s.stiffness[i] * mu).sqrt()));
            }
            node_k[a] += s.stiffness[i];
            node_k[b] += s.stiffness[i];
        }
        let has_contact = !self.settings.planes.is_empty()
            || !self.manipulators.is_empty()
            || !self.live_capsules.is_empty()
            || self.body_contact.any();
        let layer_k = if has_contact {
            self.settings.layer.stiffness
        } else {
            0.0
        };
        let min_mass = nodes
            .mass
            .iter()
            .cloned()
            .filter(|&m| m > 0.0)
            .fold(f64::INFINITY, f64::min);
        let mut omega_sq: f64 = 0.0;
        for (&m, &k) in nodes.mass.iter().zip(&node_k) {
            if m > 0.0 {
                omega_sq = omega_sq.max((2.0 * k + layer_k) / m);
            }
        }
        let mut best = SubstepChoice {
            substeps: 1,
            dt: f64::INFINITY,
            limited_by: "accuracy",
        };
        let mut consider = |dt: f64, why: &'static str| {
            if dt < best.dt {
                best.dt = dt;
                best.limited_by = why;
            }
        };
        if k_over_m > 0.0 {
            consider(accuracy_step(k_over_m, n_acc), "accuracy");
        }
        if layer_k > 0.0 && min_mass.is_finite() {
            consider(accuracy_step(layer_k / min_mass, n_acc), "contact");
        }
        if omega_sq > 0.0 {
            let zeta = max_zeta.max(self.settings.layer.damping_ratio);
            consider(
                0.8 * 2.0 * ((1.0 + zeta * zeta).sqrt() - zeta) / omega_sq.sqrt(),
                "stability",
            );
        }
        best
    }
}
