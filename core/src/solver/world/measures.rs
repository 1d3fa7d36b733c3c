//! What a world reports about itself: the frame's diagnostics (energies, inverted cells,
//! speeds), contacts for overlays and logs, volumes, momentum and memory.

use super::*;

impl World {
    /// Where rigid surfaces (floor, walls, capsules, colliders) pushed the bodies at the last
    /// substep: the display-surface points and the lattice nodes they moved (what a viewer's
    /// contact overlay marks). Empty before the first step and under the papers' integrators.
    pub fn touching_points(&self) -> Vec<Vector3<f64>> {
        let Some(model) = &self.xpbd else {
            return Vec::new();
        };
        let contact = model.point_contact();
        let points = (0..contact.len().min(self.surface.len()))
            .filter(|&i| contact[i].1 > 0.0)
            .map(|i| {
                let (w, ids) = (&self.surface.weights[i], &self.surface.nodes[i]);
                (0..8).fold(Vector3::zeros(), |x, c| {
                    x + self.nodes.position[ids[c] as usize] * w[c]
                })
            });
        let nodes = model
            .moved()
            .iter()
            .zip(&self.nodes.position)
            .filter(|(moved, _)| **moved)
            .map(|(_, x)| *x);
        points.chain(nodes).collect()
    }

    /// What each body touched during the last [`World::advance_frame`]: one record per
    /// (body, partner) pair, in body order, then partner order (see [`crate::solver::contact_log`]).
    pub fn frame_contacts(&self) -> &[ContactRecord] {
        self.contact_log.records()
    }

    /// Where node `i` was when its body was added (its rest position).
    pub fn rest_position(&self, i: usize) -> Vector3<f64> {
        self.rest[i]
    }

    /// Node positions of one body.
    pub fn body_positions(&self, body: BodyHandle) -> &[Vector3<f64>] {
        &self.nodes.position[self.bodies[body.0].nodes.clone()]
    }

    /// Node positions of one body as points.
    pub fn body_points(&self, body: BodyHandle) -> Vec<Point3<f64>> {
        self.body_positions(body)
            .iter()
            .map(|&p| Point3::from(p))
            .collect()
    }

    pub(super) fn max_speed(&self) -> f64 {
        let v = &self.nodes.velocity;
        parallel_max(v.len(), |i| v[i].norm())
    }

    /// State diagnostics at the current time (energies, inverted cells, speed).
    pub fn diagnostics(&self, frame: usize) -> FrameDiagnostics {
        self.diagnostics_from(frame, self.energies(), None)
    }

    /// [`Self::diagnostics`] with the kinetic, elastic and gravity energies already measured
    /// (and the inverted cells, where a device counted them).
    pub(super) fn diagnostics_from(
        &self,
        frame: usize,
        (kinetic_energy, elastic_energy, gravity_energy): (f64, f64, f64),
        inverted: Option<usize>,
    ) -> FrameDiagnostics {
        FrameDiagnostics {
            frame,
            time: self.time,
            kinetic_energy,
            elastic_energy,
            gravity_energy,
            inverted_cells: inverted.unwrap_or_else(|| self.inverted_cells()),
            max_speed: self.max_speed(),
            ..FrameDiagnostics::default()
        }
    }

    /// Kinetic, elastic (the XPBD cells' or the springs') and gravity energy now, J.
    pub(super) fn energies(&self) -> (f64, f64, f64) {
        let (kinetic, gravity) = self.motion_energies();
        (kinetic, self.elastic_energy(), gravity)
    }

    /// [`Self::energies`] for a frame's start and end, the elastic part remembered: a
    /// frame's start measures the positions the last frame's end measured (the same time and
    /// position bits: their fingerprint says so), and the cells' energy is the costly part
    /// (a 128³ lattice: 0.2 s on two cores, against 10 ms for the fingerprint).
    pub(super) fn frame_energies(&mut self) -> (f64, f64, f64) {
        let key = self.position_key();
        self.frame_energies_at(key)
    }

    /// [`Self::frame_energies`] with the positions' key already taken.
    pub(super) fn frame_energies_at(&mut self, key: (u64, u64)) -> (f64, f64, f64) {
        let elastic = match self.elastic_memo {
            Some((k, e)) if k == key => e,
            _ => self.elastic_energy(),
        };
        self.elastic_memo = Some((key, elastic));
        let (kinetic, gravity) = self.motion_energies();
        (kinetic, elastic, gravity)
    }

    /// The time and a fingerprint of the positions' bits: what a measurement of this state is
    /// remembered under.
    pub(crate) fn position_key(&self) -> (u64, u64) {
        (self.time.to_bits(), fingerprint(&self.nodes.position))
    }

    /// Kinetic and gravity energy now, J: one pass over the nodes, each sum added as
    /// [`deterministic_sum`] adds it (the same bits as two such sums).
    fn motion_energies(&self) -> (f64, f64) {
        let n = &self.nodes;
        let g = self.settings.gravity;
        let chunk = |r: Range<usize>| {
            r.fold((-0.0, -0.0), |(k, p), i| {
                (
                    k + 0.5 * n.mass[i] * n.velocity[i].norm_squared(),
                    p + -n.mass[i] * g.dot(&n.position[i]),
                )
            })
        };
        let add = |a: (f64, f64), b: (f64, f64)| (a.0 + b.0, a.1 + b.1);
        super::super::fold_chunks(n.len(), (-0.0, -0.0), chunk, add)
    }

