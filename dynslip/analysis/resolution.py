r"""Does the mesh resolve the contact? The depth of element chords inside the ball.

The contact penalty acts at the nodes only (:mod:`dynslip.physics.sheet`). Between two
nodes the sheet is a straight chord, which may cut through the rigid ball. For two nodes on
the surface a polar angle $\alpha$ apart the chord's deepest point is $1-\cos(\alpha/2)$
inside (0.011 R for a 0.3 rad element, 0.05 R for 0.64 rad): a resolved contact has small
depths, of order $\alpha^2/8$. A single element spanning most of the ball (the pole
material stretched round to the far side) gives a depth near 1. Such a state can look
trapped, with no friction needed, yet the sheet passes through the ball. So a run whose
largest depth exceeds the stated limit (``numerics.max_chord_depth``) has no answer to
"trapped?".

In the meridian half-plane the ball is the unit disc about $(0, z_b)$. An element is the
segment between two nodes, and it revolves into a conical band whose distance to the
ball's centre (on the axis) equals the segment's. Its depth is one minus that distance.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from dynslip.physics.sheet import chord_depths

__all__ = ["chord_depths", "chord_check"]


def chord_check(ds: xr.Dataset, limit: float) -> dict:
    """The largest chord depth over the saved frames of a trajectory, where and when, the
    end state's, and whether the mesh resolves the contact (every depth at most ``limit``).

    A piercing can begin and end between two saved frames: the sheet then ends far from the
    ball and reads "not trapped". The pole node lies on the axis, which the ball fills from
    ``zb - 1`` to ``zb + 1``, so a pole that changes sides of the ball's centre has passed
    through it: that counts as depth 1 at the first frame on the other side
    (``pole_crossed_ball``)."""
    depth = chord_depths(ds["rho"].values, ds["z"].values, ds["ball_z"].values)
    finite = np.where(np.isfinite(depth), depth, -np.inf)
    k = np.unravel_index(int(np.argmax(finite)), finite.shape)
    worst = float(finite[k])
    rbar = ds["rbar"].values
    t_worst, element = float(ds["time"].values[k[0]]), [float(rbar[k[1]]), float(rbar[k[1] + 1])]
    side = np.sign(ds["z"].values[:, 0] - ds["ball_z"].values)
    side = side[np.isfinite(side) & (side != 0)]
    flips = np.flatnonzero(np.sign(ds["z"].values[:, 0] - ds["ball_z"].values) == -side[0]) if side.size else []
    crossed = len(flips) > 0
    if crossed and worst < 1.0:
        worst, t_worst, element = 1.0, float(ds["time"].values[flips[0]]), [float(rbar[0]), float(rbar[1])]
    return {
        "max_chord_depth": worst,
        "time_s": t_worst,
        "element_rbar": element,
        "end_max_chord_depth": float(np.max(finite[-1])),
        "pole_crossed_ball": bool(crossed),
        "limit": float(limit),
        "resolved": bool(worst <= limit),
        "means": ("largest depth (units R) that a straight element between two nodes reaches inside the ball, "
                  "over the saved frames; contact acts at nodes only, so a deep chord is sheet passing through "
                  "the ball and trapped is then unknown"),
    }
