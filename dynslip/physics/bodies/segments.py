r"""Meridian profiles: line and circular-arc segments in the $(\rho, z)$ half plane, and the
closest-point projection onto them.

Nondimensional: lengths by the ball radius $R$. A profile is traversed with the solid on its
*right* (for $\rho$ to the right and $z$ up: clockwise around the solid), so that the outward
unit normal is the unit tangent turned a quarter turn counter-clockwise,

$$n = (-t_z,\ t_\rho).$$

For the unit ball traversed from its top pole $(0, 1)$ down to $(0, -1)$ this gives, at polar
angle $\theta$, $t = (\cos\theta, -\sin\theta)$ and $n = (\sin\theta, \cos\theta)$: the frame
of :meth:`dynslip.physics.sheet.SheetModel.frame`, and the arc length $s = R\theta$.

- :class:`Line` from ``start`` to ``end``;
- :class:`Arc` about ``centre`` of ``radius``, from the polar angle ``start_angle`` to
  ``end_angle`` (radians, measured counter-clockwise from $+\rho$ about the centre; the sweep
  ``end_angle - start_angle`` is negative for an arc bulging outward of the solid, positive for
  a hollow, and $|{\rm sweep}| \le 2\pi$).

Example::

    >>> import math
    >>> a = Arc((0.0, 0.0), 1.0, math.pi / 2, -math.pi / 2)  # the unit ball's meridian
    >>> round(a.length, 12) == round(math.pi, 12)
    True
"""

from __future__ import annotations

import math
from typing import cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["Arc", "Line", "Projection", "padded_arrays", "project_onto_segments",
           "segment_arrays"]


class Line(eqx.Module):
    """A straight segment from ``start`` to ``end`` (points (rho, z), units of R)."""

    start: tuple[float, float] = eqx.field(static=True)
    end: tuple[float, float] = eqx.field(static=True)

    def __init__(self, start, end):
        self.start = (float(start[0]), float(start[1]))
        self.end = (float(end[0]), float(end[1]))

    @property
    def length(self) -> float:
        return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])

    def tangent_at(self, u):
        """Unit tangent at the fraction ``u`` in [0, 1] of the segment (numpy, (..., 2))."""
        t = np.subtract(self.end, self.start) / max(self.length, 1e-300)
        return np.broadcast_to(t, np.shape(u) + (2,)).copy()

    def point_at(self, u):
        """Point at the fraction ``u`` in [0, 1] of the segment (numpy, shape (..., 2))."""
        u = np.asarray(u, float)[..., None]
        return np.asarray(self.start) + u * np.subtract(self.end, self.start)


class Arc(eqx.Module):
    """A circular arc about ``centre`` of ``radius`` from ``start_angle`` to ``end_angle``."""

    centre: tuple[float, float] = eqx.field(static=True)
    radius: float = eqx.field(static=True)
    start_angle: float = eqx.field(static=True)
    end_angle: float = eqx.field(static=True)

    def __init__(self, centre, radius, start_angle, end_angle):
        self.centre = (float(centre[0]), float(centre[1]))
        self.radius = float(radius)
        self.start_angle = float(start_angle)
        self.end_angle = float(end_angle)

    @property
    def sweep(self) -> float:
        return self.end_angle - self.start_angle

    @property
    def length(self) -> float:
        return abs(self.radius * self.sweep)

    def point_at(self, u):
        a = self.start_angle + np.asarray(u, float) * self.sweep
        return np.stack(
            [self.centre[0] + self.radius * np.cos(a), self.centre[1] + self.radius * np.sin(a)],
            axis=-1,
        )

    def tangent_at(self, u):
        a = self.start_angle + np.asarray(u, float) * self.sweep
        sg = math.copysign(1.0, self.sweep)
        return sg * np.stack([-np.sin(a), np.cos(a)], axis=-1)

    @property
    def start(self) -> tuple[float, float]:
        p = self.point_at(0.0)
        return float(p[0]), float(p[1])

    @property
    def end(self) -> tuple[float, float]:
        p = self.point_at(1.0)
        return float(p[0]), float(p[1])