    /// The XPBD cells' or the springs' elastic energy now, J.
    fn elastic_energy(&self) -> f64 {
        let (n, s) = (&self.nodes, &self.springs);
        match (&self.settings.integrator, &self.xpbd) {
            (Integrator::Xpbd, Some(model)) => model.elastic_energy(self),
            _ => deterministic_sum(s.len(), |i| spring_energy(n, s, i)),
        }
    }

    /// Cells of all bodies with a non-positive corner tetrahedron (the test of
    /// [`crate::lattice::cell_is_inverted`], on the node positions in place).
    pub fn inverted_cells(&self) -> usize {
        let pos = &self.nodes.position[..];
        self.bodies
            .iter()
            .map(|b| {
                let count = |r: Range<usize>| r.filter(|&i| cell_inverted_at(&b.cells[i], pos));
                super::super::fold_chunks(b.cells.len(), 0, |r| count(r).count(), |a, b| a + b)
            })
            .sum()
    }

    pub(super) fn check_finite(&self, frame: usize) -> Result<(), SimulationError> {
        let bad = |v: &Vector3<f64>| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite());
        for (what, values) in [
            ("position", &self.nodes.position),
            ("velocity", &self.nodes.velocity),
        ] {
            // In parallel first (a serial scan of a 128³ lattice's two arrays took a frame
            // 10 ms on two cores); the first bad node is looked for only if there is one.
            let any_bad = |r: Range<usize>| r.into_iter().any(|i| bad(&values[i]));
            if !super::super::fold_chunks(values.len(), false, any_bad, |a, b| a | b) {
                continue;
            }
            if let Some(i) = values.iter().position(bad) {
                let body = self.bodies.iter().find(|b| b.nodes.contains(&i));
                return Err(SimulationError::NonFinite {
                    frame,
                    body: body.map(|b| b.name.clone()).unwrap_or_default(),
                    node: i - body.map(|b| b.nodes.start).unwrap_or(0),
                    what,
                });
            }
        }
        Ok(())
    }

    /// Total energy (kinetic + elastic + gravity) now.
    pub fn total_energy(&self) -> f64 {
        let d = self.diagnostics(0);
        d.kinetic_energy + d.elastic_energy + d.gravity_energy
    }

    /// Bytes held by the world's arrays (node state, springs, cells, display-surface contact
    /// points, and the prepared adjacency, colouring and scratch buffers once the first step
    /// has run), counted from the vectors' capacities. Heap bookkeeping, the lattice the world
    /// was built from and the small per-body and per-constraint data are not included.
    pub fn solver_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let n = &self.nodes;
        let s = &self.springs;
        let mut total = b(&n.position) + b(&n.velocity) + b(&n.mass) + b(&n.inv_mass);
        total += b(&s.a) + b(&s.b) + b(&s.rest_length) + b(&s.stiffness) + b(&s.damping);
        total += self.bodies.iter().map(|body| b(&body.cells)).sum::<usize>();
        let sp = &self.surface;
        total += b(&sp.nodes)
            + b(&sp.weights)
            + b(&sp.share)
            + b(&sp.body_mass)
            + b(&sp.body)
            + b(&sp.reach)
            + b(&self.node_contact);
        if let Some(p) = &self.prepared {
            total += p.bytes();
        }
        total
    }

    /// Enclosed volume of a lattice body now (sum of its cells' signed volumes), m³.
    pub fn body_volume(&self, body: BodyHandle) -> f64 {
        self.bodies
            .get(body.0)
            .map(|b| cells_volume(&b.cells, &self.nodes.position))
            .unwrap_or(0.0)
    }

    /// Total linear momentum.
    pub fn momentum(&self) -> Vector3<f64> {
        let n = &self.nodes;
        (0..n.len()).map(|i| n.velocity[i] * n.mass[i]).sum()
    }
}

/// [`crate::lattice::cell_is_inverted`] on `Vector3` positions (the same arithmetic, without building a
/// `Vec<Point3>` of every node each frame).
pub(super) fn cell_inverted_at(nodes: &[u32; 8], positions: &[Vector3<f64>]) -> bool {
    let p = |c: usize| positions[nodes[c] as usize];
    if crate::cage::is_tet_cell(nodes) {
        // A cage's tet stored as a degenerate cell (see `crate::cage::tet_cell`).
        let a = p(0);
        return (p(1) - a).dot(&(p(3) - a).cross(&(p(7) - a))) <= 0.0;
    }
    (0..8).any(|c| {
        let ex = p(c ^ 1) - p(c);
        let ey = p(c ^ 2) - p(c);
        let ez = p(c ^ 4) - p(c);
        // Mirrored corners flip the handedness of (ex, ey, ez); compensate with the parity.
        let parity = ((c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1)) % 2;
        let vol = ex.dot(&ey.cross(&ez));
        let signed = if parity == 0 { vol } else { -vol };
        signed <= 0.0
    })
}

/// A hash of the positions' bits (FNV-1a over fixed chunks, the chunks' hashes folded in
/// order by `solver::fold_chunks`): the same on any thread count, different after any move, and no
/// allocation (a frame's step allocates nothing).
fn fingerprint(positions: &[Vector3<f64>]) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let fold = |h: u64, v: u64| (h ^ v).wrapping_mul(PRIME);
    let chunk = |r: std::ops::Range<usize>| {
        (positions[r].iter().flat_map(|p| [p.x, p.y, p.z]))
            .fold(OFFSET, |h, v| fold(h, v.to_bits()))
    };
    super::super::fold_chunks(positions.len(), OFFSET, chunk, fold)
}
