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

import equinox as eqx
import jax.numpy as jnp
import numpy as np

__all__ = ["Arc", "Line", "Projection", "project_onto_segments", "segment_arrays"]


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
        return np.stack([self.centre[0] + self.radius * np.cos(a),
                         self.centre[1] + self.radius * np.sin(a)], axis=-1)

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
    """The closest point of a body's surface to a point x of the meridian plane.

    ``distance`` signed (negative inside the solid), ``normal`` the outward unit normal
    (the gradient of ``distance``), ``s`` the arc length along the profile of the closest
    point, ``tangent`` the unit tangent there (toward increasing ``s``); leading shapes those
    of x, the last axis of ``normal`` and ``tangent`` (rho, z)."""

    distance: jnp.ndarray
    normal: jnp.ndarray
    s: jnp.ndarray
    tangent: jnp.ndarray


def segment_arrays(segments):
    """Stacked numpy arrays of the lines and the arcs of a profile, each with its start arc
    length: ``(p0, p1, s0_line), (centre, radius, mid_angle, half_sweep, sign, s0_arc)``."""
    s0, acc = [], 0.0
    for seg in segments:
        s0.append(acc)
        acc += seg.length
    lines = [(seg, s) for seg, s in zip(segments, s0) if isinstance(seg, Line)]
    arcs = [(seg, s) for seg, s in zip(segments, s0) if isinstance(seg, Arc)]
    lp0 = np.array([seg.start for seg, _ in lines], float).reshape(-1, 2)
    lp1 = np.array([seg.end for seg, _ in lines], float).reshape(-1, 2)
    ls0 = np.array([s for _, s in lines], float)
    ac = np.array([seg.centre for seg, _ in arcs], float).reshape(-1, 2)
    ar = np.array([seg.radius for seg, _ in arcs], float)
    amid = np.array([seg.start_angle + 0.5 * seg.sweep for seg, _ in arcs], float)
    ahalf = np.array([0.5 * abs(seg.sweep) for seg, _ in arcs], float)
    asg = np.array([math.copysign(1.0, seg.sweep) for seg, _ in arcs], float)
    as0 = np.array([s for _, s in arcs], float)
    return (lp0, lp1, ls0), (ac, ar, amid, ahalf, asg, as0)


def _safe_norm(v):
    """|v| over the last axis with a finite gradient at v = 0 (the double-where trick)."""
    sq = jnp.sum(v * v, axis=-1)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def _project_lines(x, p0, p1, s0):
    """Candidates on each line: unsigned distance, signed distance, normal, s, tangent."""
    d = p1 - p0  # (L, 2)
    length = jnp.sqrt(jnp.sum(d * d, axis=-1))  # (L,)
    t = d / length[:, None]
    n = jnp.stack([-t[:, 1], t[:, 0]], axis=-1)  # outward: tangent turned counter-clockwise
    rel = x[..., None, :] - p0  # (..., L, 2)
    u = jnp.sum(rel * t, axis=-1)  # (..., L) arc length from the start
    inside = (u >= 0) & (u <= length)
    uc = jnp.clip(u, 0.0, length)
    q = p0 + uc[..., None] * t
    w = x[..., None, :] - q
    r = _safe_norm(w)
    signed_in = jnp.sum(rel * n, axis=-1)
    side = jnp.sign(jnp.sum(w * n, axis=-1))
    side = jnp.where(side == 0, 1.0, side)
    signed = jnp.where(inside, signed_in, side * r)
    rs = jnp.where(r > 0, r, 1.0)[..., None]
    normal = jnp.where(inside[..., None] | (r[..., None] == 0), n, side[..., None] * w / rs)
    return jnp.abs(signed), signed, normal, s0 + uc, jnp.broadcast_to(t, normal.shape)


def _project_arcs(x, c, radius, mid, half, sg, s0):
    """Candidates on each arc: unsigned distance, signed distance, normal, s, tangent."""
    rel = x[..., None, :] - c  # (..., A, 2)
    r = _safe_norm(rel)
    cm, sm = jnp.cos(mid), jnp.sin(mid)
    # polar angle of x about the centre, from the arc's mid-direction, along the sweep
    alpha = sg * jnp.arctan2(cm * rel[..., 1] - sm * rel[..., 0], cm * rel[..., 0] + sm * rel[..., 1])
    inside = jnp.abs(alpha) <= half
    ac = jnp.clip(alpha, -half, half)
    ang = mid + sg * ac
    radial = jnp.stack([jnp.cos(ang), jnp.sin(ang)], axis=-1)
    q = c + radius[:, None] * radial
    n = -sg[:, None] * radial  # outward: +radial for an arc bulging out of the solid
    tang = sg[:, None] * jnp.stack([-radial[..., 1], radial[..., 0]], axis=-1)
    w = x[..., None, :] - q
    rw = _safe_norm(w)
    signed_in = -sg * (r - radius)
    side = jnp.sign(jnp.sum(w * n, axis=-1))
    side = jnp.where(side == 0, 1.0, side)
    signed = jnp.where(inside, signed_in, side * rw)
    rws = jnp.where(rw > 0, rw, 1.0)[..., None]
    normal = jnp.where(inside[..., None] | (rw[..., None] == 0), n, side[..., None] * w / rws)
    return jnp.abs(signed), signed, normal, s0 + radius * (ac + half), tang


def project_onto_segments(arrays, x) -> Projection:
    """Closest-point projection of the points ``x`` (..., 2) onto a profile given by
    :func:`segment_arrays`: the candidate on every segment, the nearest kept (pure JAX)."""
    (lp0, lp1, ls0), (ac, ar, amid, ahalf, asg, as0) = arrays
    x = jnp.asarray(x, float)
    parts = []
    if lp0.shape[0]:
        parts.append(_project_lines(x, *(jnp.asarray(a) for a in (lp0, lp1, ls0))))
    if ac.shape[0]:
        parts.append(_project_arcs(x, *(jnp.asarray(a) for a in (ac, ar, amid, ahalf, asg, as0))))
    absd, signed, normal, s, tang = (jnp.concatenate([p[i] for p in parts], axis=x.ndim - 1)
                                     for i in range(5))
    k = jnp.argmin(absd, axis=-1)[..., None]  # (..., 1) the nearest segment
    pick = lambda a: jnp.take_along_axis(a, k, axis=-1)[..., 0]
    pick2 = lambda a: jnp.take_along_axis(a, k[..., None], axis=-2)[..., 0, :]
    return Projection(distance=pick(signed), normal=pick2(normal), s=pick(s), tangent=pick2(tang))