class Projection(eqx.Module):
    r"""The closest point of a body's surface to a point x of the meridian plane.

    ``distance`` signed (negative inside the solid), ``normal`` the outward unit normal
    (the gradient of ``distance``), ``s`` the arc length along the profile of the closest
    point, ``tangent`` the unit tangent there (toward increasing ``s``); leading shapes those
    of x, the last axis of ``normal`` and ``tangent`` (rho, z). ``curvature`` $\kappa$: the
    normal's turn per unit of motion along the tangent, so the distance's Hessian is $\kappa\,t
    t^T$ (:func:`project_onto_segments`; None where a body does not give it)."""

    distance: jnp.ndarray
    normal: jnp.ndarray
    s: jnp.ndarray
    tangent: jnp.ndarray
    curvature: jnp.ndarray | None = None

    def linearised(self, dx) -> Projection:
        r"""This projection moved by ``dx`` (..., 2) to first order, by the closed-form rule of
        :func:`project_onto_segments` ($\tau = t\cdot dx$: $dd = n\cdot dx$, $dn = \kappa\tau\,t$,
        $dt = -\kappa\tau\,n$, $d\kappa = -\kappa^2\,dd$; ``s`` is kept, its factor not being
        carried). With ``dx = x - stop_gradient(x)`` its value is this projection and its first
        derivative in x the projection's own: a projection computed once serves a derivative
        taken later (the held friction's, :mod:`dynslip.physics.solver.newton_matrix`). Needs
        ``curvature``."""
        curvature = cast(jnp.ndarray, self.curvature)  # given where this is called
        dd = jnp.sum(self.normal * dx, axis=-1)
        kt = (curvature * jnp.sum(self.tangent * dx, axis=-1))[..., None]
        return Projection(distance=self.distance + dd, normal=self.normal + kt * self.tangent,
                          s=self.s, tangent=self.tangent - kt * self.normal,
                          curvature=curvature - curvature**2 * dd)


#: relative slack of the in-range tests (a foot a rounding error past a joint still counts)
_SLACK = 1e-12


def _corners(segments):
    """The profile's corners: joints where the tangent turns (not C1), and ends on the axis
    whose tangent is not horizontal (a point); each with its arc length and the bisector of
    the outward normals on either side (the mirror image's across the axis)."""
    out, acc = [], 0.0
    def rot(t):
        return np.array([-t[1], t[0]])
    closed = (
        math.hypot(
            segments[0].start[0] - segments[-1].end[0], segments[0].start[1] - segments[-1].end[1]
        )
        <= 1e-9
    )
    for k, seg in enumerate(segments):
        if k > 0 or closed:
            prev = segments[k - 1]
            na, nb = rot(prev.tangent_at(1.0)), rot(seg.tangent_at(0.0))
            if np.linalg.norm(na - nb) > 1e-9:
                out.append((seg.start, acc, na + nb))
        elif abs(seg.start[0]) <= 1e-9 and abs(seg.tangent_at(0.0)[1]) > 1e-9:
            nb = rot(seg.tangent_at(0.0))
            out.append((seg.start, 0.0, nb + nb * np.array([-1.0, 1.0])))
        acc += seg.length
    last = segments[-1]
    if not closed and abs(last.end[0]) <= 1e-9 and abs(last.tangent_at(1.0)[1]) > 1e-9:
        na = rot(last.tangent_at(1.0))
        out.append((last.end, acc, na + na * np.array([-1.0, 1.0])))
    pts = np.array([c[0] for c in out], float).reshape(-1, 2)
    sv = np.array([c[1] for c in out], float)
    bis = np.array([c[2] / np.linalg.norm(c[2]) for c in out], float).reshape(-1, 2)
    return pts, sv, bis


def segment_arrays(segments):
    """Stacked numpy arrays of a profile: its lines ``(p0, p1, s0)``, its arcs ``(centre,
    radius, mid_angle, half_sweep, sign, s0)`` (s0 the arc length at each one's start) and its
    corners ``(point, s, normal bisector)`` (:func:`_corners`)."""
    s0, acc = [], 0.0
    for seg in segments:
        s0.append(acc)
        acc += seg.length
    lines = [(seg, s) for seg, s in zip(segments, s0, strict=False) if isinstance(seg, Line)]
    arcs = [(seg, s) for seg, s in zip(segments, s0, strict=False) if isinstance(seg, Arc)]
    lp0 = np.array([seg.start for seg, _ in lines], float).reshape(-1, 2)
    lp1 = np.array([seg.end for seg, _ in lines], float).reshape(-1, 2)
    ls0 = np.array([s for _, s in lines], float)
    ac = np.array([seg.centre for seg, _ in arcs], float).reshape(-1, 2)
    ar = np.array([seg.radius for seg, _ in arcs], float)
    amid = np.array([seg.start_angle + 0.5 * seg.sweep for seg, _ in arcs], float)
    ahalf = np.array([0.5 * abs(seg.sweep) for seg, _ in arcs], float)
    asg = np.array([math.copysign(1.0, seg.sweep) for seg, _ in arcs], float)
    as0 = np.array([s for _, s in arcs], float)
    return (lp0, lp1, ls0), (ac, ar, amid, ahalf, asg, as0), _corners(tuple(segments))


