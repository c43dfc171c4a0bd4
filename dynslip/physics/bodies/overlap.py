r"""Checks at the start of a run: do two solids intersect, do they share a face, is a point
inside a solid.

Two closed solids overlap exactly when a point of one's surface lies strictly inside the other
(their surfaces cross, or one holds the other). :func:`penetration` finds the deepest point of
``a``'s profile inside ``b`` (and of ``b``'s inside ``a``): dense sampling along the profile,
then three rounds of local resampling about the deepest sample, so a depth is found to about
$10^{-12}$ R for smooth profiles. Touching (depth 0, a ball resting on a support) is not
overlap. Units of R.

Two bodies that touch along a face (:func:`shared_face`: a length of one's profile on the
other's surface) make a face inside matter: the signed distance of their union is 0 on it, a
sheet node pushed there is held by neither side and hooked. Touching at a point (a ball on its
support ring) shares a length of ~0.

Example::

    >>> from dynslip.physics.bodies.cylinder import Cylinder
    >>> from dynslip.physics.bodies.sphere import Sphere
    >>> overlap(Sphere(), Sphere(centre_z=2.0)), overlap(Sphere(), Sphere(centre_z=1.9))
    (False, True)
    >>> round(shared_face(Cylinder(1.0, -3.0, -2.0), Cylinder(0.5, -2.0, -1.0)), 6)
    0.5
"""

from __future__ import annotations

import numpy as np

from dynslip.physics.bodies.base import AbstractBody

__all__ = ["inside", "overlap", "penetration", "shared_face"]


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


def shared_face(
    a: AbstractBody, b: AbstractBody, za: float = 0.0, zb: float = 0.0, tol: float = 1e-9,
    n: int = 1025,
) -> float:
    """Length (units of R) of ``a``'s profile (displaced by ``za``) lying on ``b``'s surface
    (displaced by ``zb``): the sum over the ``n`` samples of each segment of the pieces whose
    both ends are within ``tol`` of it (|distance| <= tol). Exact to a piece (the segment's
    length / (n - 1)) at each end of a shared stretch; a contact at a point gives 0 (or a
    piece where the surfaces stay within ``tol`` of each other, ~1e-4 R for curvatures
    differing by 1/R). Not symmetric in general: check both ways round."""
    u = np.linspace(0.0, 1.0, n)
    pts = np.concatenate([seg.point_at(u) for seg in a.segments], axis=0)
    pts[:, 1] += za
    on = (np.abs(np.asarray(b.distance(pts, zb))) <= tol).reshape(len(a.segments), n)
    pieces = np.sum(on[:, :-1] & on[:, 1:], axis=1)
    return float(sum(seg.length / (n - 1) * k for seg, k in zip(a.segments, pieces, strict=True)))
