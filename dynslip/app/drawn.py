"""The bodies a saved trajectory's world holds, as outlines to draw (animations, the VTK export).

A trajectory carries its resolved scenario (global attribute ``scenario``); the schema rebuilds
the ball and the held bodies from it, and the figures and files get plain data: outlines of
the meridian section in the bodies' reference placements (units of R), never a schema or body
object (``plot`` and ``data`` know no schema).
"""

from __future__ import annotations

import json

import numpy as np

from dynslip.data.trajectory import body_shift, open_trajectory
from dynslip.physics.bodies import Sphere

__all__ = ["drawn_bodies", "drawn_bodies_at"]


def drawn_bodies(ds) -> dict | None:
    """``{"ball": outline or None, "held": [(name, outline, shift), ...]}`` of the
    trajectory ``ds``'s world: ``ball`` the ball's closed outline (M, 2) at ``ball_z = 0`` (None
    for the unit sphere, drawn as a circle), ``held`` each held body's (``physics.named_bodies()``
    order) at its placement, displaced at frame k by ``shift[k]``
    (:func:`~dynslip.data.trajectory.body_shift`: with the ball, by the stages or free; None
    for a body at rest). None when the trajectory
    carries no scenario this version validates (an older file: the unit sphere only)."""
    # at call time: the tests replace it in its home module
    from dynslip.schema.base import validate_data

    try:
        sc = validate_data(json.loads(ds.attrs["scenario"]), "trajectory scenario")
        p = sc.physics
        ball = p.ball_body()
        held = [(name, np.asarray(body.outline()), body_shift(ds, k, bool(with_ball)))
                for k, (name, body, with_ball) in enumerate(p.named_bodies())]
    except (KeyError, TypeError, ValueError, AttributeError):  # no scenario this version validates
        return None
    unit = isinstance(ball, Sphere) and ball.is_unit
    return {"ball": None if unit else np.asarray(ball.outline()), "held": held}


def drawn_bodies_at(trajectory_path) -> dict | None:
    """:func:`drawn_bodies` of the trajectory file ``trajectory_path`` (an
    :class:`~dynslip.errors.InputError` for a file that is not one)."""

    return drawn_bodies(open_trajectory(trajectory_path))
