r"""When a pocket holds its body: "trapped" as a criterion on the contact's extent along the
body's surface coordinate $s$ (arc length along the profile from its start, units of R).

A criterion gives a threshold $s^*$; the pocket traps when the contact reaches past it,
$s_{max} > s^*$ (with the other conditions of a trap, slip stopped and the support's reaction
gone, checked by the caller). :meth:`AbstractTrapCriterion.margin` is
$s_{max} - s^*$, positive when trapped.

- :class:`PastEquator`, the ball's (``theta_max > pi/2``, physics.md Section 4):
  $s^* = a\pi/2$ for a sphere of radius $a$, so for the unit ball $s = \theta$ and the
  criterion is ``theta_max > pi/2`` exactly.
- :class:`PastEdgeMidHeight`, the coin's: the contact runs over the rounded corner and past
  the middle of the vertical edge, onto the half that faces the underside.
- :class:`PastWidest`, any body's: past the middle of the profile's widest part (largest
  $\rho$); the two above are its closed forms.

Example::

    >>> import math
    >>> bool(PastEquator().trapped(1.8)), bool(PastEquator().trapped(math.pi / 2 - 1e-3))
    (True, False)
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.base import AbstractBody
from dynslip.physics.bodies.disc import Disc

__all__ = ["AbstractTrapCriterion", "PastEdgeMidHeight", "PastEquator", "PastWidest"]


class AbstractTrapCriterion(eqx.Module):
    """A body's trapped criterion on the contact's extent ``s_max`` along its profile."""

    @abc.abstractmethod
    def threshold(self) -> float:
        """The surface coordinate s* the contact must pass (units of R)."""

    def margin(self, s_max):
        """s_max - s* (units of R): positive when the contact reaches past the threshold;
        NaN stays NaN (no contact)."""
        return jnp.asarray(s_max, float) - self.threshold()

    def trapped(self, s_max):
        """Whether the contact extends past the threshold (boolean array of the shape of
        ``s_max``; False without contact, NaN)."""
        m = self.margin(s_max)
        return jnp.isfinite(m) & (m > 0)


class PastEquator(AbstractTrapCriterion):
    """A sphere of ``radius``: the contact passes its equator, s* = radius pi/2."""

    radius: float = 1.0

    def threshold(self) -> float:
        return self.radius * math.pi / 2


class PastEdgeMidHeight(AbstractTrapCriterion):
    """A coin: the contact passes its vertical edge's mid-height toward the underside,
    s* = (a - e) + pi e/2 + (h/2 - e) (:mod:`.disc`)."""

    disc: Disc

    def threshold(self) -> float:
        a, h, e = self.disc.radius, self.disc.thickness, self.disc.edge_radius
        return (a - e) + math.pi * e / 2 + (h / 2 - e)


class PastWidest(AbstractTrapCriterion):
    """Any body: the contact passes the middle of the profile's widest part (the largest rho,
    taken on a line or at one point), found on the profile sampled every 1e-4 of its length
    and refined on the segments that reach the widest rho."""

    body: AbstractBody

    def threshold(self) -> float:
        total = self.body.length
        s = np.linspace(0.0, total, 10001)
        rho = self.body.point_at(s)[:, 0]
        widest = rho >= rho.max() - 1e-9 * max(1.0, rho.max())
        acc, lo, hi = 0.0, math.inf, -math.inf
        for (
            seg
        ) in self.body.segments:  # exact ends of the widest part: a vertical line or an arc's top
            u = np.linspace(0.0, 1.0, 2001)
            r = seg.point_at(u)[:, 0]
            on = r >= rho.max() - 1e-9 * max(1.0, rho.max())
            if on.any():
                lo = min(lo, acc + seg.length * u[on][0])
                hi = max(hi, acc + seg.length * u[on][-1])
            acc += seg.length
        if not np.isfinite(lo):
            lo = hi = float(s[widest].mean())
        return 0.5 * (lo + hi)
