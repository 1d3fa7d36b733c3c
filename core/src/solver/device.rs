//! The seam between a [`World`] and an XPBD solver that runs elsewhere (the GPU backend of
//! the `springbake-gpu` crate, wgpu compute shaders). The world stays the owner of the state:
//! it hands a device the flat inputs of the small-step XPBD substep once ([`DeviceModel`],
//! from [`World::device_model`]); then, for each output frame, it chooses the substeps as on
//! the CPU, the device runs them ([`DeviceSolver::advance`]) and hands positions and velocities
//! back, and the world computes the frame's diagnostics from them as it always does, except
//! what a device measured of its cells at the frame's end ([`DeviceCensus`]: their energy,
//! inverted cells and least corner ratio), which spares the host a pass over every cell.
//!
//! A device runs the substep of [`super::xpbd`] stage for stage, in f32: prediction with
//! gravity, static pins, the lattice cells colour by colour, the torque cancellation, contact
//! with friction against the floor, walls and capsule manipulators for nodes and
//! display-surface points (the points a colour of cells at a time, in the order the CPU visits
//! them), the collapse barriers of the cells the contacts moved, velocities, and the
//! deformation damping. What it does not run is named by
//! [`World::device_model`]'s error, and the caller steps that world on the CPU.

use super::diagnostics::SimulationError;
use super::integrator::{FrameAccumulator, Integrator};
use super::manipulator::Capsule;
use super::World;
use nalgebra::Vector3;
use std::ops::Range;

/// One lattice cell as a device takes it (all cells are axis-aligned cubes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceCell {
    /// World node ids, corner `c` at `(c & 1, c >> 1 & 1, c >> 2 & 1)`.
    pub nodes: [u32; 8],
    /// One over the rest edge, 1/m.
    pub inv_h: f64,
    /// The shear corners are `1, 2, 4, 7` (else `0, 3, 5, 6`).
    pub odd: bool,
    /// Compliance of the volume constraint, `1/(λ V_0)` (`None`: λ = 0, no such constraint).
    pub volume_compliance: Option<f64>,
    /// Compliance of each corner's shear constraint, `1/(2 μ V_c)`.
    pub shear_compliance: f64,
    /// `sqrt` of the per-axis stiffness factors.
    pub axis_root: [f64; 3],
}

/// One body's node range and what the per-body passes do to it.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceBody {
    pub nodes: Range<u32>,
    /// Deformation damping rate, 1/s (0: none).
    pub damping_rate: f64,
    /// Whether the internal torque of the elastic corrections is removed (bodies without a
    /// pinned node).
    pub cancel_torque: bool,
}

/// Everything a device needs to run the XPBD substep of a world (module docs).
#[derive(Debug, Clone, Default)]
pub struct DeviceModel {
    pub position: Vec<[f64; 3]>,
    pub velocity: Vec<[f64; 3]>,
    pub mass: Vec<f64>,
    /// 0 for pinned nodes (and massless ones).
    pub inv_mass: Vec<f64>,
    /// Per node: where a pin holds it (`None`: free).
    pub pin: Vec<Option<[f64; 3]>>,
    /// Per node: whether it takes rigid contacts itself.
    pub node_contact: Vec<bool>,
    /// Cells in colour order; `cell_colours` are ranges of it whose cells share no node.
    pub cells: Vec<DeviceCell>,
    pub cell_colours: Vec<Range<u32>>,
    /// Display-surface points: their cells' nodes, trilinear weights and reach (m).
    pub point_nodes: Vec<[u32; 8]>,
    pub point_weights: Vec<[f64; 8]>,
    pub point_reach: Vec<f64>,
    /// Point indices, group after group (the points of one cell, visited in this order).
    pub point_order: Vec<u32>,
    /// Ranges of `point_order`.
    pub point_groups: Vec<Range<u32>>,
    /// Ranges of `point_groups` whose groups share no node (the last may be one group of
    /// points in no cell).
    pub point_colours: Vec<Range<u32>>,
    pub bodies: Vec<DeviceBody>,
    /// Rigid planes: unit normal and offset (`n · x ≥ offset` is outside).
    pub planes: Vec<([f64; 3], f64)>,
    /// Coulomb friction of the planes.
    pub friction: f64,
    /// m/s².
    pub gravity: [f64; 3],
}

