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
A ball of another kind (a coin, ``physics.ball``) is checked with its own geometry
(:mod:`dynslip.physics.bodies.chords`: the deepest point of each chord inside the body).

Every held body is checked the same way (:func:`body_chord_check`, ``mesh_check`` ``bodies``
in ``summary.json``), each placed where it is in each saved frame (the trajectory's
``body_z``: a body carried with the ball, moved by the stages or free). The pole's crossing
stays the ball's check: the ball's centre is on the axis the pole moves along, and a runaway
pole passes through it; a held body is off the axis or pressed by the pole from one side
(:mod:`dynslip.physics.bodies.chords`). A held body is judged (``resolved``) on the depth
relative to the local radius of its profile where the chord cuts it, the scale-free form of the
ball's test: reported, while the run's stop rule stays on the absolute depth
(:func:`body_chord_check`).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from dynslip.data.trajectory import body_shift
from dynslip.physics.bodies.chords import deepest_chords_in
from dynslip.physics.sheet import ball_chord_depths, deepest_chord

__all__ = ["body_chord_check", "chord_check", "ball_chord_depths", "span_of"]


def chord_check(ds: xr.Dataset, limit: float, body=None) -> dict:
    """The largest chord depth over the saved frames of a trajectory, where and when, the
    end state's, and whether the mesh resolves the contact (every depth at most ``limit``).

    A piercing can begin and end between two saved frames: the sheet then ends far from the
    ball and reads "not trapped". The pole node lies on the axis, which the ball fills from
    ``zb - 1`` to ``zb + 1``, so a pole that changes sides of the ball's centre has passed
    through it: that counts as depth 1 at the first frame on the other side
    (``pole_crossed_ball``). ``body``: the ball's body (None: the unit ball, in closed
    form; any other body by :func:`dynslip.physics.bodies.chords.chord_depths`)."""
    rho, z, zb, times, rbar = (ds[v].values for v in ("rho", "z", "ball_z", "time", "rbar"))
    depth, k, crossed = deepest_chord(rho, z, zb, np.sign(z[0, 0] - zb[0]), body)
    f = int(
        np.argmax(depth)
    )  # the first frame of the deepest (a crossing: the first on the other side)
    worst = float(depth[f])
    return {
        "max_chord_depth": worst,
        "time_s": float(times[f]),
        "element_rbar": [float(rbar[k[f]]), float(rbar[k[f] + 1])],
        "end_max_chord_depth": float(deepest_chord(rho[-1], z[-1], zb[-1], 0.0, body)[0]),
        "pole_crossed_ball": bool(crossed.any()),
        "limit": float(limit),
        "resolved": bool(worst <= limit),
        "means": (
            "largest depth (units R) that a straight element between two nodes reaches inside the "
            "ball, "
            "over the saved frames; contact acts at nodes only, so a deep chord is sheet passing "
            "through "
            "the ball and trapped is then unknown"
        ),
    }


def span_of(relative: float) -> float:
    """The arc (rad) that one element spans on a circle when its chord dips ``relative`` times
    the circle's radius: 2 arccos(1 - relative), at most pi (a chord through the centre; a
    relative depth of 1 or more says the element spans at least a half circle)."""
    return float(2.0 * np.arccos(1.0 - np.clip(relative, 0.0, 1.0)))


def body_chord_check(ds: xr.Dataset, entries, limit: float, length_mm: float) -> dict:
    """Per held body, the largest chord depth into it over the saved frames of a trajectory,
    with the body placed where it is in each frame (:func:`~dynslip.data.trajectory.body_shift`,
    the trajectory's ``body_z``). ``entries``: ``(name, body, moves_with_ball)`` in held order
    (``physics.named_bodies()``). Returns ``{name: {max_chord_depth, max_chord_depth_mm,
    time_s, element_rbar, end_max_chord_depth, max_relative_chord_depth, radius_R, radius_mm,
    span_rad, relative_time_s, relative_element_rbar, resolved}}``: depths in R (negative: every
    chord outside the body by that much at the least), the first frame of the deepest, the
    element's material radii; the largest depth relative to the local radius of curvature of
    the part of the profile the chord cuts off
    (:func:`~dynslip.physics.bodies.chords.relative_chord_depths`: on the unit ball the
    absolute depth), that radius (R and mm; null where no chord enters the body, 0 at a sharp
    corner), the arc one element spans on it (:func:`span_of`), when and on which element.

    ``resolved``: every *relative* depth at most ``limit``, the scale-free form of the ball's
    test (an element spans at most 2 arccos(1 - limit) of any arc): a rim thinner than twice
    the limit is judged on its own radius. Reported, not enforced: the run's stop rule
    (:func:`dynslip.physics.driver.meshcheck.held_unresolved`) stays on the absolute depth, because
    the main job at its default mesh (N = 50) crosses the tube's rounded rim with one element
    (relative depth 1) and would stop (docs/bodies.md, "The mesh check against every body").
    No pole crossing: that is the ball's (:func:`chord_check`)."""
    rho, z, times, rbar = (ds[v].values for v in ("rho", "z", "time", "rbar"))
    out = {}
    for k, (name, body, with_ball) in enumerate(entries):
        shift = body_shift(ds, k, with_ball)
        shift = np.zeros(times.shape) if shift is None else shift
        (depth, el), (rel, radius, rel_el) = deepest_chords_in(body, rho, z, shift)
        f = int(np.argmax(depth))
        worst = float(depth[f])
        g = int(np.argmax(rel))
        r = float(radius[g])
        rel_worst = float(rel[g])
        r_out = None if not np.isfinite(r) else r  # null: no chord enters, or a line's inf
        out[name] = {
            "max_chord_depth": worst,
            "max_chord_depth_mm": worst * length_mm,
            "time_s": float(times[f]),
            "element_rbar": [float(rbar[el[f]]), float(rbar[el[f] + 1])],
            "end_max_chord_depth": float(depth[-1]),
            "max_relative_chord_depth": rel_worst,
            "radius_R": r_out,
            "radius_mm": None if r_out is None else r_out * length_mm,
            "span_rad": span_of(rel_worst) if r_out is not None and r_out > 0 else None,
            "relative_time_s": float(times[g]),
            "relative_element_rbar": [float(rbar[rel_el[g]]), float(rbar[rel_el[g] + 1])],
            "resolved": bool(rel_worst <= limit),
        }
    return out
