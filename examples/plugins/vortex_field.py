"""A springbake force-field plug-in: a vortex of air turning at OMEGA rad/s about a vertical
axis through CENTRE. Each node is dragged towards the air's velocity (rate DRAG, 1/s) and
pulled inward by the pressure a rotating fluid has (m ω² r), so a body caught in it swirls
around the axis at its own radius. Positions are in simulation metres; the axis is +Y (set
AXIS for a Z-up scene). Bound in a scene with

    [[force_field]]
    field = "vortex"
    bodies = ["ball"]      # optional: every body

See docs/plugins.md."""

import numpy as np

SPRINGBAKE_PLUGIN = {"kind": "force_field", "name": "vortex", "every": "substep"}

OMEGA = 2.0
DRAG = 5.0
CENTRE = np.array([0.0, 0.0, 0.0])
AXIS = np.array([0.0, 1.0, 0.0])


def force(positions, velocities, time, masses):
    r = positions - CENTRE
    r_perp = r - np.outer(r @ AXIS, AXIS)
    air = OMEGA * np.cross(AXIS, r_perp)
    accel = DRAG * (air - velocities) - OMEGA ** 2 * r_perp
    return accel * masses[:, None]
