r"""The rigid axisymmetric body: a solid of revolution about the $z$ axis, given by its
meridian profile in the $(\rho, z)$ half plane (lengths by the ball radius $R$).

The equinox pattern (as :mod:`dynslip.physics.materials`): every method is abstract or final.
:class:`AbstractBody` declares the profile (:attr:`segments`) and the closest-point
:meth:`project`, and derives everything else from them; :class:`AbstractProfileBody`
implements :meth:`project` for any profile of lines and arcs; :class:`~.sphere.Sphere`
implements it in closed form.

**Position.** A body is described in its reference placement; its position along the axis is
the argument ``z`` of every method (a displacement, 0 by default), so a moving body is one
traced scalar under :func:`jax.jit` and the force on it is a derivative with respect to it.
The geometry itself is static (every field ``eqx.field(static=True)``): a body passed to a
jitted function is part of its signature, compiled for once, and not differentiated.

**Signs.** ``distance`` is the signed distance from x to the body's surface, negative inside
the solid; ``normal`` its gradient, the outward unit normal at the closest point; the tangent
points toward increasing arc length ``s`` along the profile, and ``normal`` is the tangent
turned counter-clockwise (:mod:`.segments`). The sheet's penetration of the unit ball,
``1 - |x - x_b|`` (:mod:`dynslip.physics.sheet`), is ``-distance``.

The distance in the meridian plane is the distance in space: for $\rho \ge 0$ the nearest
point of a surface of revolution lies in the point's own meridian half plane. A point with
$\rho < 0$ (an iterate across the axis) is its mirror image $(-\rho, z)$ in space: the same
distance and surface coordinate, the normal's and tangent's $\rho$ components negated.
"""

from __future__ import annotations

import abc
import functools
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.segments import (
    Arc,
    Line,
    Projection,
    padded_arrays,
    project_onto_segments,
    segment_arrays,
)

__all__ = ["AbstractBody", "AbstractProfileBody", "BodyGeometryError", "check_profile",
           "padded_profile", "project_profile"]

#: joints closer than this (units of R) are connected; tangents closer than this (radians)
#: are continuous
JOINT_TOL = 1e-9
TANGENT_TOL = 1e-7


class BodyGeometryError(ValueError):
    """A body's geometry is not a valid solid: a profile not connected, crossing itself or not
    closed, a zero or negative size, or bodies that overlap."""


