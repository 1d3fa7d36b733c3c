//! Building a world: bodies (lattices, cages, explicit models), their contact surfaces, pins,
//! paths, volume preservation, rigid kinds and anisotropy.

use super::*;

impl World {
    /// Add a fitted lattice as a body: masses from density (each cell's mass shared equally by
    /// its 8 corners, so the total is density × lattice volume), springs `k = E·L` with
    /// dampers `D = 2ζ sqrt(k μ)` (μ the reduced mass of the ends), all nodes moving at
    /// `velocity`.
    pub fn add_lattice_body(
        &mut self,
        name: impl Into<String>,
        lattice: &Lattice,
        material: &Material,
        velocity: Vector3<f64>,
    ) -> BodyHandle {
        let base = self.nodes.len();
        let cell_mass = material.cell_mass(lattice.cell_size);
        let mut mass = vec![0.0; lattice.node_count()];
        for corners in &lattice.cell_nodes {
            for &n in corners {
                mass[n as usize] += cell_mass / 8.0;
            }
        }
        let k = material.spring_constant(lattice.cell_size);
        let zeta = material.damping_ratio;
        let springs: Vec<(u32, u32, f64, f64)> = lattice
            .springs
            .iter()
            .map(|s| {
                let (ma, mb) = (mass[s.a as usize], mass[s.b as usize]);
                let mu = ma * mb / (ma + mb);
                (s.a, s.b, k, 2.0 * zeta * (k * mu).sqrt())
            })
            .collect();
        let positions: Vec<Vector3<f64>> =
            lattice.rest_positions.iter().map(|p| p.coords).collect();
        let handle = self.add_body(name, &positions, &mass, &springs, velocity);
        let longest = lattice.dims.iter().copied().max().unwrap_or(1) as f64 * lattice.cell_size;
        self.bodies[handle.0].deformation_damping =
            crate::solver::deformation_damping::damping_rate(
                material.damping_ratio,
                material.young_pa,
                material.density_kg_m3,
                longest,
            );
        self.bodies[handle.0].material = Some(material.clone());
        self.bodies[handle.0].cells = lattice
            .cell_nodes
            .iter()
            .map(|c| c.map(|n| n + base as u32))
            .collect();
        let mut coords = vec![[0u32; 3]; lattice.node_count()];
        for (cell, nodes) in lattice.cells.iter().zip(&lattice.cell_nodes) {
            for (corner, &n) in CORNERS.iter().zip(nodes) {
                coords[n as usize] = std::array::from_fn(|k| cell[k] + corner[k]);
            }
        }
        self.bodies[handle.0].grid = Some(LatticeGrid {
            dims: lattice.dims.map(|d| d + 1),
            coords,
        });
        handle
    }

    /// Scale a lattice body's cells by how much of each its mesh fills (`fill`, per cell in
    /// the lattice's order, from [`crate::lattice::fill::cell_fill`]): each cell's mass (shared
    /// by its 8 corners) and its XPBD stiffness take the factor, so the body weighs what its
    /// mesh does, its centre of mass and inertia are the mesh's, and each cell's wave speed is
    /// kept. The springs (the papers' integrators) are left as they are.
    pub fn set_cell_fill(&mut self, body: BodyHandle, fill: &[f64]) {
        let info = &mut self.bodies[body.0];
        if fill.len() != info.cells.len() || fill.iter().all(|&f| f == 1.0) {
            return;
        }
        let base = info.nodes.start;
        let mut share = vec![(0.0, 0u32); info.nodes.len()];
        for (cell, &f) in info.cells.iter().zip(fill) {
            for &n in cell {
                let s = &mut share[n as usize - base];
                s.0 += f;
                s.1 += 1;
            }
        }
        info.cell_stiffness.resize(info.cells.len(), 1.0);
        for (scale, &f) in info.cell_stiffness.iter_mut().zip(fill) {
            *scale *= f;
        }
        info.cell_fill = fill.to_vec();
        let n = &mut self.nodes;
        for (i, &(sum, count)) in share.iter().enumerate() {
            if count > 0 {
                let m = &mut n.mass[base + i];
                *m *= sum / count as f64;
                if n.inv_mass[base + i] > 0.0 {
                    n.inv_mass[base + i] = 1.0 / *m;
                }
            }
        }
        self.invalidate_prepared();
    }

