"""A springbake event-procedure plug-in: "squash on landing". Run from an event, it gives the
body's nodes a velocity that flattens it along the up axis and spreads it sideways about its
centre of mass (the classic squash of a landing), on top of their motion:

    [[event]]
    name = "land"
    body = "ball"
    on = { collision = "floor" }
    procedure = { plugin = { name = "squash", args = { rate = 3.0 } } }

`rate` (1/s): how fast the squash starts; `up`: the scene's up axis (default +Y).
See docs/plugins.md."""

import numpy as np

SPRINGBAKE_PLUGIN = {"kind": "procedure", "name": "squash"}


def check(args):
    rate = args.get("rate", 3.0)
    if not isinstance(rate, (int, float)) or not 0 < rate <= 100:
        raise ValueError("rate must be a number in (0, 100], got %r" % (rate,))


def run(body, args):
    x, v, m = body["positions"], body["velocities"], body["masses"]
    up = np.asarray(args.get("up", [0.0, 1.0, 0.0]), dtype=float)
    up /= np.linalg.norm(up)
    rate = float(args.get("rate", 3.0))
    r = x - (m[:, None] * x).sum(axis=0) / m.sum()
    along = np.outer(r @ up, up)
    # Down along up, out across it: volume-neutral to first order.
    return {"velocities": v + rate * (-along + 0.5 * (r - along))}
