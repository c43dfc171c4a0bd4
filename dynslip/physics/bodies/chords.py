r"""The mesh check against any body: how deep each element chord dips into it.

The penalty acts at the nodes only, so nothing keeps an element's chord (the straight
meridian of its conical frustum) out of a body; a deep chord means the mesh does not resolve
the contact (:func:`dynslip.physics.sheet.chord_depths` does this for the unit ball in closed
form). Here for any body: the depth $\max_{u\in[0,1]} -d(x_e + u(x_{e+1} - x_e))$ along each
chord, from 17 samples and then golden-section search on the bracket of the deepest one
(60 steps: the bracket shrinks to $10^{-13}$ of the chord), exact where the depth along the
chord has one maximum in the bracket (a convex body, or a chord short against the profile's
radii of curvature). Positive inside, units of R.

:func:`relative_chord_depths` gives each chord's depth relative to the local radius of
curvature of the part of the profile it cuts off (between where it enters the body and where
it leaves; :meth:`~.base.AbstractBody.curvature_radius`), the scale-free form of the ball's
test (on the unit ball the same number): a chord across a thin wall with a rounded rim reads
the wall's half thickness in R, and 1 relative to the rim. It is reported
(``summary.json`` ``mesh_check.bodies``), not enforced: the run's stop rule stays on the
absolute depth (docs/bodies.md, "The relative test").

:func:`deepest_chord_in` gives the deepest chord per frame into any body (a held body at the
height it has in each frame). The pole's crossing (a pole found on the other side of the
body's centre: passed through it between two saved frames) is the ball's check only
(:func:`dynslip.physics.sheet.deepest_chord`): the ball is the body the sheet is drawn round,
whose centre lies on the axis the pole moves along, and the runaway pole of a coarse mesh
passes through it. A held body is off the axis (a tube's wall, the bottle's neck: the pole
cannot reach it) or, on it, pressed by the pole from one side (a weight set on the sheet);
it is checked at the saved frames only.

Example::

    >>> import numpy as np
    >>> from dynslip.physics.bodies.sphere import Sphere
    >>> th = np.array([0.0, 0.3])  # two nodes on the ball, 0.3 rad apart
    >>> d = chord_depths(Sphere(), np.sin(th), np.cos(th), 0.0)
    >>> bool(abs(d[0] - (1 - np.cos(0.15))) < 1e-12)
    True
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.base import AbstractBody

__all__ = [
    "chord_depths",
    "deepest_chord_in",
    "deepest_relative_chord_in",
    "relative_chord_depths",
]

_SAMPLES = 17
_GOLDEN_STEPS = 60
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0
_BISECT_STEPS = 50


def _depths(body: AbstractBody, a, b, zpos):
    """Depths (...,) of the chords from ``a`` to ``b`` (..., 2), body displaced by zpos (...)."""
    return _deepest(body, a, b, zpos)[0]


@eqx.filter_jit
def _deepest(body: AbstractBody, a, b, zpos):
    """``(depth, u)`` of the chords from ``a`` to ``b`` (..., 2): the depth and the fraction u
    in [0, 1] along the chord of its deepest point, body displaced by zpos (...)."""
    def depth(u):
        return -body.distance(a + u[..., None] * (b - a), zpos)
    u = jnp.linspace(0.0, 1.0, _SAMPLES)
    samples = jax.vmap(lambda ui: depth(jnp.full(a.shape[:-1], ui)))(u)  # (S, ...)
    k = jnp.argmax(samples, axis=0)
    lo = u[jnp.clip(k - 1, 0, _SAMPLES - 1)]
    hi = u[jnp.clip(k + 1, 0, _SAMPLES - 1)]

    def step(_, lh):
        lo, hi = lh
        c, d = hi - _INV_PHI * (hi - lo), lo + _INV_PHI * (hi - lo)
        left = depth(c) >= depth(d)
        return jnp.where(left, lo, c), jnp.where(left, d, hi)

    lo, hi = jax.lax.fori_loop(0, _GOLDEN_STEPS, step, (lo, hi))
    um = 0.5 * (lo + hi)
    dm, ds = depth(um), jnp.max(samples, axis=0)
    return jnp.maximum(ds, dm), jnp.where(dm >= ds, um, u[k])


@eqx.filter_jit
def _cut_off(body: AbstractBody, a, b, zpos, um):
    """Arc lengths ``(s_in, s_out)`` along the profile where the chords from ``a`` to ``b``
    enter and leave the body, by bisection between the deepest point ``um`` (inside) and each
    node (a node inside the body: the node itself); the closest points' s."""
    def depth(u):
        return -body.distance(a + u[..., None] * (b - a), zpos)

    def crossing(end):
        def step(_, lh):
            lo, hi = lh  # lo inside, hi outside
            mid = 0.5 * (lo + hi)
            inside = depth(mid) > 0
            return jnp.where(inside, mid, lo), jnp.where(inside, hi, mid)
        lo, hi = jax.lax.fori_loop(0, _BISECT_STEPS, step, (um, jnp.full(um.shape, end)))
        return jnp.where(depth(jnp.full(um.shape, end)) > 0, end, 0.5 * (lo + hi))

    def s_at(u):
        return body.project(a + u[..., None] * (b - a), zpos).s
    return s_at(crossing(0.0)), s_at(crossing(1.0))


