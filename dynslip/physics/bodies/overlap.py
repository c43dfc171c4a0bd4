r"""Checks at the start of a run: do two solids intersect, is a point inside a solid.

Two closed solids overlap exactly when a point of one's surface lies strictly inside the other
(their surfaces cross, or one holds the other). :func:`penetration` finds the deepest point of
``a``'s profile inside ``b`` (and of ``b``'s inside ``a``): dense sampling along the profile,
then three rounds of local resampling about the deepest sample, so a depth is found to about
$10^{-12}$ R for smooth profiles. Touching (depth 0, a ball resting on a support) is not
overlap. Units of R.

Example::

    >>> from dynslip.physics.bodies.sphere import Sphere
    >>> overlap(Sphere(), Sphere(centre_z=2.0)), overlap(Sphere(), Sphere(centre_z=1.9))
    (False, True)
"""

from __future__ import annotations

import numpy as np

from dynslip.physics.bodies.base import AbstractBody

__all__ = ["inside", "overlap", "penetration"]


def _deepest(a: AbstractBody, b: AbstractBody, za: float, zb: float, n: int) -> float:
    """Most negative distance to ``b`` of a point of ``a``'s profile (units of R)."""
    total = a.length
    s = np.linspace(0.0, total, n)
    d = np.asarray(b.distance(a.point_at(s, za), zb))
    h = total / (n - 1)  # half-width of the window about the deepest sample
    for _ in range(3):
        k = int(np.argmin(d))
        s = np.clip(np.linspace(s[k] - h, s[k] + h, 101), 0.0, total)
        d = np.asarray(b.distance(a.point_at(s, za), zb))
        h = 2 * h / 100
    return float(np.min(d))


def penetration(
    a: AbstractBody, b: AbstractBody, za: float = 0.0, zb: float = 0.0, n: int = 4001
) -> float:
    """Depth by which the solids ``a`` (displaced by ``za``) and ``b`` (by ``zb``)
    intersect: the deepest point of either surface inside the other, >= 0 (0 when apart or
    touching)."""
    return max(0.0, -_deepest(a, b, za, zb, n), -_deepest(b, a, zb, za, n))


def overlap(
    a: AbstractBody, b: AbstractBody, za: float = 0.0, zb: float = 0.0, tol: float = 1e-9
) -> bool:
    """Whether the solids intersect by more than ``tol`` (R): bodies that overlap at the
    start of a run."""
    return penetration(a, b, za, zb) > tol


def inside(body: AbstractBody, points, z: float = 0.0, tol: float = 1e-9) -> np.ndarray:
    """Boolean array (...,): which of the points (..., 2) = (rho, z) lie inside the solid by
    more than ``tol`` (R): a sheet starting inside a body. A point on the surface is not
    inside."""
    return np.asarray(body.distance(np.asarray(points, float), z)) < -tol
