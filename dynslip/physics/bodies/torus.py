r"""A torus: the ring swept by a circle of ``minor_radius`` $r$ whose centre lies at
``ring_radius`` $R_0 > r$ from the axis, at height ``centre_z`` (units of R): a tube's rounded
rim. Closed form: $d = |x - (R_0, z_c)| - r$, $n$ radial about the tube's centre.

Profile: the whole circle, clockwise from its top point $(R_0, z_c + r)$; $s = r\varphi$,
$\varphi$ the angle turned from the top toward the outside.

Example::

    >>> import jax.numpy as jnp
    >>> t = Torus(ring_radius=2.0, minor_radius=0.25)
    >>> float(t.distance(jnp.array([2.0, 1.25])))
    1.0
"""

from __future__ import annotations

import math

import equinox as eqx

from dynslip.physics.bodies.base import AbstractProfileBody, BodyGeometryError, check_profile
from dynslip.physics.bodies.segments import Arc

__all__ = ["Torus"]


class Torus(AbstractProfileBody):
    """A ring of ``minor_radius`` about the circle of ``ring_radius`` at ``centre_z``."""

    ring_radius: float = eqx.field(static=True)
    minor_radius: float = eqx.field(static=True)
    centre_z: float = eqx.field(static=True)
    segments: tuple = eqx.field(static=True)

    def __init__(self, ring_radius: float, minor_radius: float, centre_z: float = 0.0):
        if not minor_radius > 0:
            raise BodyGeometryError(f"torus minor radius {minor_radius:g}, must be > 0")
        if not ring_radius > minor_radius:
            raise BodyGeometryError(
                f"torus ring radius {ring_radius:g}, must exceed the minor radius {minor_radius:g}"
            )
        self.ring_radius, self.minor_radius = float(ring_radius), float(minor_radius)
        self.centre_z = float(centre_z)
        self.segments = (
            Arc(
                (self.ring_radius, self.centre_z),
                self.minor_radius,
                math.pi / 2,
                math.pi / 2 - 2 * math.pi,
            ),
        )
        check_profile(self.segments)
