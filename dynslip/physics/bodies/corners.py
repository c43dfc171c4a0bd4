r"""Two-pass contact: a body's sharp features against the sheet's segments.

The node-to-body penalty (:mod:`.contact`) acts at the sheet's nodes: where a body turns the
sheet around a radius smaller than an element, the straight element between two nodes cuts
through the body's corner and nothing resists it. The second pass swaps master and slave
(the two-pass node-to-segment contact: Wriggers, *Computational Contact Mechanics*, 2nd ed.,
Springer 2006, its node-to-segment element with the penalty method; Laursen, *Computational
Contact and Impact Mechanics*, Springer 2002; Zavarise and De Lorenzis, Int. J. Numer. Meth.
Engng 79 (2009) 379-416, on the penalty node-to-segment pair and the bias of one pass): the
body's **corners** act as points against the sheet's **segments** (a point-to-line pair:
Konyukhov and Schweizerhof, Open J. Appl. Sci. 3 (2013) 15-20).

**Corners.** Every convex arc of a body's profile (negative sweep: bulging out of the solid)
of radius $r \le$ :data:`CORNER_RADIUS` is a corner: a circle of radius $r$ about the arc's
centre $c$. The whole circle lies inside the solid (a convex fillet's circle is inscribed in
the solid it rounds), so a segment that enters the circle enters the body: the second pass
never pushes where the body is not. A profile without such an arc (the unit ball, the 6 mm
tube wall's rim of 0.15 R) has no corners and its contact is exactly today's (the code path is
not traced at all).

**The energy.** Segment $j$ from node $a = x_j$ to $b = x_{j+1}$, its closest point to the
centre $p = a + s(b - a)$, $s = {\rm clip}((c - a)\cdot(b - a)/|b - a|^2, 0, 1)$, penetrates
the corner by $\delta_j = r - |c - p|$; the corner's penalty energy is

$$E_c = \sum_j w\,\phi(\delta_j),\qquad w = 2\pi\max(\rho_c, r)\,r\,|\Delta\alpha|,$$

$\phi$ the nodes' $C^2$ penalty (:func:`~dynslip.physics.penalty.penalty_energy`) and $w$ the
corner's ring area (the arc's surface of revolution, $\Delta\alpha$ its sweep), so a corner's
penetration under a line force is the same as a resolved arc's nodes' would be. The distance
to a segment is $C^1$ in $a$, $b$ and $c$ away from the segment itself (at the clip's ends
$c - p$ is normal to the segment), so $E_c$ is $C^1$ and its gradient, by automatic
differentiation, is exact: $\partial E_c/\partial a = -w\,\phi'(\delta_j)(1 - s)\,e$,
$\partial E_c/\partial b = -w\,\phi'(\delta_j)\,s\,e$, $e = (c - p)/|c - p|$. The force on
the nodes pushes the segment away from the corner, split over its two nodes by the weights
$1 - s$ and $s$; the force on the body is minus their sum. Segment $j$ couples nodes $j$ and
$j + 1$ only, so the Hessian stays block tridiagonal (:func:`corner_terms`).

**Energy balance.** $E_c$ is part of the penalty energy (the stored energy the balance reads:
:meth:`dynslip.physics.sheet.SheetModel.penalty_energy`), and the forces are its gradient, so
the balance stays a test.

**Friction.** Each corner-segment pair's normal force $N_j = w\,\phi'(\delta_j)$ is shared by
the segment's nodes with the same weights (:func:`corner_normal`: $(1 - s)N_j$ to node $j$,
$s N_j$ to node $j + 1$) and added to the normal force the ball's friction law reads at those
nodes (:meth:`dynslip.physics.sheet.SheetModel.normal_force`); the friction then acts on the
nodes, along the body's tangent at each node, and its dissipation is the nodes' (counted as
every node's). A held body's corners are frictionless: adding their shares to that body's
friction the same way (:func:`dynslip.physics.bodies.held.held_corner_normal`, switched by
``HELD_CORNER_FRICTION``) broke the lab frame's agreement with the tube's frame, for a cause
not found, and is off. The Newton matrix reads the
shares' derivatives in the three nodes each reads (block tridiagonal:
:mod:`dynslip.physics.solver.newton_matrix`), so it stays the residual's exact Jacobian.

**Limit.** The distance is unsigned: a segment that passed a corner's centre would be pushed
out the far side. The penalty keeps the penetration to $\sim F/(k w)$, a small fraction of $r$,
and an increment in which a segment passes through a centre is refused and cut
(:func:`corner_crossed`; docs/sharp-edges.md).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.segments import Arc
from dynslip.physics.penalty import Penalty, penalty_energy, penalty_pressure

__all__ = ["CORNER_RADIUS", "corner_crossed", "corner_energy", "corner_normal",
           "corner_normal_jacobian", "corner_terms", "corners_of"]

#: arcs of this radius or smaller (units of R) are corners; an arc this small is crossed by one
#: element of the meshes the scenarios run (0.02-0.03 R of material stretched 3-5 times), and
#: the term is consistent for any element length (a resolved arc's chords cut its circle by
#: their sagitta, which the term pushes out), so this only picks which bodies get it: the ball,
#: the bottle's shoulder and base and a 6 mm wall's rim keep today's contact exactly
CORNER_RADIUS = 0.1

#: the segments nearest each corner (by distance) whose Hessian (and normal shares'
#: derivatives) the Newton matrix reads; the energy and forces sum every segment. A segment
#: reaches a corner's circle only where the sheet wraps it: on a resolved arc each chord cuts it
#: by its sagitta, so up to (wrapped angle) / (angle per element) + 2 segments (the 3 mm rim:
#: 0.34-0.40 rad an element at N = 100-200, so 11 segments cover 3.4-4 rad, more than its half
#: circle). Past them the matrix leaves a segment out (Newton's path changes, not its root)
WINDOW = 11

#: added to the squared distance so its gradient stays finite where a segment passes a centre
_TINY = 1e-24


@functools.lru_cache(maxsize=64)
def corners_of(body):
    """The corners of ``body`` (static numpy: ``(centre (K, 2), radius (K,), weight (K,))``) or
    None when its profile has none (module docstring)."""
    arcs = [seg for seg in body.segments
            if isinstance(seg, Arc) and seg.sweep < 0 and seg.radius <= CORNER_RADIUS]
    if not arcs:
        return None
    # arcs about one centre with one radius (a rounded end drawn as two quarter circles) are
    # one circle: one corner, its ring area their sum
    found: dict[tuple, float] = {}
    for a in arcs:
        key = (round(a.centre[0], 12), round(a.centre[1], 12), round(a.radius, 12))
        found[key] = found.get(key, 0.0) + abs(a.sweep)
    centre = np.array([k[:2] for k in found], float)
    radius = np.array([k[2] for k in found], float)
    weight = np.array([2 * math.pi * max(k[0], k[2]) * k[2] * min(sw, 2 * math.pi)
                       for k, sw in found.items()])
    return centre, radius, weight


def _closest(c, a, b):
    """The segment parameter s of the closest point to ``c`` and the penetration ``r - |c - p|``
    without r: ``(s, dist)``."""
    d = b - a
    s = jnp.clip(jnp.dot(c - a, d) / jnp.maximum(jnp.dot(d, d), _TINY), 0.0, 1.0)
    e = c - (a + s * d)
    return s, jnp.sqrt(jnp.dot(e, e) + _TINY)


def _pair_energy(pen: Penalty, r, w, c, ab):
    _, dist = _closest(c, ab[:2], ab[2:])
    return w * penalty_energy(pen, r - dist)


def _pairs(body, x, z):
    """The corners of ``body`` displaced by ``z`` (centre (K, 2) traced, radius, weight) and the
    segments of the nodes ``x`` (n, 2) as (n - 1, 4)."""
    centre, radius, weight = corners_of(body)
    c = jnp.asarray(centre) + jnp.stack([jnp.zeros(()), jnp.asarray(z, float)])
    return c, jnp.asarray(radius), jnp.asarray(weight), jnp.concatenate([x[:-1], x[1:]], axis=1)


def corner_energy(body, x, pen: Penalty, z=0.0):
    """The corners' penalty energy $E_c$ of ``body`` (displaced by ``z``) against the segments
    of the nodes ``x`` (n, 2) (G h0 R^2; 0 for a body without corners)."""
    if corners_of(body) is None:
        return jnp.zeros(())
    c, r, w, ab = _pairs(body, x, z)
    per = jax.vmap(lambda ci, ri, wi: jax.vmap(lambda s: _pair_energy(pen, ri, wi, ci, s))(ab))
    return jnp.sum(per(c, r, w))


def corner_normal(body, x, pen: Penalty, z=0.0):
    """Each node's share of the corners' normal force (n,) (G h0 R): pair $j$'s
    $w\\,\\phi'(\\delta_j)$ split $1 - s$ to node $j$ and $s$ to node $j + 1$; zeros without
    corners."""
    n = x.shape[0]
    if corners_of(body) is None:
        return jnp.zeros(n)

    def one(ci, ri, wi, s):
        sj, dist = _closest(ci, s[:2], s[2:])
        f = wi * penalty_pressure(pen, ri - dist)
        return (1.0 - sj) * f, sj * f

    c, r, w, ab = _pairs(body, x, z)
    lo, hi = jax.vmap(lambda ci, ri, wi: jax.vmap(lambda s: one(ci, ri, wi, s))(ab))(c, r, w)
    lo, hi = jnp.sum(lo, axis=0), jnp.sum(hi, axis=0)
    return jnp.zeros(n).at[:-1].add(lo).at[1:].add(hi)


def _window(ab, c):
    """The :data:`WINDOW` segments nearest the centre ``c`` by distance (fewer on a shorter
    sheet): their indices (W,). Not a run of neighbours: a sheet can touch one corner in two
    places far apart along it (the tube's rim, with the sheet folded back up its outer wall)."""
    w = min(WINDOW, ab.shape[0])
    d = jax.vmap(lambda v: _closest(c, v[:2], v[2:])[1])(ab)
    return jax.lax.top_k(-d, w)[1]


def corner_terms(body, x, pen: Penalty, z=0.0, hessian=False):
    """$E_c$ (:func:`corner_energy`), its gradient in the nodes (n, 2) and, with ``hessian``,
    its Hessian as blocks ``(h_diag (n, 2, 2), h_up (n - 1, 2, 2))``: per corner, one 4 x 4
    Hessian for each of the :data:`WINDOW` segments nearest it (block tridiagonal: a segment
    couples its two nodes); ``None`` without corners. The energy and gradient sum every
    segment."""
    if corners_of(body) is None:
        return None
    n = x.shape[0]
    c, r, w, ab = _pairs(body, x, z)

    def seg(v):
        return jnp.sum(jax.vmap(lambda ci, ri, wi: _pair_energy(pen, ri, wi, ci, v))(c, r, w))

    e, g = jax.vmap(jax.value_and_grad(seg))(ab)
    grad = jnp.zeros((n, 2)).at[:-1].add(g[:, :2]).at[1:].add(g[:, 2:])
    if not hessian:
        return jnp.sum(e), grad

    def near(ci, ri, wi):
        idx = _window(ab, ci)
        return idx, jax.vmap(jax.hessian(lambda v: _pair_energy(pen, ri, wi, ci, v)))(ab[idx])

    idx, h = jax.vmap(near)(c, r, w)
    idx, h = idx.reshape(-1), h.reshape(-1, 4, 4)
    h_diag = jnp.zeros((n, 2, 2)).at[idx].add(h[:, :2, :2]).at[idx + 1].add(h[:, 2:, 2:])
    h_up = jnp.zeros((n - 1, 2, 2)).at[idx].add(h[:, :2, 2:])
    return jnp.sum(e), grad, (h_diag, h_up)


def corner_normal_jacobian(body, x, pen: Penalty, z=0.0):
    r"""The derivatives of each node's share of the corners' normal force
    (:func:`corner_normal`) in the nodes it reads: ``(self, up, low)``, each (n, 2),
    $\partial N_i/\partial x_i$, $\partial N_i/\partial x_{i+1}$ and $\partial N_i/\partial
    x_{i-1}$ (a share reads the two segments at node $i$: block tridiagonal). Zeros without
    corners."""
    n = x.shape[0]
    zero = jnp.zeros((n, 2))
    if corners_of(body) is None:
        return zero, zero, zero
    c, r, w, ab = _pairs(body, x, z)

    def near(ci, ri, wi):
        idx = _window(ab, ci)

        def one(v):
            sj, dist = _closest(ci, v[:2], v[2:])
            f = wi * penalty_pressure(pen, ri - dist)
            return jnp.stack([(1.0 - sj) * f, sj * f])

        return idx, jax.vmap(jax.jacfwd(one))(ab[idx])  # (W, 2, 4): (lo, hi) in (a, b)

    idx, j = jax.vmap(near)(c, r, w)
    idx, j = idx.reshape(-1), j.reshape(-1, 2, 4)
    own = zero.at[idx].add(j[:, 0, :2]).at[idx + 1].add(j[:, 1, 2:])
    return own, zero.at[idx].add(j[:, 0, 2:]), zero.at[idx + 1].add(j[:, 1, :2])


def corner_crossed(body, x0, x1, z=0.0):
    """Whether a segment of the sheet passed through a corner's centre between the node
    positions ``x0`` and ``x1`` (n, 2) (the body displaced by ``z``): the centre changed sides
    of the segment's line while projecting inside the segment at both. The penalty's distance
    is unsigned (module docstring), so such a state would be pushed on through; an increment
    that reaches one is refused (:class:`dynslip.physics.solver.newton.MotionNewton`). False
    without corners."""
    if corners_of(body) is None:
        return jnp.array(False)
    centre = jnp.asarray(corners_of(body)[0]) + jnp.stack([jnp.zeros(()),
                                                           jnp.asarray(z, float)])

    def side(x, c):
        a, b = x[:-1], x[1:]
        d = b - a
        s = jnp.einsum("ij,ij->i", c - a, d) / jnp.maximum(jnp.einsum("ij,ij->i", d, d), _TINY)
        cross = d[:, 0] * (c[1] - a[:, 1]) - d[:, 1] * (c[0] - a[:, 0])
        return jnp.sign(cross), (s >= 0.0) & (s <= 1.0)

    def one(c):
        s0, in0 = side(x0, c)
        s1, in1 = side(x1, c)
        return jnp.any((s0 * s1 < 0) & in0 & in1)

    return jnp.any(jax.vmap(one)(centre))
