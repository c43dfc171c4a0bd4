r"""The run's mesh check (``Settings.max_chord_depth``), frame by frame: how deep an element
chord dips into the ball (:func:`ball_unresolved`, closed form, on the host) and into each held
body (:func:`held_unresolved`, a search per body, about 1 ms each at 50 nodes), checked in line
as each frame is recorded (:meth:`dynslip.physics.driver.member.MemberRun.record`): a failed check
fails the run at that frame, which is kept.
"""

from __future__ import annotations

import numpy as np

from dynslip.physics.bodies.chords import deepest_chord_in
from dynslip.physics.bodies.held import held_entries
from dynslip.physics.driver.failures import ContactUnresolved
from dynslip.physics.sheet import deepest_chord

__all__ = ["ball_unresolved", "held_unresolved"]


def _failure(model, stage, t, limit, depth, k, crossed, body=None) -> ContactUnresolved:
    rbar = np.asarray(model.mesh.rbar)
    return ContactUnresolved(stage, t, float(depth), float(limit),
                             (float(rbar[k]), float(rbar[k + 1])), bool(crossed), body=body)


def ball_unresolved(model, rec: dict, first: dict, limit: float, stage: str, t: float):
    """Why the frame ``rec`` (of stage ``stage``, saved at ``t``) is past what the mesh
    resolves against the ball, or None: an element chord deeper than ``limit`` (R) inside the
    ball, or the pole through it (:func:`~dynslip.physics.sheet.deepest_chord`; the side of the
    ball the pole started on is read from ``first``, the run's initial frame)."""
    depth, k, crossed = deepest_chord(
        rec["rho"], rec["z"], rec["ball_z"], np.sign(first["z"][0] - first["ball_z"]),
        model.ball,
    )
    if crossed or depth > limit:
        return _failure(model, stage, t, limit, depth, k, crossed)
    return None


def held_unresolved(model, names, rec: dict, limit: float, stage: str, t: float):
    """Why the frame ``rec`` is past what the mesh resolves against a held body, or None: a
    chord deeper than ``limit`` inside a held body, each placed at its height in the frame
    (``rec["body_z"]``; :func:`~dynslip.physics.bodies.chords.deepest_chord_in`), the first
    such body's, named from ``names`` (the settings' ``body_names``)."""
    for j, e in enumerate(held_entries(model.bodies)):
        depth, k = deepest_chord_in(e.body, rec["rho"], rec["z"], rec["body_z"][j])
        if depth > limit:
            name = names[j] if j < len(names) else f"held body {j}"
            return _failure(model, stage, t, limit, depth, k, False, name)
    return None
