r"""The ball: a sphere of ``radius`` about $(0, z_c)$, $z_c$ = ``centre_z`` (units of R).

Closed form, the same floating-point operations as :mod:`dynslip.physics.sheet` (whose
penetration of the unit ball is $1 - |x - x_b|$, here $-d$):

$$d(x) = |x - x_c| - a,\quad n = \frac{x - x_c}{|x - x_c|} = (\sin\theta, \cos\theta),\quad
  s = a\,\theta,\quad t = (\cos\theta, -\sin\theta),$$

$\theta = \operatorname{atan2}(\rho, z - z_c)$ the polar angle from the top pole, $x_c =
(0, z_c + z)$ for a ball displaced by $z$. The profile runs from the top pole down to the
bottom one. At the centre the normal is $(0, 1)$ by convention.

Example::

    >>> import jax.numpy as jnp
    >>> float(Sphere().distance(jnp.array([0.0, 1.5])))
    0.5
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp

from dynslip.physics.bodies.base import AbstractBody, BodyGeometryError
from dynslip.physics.bodies.segments import Arc, Projection

__all__ = ["Sphere"]


class Sphere(AbstractBody):
    """A sphere of ``radius`` centred on the axis at ``centre_z`` (its reference placement)."""

    radius: float = eqx.field(static=True)
    centre_z: float = eqx.field(static=True)
    segments: tuple = eqx.field(static=True)

    def __init__(self, radius: float = 1.0, centre_z: float = 0.0):
        if not radius > 0:
            raise BodyGeometryError(f"sphere radius {radius:g}, must be > 0")
        self.radius = float(radius)
        self.centre_z = float(centre_z)
        self.segments = (Arc((0.0, self.centre_z), self.radius, math.pi / 2, -math.pi / 2),)

    @property
    def is_unit(self) -> bool:
        """The unit ball about the origin: the closed forms of the sheet, its mesh check and its
        figures apply."""
        return (self.radius, self.centre_z) == (1.0, 0.0)

    def project(self, x, z=0.0) -> Projection:
        x = jnp.asarray(x, float)
        rho, dz = x[..., 0], x[..., 1] - (self.centre_z + z)
        r = jnp.sqrt(rho**2 + dz**2)
        pos = r > 0
        rs = jnp.where(pos, r, 1.0)
        n = jnp.where(
            pos[..., None], jnp.stack([rho / rs, dz / rs], axis=-1), jnp.array([0.0, 1.0])
        )
        sg = jnp.where(rho < 0, -1.0, 1.0)  # rho < 0: the mirror image (physics.bodies.base)
        t = jnp.stack([sg * n[..., 1], -sg * n[..., 0]], axis=-1)
        return Projection(
            distance=r - self.radius,
            normal=n,
            s=self.radius * jnp.arctan2(jnp.abs(rho), dz),
            tangent=t,
            curvature=jnp.where(pos, 1.0 / rs, 0.0),  # the normal's turn, 1/|x - x_c|
        )