/// One output frame for a device: its substeps, the state to start from (and to leave the
/// result in), and the capsules of every substep.
pub struct DeviceFrame<'a> {
    pub substeps: u32,
    /// Seconds per substep.
    pub dt: f64,
    pub position: &'a mut [Vector3<f64>],
    pub velocity: &'a mut [Vector3<f64>],
    /// Per substep, `capsule_count` pairs (the capsule at the substep's end, and at its
    /// start: its surface's motion gives the friction's reference), substep after substep.
    pub capsules: &'a [(Capsule, Capsule)],
    pub capsule_count: usize,
}

/// What a device's frame adds to the frame's diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceTotals {
    /// Deepest penetration a contact resolved, m.
    pub max_depth: f64,
    /// The capsules' force on the bodies, summed over the substeps, N.
    pub capsule_force: Vector3<f64>,
    /// The capsules' work on the bodies, J.
    pub capsule_work: f64,
    /// What the device measured of the cells (see [`DeviceCensus`]), where it measures them.
    pub census: Option<DeviceCensus>,
}

/// The cells of a frame as a device measured them (in its precision), so that the world
/// need not pass over every cell again on the host for the frame's diagnostics and the next
/// frame's substeps (at 128³ three passes, about half a frame's host work).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceCensus {
    /// How many cells were measured (all of the model's).
    pub cells: usize,
    /// Their elastic energy, J ([`super::xpbd`]'s cells: volume and shear terms), as the last
    /// substep's elastic solve left them: before its contacts, as the CPU reads it.
    pub elastic_energy: f64,
    /// Cells with a corner of volume ratio 0 or less, at the frame's end.
    pub inverted_cells: usize,
    /// The smallest corner volume ratio `det F` of any cell, at the frame's end.
    pub most_collapsed: f64,
}

/// A solver that runs a [`DeviceModel`]'s substeps elsewhere.
pub trait DeviceSolver: Send {
    /// The adapter it runs on, for logs and reports (e.g. "llvmpipe (Vulkan, CPU)").
    fn adapter(&self) -> &str;
    /// Run the frame's substeps from its state and leave the state after them there.
    fn advance(&mut self, frame: DeviceFrame<'_>) -> Result<DeviceTotals, String>;
}

/// The world's attached device, if any. A clone of a world steps on the CPU (a device's
/// buffers are not shared).
#[derive(Default)]
pub(crate) struct DeviceSlot {
    solver: Option<Box<dyn DeviceSolver>>,
    /// Node count the device was built for.
    nodes: usize,
    /// The last frame's census, under the key of the positions it measured (time and
    /// fingerprint bits).
    census: Option<((u64, u64), DeviceCensus)>,
}

impl Clone for DeviceSlot {
    fn clone(&self) -> Self {
        DeviceSlot::default()
    }
}

impl std::fmt::Debug for DeviceSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = self.solver.as_ref().map(|s| s.adapter());
        f.debug_struct("DeviceSlot")
            .field("adapter", &name)
            .finish()
    }
}