class AbstractBody(eqx.Module):
    """A rigid solid of revolution about the z axis (units of R)."""

    segments: eqx.AbstractVar[tuple]

    @abc.abstractmethod
    def project(self, x, z=0.0) -> Projection:
        """Closest point of the surface to ``x`` (..., 2) = (rho, z), the body displaced by
        ``z`` along the axis: a :class:`~.segments.Projection` (pure JAX)."""

    def distance(self, x, z=0.0):
        """Signed distance (..., ) from x to the surface, negative inside the solid."""
        return self.project(x, z).distance

    def normal(self, x, z=0.0):
        """Outward unit normal (..., 2) at the closest point: the gradient of the distance."""
        return self.project(x, z).normal

    def surface_coordinate(self, x, z=0.0):
        """``(s, tangent)``: arc length along the profile of the closest point, shape (...,),
        and the unit tangent there toward increasing s, (..., 2)."""
        p = self.project(x, z)
        return p.s, p.tangent

    @property
    def length(self) -> float:
        """Arc length of the whole profile (units of R)."""
        return float(sum(seg.length for seg in self.segments))

    @property
    def closed(self) -> bool:
        """True for a profile that closes on itself (a ring: not on the axis)."""
        a, b = self.segments[0].start, self.segments[-1].end
        return math.hypot(a[0] - b[0], a[1] - b[1]) <= JOINT_TOL

    def curvature_radius(self, s, s_end=None) -> np.ndarray:
        """Radius of curvature (units of R) of the profile at arc length ``s`` (numpy, any
        shape): an arc's radius, a line's ``inf``, a sharp corner's 0 (a joint whose tangent
        turns, or an end on the axis that is a point: :func:`~.segments._corners`). At a joint
        (within 1e-9 of it) the smaller of the two sides': where a line meets an arc, the arc's.

        With ``s_end`` (the same shape): the smallest radius of the part of the profile between
        ``s`` and ``s_end``, joints included; for a closed profile (a ring) the shorter way
        round. The mesh check's scale: a chord's depth relative to the radius of the part of the
        profile it cuts off (:func:`~dynslip.physics.bodies.chords.relative_chord_depths`)."""
        s = np.asarray(s, float)
        e = s if s_end is None else np.asarray(s_end, float)
        a, b = np.minimum(s, e), np.maximum(s, e)
        total, tol = self.length, 1e-9
        if self.closed:
            a, b = np.mod(a, total), np.mod(b, total)
            a, b = np.minimum(a, b), np.maximum(a, b)
            around = (b - a) > 0.5 * total  # the shorter way: through s = 0 (= total)

            def hit(lo, hi):  # whether [lo, hi] meets the profile's part between s and s_end
                inside = (lo <= b + tol) & (hi >= a - tol)
                wrap = (hi >= b - tol) | (lo <= a + tol)
                return np.where(around, wrap, inside)
        else:
            def hit(lo, hi):
                return (lo <= b + tol) & (hi >= a - tol)
        out = np.full(np.broadcast(a, b).shape, np.inf)
        acc = 0.0
        for seg in self.segments:
            r = seg.radius if isinstance(seg, Arc) else np.inf
            out = np.where(hit(acc, acc + seg.length), np.minimum(out, r), out)
            acc += seg.length
        for sc in segment_arrays(self.segments)[2][1]:  # the sharp corners' arc lengths
            cs = [sc, sc + total] if self.closed and sc <= tol else [sc]
            for c in cs:
                out = np.where(hit(c, c), 0.0, out)
        return out

    def point_at(self, s, z=0.0):
        """Profile points (..., 2) at arc lengths ``s`` (numpy), the body displaced by z."""
        s = np.asarray(s, float)
        out = np.zeros(s.shape + (2,))
        acc = 0.0
        for k, seg in enumerate(self.segments):
            last = k == len(self.segments) - 1
            sel = (s >= acc) & ((s < acc + seg.length) | last)
            u = np.clip((s[sel] - acc) / seg.length, 0.0, 1.0)
            out[sel] = seg.point_at(u)
            acc += seg.length
        out[..., 1] += z
        return out

    def meridian_points(self, n: int = 200, z=0.0) -> np.ndarray:
        """About ``n`` points (M, 2) along the profile, every segment's ends included, for
        drawing; ``z`` the body's displacement. Mirror rho for the other half of the section."""
        total = self.length
        pts = []
        for k, seg in enumerate(self.segments):
            m = max(2, math.ceil(n * seg.length / total) + 1)
            u = np.linspace(0.0, 1.0, m)
            pts.append(seg.point_at(u if k == 0 else u[1:]))
        out = np.concatenate(pts, axis=0)
        out[:, 1] += z
        return out

    def outline(self, z=0.0) -> np.ndarray:
        """The closed outline of the meridian section (M, 2), closed through the axis for a
        profile from axis to axis: a polyline to fill."""
        pts = self.meridian_points(200, z)
        return np.concatenate([pts, pts[:1]], axis=0)


class AbstractProfileBody(AbstractBody):
    """A body whose surface is its profile of lines and arcs, projected onto segment by
    segment (:func:`~.segments.project_onto_segments`)."""

    def project(self, x, z=0.0) -> Projection:
        return project_profile(segment_arrays(self.segments), x, z)


@functools.lru_cache(maxsize=64)
def padded_profile(body: AbstractProfileBody):
    """The profile's :func:`~.segments.padded_arrays` as device arrays, once per body (bodies
    are static and hashable): the traced argument of a function compiled once for every
    profile (the chord check, the summary's clearance) with :func:`project_profile`."""
    return jax.tree_util.tree_map(jnp.asarray, padded_arrays(segment_arrays(body.segments)))


def project_profile(arrays, x, z=0.0) -> Projection:
    """:meth:`AbstractProfileBody.project` of the profile given by its arrays
    (:func:`~.segments.segment_arrays`, constants; or :func:`~.segments.padded_arrays` passed
    traced, so that one compiled function serves every profile: :mod:`.chords`): a point
    across the axis is its mirror image (module docstring)."""
    x = jnp.asarray(x, float)
    rho = x[..., 0]
    mirror = rho < 0
    xm = jnp.stack([jnp.where(mirror, -rho, rho), x[..., 1] - z], axis=-1)
    p = project_onto_segments(arrays, xm)
    flip = jnp.where(mirror, -1.0, 1.0)[..., None] * jnp.array([1.0, 0.0]) + jnp.array(
        [0.0, 1.0]
    )
    return Projection(distance=p.distance, normal=flip * p.normal, s=p.s,
                      tangent=flip * p.tangent, curvature=p.curvature)


