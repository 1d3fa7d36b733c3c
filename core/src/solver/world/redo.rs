//! A frame that folds or crowds a cell is taken again from its start at twice the substeps.
//!
//! The XPBD solver's automatic substeps follow the bodies' stiffness and speed, and the
//! crowding rule (`xpbd::crowding`) doubles them once a frame starts with a cell near
//! collapse. An impact that folds a cell within one frame gives no such warning: the corpus's
//! jelly snowman (`blender/two_objects.glb`) folded a cell in frame 20 at 60 substeps, as its
//! head reached the floor beside the body at 6.7 m/s, and the bake ended with a warning. At
//! 120 substeps from the start nothing folded.
//!
//! So a frame that may fold keeps a copy of the world at its start; if it ends with more
//! inverted cells than it started with, it is taken again from that copy at twice the
//! substeps, up to [`MAX_REDOS`] times and the impact cap, and the crowding rule holds the
//! doubling for the frames after (`xpbd::hold_doubling`). A cell folds where something moves
//! fast against the material's elastic waves: the copy is kept when the fastest node or
//! capsule moves at least [`REDO_WAVE_FRACTION`] of the slowest material's `sqrt(E/ρ)`
//! (jelly from 0.06 m/s, rubber from 0.74 m/s: a 20 cm rubber box tipping onto an edge at
//! 1 m/s folded a cell). A whole copy at every frame cost the standard scene (a rubber cube
//! dropped 1 m) 6–8 % of its bake; the gate and what the copy leaves out bring that within
//! the measurement's noise.
//!
//! A frame that crowds a cell (presses a corner past [`xpbd::CROWDED_J`], where none was at
//! its start) is taken again too. Left to the crowding rule, which doubles the frame after,
//! such a frame stores energy its motion did not give: a rubber cube landing on a corner at
//! 30 substeps a frame had its contact lift the corner's light node into the cell every
//! substep and the collapse barrier push it back, and the crushed cell's volume term read
//! 85 J for a cube moving with 2.4 J. The doubled frame after it resolved the cells well
//! enough to give much of that back as motion: a 20 cm cube left that bounce with 22.0 J
//! where it had landed with 15.6 J, and a 10 cm cube tumbling off a tilted drop hopped with
//! 40 % more energy than its bounce before. At a fixed 30 or 60 substeps no bounce gained; the
//! gain came from the count changing under a crushed cell. Taken again from its start, the
//! frame never stores it (the 10 cm cube: no bounce gains; the 20 cm cube dropped flat: 12 %
//! more above rest instead of 90 %, from a store built in frames that stayed short of the
//! threshold).
//!
//! No copy is kept by a world that sets its substeps, runs on a device, has more than
//! [`MAX_REDO_NODES`] nodes (a copy per frame of a large lattice costs memory and time), or has
//! a plug-in force field evaluated every substep (a plug-in may keep state from call to call,
//! which a redone frame would call again at the same times).

use super::World;
use crate::solver::{parallel_max, xpbd, Integrator, SpringSet};
use nalgebra::Vector3;

/// How many times one frame is taken again at most (at 2, 4 and 8 times its substeps).
pub(super) const MAX_REDOS: u32 = 3;

/// Worlds of at most this many nodes keep a copy of a fast frame's start (a 64³ lattice).
pub(super) const MAX_REDO_NODES: usize = 1 << 18;

/// The share of the slowest elastic wave speed from which a frame may fold a cell.
pub(super) const REDO_WAVE_FRACTION: f64 = 0.02;

impl World {
    /// A copy of this world at the frame's start, where a frame that may fold a cell can be
    /// taken again from (module docs); `None` where it would not be. What no frame of the
    /// XPBD solver changes stays out of the copy ([`FrameStatic`]).
    pub(super) fn redo_point(&mut self) -> Option<Box<World>> {
        let redo = self.settings.integrator == Integrator::Xpbd
            && self.settings.fixed_substeps.is_none()
            && !self.on_device()
            && self.nodes.len() <= MAX_REDO_NODES
            && !self.fields.iter().any(|f| f.field.per_substep());
        let wave = xpbd::slowest_wave(self).filter(|_| redo)?;
        if self.fastest_motion() < REDO_WAVE_FRACTION * wave {
            return None;
        }
        let kept = FrameStatic::take(self);
        let copy = Box::new(self.clone());
        kept.put_back(self);
        Some(copy)
    }

    /// Go back to `start` ([`World::redo_point`]'s copy), keeping what no frame changes.
    pub(super) fn redo_from(&mut self, start: &World) {
        let kept = FrameStatic::take(self);
        *self = start.clone();
        kept.put_back(self);
    }

    /// Whether the frame that started at `start` and ended here (with `inverted` cells) is
    /// taken again: it folded a cell, ending with more inverted than it started with, or it
    /// crowded one, pressing a corner past [`xpbd::CROWDED_J`] where none was at its start.
    pub(super) fn spoiled_since(&mut self, start: &World, inverted: usize) -> bool {
        let crowded = |ratio: Option<f64>| ratio.is_some_and(|j| j < xpbd::CROWDED_J);
        (inverted > 0 && inverted > start.inverted_cells())
            || (crowded(xpbd::most_collapsed_now(self))
                && !crowded(xpbd::most_collapsed_in_copy(self, start)))
    }

    /// The fastest node or capsule now, m/s.
    fn fastest_motion(&self) -> f64 {
        let v = &self.nodes.velocity;
        let capsules = (self.manipulators.iter())
            .map(|m| m.capsule_at(self.time).velocity.norm())
            .chain(self.live_capsules.iter().map(|c| c.velocity.norm()));
        capsules.fold(parallel_max(v.len(), |i| v[i].norm()), f64::max)
    }
}

/// What a frame of the XPBD solver does not change, left out of the copy a frame is taken
/// again from: the springs (the papers' model; the solver reads a few as constraints), the
/// rest positions and the cells (their lane caches are keyed by what they were made from).
/// Copying them was two thirds of the copy of a resting 16³ cube.
struct FrameStatic {
    springs: SpringSet,
    rest: Vec<Vector3<f64>>,
    cells: Option<xpbd::CellSet>,
}

impl FrameStatic {
    fn take(world: &mut World) -> Self {
        FrameStatic {
            springs: std::mem::take(&mut world.springs),
            rest: std::mem::take(&mut world.rest),
            cells: xpbd::take_cells(world),
        }
    }

    fn put_back(self, world: &mut World) {
        world.springs = self.springs;
        world.rest = self.rest;
        if let Some(cells) = self.cells {
            xpbd::put_cells(world, cells);
        }
    }
}