    /// Add any mass-spring model: node positions (metres) and masses (kg), springs as
    /// `(a, b, k, D)` with rest lengths taken from the given positions.
    pub fn add_body(
        &mut self,
        name: impl Into<String>,
        positions: &[Vector3<f64>],
        masses: &[f64],
        springs: &[(u32, u32, f64, f64)],
        velocity: Vector3<f64>,
    ) -> BodyHandle {
        let base = self.nodes.len() as u32;
        let first_spring = self.springs.len();
        for (p, &m) in positions.iter().zip(masses) {
            self.nodes.position.push(*p);
            self.nodes.velocity.push(velocity);
            self.nodes.mass.push(m);
            self.nodes
                .inv_mass
                .push(if m > 0.0 { 1.0 / m } else { 0.0 });
            self.node_contact.push(true);
            self.rest.push(*p);
        }
        for &(a, b, k, d) in springs {
            let rest = (positions[a as usize] - positions[b as usize]).norm();
            self.springs.push(a + base, b + base, rest, k, d);
        }
        self.bodies.push(BodyInfo {
            name: name.into(),
            nodes: base as usize..self.nodes.len(),
            springs: first_spring..self.springs.len(),
            cells: Vec::new(),
            deformation_damping: 0.0,
            grid: None,
            material: None,
            cell_stiffness: Vec::new(),
            cell_fill: Vec::new(),
            axis_stiffness: [1.0; 3],
        });
        self.invalidate_prepared();
        BodyHandle(self.bodies.len() - 1)
    }

    /// Give a lattice body a contact surface: `points` (world metres, rest pose, e.g. from
    /// [`crate::lattice::surface_samples`]) with the area each stands for. From then on the
    /// floor, walls and manipulators touch these points instead of the body's nodes.
    pub fn add_contact_surface(
        &mut self,
        body: BodyHandle,
        lattice: &Lattice,
        points: &[Point3<f64>],
        areas_m2: &[f64],
    ) {
        self.add_contact_surface_with_normals(body, lattice, points, areas_m2, &[]);
    }

    /// [`World::add_contact_surface`] with the surface's unit normal at each point (at rest,
    /// from [`crate::lattice::surface_samples_with_normals`]; missing ones count as unknown):
    /// a point meeting another body's edge or corner takes its own surface's normal where the
    /// direction to the edge would push sideways (a box sliding over a slab met the slab's
    /// points ahead of its front edge and stopped).
    pub fn add_contact_surface_with_normals(
        &mut self,
        body: BodyHandle,
        lattice: &Lattice,
        points: &[Point3<f64>],
        areas_m2: &[f64],
        normals: &[Vector3<f64>],
    ) {
        let info = &self.bodies[body.0];
        let base = info.nodes.start as u32;
        let embedding = crate::lattice::Embedding::new(lattice, points);
        let face = lattice.cell_size * lattice.cell_size;
        let shares: Vec<f64> = (0..points.len())
            .map(|i| areas_m2.get(i).copied().unwrap_or(0.0) / face)
            .collect();
        let total_share: f64 = shares.iter().sum();
        let body_mass: f64 = self.nodes.mass[info.nodes.clone()].iter().sum();
        let surface = std::sync::Arc::make_mut(&mut self.surface);
        for (i, nodes) in embedding.nodes.iter().enumerate() {
            surface.nodes.push(nodes.map(|n| n + base));
            surface.weights.push(embedding.weights[i]);
            surface.share.push(shares[i]);
            surface.body.push(body.0 as u32);
            surface.reach.push(3.0 * 3f64.sqrt() * lattice.cell_size);
            (surface.rest_normal).push(normals.get(i).copied().unwrap_or_default());
            surface.body_mass.push(if total_share > 0.0 {
                body_mass * shares[i] / total_share
            } else {
                0.0
            });
        }
        for n in info.nodes.clone() {
            self.node_contact[n] = false;
        }
        self.invalidate_prepared();
    }

