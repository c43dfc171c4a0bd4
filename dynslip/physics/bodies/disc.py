r"""A coin: a disc of ``radius`` $a$ and ``thickness`` $h$, its flat top and bottom joined by
a vertical edge whose corners are rounded to ``edge_radius`` $e$, $0 < e \le h/2$
($e = h/2$: a fully rounded edge). Centred at ``centre_z`` on the axis (units of R).

Profile, from the top of the axis: the top face $z = z_c + h/2$ out to $\rho = a - e$; a
quarter circle of radius $e$ about $(a - e, z_c + h/2 - e)$; the vertical edge $\rho = a$
down to $z_c - h/2 + e$ (absent when $e = h/2$); a quarter circle; the bottom face back to the
axis. Arc lengths: top face $a - e$, each corner $\pi e/2$, edge $h - 2e$; the edge's
mid-height lies at $s = a - e + \pi e/2 + h/2 - e$ (:class:`~.trap.PastEdgeMidHeight`).

Example::

    >>> import jax.numpy as jnp
    >>> coin = Disc(radius=2.0, thickness=0.2, edge_radius=0.05)
    >>> round(float(coin.distance(jnp.array([0.5, 0.3]))), 12)
    0.2
"""

from __future__ import annotations

import math

import equinox as eqx

from dynslip.physics.bodies.base import AbstractProfileBody, BodyGeometryError, check_profile
from dynslip.physics.bodies.segments import Arc, Line

__all__ = ["Disc", "rounded_box"]


def rounded_box(r_in: float, r_out: float, z0: float, z1: float, e: float) -> tuple:
    """Profile of the solid r_in <= rho <= r_out, z0 <= z <= z1 with its outer corners (and,
    when r_in > 0, its inner ones) rounded to ``e`` (0: sharp). From the axis (r_in = 0) or
    from the top face's inner end (a ring), clockwise."""
    segs: list[Line | Arc] = []
    if e > 0:
        segs.append(Line((r_in + (e if r_in > 0 else 0.0), z1), (r_out - e, z1)))
        segs.append(Arc((r_out - e, z1 - e), e, math.pi / 2, 0.0))
        segs.append(Line((r_out, z1 - e), (r_out, z0 + e)))
        segs.append(Arc((r_out - e, z0 + e), e, 0.0, -math.pi / 2))
        segs.append(Line((r_out - e, z0), (r_in + (e if r_in > 0 else 0.0), z0)))
        if r_in > 0:
            segs.append(Arc((r_in + e, z0 + e), e, -math.pi / 2, -math.pi))
            segs.append(Line((r_in, z0 + e), (r_in, z1 - e)))
            segs.append(Arc((r_in + e, z1 - e), e, -math.pi, -3 * math.pi / 2))
    else:
        segs += [
            Line((r_in, z1), (r_out, z1)),
            Line((r_out, z1), (r_out, z0)),
            Line((r_out, z0), (r_in, z0)),
        ]
        if r_in > 0:
            segs.append(Line((r_in, z0), (r_in, z1)))
    return tuple(seg for seg in segs if not (isinstance(seg, Line) and seg.length <= 1e-12))


class Disc(AbstractProfileBody):
    """A coin of ``radius``, ``thickness`` and ``edge_radius``, centred at ``centre_z``."""

    radius: float = eqx.field(static=True)
    thickness: float = eqx.field(static=True)
    edge_radius: float = eqx.field(static=True)
    centre_z: float = eqx.field(static=True)
    segments: tuple = eqx.field(static=True)

    def __init__(self, radius: float, thickness: float, edge_radius: float, centre_z: float = 0.0):
        for what, v in (
            ("disc radius", radius),
            ("disc thickness", thickness),
            ("disc edge radius", edge_radius),
        ):
            if not v > 0:
                raise BodyGeometryError(f"{what} {v:g}, must be > 0")
        if edge_radius > 0.5 * thickness * (1 + 1e-12) or edge_radius >= radius:
            raise BodyGeometryError(
                f"disc edge radius {edge_radius:g}, must be at most half the thickness "
                f"({0.5 * thickness:g}) and below the radius ({radius:g})"
            )
        self.radius, self.thickness = float(radius), float(thickness)
        self.edge_radius, self.centre_z = (
            min(float(edge_radius), 0.5 * self.thickness),
            float(centre_z),
        )
        h2 = 0.5 * self.thickness
        self.segments = rounded_box(
            0.0, self.radius, self.centre_z - h2, self.centre_z + h2, self.edge_radius
        )
        check_profile(self.segments)