#: where padded_arrays puts its inert candidates (units of R): far from any profile
_FAR = 1e6


def padded_arrays(arrays, multiple: int = 4):
    """:func:`segment_arrays` with each kind's count rounded up to a multiple of ``multiple``
    (at least one multiple) by inert candidates far away (a line and an arc whose foot never
    falls on them, a corner at distance ~1e6 R), so that profiles of a few segments share one
    shape: a function taking the arrays as traced arguments compiles once for all of them
    (the chord check, :mod:`.chords`). Projections are unchanged."""
    (lp0, lp1, ls0), (ac, ar, amid, ahalf, asg, as0), (cv, csv, cbis) = arrays

    def size(k):
        return max(multiple, -(-k // multiple) * multiple)

    def pad(a, m, value):
        extra = np.broadcast_to(np.asarray(value, float), (m - a.shape[0],) + a.shape[1:])
        return np.concatenate([a, extra], axis=0)

    far = (_FAR, _FAR)
    nl, na, nv = size(lp0.shape[0]), size(ac.shape[0]), size(cv.shape[0])
    return (
        (pad(lp0, nl, far), pad(lp1, nl, (_FAR + 1.0, _FAR)), pad(ls0, nl, 0.0)),
        (pad(ac, na, far), pad(ar, na, 1.0), pad(amid, na, 0.0), pad(ahalf, na, 0.0),
         pad(asg, na, 1.0), pad(as0, na, 0.0)),
        (pad(cv, nv, far), pad(csv, nv, 0.0), pad(cbis, nv, (1.0, 0.0))),
    )


def _xp(a):
    """numpy for a profile's own (constant) arrays, jax.numpy for traced ones."""
    return np if isinstance(a, np.ndarray) else jnp


def _safe_norm(v):
    """|v| over the last axis with a finite gradient at v = 0 (the double-where trick)."""
    sq = jnp.sum(v * v, axis=-1)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def _feet_on_lines(x, p0, p1, s0):
    """The foot of the normal from x on each line: |distance| (inf where the foot falls off
    the line), signed distance, normal, s, tangent, and the derivative factors of
    :func:`project_onto_segments` (curvature 0, ``ds/d(t.x)`` 1); shapes (..., L) and
    (..., L, 2)."""
    xp = _xp(p0)
    d = p1 - p0  # (L, 2)
    length = xp.sqrt(xp.sum(d * d, axis=-1))  # (L,)
    t = d / length[:, None]
    n = xp.stack([-t[:, 1], t[:, 0]], axis=-1)  # outward: the tangent turned counter-clockwise
    rel = x[..., None, :] - p0  # (..., L, 2)
    u = jnp.sum(rel * t, axis=-1)  # (..., L) arc length of the foot from the line's start
    ok = (u >= -_SLACK * length) & (u <= (1 + _SLACK) * length)
    signed = jnp.sum(rel * n, axis=-1)
    shape = signed.shape + (2,)
    return (
        jnp.where(ok, jnp.abs(signed), jnp.inf),
        signed,
        jnp.broadcast_to(n, shape),
        s0 + jnp.clip(u, 0.0, length),
        jnp.broadcast_to(t, shape),
        jnp.zeros_like(signed),
        jnp.ones_like(signed),
    )


def _feet_on_arcs(x, c, radius, mid, half, sg, s0):
    """The foot of the normal from x on each arc, as :func:`_feet_on_lines`: the radial
    projection, on the arc where x lies within its half-sweep of the mid-direction m,
    m.(x - c) >= cos(half) |x - c|. The normal turns by -sg/r per unit of
    tangential motion, and $s$ moves by radius/r of it."""
    xp = _xp(mid)
    m = xp.stack([xp.cos(mid), xp.sin(mid)], axis=-1)  # (A, 2)
    rel = x[..., None, :] - c  # (..., A, 2)
    r = _safe_norm(rel)
    along = jnp.sum(rel * m, axis=-1)
    ok = along >= (xp.cos(half) - _SLACK) * r
    signed = -sg * (r - radius)  # +radial outward for an arc bulging out of the solid
    rs = jnp.where(r > 0, r, 1.0)[..., None]
    radial = jnp.where((r > 0)[..., None], rel / rs, m)
    normal = -sg[:, None] * radial
    tangent = sg[:, None] * jnp.stack([-radial[..., 1], radial[..., 0]], axis=-1)
    across = m[:, 0] * rel[..., 1] - m[:, 1] * rel[..., 0]
    alpha = jnp.clip(sg * jnp.arctan2(across, along), -half, half)  # angle from m, along the sweep
    return (
        jnp.where(ok, jnp.abs(signed), jnp.inf),
        signed,
        normal,
        s0 + radius * (alpha + half),
        tangent,
        jnp.where(r > 0, -sg / rs[..., 0], 0.0),
        radius / rs[..., 0],
    )


def _at_corners(x, v, sv, bis):
    """Distance to each corner point, signed by the side of the normals' bisector (the normal
    turns by 1/distance per unit of tangential motion; s stays)."""
    w = x[..., None, :] - v  # (..., V, 2)
    r = _safe_norm(w)
    side = jnp.where(jnp.sum(w * bis, axis=-1) < 0, -1.0, 1.0)
    rs = jnp.where(r > 0, r, 1.0)[..., None]
    normal = jnp.where((r > 0)[..., None], side[..., None] * w / rs, bis)
    tangent = jnp.stack([normal[..., 1], -normal[..., 0]], axis=-1)
    kappa = jnp.where(r > 0, side / rs[..., 0], 0.0)
    return r, side * r, normal, jnp.broadcast_to(sv, r.shape), tangent, kappa, jnp.zeros_like(r)


def _nearest(arrays, x):
    """The nearest candidate of :func:`project_onto_segments`: ``(distance, normal, s,
    tangent, kappa, lam)``, kappa and lam the derivative factors of its closed-form rule."""
    (lp0, lp1, ls0), (ac, ar, amid, ahalf, asg, as0), (cv, csv, cbis) = arrays
    parts = []
    if lp0.shape[0]:
        parts.append(_feet_on_lines(x, lp0, lp1, ls0))
    if ac.shape[0]:
        parts.append(_feet_on_arcs(x, ac, ar, amid, ahalf, asg, as0))
    if cv.shape[0]:
        parts.append(_at_corners(x, cv, csv, cbis))
    absd, signed, normal, s, tang, kappa, lam = (
        jnp.concatenate([p[i] for p in parts], axis=x.ndim - 1) for i in range(7)
    )
    # the nearest candidate as a one-hot mask (cheaper than a gather and its scatter-add
    # gradient on a handful of candidates); a tie keeps the first
    k = jnp.argmin(absd, axis=-1)[..., None]  # (..., 1)
    hot = jnp.arange(absd.shape[-1]) == k  # (..., C)
    def pick(a):
        return jnp.sum(jnp.where(hot, a, 0.0), axis=-1)
    def pick2(a):
        return jnp.sum(jnp.where(hot[..., None], a, 0.0), axis=-2)
    return pick(signed), pick2(normal), pick(s), pick2(tang), pick(kappa), pick(lam)


def project_onto_segments(arrays, x) -> Projection:
    r"""Closest-point projection of the points ``x`` (..., 2) onto a profile given by
    :func:`segment_arrays` (pure JAX). The nearest point of a profile is the foot of a normal
    on one of its segments or one of its corners (where two segments' normals differ, so
    a C1 joint needs no candidate of its own): every candidate is computed, the nearest kept.

    Differentiated in closed form (a ``jax.custom_jvp``), not through the candidates: with
    $\tau = t\cdot dx$, $dd = n\cdot dx$, $dn = \kappa\tau\,t$, $dt = -\kappa\tau\,n$,
    $ds = \lambda\tau$, the foot's curvature factor $\kappa$ ($-\mathrm{sg}/r$ at a
    distance $r$ from an arc's centre, $1/d$ from a corner, 0 on a line) and $\lambda$ (radius/r
    on an arc, 1 on a line, 0 at a corner), with $d\kappa = -\kappa^2\,dd$ and $d\lambda =
    -\lambda\kappa\,dd$ so the rule differentiates again. The penalty's force and Hessian
    then cost one projection each, not a derivative pass through every candidate (a third of
    the world's compile; docs/speed.md); tests/test_bodies.py holds the rule to finite
    differences of the projection."""

    @jax.custom_jvp
    def nearest(x):
        return _nearest(arrays, x)

    @nearest.defjvp
    def _rule(primals, tangents):
        (x,), (dx,) = primals, tangents
        out = nearest(x)
        _, n, _, t, kappa, lam = out
        dd = jnp.sum(n * dx, axis=-1)
        tau = jnp.sum(t * dx, axis=-1)
        kt = (kappa * tau)[..., None]
        return out, (dd, kt * t, lam * tau, -kt * n, -kappa**2 * dd, -lam * kappa * dd)

    d, n, s, t, kappa, _ = nearest(jnp.asarray(x, float))
    return Projection(distance=d, normal=n, s=s, tangent=t, curvature=kappa)
