r"""The mesh check against any body: how deep each element chord dips into it.

The penalty acts at the nodes only, so nothing keeps an element's chord (the straight
meridian of its conical frustum) out of a body; a deep chord means the mesh does not resolve
the contact (:func:`dynslip.physics.sheet.ball_chord_depths` does this for the unit ball in closed
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

import collections
import threading

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.base import (
    AbstractBody,
    AbstractProfileBody,
    padded_profile,
    project_profile,
)

__all__ = [
    "chord_depths",
    "deepest_chord_in",
    "deepest_chords_in",
    "deepest_relative_chord_in",
    "relative_chord_depths",
]

_SAMPLES = 17
_GOLDEN_STEPS = 60
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0
_BISECT_STEPS = 50


def _search(project, a, b, zpos):
    """``(depth, s_in, s_out)`` of the chords from ``a`` to ``b`` (M, 2), the body whose
    ``project(x, z)`` is given displaced by ``zpos`` (M,): the depth of the deepest point
    (fraction u in [0, 1] along the chord), and the arc lengths along the profile where the
    chord enters and leaves the body, by bisection between the deepest point (inside) and each
    node (a node inside the body: the node itself); the closest points' s.

    The body's distance is evaluated at six call sites (the samples, the golden-section pair,
    the deepest point, the bisection pair, the chord's ends, the projection): each call site is
    compiled anew (docs/speed.md, "the chord check")."""
    def depth(u):  # u (..., M): the depth at the fractions u along each chord
        x = a + u[..., None] * (b - a)
        return -project(x, jnp.broadcast_to(zpos, u.shape)).distance

    u = jnp.linspace(0.0, 1.0, _SAMPLES)
    samples = depth(jnp.broadcast_to(u[:, None], (_SAMPLES,) + zpos.shape))  # (S, M)
    k = jnp.argmax(samples, axis=0)
    lo = u[jnp.clip(k - 1, 0, _SAMPLES - 1)]
    hi = u[jnp.clip(k + 1, 0, _SAMPLES - 1)]

    def golden(_, lh):
        lo, hi = lh
        c, d = hi - _INV_PHI * (hi - lo), lo + _INV_PHI * (hi - lo)
        dc, dd = depth(jnp.stack([c, d]))
        left = dc >= dd
        return jnp.where(left, lo, c), jnp.where(left, d, hi)

    lo, hi = jax.lax.fori_loop(0, _GOLDEN_STEPS, golden, (lo, hi))
    um = 0.5 * (lo + hi)
    dm, ds = depth(um), jnp.max(samples, axis=0)
    deepest = jnp.maximum(ds, dm)
    um = jnp.where(dm >= ds, um, u[k])

    # where the chord enters (towards u = 0) and leaves (towards u = 1), both ends at once
    ends = jnp.stack([jnp.zeros_like(um), jnp.ones_like(um)])

    def bisect(_, lh):
        lo, hi = lh  # lo inside, hi outside
        mid = 0.5 * (lo + hi)
        inside = depth(mid) > 0
        return jnp.where(inside, mid, lo), jnp.where(inside, hi, mid)

    lo, hi = jax.lax.fori_loop(0, _BISECT_STEPS, bisect, (jnp.stack([um, um]), ends))
    cross = jnp.where(depth(ends) > 0, ends, 0.5 * (lo + hi))
    s = project(a + cross[..., None] * (b - a), jnp.broadcast_to(zpos, cross.shape)).s
    return deepest, s[0], s[1]


@eqx.filter_jit
def _chords(body: AbstractBody, a, b, zpos):
    """:func:`_search` of a body in closed form (the sphere): one compiled function per body."""
    return _search(body.project, a, b, zpos)


@jax.jit
def _profile_chords(arrays, a, b, zpos):
    """:func:`_search` of a profile body given by its padded arrays (traced): one compiled
    function for every profile of a few segments (the main job's four held bodies share it:
    a compile each before, 2.8 s in all)."""
    return _search(lambda x, z: project_profile(arrays, x, z), a, b, zpos)


def _chord_fn(body: AbstractBody):
    """``f(a, b, zpos)``: :func:`_search` of ``body``, compiled as :func:`_profile_chords` for a
    profile body, else :func:`_chords`."""
    if isinstance(body, AbstractProfileBody):
        arrays = padded_profile(body)
        return lambda a, b, zpos: _profile_chords(arrays, a, b, zpos)
    return lambda a, b, zpos: _chords(body, a, b, zpos)


#: the last frames' searches, by body and frame content (:func:`_per_frame`)
_SEEN: collections.OrderedDict = collections.OrderedDict()
_SEEN_MAX = 1024
_SEEN_LOCK = threading.Lock()  # a sweep's members may run in threads of one process


def _frame(body: AbstractBody, xf, zf):
    """:func:`_search` of one frame (node positions ``xf`` (N, 2), the body at ``zf``), kept
    for the last ``_SEEN_MAX`` frames by the frame's exact values: the summary's check of a
    trajectory (every frame) finds the run's own check of each frame (the stop rule's, one
    frame at a time; 0.3 s of the main job). A body that cannot be hashed (array fields) is
    searched every time."""
    try:
        key: tuple | None = (body, xf.tobytes(), float(zf))
        with _SEEN_LOCK:
            hit = _SEEN.get(key)
            if hit is not None:
                _SEEN.move_to_end(key)
    except TypeError:
        key = hit = None
    if hit is not None:
        return hit
    n = xf.shape[0]
    out = tuple(np.asarray(o) for o in _chord_fn(body)(xf[:-1], xf[1:], np.full(n - 1, zf)))
    if key is not None:
        with _SEEN_LOCK:
            _SEEN[key] = out
            if len(_SEEN) > _SEEN_MAX:
                _SEEN.popitem(last=False)
    return out


def _per_frame(body: AbstractBody, rho, z, zpos):
    """:func:`_search` of every frame (leading shape (...)) of node positions ``rho, z`` (..., N),
    the body displaced by ``zpos`` (...): three arrays (..., N-1). Frame by frame, so that a
    run's check (one frame at a time) and a trajectory's (every frame) share one compiled
    function (:func:`_chord_fn`: one for every profile body) and each frame's result
    (:func:`_frame`)."""
    x = np.stack([np.asarray(rho, float), np.asarray(z, float)], axis=-1)
    lead, n = x.shape[:-2], x.shape[-2]
    zp = np.broadcast_to(np.asarray(zpos, float), lead).reshape(-1)
    x = np.ascontiguousarray(x.reshape((-1, n, 2)))
    out = [_frame(body, xf, zf) for xf, zf in zip(x, zp, strict=True)]
    return tuple(np.stack([o[j] for o in out]).reshape(lead + (n - 1,)) for j in range(3))


def chord_depths(body: AbstractBody, rho, z, zpos) -> np.ndarray:
    """Depth inside ``body`` (displaced by ``zpos``, shape (...)) of each element chord, for
    node positions ``rho, z`` of shape (..., N): shape (..., N-1), positive inside, as
    :func:`dynslip.physics.sheet.ball_chord_depths` for the unit ball."""
    return _per_frame(body, rho, z, zpos)[0]


def _deepest(v, *also):
    """Per frame, the largest of ``v`` (..., N-1) over its elements (a non-finite one counts as
    -inf), the same element's values of each of ``also``, and the element."""
    v = np.where(np.isfinite(v), v, -np.inf)
    k = np.argmax(v, axis=-1)
    pick = lambda a: np.take_along_axis(a, k[..., None], axis=-1)[..., 0]  # noqa: E731
    return (pick(v), *(pick(a) for a in also), k)


