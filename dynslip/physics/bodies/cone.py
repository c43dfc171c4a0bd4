r"""A cone: its apex on the axis at ``z_apex``, its base a flat disc of ``radius`` at
``z_base`` (apex above or below the base). Units of R. The apex and the base's rim are sharp
(convex) edges: outside them the distance is the distance to the edge, and smooth.

Profile, from the top of the axis: apex above the base, the flank from the apex down to the
rim then the base back to the axis; apex below, the base out to the rim then the flank down
to the apex. The flank's outward normal makes the half-angle $\alpha$,
$\tan\alpha = a/|z_{apex} - z_{base}|$, with the horizontal.

Example::

    >>> import jax.numpy as jnp
    >>> c = Cone(radius=1.0, z_base=0.0, z_apex=1.0)
    >>> round(float(c.distance(jnp.array([1.0, 1.0]))), 12) == round(0.5 ** 0.5, 12)
    True
"""

from __future__ import annotations

import equinox as eqx

from dynslip.physics.bodies.base import AbstractProfileBody, BodyGeometryError, check_profile
from dynslip.physics.bodies.segments import Line

__all__ = ["Cone"]


class Cone(AbstractProfileBody):
    """A pointed cone of base ``radius`` at ``z_base`` and apex at ``z_apex``."""

    radius: float = eqx.field(static=True)
    z_base: float = eqx.field(static=True)
    z_apex: float = eqx.field(static=True)
    segments: tuple = eqx.field(static=True)

    def __init__(self, radius: float, z_base: float, z_apex: float):
        if not radius > 0:
            raise BodyGeometryError(f"cone radius {radius:g}, must be > 0")
        if not abs(z_apex - z_base) > 0:
            raise BodyGeometryError("cone height 0, must be nonzero")
        self.radius, self.z_base, self.z_apex = float(radius), float(z_base), float(z_apex)
        apex, rim, axis = (0.0, self.z_apex), (self.radius, self.z_base), (0.0, self.z_base)
        if self.z_apex > self.z_base:
            self.segments = (Line(apex, rim), Line(rim, axis))
        else:
            self.segments = (Line(axis, rim), Line(rim, apex))
        check_profile(self.segments, smooth=False)
