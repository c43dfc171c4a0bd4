r"""The experiment's apparatus as held bodies: the bottle the ball sits on, the tube's wall.

Sizes are the paper's where it gives them (Section 2: a 4 in OD, 4 in tall PVC tube; a bottle
with a 1 in OD neck) and stated assumptions where it does not (physics.md Section 4, "The
experiment's world"): the neck's wall 2 mm, its length 65 mm (bottles with such a neck: 50-80
mm), a conical shoulder 18.6 mm high to a body 70 mm across (typically 60-75 mm), the body 140
mm tall; the tube's wall 3 mm with a fully rounded end. Every size is an argument in mm.
Lengths returned in units of the ball's radius R, in the lab frame with the ball's centre at
the origin when it rests on the neck.

The neck's rounded lip is placed so that it touches the resting ball (distance 0): its torus
centre at $(\rho_c, z_c)$, $\rho_c = r_o - w/2$, $z_c = -\sqrt{(1 + w/2)^2 - \rho_c^2}$ (with
$r_o$, $w$ in R). The tube's wall hangs from its rim: the rim (the wall's end) at height
$z_{\rm rim}$ (the clamp's height), the wall up to $z_{\rm rim} + H$; the ball stays inside the
tube while $z_{\rm rim} + H \ge 1$, so the deepest push-down the tube allows is
$z_{\rm rim} = 1 - H$ (:func:`deepest_rim`: -81.6 mm for the paper's tube and ball).

Example::

    >>> parts = bottle(20.0)
    >>> len(parts)
    3
    >>> round(deepest_rim(20.0), 2)
    -4.08
"""

from __future__ import annotations

import functools
import math

from dynslip.physics.bodies.base import BodyGeometryError
from dynslip.physics.bodies.cone import Cone
from dynslip.physics.bodies.cylinder import Cylinder

__all__ = ["bottle", "tube_wall", "deepest_rim"]


@functools.lru_cache(maxsize=32)
def bottle(
    ball_radius_mm: float,
    neck_od_mm: float = 25.4,
    neck_wall_mm: float = 2.0,
    neck_length_mm: float = 65.0,
    shoulder_height_mm: float = 18.6,
    body_od_mm: float = 70.0,
    body_height_mm: float = 140.0,
) -> tuple:
    """The bottle as three held bodies (neck tube with a rounded lip, conical shoulder,
    cylindrical body), in units of R, the ball resting on the lip at the origin. Built once per
    set of arguments (bodies are immutable; checking a profile costs milliseconds, and a run
    asks for the bottle some ten times: the solver, the summary, the figures)."""
    R = float(ball_radius_mm)
    ro, w = neck_od_mm / 2 / R, neck_wall_mm / R
    if not 0 < w < ro:
        raise BodyGeometryError(
            f"bottle neck wall {neck_wall_mm:g} mm, must be in (0, neck radius)"
        )
    if not ro < 1.0:
        raise BodyGeometryError(
            f"bottle neck radius {neck_od_mm / 2:g} mm, must be below the ball's radius {R:g} mm"
        )
    if not body_od_mm / 2 / R > ro:
        raise BodyGeometryError(
            f"bottle body {body_od_mm:g} mm across, must be wider than the neck"
        )
    rc = ro - w / 2
    zc = -math.sqrt((1 + w / 2) ** 2 - rc**2)
    z_top = zc + w / 2
    z_shoulder = z_top - neck_length_mm / R
    z_body = z_shoulder - shoulder_height_mm / R
    rb = body_od_mm / 2 / R
    neck = Cylinder(ro, z_shoulder - w, z_top, inner_radius=ro - w, edge_radius=w / 2)
    # the shoulder: a cone through (ro, z_shoulder) and (rb, z_body)
    apex = z_body + rb * (z_shoulder - z_body) / (rb - ro)
    shoulder = Cone(rb, z_body, apex)
    body = Cylinder(rb, z_body - body_height_mm / R, z_body)
    return (neck, shoulder, body)


@functools.lru_cache(maxsize=32)
def tube_wall(
    ball_radius_mm: float,
    od_mm: float = 101.6,
    wall_mm: float = 3.0,
    height_mm: float = 101.6,
    rim_z: float = 0.0,
) -> Cylinder:
    """The tube's wall with a fully rounded end (a half torus of radius ``wall_mm / 2``, the
    outer wall a cylinder of radius ``od_mm / 2``), its rim (lowest point) at ``rim_z`` (units
    of R; 0: displace it by the clamp's height). Units of R. Built once per set of arguments
    (as :func:`bottle`)."""
    R = float(ball_radius_mm)
    ro, w = od_mm / 2 / R, wall_mm / R
    if not 0 < w < ro:
        raise BodyGeometryError(f"tube wall {wall_mm:g} mm, must be in (0, tube radius)")
    return Cylinder(ro, rim_z, rim_z + height_mm / R, inner_radius=ro - w, edge_radius=w / 2)


def deepest_rim(ball_radius_mm: float, height_mm: float = 101.6) -> float:
    """The lowest rim height (units of R, below the ball's centre) at which the ball is still
    inside the tube: $1 - H/R$."""
    return 1.0 - height_mm / ball_radius_mm