def deepest_chord_in(body: AbstractBody, rho, z, zpos) -> tuple[np.ndarray, np.ndarray]:
    """Per frame (frames leading, shape (...)) ``(depth, element)`` of the deepest element chord
    inside ``body`` displaced along the axis by ``zpos`` (shape (...): a held body's height in
    each frame), for node positions ``rho, z`` of shape (..., N): depth in R (positive inside,
    a non-finite chord counts as -inf), ``element`` the index of its element (nodes ``element``
    and ``element + 1``). No pole crossing (the module's docstring: the ball's check only)."""
    return _deepest(chord_depths(body, rho, z, zpos))


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
    depth, s_in, s_out = _per_frame(body, rho, z, zpos)
    radius = np.where(depth > 0, body.curvature_radius(s_in, s_out), np.nan)
    scale = np.where((depth > 0) & (radius > 0), radius, 1.0)
    return depth, radius, depth / scale


def deepest_relative_chord_in(body: AbstractBody, rho, z, zpos):
    """Per frame (frames leading, shape (...)) ``(relative, radius, element)`` of the element
    chord deepest relative to the radius it cuts off (:func:`relative_chord_depths`), as
    :func:`deepest_chord_in` (a non-finite chord counts as -inf)."""
    return deepest_chords_in(body, rho, z, zpos)[1]


def deepest_chords_in(body: AbstractBody, rho, z, zpos):
    """:func:`deepest_chord_in` and :func:`deepest_relative_chord_in` from one evaluation of the
    chords: ``((depth, element), (relative, radius, element))``."""
    depth, radius, rel = relative_chord_depths(body, rho, z, zpos)
    return _deepest(depth), _deepest(rel, radius)