fn xyz(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl World {
    /// The inputs of the XPBD substep for a device (module docs), or what in this world a
    /// device does not run, as a phrase for the user ("manipulators", "rigid bodies", …).
    pub fn device_model(&mut self) -> Result<DeviceModel, String> {
        self.device_blocker()?;
        if self.xpbd.is_none() {
            self.xpbd = Some(super::xpbd::Model::build(self));
        }
        let Some(model) = self.xpbd.as_ref() else {
            return Err("no solver model".into());
        };
        let (cells, cell_colours, points) = model.device_parts()?;
        if model.restitution_may_act() {
            return Err(
                "bodies too stiff for their size to resolve an impact in a substep \
                        (wood, steel: the CPU gives them restitution)"
                    .into(),
            );
        }
        let n = self.nodes.len();
        let mut inv_mass = self.nodes.inv_mass.clone();
        let mut pin = vec![None; n];
        for c in &self.constraints {
            for (j, &i) in c.nodes.iter().enumerate() {
                pin[i] = Some(xyz(&c.target(j, 0.0)));
                inv_mass[i] = 0.0;
            }
        }
        let bodies = self
            .bodies
            .iter()
            .map(|b| DeviceBody {
                nodes: b.nodes.start as u32..b.nodes.end as u32,
                damping_rate: b.deformation_damping,
                cancel_torque: !b
                    .nodes
                    .clone()
                    .any(|i| inv_mass[i] <= 0.0 && self.nodes.mass[i] > 0.0),
            })
            .collect();
        let s = &self.surface;
        Ok(DeviceModel {
            position: self.nodes.position.iter().map(xyz).collect(),
            velocity: self.nodes.velocity.iter().map(xyz).collect(),
            mass: self.nodes.mass.clone(),
            inv_mass,
            pin,
            node_contact: self.node_contact.clone(),
            cells,
            cell_colours,
            point_nodes: s.nodes.clone(),
            point_weights: s.weights.clone(),
            point_reach: s.reach.clone(),
            point_order: points.order,
            point_groups: points.groups,
            point_colours: points.colours,
            bodies,
            planes: self
                .settings
                .planes
                .iter()
                .map(|p| (xyz(&p.normal), p.offset))
                .collect(),
            friction: self.settings.layer.friction,
            gravity: xyz(&self.settings.gravity),
        })
    }

    /// The first feature of this world a device does not run (see [`Self::device_model`]).
    fn device_blocker(&self) -> Result<(), String> {
        let blocker = if self.settings.integrator != Integrator::Xpbd {
            Some("the papers' integrators (a device runs the XPBD solver)")
        } else if !self.rigid.is_empty() {
            Some("rigid bodies")
        } else if !self.joints.is_empty() {
            Some("joints")
        } else if !self.volume.is_empty() {
            Some("volume preservation")
        } else if !self.fields.is_empty() {
            Some("force fields")
        } else if self.settings.wind.is_some() {
            Some("wind")
        } else if self.body_contact.touches_others() {
            Some("contact between bodies or with static colliders")
        } else if self
            .constraints
            .iter()
            .any(|c| c.strength < 1.0 || c.path.keys().len() > 1)
        {
            Some("trajectories and loose pins")
        } else {
            None
        };
        blocker.map_or(Ok(()), |b| Err(b.to_string()))
    }

    /// Step this world's frames on `solver` from now on (built from this world's
    /// [`Self::device_model`]).
    pub fn attach_device(&mut self, solver: Box<dyn DeviceSolver>) {
        self.device = DeviceSlot {
            solver: Some(solver),
            nodes: self.nodes.len(),
            census: None,
        };
    }

    /// The adapter of the attached device (`None`: the world steps on the CPU).
    pub fn device_adapter(&self) -> Option<&str> {
        self.device.solver.as_ref().map(|s| s.adapter())
    }

    /// File the frame's census under `key` (the positions it measured) for the next frame's
    /// substeps.
    pub(crate) fn file_device_census(&mut self, key: (u64, u64), census: Option<DeviceCensus>) {
        self.device.census = census.map(|c| (key, c));
    }

    /// The device's census of the positions as they are now, if it measured them (the
    /// fingerprint is taken only when there is a census to check).
    pub(crate) fn device_census_now(&self) -> Option<DeviceCensus> {
        let (key, census) = self.device.census?;
        (key == self.position_key()).then_some(census)
    }

    /// Whether a device steps this world's frames.
    pub(crate) fn on_device(&self) -> bool {
        self.device.solver.is_some()
    }

    /// One output frame's substeps on the attached device, its totals added to `acc`; what
    /// the device measured of the cells, when it measured all of them.
    pub(crate) fn advance_on_device(
        &mut self,
        substeps: u32,
        dt: f64,
        acc: &mut FrameAccumulator,
    ) -> Result<Option<DeviceCensus>, SimulationError> {
        if self.device.nodes != self.nodes.len() {
            return Err(SimulationError::Device(
                "the world's bodies changed after the device was attached".into(),
            ));
        }
        // The capsules of each substep, as the CPU's contact stage takes them.
        let mut capsules = Vec::new();
        let mut time = self.time;
        for _ in 0..substeps {
            super::xpbd::push_capsules(self, time, dt, &mut capsules);
            time += dt;
        }
        let Some(solver) = self.device.solver.as_mut() else {
            return Ok(None);
        };
        let nodes = &mut self.nodes;
        let totals = solver
            .advance(DeviceFrame {
                substeps,
                dt,
                position: &mut nodes.position,
                velocity: &mut nodes.velocity,
                capsules: &capsules,
                capsule_count: self.manipulators.len() + self.live_capsules.len(),
            })
            .map_err(SimulationError::Device)?;
        for _ in 0..substeps {
            self.time += dt;
        }
        self.device.census = None;
        acc.max_depth = acc.max_depth.max(totals.max_depth);
        acc.steps += substeps;
        acc.manipulator_work += totals.capsule_work;
        if !self.manipulators.is_empty() || !self.live_capsules.is_empty() {
            acc.reaction_sum -= totals.capsule_force;
        }
        let cells: usize = self.bodies.iter().map(|b| b.cells.len()).sum();
        Ok(totals.census.filter(|c| c.cells == cells))
    }
}