    /// Bind `nodes` (world indices) to `path` with `strength` in [0, 1] (1: exact); each node
    /// keeps its current offset from the path's position now. Returns the constraint's index.
    pub fn add_trajectory(
        &mut self,
        nodes: &[usize],
        path: Path,
        strength: f64,
    ) -> Result<usize, ConstraintError> {
        if !(0.0..=1.0).contains(&strength) {
            return Err(ConstraintError::BadStrength(strength));
        }
        if nodes.is_empty() {
            return Err(ConstraintError::NoNodes);
        }
        let count = self.nodes.len();
        if let Some(&node) = nodes.iter().find(|&&i| i >= count) {
            return Err(ConstraintError::NodeOutOfRange { node, count });
        }
        let here = path.at(self.time);
        let offsets = nodes
            .iter()
            .map(|&i| self.nodes.position[i] - here)
            .collect();
        self.constraints.push(TrajectoryConstraint {
            nodes: nodes.to_vec(),
            offsets,
            path,
            strength,
        });
        Ok(self.constraints.len() - 1)
    }

    /// Pin `nodes` where they are now (a constant path, exact).
    pub fn pin(&mut self, nodes: &[usize]) -> Result<usize, ConstraintError> {
        let at = nodes
            .first()
            .and_then(|&i| self.nodes.position.get(i))
            .copied()
            .unwrap_or_else(Vector3::zeros);
        self.add_trajectory(nodes, Path::constant(at), 1.0)
    }

    /// Hold `body`'s volume at `scale` × its volume now (lattice bodies; 3 Newton iterations
    /// per step; the target moves from the present volume to the scaled one at 2 V0/s).
    pub fn preserve_volume(&mut self, body: BodyHandle, scale: f64) -> Result<(), ConstraintError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(ConstraintError::BadVolumeScale(scale));
        }
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        if info.cells.is_empty() {
            return Err(ConstraintError::NoCells(info.name.clone()));
        }
        let volume = cells_volume(&info.cells, &self.nodes.position);
        if volume.is_nan() || volume <= 0.0 {
            return Err(ConstraintError::BadRestVolume {
                body: info.name.clone(),
                volume,
            });
        }
        self.volume.retain(|v| v.body != body.0);
        self.volume.push(VolumeConstraint {
            body: body.0,
            rest_volume: volume,
            scale,
            iterations: 3,
            max_rate: 2.0,
            target: volume,
        });
        Ok(())
    }

    /// Step `body` as a rigid body from now on, with the momentum and angular momentum its
    /// nodes have now (see [`crate::solver::rigid`]).
    pub fn make_rigid(&mut self, body: BodyHandle) -> Result<(), ConstraintError> {
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        let rigid = RigidBody::from_nodes(body.0, &self.nodes, info.nodes.clone())
            .ok_or_else(|| ConstraintError::NotRigid(info.name.clone()))?;
        self.rigid.retain(|r| r.body != body.0);
        self.rigid.push(rigid);
        self.xpbd = None;
        Ok(())
    }

    /// Anisotropic material: scale the stiffness of `body`'s springs by axis. A spring with
    /// unit rest direction `u` gets `k · (s_x u_x² + s_y u_y² + s_z u_z²)` (an edge along x
    /// exactly `s_x k`, a diagonal the blend) and its damper `D · sqrt` of the same factor, so
    /// the damping ratio is kept. Directions are taken from the current positions, so call it
    /// before stepping. Scales must be finite and positive.
    pub fn scale_stiffness_per_axis(
        &mut self,
        body: BodyHandle,
        scale: Vector3<f64>,
    ) -> Result<(), ConstraintError> {
        if let Some(&bad) = scale.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(ConstraintError::BadStiffnessScale(bad));
        }
        let info = self
            .bodies
            .get(body.0)
            .ok_or(ConstraintError::BodyOutOfRange(body.0))?;
        let s = &mut self.springs;
        for i in info.springs.clone() {
            let r = self.nodes.position[s.a[i] as usize] - self.nodes.position[s.b[i] as usize];
            let len_sq = r.norm_squared();
            if len_sq <= 0.0 {
                continue;
            }
            let factor = (scale.x * r.x * r.x + scale.y * r.y * r.y + scale.z * r.z * r.z) / len_sq;
            s.stiffness[i] *= factor;
            s.damping[i] *= factor.sqrt();
        }
        let body_info = &mut self.bodies[body.0];
        for k in 0..3 {
            body_info.axis_stiffness[k] *= scale[k];
        }
        self.invalidate_prepared();
        Ok(())
    }
}