def chord_depths(body: AbstractBody, rho, z, zpos) -> np.ndarray:
    """Depth inside ``body`` (displaced by ``zpos``, shape (...)) of each element chord, for
    node positions ``rho, z`` of shape (..., N): shape (..., N-1), positive inside, as
    :func:`dynslip.physics.sheet.chord_depths` for the unit ball."""
    x = jnp.stack([jnp.asarray(rho, float), jnp.asarray(z, float)], axis=-1)
    zp = jnp.asarray(zpos, float)[..., None]
    zp = jnp.broadcast_to(zp, x.shape[:-2] + (x.shape[-2] - 1,))
    return np.asarray(_depths(body, x[..., :-1, :], x[..., 1:, :], zp))


def deepest_chord_in(body: AbstractBody, rho, z, zpos) -> tuple[np.ndarray, np.ndarray]:
    """Per frame (frames leading, shape (...)) ``(depth, element)`` of the deepest element chord
    inside ``body`` displaced along the axis by ``zpos`` (shape (...): a held body's height in
    each frame), for node positions ``rho, z`` of shape (..., N): depth in R (positive inside,
    a non-finite chord counts as -inf), ``element`` the index of its element (nodes ``element``
    and ``element + 1``). No pole crossing (the module's docstring: the ball's check only)."""
    depth = chord_depths(body, rho, z, zpos)
    depth = np.where(np.isfinite(depth), depth, -np.inf)
    k = np.argmax(depth, axis=-1)
    return np.take_along_axis(depth, k[..., None], axis=-1)[..., 0], k


def relative_chord_depths(body: AbstractBody, rho, z, zpos):
    r"""``(depth, radius, relative)`` of each element chord (shapes (..., N-1), as
    :func:`chord_depths`): the depth (R), the local radius of curvature r (R) of the part of the
    profile the chord cuts off, and the depth relative to it.

    The radius: the smallest of the profile between where the chord enters the body and where
    it leaves it (:meth:`~.base.AbstractBody.curvature_radius`; a node inside the body counts
    as the chord's end): an arc's radius, ``inf`` on a line alone (relative depth 0), the arc's
    where the chord reaches past a line's joint onto it, 0 at a sharp corner. The relative
    depth is depth / r: the scale-free form of the ball's test (on the unit ball r = 1, the
    same number; two nodes on an arc a half-angle a apart give 1 - cos a on any arc). A chord
    straight across a wall with a rounded rim (one node on either face) cuts off the rim: its
    depth, the wall's half thickness, is the rim's radius, relative depth 1. Where no radius
    applies the depth is taken as it is (relative to R): a chord that does not enter the body
    (depth <= 0, radius nan) and one that cuts a sharp corner (radius 0)."""
    x = jnp.stack([jnp.asarray(rho, float), jnp.asarray(z, float)], axis=-1)
    zp = jnp.asarray(zpos, float)[..., None]
    zp = jnp.broadcast_to(zp, x.shape[:-2] + (x.shape[-2] - 1,))
    a, b = x[..., :-1, :], x[..., 1:, :]
    depth, um = _deepest(body, a, b, zp)
    s_in, s_out = _cut_off(body, a, b, zp, um)
    depth = np.asarray(depth)
    radius = np.where(depth > 0, body.curvature_radius(np.asarray(s_in), np.asarray(s_out)),
                      np.nan)
    scale = np.where((depth > 0) & (radius > 0), radius, 1.0)
    return depth, radius, depth / scale


def deepest_relative_chord_in(body: AbstractBody, rho, z, zpos):
    """Per frame (frames leading, shape (...)) ``(relative, radius, element)`` of the element
    chord deepest relative to the radius it cuts off (:func:`relative_chord_depths`), as
    :func:`deepest_chord_in` (a non-finite chord counts as -inf)."""
    _, radius, rel = relative_chord_depths(body, rho, z, zpos)
    rel = np.where(np.isfinite(rel), rel, -np.inf)
    k = np.argmax(rel, axis=-1)
    pick = lambda v: np.take_along_axis(v, k[..., None], axis=-1)[..., 0]  # noqa: E731
    return pick(rel), pick(radius), k
