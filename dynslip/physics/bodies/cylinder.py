r"""A cylinder on the axis from ``z_bottom`` to ``z_top`` of ``radius``, solid or, with
``inner_radius`` $> 0$, a tube wall $r_i \le \rho \le r_o$ (open at both ends); its corners
sharp (``edge_radius`` 0) or rounded to ``edge_radius``. A tube wall with
``edge_radius = (radius - inner_radius)/2`` has fully rounded ends (a half torus: the
tube's rim, :mod:`dynslip.physics.bodies.apparatus`). Units of R.

Profile: the top face from the axis (or the inner wall's top) outward, down the outer wall,
the bottom face inward, and for a tube up the inner wall (a closed ring).

Example::

    >>> import jax.numpy as jnp
    >>> c = Cylinder(radius=1.0, z_bottom=-2.0, z_top=0.0)
    >>> float(c.distance(jnp.array([1.5, -1.0])))
    0.5
"""

from __future__ import annotations

import equinox as eqx

from dynslip.physics.bodies.base import AbstractProfileBody, BodyGeometryError, check_profile
from dynslip.physics.bodies.disc import rounded_box

__all__ = ["Cylinder"]


class Cylinder(AbstractProfileBody):
    """A solid cylinder or a tube wall, from ``z_bottom`` to ``z_top``."""

    radius: float = eqx.field(static=True)
    z_bottom: float = eqx.field(static=True)
    z_top: float = eqx.field(static=True)
    inner_radius: float = eqx.field(static=True)
    edge_radius: float = eqx.field(static=True)
    segments: tuple = eqx.field(static=True)

    def __init__(
        self,
        radius: float,
        z_bottom: float,
        z_top: float,
        inner_radius: float = 0.0,
        edge_radius: float = 0.0,
    ):
        if not radius > 0:
            raise BodyGeometryError(f"cylinder radius {radius:g}, must be > 0")
        if not z_top > z_bottom:
            raise BodyGeometryError(f"cylinder height {z_top - z_bottom:g}, must be > 0")
        if not 0 <= inner_radius < radius:
            raise BodyGeometryError(
                f"cylinder inner radius {inner_radius:g}, "
                f"must be >= 0 and below the radius {radius:g}"
            )
        wall = radius - inner_radius if inner_radius > 0 else radius
        limit = min(0.5 * (z_top - z_bottom), 0.5 * wall if inner_radius > 0 else wall)
        if not 0 <= edge_radius <= limit * (1 + 1e-12):
            raise BodyGeometryError(
                f"cylinder edge radius {edge_radius:g}, must be >= 0 and at most {limit:g} "
                "(half the height, and half the wall or the radius)"
            )
        self.radius, self.z_bottom, self.z_top = float(radius), float(z_bottom), float(z_top)
        self.inner_radius, self.edge_radius = float(inner_radius), min(float(edge_radius), limit)
        self.segments = rounded_box(
            self.inner_radius, self.radius, self.z_bottom, self.z_top, self.edge_radius
        )
        check_profile(self.segments, smooth=self.edge_radius > 0)