def _samples(seg, m=64):
    return seg.point_at(np.linspace(0.0, 1.0, m))


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _polylines_cross(p, q) -> bool:
    """Whether any piece of polyline p (m, 2) properly crosses a piece of polyline q."""
    a0, a1 = p[:-1, None, :], p[1:, None, :]
    b0, b1 = q[None, :-1, :], q[None, 1:, :]
    d1 = _cross(a1 - a0, b0 - a0)
    d2 = _cross(a1 - a0, b1 - a0)
    d3 = _cross(b1 - b0, a0 - b0)
    d4 = _cross(b1 - b0, a1 - b0)
    tol = 1e-14
    return bool(np.any((d1 * d2 < -tol) & (d3 * d4 < -tol)))


def check_profile(segments, smooth: bool = True) -> None:
    """Raise :class:`BodyGeometryError` unless the segments make a valid solid's profile:
    positive lengths and radii, connected and (``smooth``) C1 where they join, in the half plane
    rho >= 0, from axis to axis or closed on itself, not crossing itself, with the solid on
    the right (traversed clockwise for rho to the right and z up)."""
    segments = tuple(segments)
    if not segments:
        raise BodyGeometryError("a profile needs at least one segment")
    for k, seg in enumerate(segments):
        if isinstance(seg, Arc):
            if not seg.radius > 0:
                raise BodyGeometryError(
                    f"profile segment {k}: arc radius {seg.radius:g}, must be > 0"
                )
            if not 0 < abs(seg.sweep) <= 2 * math.pi + 1e-12:
                raise BodyGeometryError(
                    f"profile segment {k}: arc sweep {seg.sweep:g} rad, "
                    "must be nonzero and at most 2 pi"
                )
        elif isinstance(seg, Line):
            if not seg.length > JOINT_TOL:
                raise BodyGeometryError(f"profile segment {k}: line of zero length")
        else:
            raise BodyGeometryError(
                f"profile segment {k}: {type(seg).__name__} is neither a line nor an arc"
            )
        if np.min(_samples(seg, 257)[:, 0]) < -JOINT_TOL:
            raise BodyGeometryError(f"profile segment {k} crosses the axis (rho < 0)")
    for k in range(len(segments) - 1):
        a, b = segments[k], segments[k + 1]
        gap = math.hypot(a.end[0] - b.start[0], a.end[1] - b.start[1])
        if gap > JOINT_TOL:
            raise BodyGeometryError(
                f"profile not connected: segment {k} ends at ({a.end[0]:.6g}, {a.end[1]:.6g}), "
                f"segment {k + 1} starts at ({b.start[0]:.6g}, {b.start[1]:.6g})"
            )
        ta, tb = a.tangent_at(1.0), b.tangent_at(0.0)
        if smooth and (abs(float(_cross(ta, tb))) > TANGENT_TOL or float(np.dot(ta, tb)) < 0):
            raise BodyGeometryError(
                f"profile not smooth where segments {k} and {k + 1} join: tangents "
                f"({ta[0]:.4g}, {ta[1]:.4g}) and ({tb[0]:.4g}, {tb[1]:.4g})"
            )
    first, last = segments[0].start, segments[-1].end
    closed = math.hypot(first[0] - last[0], first[1] - last[1]) <= JOINT_TOL
    if not closed and not (abs(first[0]) <= JOINT_TOL and abs(last[0]) <= JOINT_TOL):
        raise BodyGeometryError(
            "profile not closed: it must run from the axis to the axis, or end where it starts"
        )
    if closed and smooth:
        ta, tb = segments[-1].tangent_at(1.0), segments[0].tangent_at(0.0)
        if abs(float(_cross(ta, tb))) > TANGENT_TOL or float(np.dot(ta, tb)) < 0:
            raise BodyGeometryError("profile not smooth where its last segment meets its first")
    polys = [_samples(seg) for seg in segments]
    # pieces sharing only a joint do not cross properly (the test is strict), so every pair
    # of distinct segments is checked whole
    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            if _polylines_cross(polys[i], polys[j]):
                raise BodyGeometryError(f"profile crosses itself (segments {i} and {j})")
    if not closed:
        interior = np.concatenate(
            [pp[1:-1] for pp in polys] + [np.array([s.end for s in segments[:-1]]).reshape(-1, 2)]
        )
        if interior.size and np.min(interior[:, 0]) <= JOINT_TOL:
            raise BodyGeometryError("profile touches the axis between its ends")
    pts = np.concatenate(polys, axis=0)
    area2 = np.sum(pts[:-1, 0] * pts[1:, 1] - pts[1:, 0] * pts[:-1, 1])
    if not closed:
        area2 += pts[-1, 0] * pts[0, 1] - pts[0, 0] * pts[-1, 1]
    if area2 >= 0:
        raise BodyGeometryError(
            "profile runs with the solid on its left: list it with the solid on the right "
            "(clockwise for rho to the right and z up; from the top of the axis down)"
        )
