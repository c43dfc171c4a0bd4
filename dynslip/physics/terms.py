r"""The increment's element and node terms (:mod:`dynslip.physics.solver.newton`): the elastic
energy of one element, the contact gap against a body, the penalties, and the energy's
gradient and Hessian blocks from them (``vmap`` of ``jacfwd`` of ``grad`` per element; the
penalties' in closed form from one projection per body; no pass over the whole field).

The held bodies (:attr:`SheetModel.bodies`) see a node at its absolute position
$q + z_b e_z$; the ball sees the relative position $q$.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from dynslip.physics.bodies.corners import corner_crossed, corner_terms, corners_of
from dynslip.physics.bodies.held import held_entries, projected
from dynslip.physics.materials import relaxed_energy
from dynslip.physics.sheet import SheetModel, penalty_energy, penalty_pressure

__all__ = ["contact_gap", "corner_parts", "corners_crossed", "element_energy", "forces",
           "forces_and_hessians", "held_projections"]


def element_energy(material, dr, rsum, area_el, xa, xb):
    """Elastic energy of one element from its two nodes (rho, z) (G h0 R^2), as
    :meth:`dynslip.physics.sheet.SheetModel.elastic_energy` sums it."""
    d = xb - xa
    lt = jnp.sqrt(d[0] ** 2 + d[1] ** 2) / dr
    lp = (xa[0] + xb[0]) / rsum
    return area_el * relaxed_energy(material, lt, lp)


def contact_gap(body, q, z=0.0):
    """Penetration $-d$ of a node at ``q`` = (rho, z) into ``body`` (an
    :class:`~dynslip.physics.bodies.base.AbstractBody` displaced by ``z``), and the body's
    outward normal and tangent (toward increasing arc length: for the unit sphere,
    ``1 - |q|`` about its centre and the tangent toward the equator): the ball at ``q``
    relative to its reference placement, the held bodies at the node's absolute position. The
    penalties read the projection itself (:func:`_penalty`: its curvature too)."""
    p = body.project(q, z)
    return -p.distance, p.normal, p.tangent


def _penalty(pen, area, p, hessian=False):
    r"""The penalty of nodes against a body from their projection ``p`` in closed form: energy
    $E = A\,\phi(-d)$ and gradient $-A\,\phi'(-d)\,n$, with ``hessian`` also the Hessian
    $A\,\phi''(-d)\,n n^T - A\,\phi'(-d)\,\kappa\,t t^T$ (the distance's Hessian $\kappa\,t
    t^T$, ``p.curvature``): one projection, no derivative pass through it (each would be
    compiled anew: docs/speed.md)."""
    d = -p.distance
    dphi, ddphi = jax.vmap(jax.value_and_grad(lambda v: penalty_pressure(pen, v)))(d)
    energy, grad = area * penalty_energy(pen, d), -(area * dphi)[..., None] * p.normal
    if not hessian:
        return energy, grad
    n, t = p.normal, p.tangent
    nn = jnp.einsum("...i,...j->...ij", n, n)
    tt = jnp.einsum("...i,...j->...ij", t, t)
    a = area[..., None, None]
    return energy, grad, a * (ddphi[..., None, None] * nn
                              - (dphi * p.curvature)[..., None, None] * tt)


def held_projections(model: SheetModel, q, zb):
    """Each held body's projection of the nodes at relative positions ``q``, in held order (a
    body sees the node at $q + z_b e_z$, displaced by its
    :meth:`~dynslip.physics.bodies.held.Held.shift`): computed once per residual and shared by
    the penalty (:func:`forces`) and the held friction (its frame,
    :func:`dynslip.physics.bodies.held.held_frame`); each call site of a projection is traced
    and compiled anew (docs/speed.md)."""
    x = q + jnp.stack([jnp.zeros(()), zb])
    return tuple(projected(e, k, x, zb) for k, e in enumerate(held_entries(model.bodies)))


def _held_parts(model: SheetModel, q, zb, hessian=False, projections=None):
    """:func:`_penalty` of the nodes at relative positions ``q`` against each held body, in
    held order, from ``projections`` (:func:`held_projections`; None: projected here)."""
    ps = held_projections(model, q, zb) if projections is None else projections
    return [_penalty(model.penalty, model.mesh.area, p, hessian) for p in ps]


def _column_sums(h_diag, h_up):
    r"""$\sum_j H_{ij}[:, 1]$ per node (n, 2) of a symmetric block-tridiagonal Hessian: the
    derivative of node $i$'s force under a shift of every node along $z$, and (by symmetry) of
    the axial load $\sum_j g_{j,z}$ in $x_i$."""
    col = h_diag[:, :, 1]
    col = col.at[:-1].add(h_up[:, :, 1])
    return col.at[1:].add(h_up[:, 1, :])


def corner_parts(model: SheetModel, q, zb, hessian=False):
    r"""The second pass (:mod:`dynslip.physics.bodies.corners`): the corners of the ball (at
    ``q``'s origin) and of each held body (seeing the nodes at $q + z_b e_z$) against the
    sheet's segments, as ``(ball, held)``: each None without corners, else
    :func:`~dynslip.physics.bodies.corners.corner_terms`' ``(energy, grad[, (h_diag, h_up)])``
    summed; ``held`` with ``hessian`` also the pair ``(hl, hz)`` of :func:`forces_and_hessians`'
    ``h_held`` (the load's derivative in each node and the force's in ``zb``, from the
    Hessian's column sums: exact for a segment coupling two nodes)."""
    pen = model.penalty
    ball = corner_terms(model.ball, q, pen, 0.0, hessian)
    x = q + jnp.stack([jnp.zeros(()), zb])
    parts = [(e, corner_terms(e.body, x, pen, e.shift(zb), hessian))
             for e in held_entries(model.bodies) if corners_of(e.body) is not None]
    if not parts:
        return ball, None
    held = tuple(sum((p[j] for _, p in parts), jnp.zeros(())) for j in range(2))
    if not hessian:
        return ball, held
    n = q.shape[0]
    hd = sum((p[2][0] for _, p in parts), jnp.zeros((n, 2, 2)))
    hu = sum((p[2][1] for _, p in parts), jnp.zeros((n - 1, 2, 2)))
    hl = jnp.zeros((n, 2, 2)).at[:, 1, :].set(_column_sums(hd, hu))
    # a body that moves with the ball sees q alone: its corners' force does not move with zb
    rest = [p[2] for e, p in parts if not e.moves_with_ball]
    hz = jnp.zeros((n, 2, 2))
    if rest:
        col = _column_sums(sum((r[0] for r in rest), jnp.zeros((n, 2, 2))),
                           sum((r[1] for r in rest), jnp.zeros((n - 1, 2, 2))))
        hz = hz.at[:, :, 1].set(col)
    return ball, held + ((hd, hu), (hl, hz))


def corners_crossed(model: SheetModel, q0, zb0, q, zb):
    """Whether a segment passed through a corner's centre of the ball or of a held body
    between the increment's start ``(q0, zb0)`` and ``(q, zb)``
    (:func:`~dynslip.physics.bodies.corners.corner_crossed`, each body's corners against the
    nodes relative to it), or a node touching a ball with corners at the start went through it
    (the side of the ball nearest it turned over: a thin body, as the coin, whose nearest face
    changes from the top to the bottom); False without corners (nothing traced)."""
    out = corner_crossed(model.ball, q0, q)
    if corners_of(model.ball) is not None:
        p0, p1 = model.ball.project(q0), model.ball.project(q)
        out = out | jnp.any((p0.distance <= 0) & (jnp.sum(p0.normal * p1.normal, axis=-1) < 0))
    for e in held_entries(model.bodies):
        if corners_of(e.body) is not None:
            x0 = q0 + jnp.stack([jnp.zeros(()), zb0 - e.shift(zb0)])
            x1 = q + jnp.stack([jnp.zeros(()), zb - e.shift(zb)])
            out = out | corner_crossed(e.body, x0, x1)
    return out


def forces(model: SheetModel, q, zb, projections=None):
    """$\\partial E/\\partial x$ per node, (n, 2), NaN everywhere where the energy is not finite
    (as :meth:`SheetModel.gradients`), and the held bodies' load
    (:meth:`SheetModel.held_load`; 0 without any). The held bodies see the node at
    $q + z_b e_z$ (``projections``: theirs, :func:`held_projections`; None: projected here)."""
    m = model.mesh
    rsum = m.rbar[1:] + m.rbar[:-1]

    def el(dr, rs, a, xa, xb):
        return jax.value_and_grad(element_energy, argnums=(4, 5))(model.material, dr, rs, a, xa, xb)

    e, (ga, gb) = jax.vmap(el)(m.dr, rsum, m.area_el, q[:-1], q[1:])
    ep, gp = _penalty(model.ball_contact, m.area, model.ball.project(q))
    load = jnp.zeros(())
    if model.bodies:
        parts = _held_parts(model, q, zb, projections=projections)
        eh, gh = (sum((p[j] for p in parts), jnp.zeros(())) for j in range(2))
        ep, gp, load = ep + eh, gp + gh, jnp.sum(gh[:, 1])
    ball, held = corner_parts(model, q, zb)
    for c in (ball, held):
        if c is not None:
            ep, gp = ep + c[0], gp + c[1]
    if held is not None:
        load = load + jnp.sum(held[1][:, 1])
    g = gp.at[:-1].add(ga).at[1:].add(gb)
    bad = ~jnp.isfinite(jnp.sum(e) + jnp.sum(ep))
    return jnp.where(bad, jnp.nan, g), load


def forces_and_hessians(model: SheetModel, q, zb, projections=None):
    """:func:`forces` and the blocks of the energy's Hessian: ``(g, h_diag, h_up, load, h_held)``,
    ``h_diag[i] = d2E/dx_i^2``, ``h_up[i] = d2E/dx_i dx_{i+1}`` (n-1 of them), ``h_held`` the
    pair ``(hh, hz)``: ``hh[i]`` the held bodies' part of ``h_diag[i]``, ``hz[i]`` its part that
    moves with ``zb`` at fixed ``q`` (the bodies at rest: a body that moves with the ball sees
    ``q`` alone) (None without held bodies). The Newton matrix reads row 1 of ``hh[i]`` (the
    load's derivative in ``x_i``) and column 1 of ``hz[i]`` (node ``i``'s force's in ``zb``);
    the held corners, whose segments couple two nodes, add their exact values there
    (:func:`corner_parts`)."""
    m = model.mesh
    rsum = m.rbar[1:] + m.rbar[:-1]

    def el(dr, rs, a, x):
        def f(x):
            return element_energy(model.material, dr, rs, a, x[:2], x[2:])

        gfun = jax.grad(f)
        h, g = jax.jacfwd(lambda x: (gfun(x), gfun(x)), has_aux=True)(x)
        return f(x), g, h

    e, ge, he = jax.vmap(el)(m.dr, rsum, m.area_el, jnp.concatenate([q[:-1], q[1:]], axis=1))

    ep, gp, hp = _penalty(model.ball_contact, m.area, model.ball.project(q), hessian=True)
    load, hh = jnp.zeros(()), None
    if model.bodies:
        # per body, summed here: the Hessian of the bodies at rest is the part that moves with
        # zb at fixed q
        entries = held_entries(model.bodies)
        parts = _held_parts(model, q, zb, hessian=True, projections=projections)
        eh, gh, hh = (sum((p[j] for p in parts), jnp.zeros(())) for j in range(3))
        ep, gp, hp, load = ep + eh, gp + gh, hp + hh, jnp.sum(gh[:, 1])
        hz = sum((p[2] for p, e in zip(parts, entries, strict=True) if not e.moves_with_ball),
                 jnp.zeros_like(hh))
        hh = (hh, hz)
    g = gp.at[:-1].add(ge[:, :2]).at[1:].add(ge[:, 2:])
    h_diag = hp.at[:-1].add(he[:, :2, :2]).at[1:].add(he[:, 2:, 2:])
    h_up = he[:, :2, 2:]
    ball, held = corner_parts(model, q, zb, hessian=True)
    for c in (ball, held):
        if c is not None:
            ep, g = ep + c[0], g + c[1]
            h_diag, h_up = h_diag + c[2][0], h_up + c[2][1]
    if held is not None:
        # a held body has corners: the held bodies' pair (hh, hz) is set above
        assert isinstance(hh, tuple)
        load = load + jnp.sum(held[1][:, 1])
        hh = (hh[0] + held[3][0], hh[1] + held[3][1])
    bad = ~jnp.isfinite(jnp.sum(e) + jnp.sum(ep))
    return jnp.where(bad, jnp.nan, g), h_diag, h_up, load, hh
