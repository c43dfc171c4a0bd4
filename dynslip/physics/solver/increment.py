r"""The residual of one implicit Euler load increment on the motion alone
(:mod:`dynslip.physics.solver.newton`, whose docstring states the method): the increment's data
(:class:`Increment`), each node's rate relative to the ball under the friction law with its
return map for the slip distance (:func:`slip_update`, :func:`node_rate`), the node rate's
force Jacobian in closed form (:func:`node_force_jacobian`), the ball's and the clamped edge's
rates, and the residual $q - q_0 - \Delta t\,u(q)$, $z_b - z_{b,0} - \Delta t\,v_b$.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics import conditions
from dynslip.physics.bodies.corners import corner_normal, corner_normal_jacobian, corners_of
from dynslip.physics.bodies.held import frictional, held_corner_normal, held_entries, held_frame
from dynslip.physics.conditions import Edge
from dynslip.physics.field import StageArgs
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.sheet import SheetModel, penalty_pressure
from dynslip.physics.terms import contact_gap, forces, held_projections

__all__ = [
    "Increment",
    "NodeLaw",
    "ball_rate",
    "ball_velocity",
    "corner_share_jacobians",
    "corner_shares",
    "held_share_jacobians",
    "held_shares",
    "edge_rate",
    "increment_rates",
    "law_area",
    "node_force_jacobian",
    "node_held_frame",
    "node_law",
    "node_rate",
    "residual",
    "residual_and_state",
    "sheet_held_frame",
    "slip_update",
    "untouched",
    "weighted_slip",
]


# --------------------------------------------------------------------------- friction return map


def _slip(friction: AbstractFriction, ft, normal, delta, eps, area):
    """$|S|$ of one node with slip distance ``delta`` (None for a memoryless law)."""
    return jnp.abs(friction.slip_force(ft, normal, delta, eps=eps, area=area))


def slip_update(friction, ft, normal, eps, delta0, c, area=None):
    r"""The node's return map: the slip force with the coefficient of the increment's start,
    $S(F_t, \mu(\delta_0) N)$ (exactly zero on the trial's stick side), and the slip distance
    it adds, $\delta_1 = \delta_0 + c\,|S|$, $c = \Delta t/(\eta A)$; $\delta_1 = \delta_0$ out of
    contact. Continuous in the motion, so its autodiff derivative is the map's consistent
    tangent. Returns ``(delta_mu, delta1)``: the slip distance at which $\mu$ is evaluated,
    and the new one.

    Why $\mu$ at $\delta_0$ (first order in time, as implicit Euler itself): the fully implicit
    root of $\delta = \delta_0 + c|S(F_t, \mu(\delta) N)|$ at fixed forces is unique, but where
    the weakening outruns the drag ($c\,(\mu_s - \mu_k) N/d_c > 1$, the case at increments of
    20 drag times) it lies on the kinetic branch past $d_c$ as soon as the node slips: the
    node's slip force jumps from 0 to $|F_t| - \mu_k N$ across the trial's stick boundary, and
    Newton on the motion chatters across it (33323 increments against 431 on the frozen
    let-go path at N = 50, docs/speed.md). A corrector ($\mu$ at the predicted $\delta_1$) is
    continuous too but needed 1185."""
    live = normal > 0
    d1 = delta0 + c * _slip(friction, ft, normal, delta0, eps, area)
    return delta0, jnp.where(live, d1, delta0)


# --------------------------------------------------------------------------- the increment's
# residual


class Increment(eqx.Module):
    """The data of one increment: start state (relative positions, ball height, slip
    distance), its end time and length, the loads."""

    q0: jax.Array  # (n, 2)
    zb0: jax.Array
    delta0: jax.Array | None
    t1: jax.Array
    h: jax.Array
    args: StageArgs
    # the held bodies' slip distances at the start (K_mem, n): mu of a held law with memory is
    # taken at them (the return map's delta0); None without such a body
    held_delta0: jax.Array | None = None
    # each node's areal stretch, for a ball law that reads its pressure on the deformed area
    # (None: the reference area). The residual reads it at the increment's end
    # (:func:`increment_rates`); the Newton matrix's friction blocks hold it at the value given
    # here (the start's), leaving out its derivative through the neighbouring nodes: an inexact
    # Jacobian for the pressure law only, which changes Newton's path, not its root
    areal_stretch: jax.Array | None = None
    # the complementarity parameter c of the ball friction's weighted form (:func:`weighted_slip`,
    # G h0); None: the law's own form
    weight: float | None = None


def corner_shares(model: SheetModel, q):
    """Each node's share of the ball's corners' normal force at relative positions ``q`` (n,)
    (:func:`dynslip.physics.bodies.corners.corner_normal`), or None when the ball has no
    corners: the ball's friction law reads it beside the node's own penalty force. The Newton
    matrix holds it at the iterate's value (its derivative through the segment's other node
    left out: an inexact Jacobian for the corners' friction only, which changes Newton's path,
    not its root)."""
    if corners_of(model.ball) is None:
        return None
    return corner_normal(model.ball, q, model.penalty)


def corner_share_jacobians(model: SheetModel, q):
    """:func:`corner_shares`' derivatives in the nodes, ``(own, up, low)`` (n, 2) each
    (:func:`dynslip.physics.bodies.corners.corner_normal_jacobian`), or None without corners:
    the Newton matrix's corner friction terms."""
    if corners_of(model.ball) is None:
        return None
    return corner_normal_jacobian(model.ball, q, model.penalty)


def held_share_jacobians(model: SheetModel, q, zb):
    """:func:`held_shares`' derivatives in the nodes, ``(own, up, low)`` (K, n, 2) each, or
    None where :func:`held_shares` is None."""
    if held_shares(model, q, zb) is None:
        return None
    entries = held_entries(model.bodies)
    x = q + jnp.stack([jnp.zeros(()), zb])
    parts = [corner_normal_jacobian(e.body, x, model.penalty, e.shift(zb)) for e in entries]
    return tuple(jnp.stack([p[j] for p in parts]) for j in range(3))


def node_contact(model: SheetModel, i, q, g, corner=None):
    """Node ``i``'s normal and tangential driving forces against the ball, its normal and
    tangent, the penalty's normal force (with ``corner``, the node's share of the ball's
    corners', :func:`corner_shares`) and the node's area."""
    return _node_contact(model, i, q, g, corner)[:6]


def _node_contact(model: SheetModel, i, q, g, corner=None):
    # node_contact's and the node's penetration into the ball (an adhesive law reads it)
    f = -g
    d, n, t = contact_gap(model.ball, q)
    pole = i == 0
    fn = jnp.where(pole, f[1] * jnp.sign(n[1]), f @ n)
    ft = jnp.where(pole, 0.0, f @ t)
    area = model.mesh.area[i]
    normal = area * penalty_pressure(model.ball_contact, d)
    if corner is not None:
        normal = normal + corner
    return fn, ft, n, t, normal, area, d


def law_area(friction: AbstractFriction, inc: Increment, i, area, d=None):
    """Node ``i``'s area as the ball's law reads its pressure (``area`` its reference area,
    ``d`` its penetration into the ball, for a law that reads its gap)."""
    stretch = 1.0 if inc.areal_stretch is None else inc.areal_stretch[i]
    return friction.contact_area(area, stretch, d)


class NodeLaw(NamedTuple):
    """What the ball's friction law reads at one node: the driving forces, normal and tangent
    and the penalty's normal force of :func:`node_contact`, the node's reference area, the drag
    ``eta_a`` and the smoothing ``eps`` over that area, and its area as the law reads its
    pressure (:func:`law_area`)."""

    fn: jax.Array
    ft: jax.Array
    n: jax.Array
    t: jax.Array
    normal: jax.Array
    area: jax.Array
    eta_a: jax.Array
    eps: jax.Array
    a_law: jax.Array


def node_law(model: SheetModel, friction: AbstractFriction, inc: Increment, i, q, g,
             corner=None) -> NodeLaw:
    """The :class:`NodeLaw` of node ``i`` at relative position ``q`` under the energy gradient
    ``g`` (``corner``: its share of the ball's corners' normal force, :func:`corner_shares`)."""
    fn, ft, n, t, normal, area, d = _node_contact(model, i, q, g, corner)
    return NodeLaw(fn, ft, n, t, normal, area, inc.args.drag * area, inc.args.eps * area,
                   law_area(friction, inc, i, area, d))


def held_shares(model: SheetModel, q, zb):
    """Each node's share of each held body's corners' normal force at relative positions
    ``q``, (n, K), or None when no held body has corners or none has friction
    (:func:`dynslip.physics.bodies.held.held_corner_normal`; held at the iterate's value in the
    Newton matrix, as :func:`corner_shares`)."""
    if not frictional(model.bodies):
        return None
    x = q + jnp.stack([jnp.zeros(()), zb])
    c = held_corner_normal(model.bodies, x, model.penalty, zb)
    return None if c is None else c.T


def node_held_frame(model: SheetModel, inc: Increment, i, q, g, zb, projections=None,
                    corner=None):
    """The held bodies' friction frame of node ``i`` at relative position ``q`` under the
    energy gradient ``g``, the ball at ``zb`` (held friction acts on neither the pole nor the
    clamped edge); ``projections`` the held bodies' of the node (None: projected here);
    ``corner`` (K,) its shares of the held bodies' corners' normal force (:func:`held_shares`;
    None: none)."""
    live = (i > 0) & (i < model.mesh.n - 1)
    hd = None if inc.held_delta0 is None else inc.held_delta0[:, i]
    return _held_frame(model, q + jnp.stack([jnp.zeros(()), zb]), -g, model.mesh.area[i],
                       inc.args, live, zb, hd, projections, corner)


def node_rate(model: SheetModel, friction, inc: Increment, i, q, g, delta0, zb=None, vb=None,
              held=True, projections=None, alone=None, corner=None, held_corner=None):
    """Rate relative to the ball of node ``i`` at relative position ``q`` under the energy
    gradient ``g``, and its slip distance at the increment's end (None: memoryless law).
    ``zb`` and ``vb`` (the ball's height and velocity) enter the friction of the held bodies
    (:mod:`dynslip.physics.bodies.held`), needed only when one has friction; ``held=False``
    leaves that friction out (the ball's part alone); ``projections`` the held bodies' of the
    node (None: projected here); ``alone``: whether no frictional held body touches the node
    (:func:`untouched`; None: found here with held friction, else True); ``corner``: the node's
    share of the ball's corners' normal force (:func:`corner_shares`; None: no corners), and
    ``held_corner`` of the held bodies' (:func:`held_shares`)."""
    pole = i == 0
    fn, ft, n, t, normal, area, eta_a, eps, a_law = node_law(model, friction, inc, i, q, g,
                                                             corner)
    hf = None
    if held and frictional(model.bodies):
        hf = node_held_frame(model, inc, i, q, g, zb, projections, held_corner)
        alone = untouched(hf) if alone is None else alone
    delta1, delta_mu = None, None
    if inc.weight is None:
        if delta0 is not None:
            delta_mu, delta1 = slip_update(friction, ft, normal, eps, delta0, inc.h / eta_a,
                                           a_law)
        s = friction.slip_force(ft, normal, delta_mu, eps=eps, area=a_law)
    else:
        # the weighted form (:func:`weighted_slip`), and the return map with its slip force,
        # which is the law's at the root (one evaluation of the law: the step's compile)
        s = weighted_slip(friction, inc, i, q, t, ft, normal, delta0, eps, area, alone, a_law)
        if delta0 is not None:
            delta_mu = delta0
            delta1 = jnp.where(normal > 0, delta0 + inc.h / eta_a * jnp.abs(s), delta0)
    u = (fn * n + s * t) / eta_a
    if hf is not None:
        u = u + hf.force(vb) / eta_a
    u = u.at[0].set(jnp.where(pole, 0.0, u[0]))
    return u, delta1


def untouched(hf):
    """Whether no frictional held body's friction acts on the node of the held frame ``hf``
    (one node's; :func:`node_held_frame`): the weighted form of the ball's law applies there
    (:func:`weighted_slip`)."""
    return jax.lax.stop_gradient(~(hf.live & jnp.any(hf.normal > 0)))


def node_force_jacobian(model: SheetModel, friction, inc: Increment, i, q, g, delta0,
                        alone=None, corner=None):
    r"""$\partial u_i/\partial g_i$ of :func:`node_rate` without held friction, in closed form:
    the rate reads the force only through $F_n = f\cdot n$ and $F_t = f\cdot t$ ($f = -g$; at
    the pole $F_n = f_z\,{\rm sign}\,n_z$, $F_t = 0$), so
    $\partial u/\partial g = -(n\,\partial F_n/\partial f^T + S'(F_t)\,t\,\partial F_t/
    \partial f^T)/(\eta A)$, with $S'$ the slip law's slope (one scalar forward pass; $\mu$ at
    the increment's start, as the return map takes it). Two forward directions fewer than
    ``jacfwd`` in $g$ (the Newton matrix's largest part at large N); checked against it in
    tests/test_newton.py."""
    pole = i == 0
    _, ft, n, t, normal, _, eta_a, eps, a_law = node_law(model, friction, inc, i, q, g, corner)

    w, shift = (1.0, 0.0) if inc.weight is None else _weighting(inc, i, q, t, eta_a, alone)

    def slip(ft):
        # the weighted form's slope in F_t: its curve's at the shifted trial
        return friction.slip_force(ft + shift, normal, delta0, eps=eps, area=a_law, weight=w)

    _, ds = jax.jvp(slip, (ft,), (jnp.ones_like(ft),))
    dfn = jnp.where(pole, jnp.stack([jnp.zeros(()), jnp.sign(n[1])]), n)
    dft = jnp.where(pole, jnp.zeros(2), t)
    lg = -(jnp.outer(n, dfn) + ds * jnp.outer(t, dft)) / eta_a
    return jnp.where(pole, jnp.stack([jnp.zeros(2), lg[1]]), lg)


def _weighting(inc: Increment, i, q, t, eta_a, alone=None):
    r"""Node ``i``'s weight in the friction law's weighted form, $\gamma = \max(1,\ c\,
    \Delta t/(\eta A))$ for the complementarity parameter $c$ = ``inc.weight`` (force per
    displacement, $G h_0$), and the shift of its trial force, $(\gamma - 1)\,\eta A\,
    \Delta_t/\Delta t$, with $\Delta_t = (q - q_0)\cdot t$ its tangential displacement over
    the increment (1 and 0 over a zero-length increment, and where ``alone`` is False: a held
    body's friction acts on the node too, :func:`weighted_slip`)."""
    assert inc.weight is not None  # the weighted form is taken only with a weight
    moved = inc.h > 0
    if alone is not None:
        moved = moved & alone
    h = jnp.where(moved, inc.h, 1.0)
    gamma = jnp.where(moved, jnp.maximum(1.0, inc.weight * h / eta_a), 1.0)
    dt = (q - inc.q0[i]) @ t
    return gamma, (gamma - 1.0) * eta_a * dt / h


def weighted_slip(friction, inc: Increment, i, q, t, ft, normal, delta_mu, eps, area,
                  alone=None, a_law=None):
    r"""The slip force in the weighted (primal-dual) form of the friction law, node weight
    $\gamma = \max(1, c\,\Delta t/(\eta A))$ for $c$ = ``inc.weight``: $S_\gamma =
    \gamma\Psi_\gamma(y) - (\gamma - 1)\,\eta A\,u_t$ at the shifted trial $y = F_t +
    (\gamma - 1)\,\eta A\,u_t$, $u_t = \Delta_t/\Delta t$ the node's tangential rate over the
    increment, $\gamma\Psi_\gamma$ the law's curve read at $y$
    (:func:`dynslip.physics.friction.weighted_form`; for the ideal law $S_\gamma = F_t - P(y)$).

    Why: with the friction force $\lambda = F_t - \eta A u_t$ the law $\eta A u_t = S(F_t)$ is
    $\lambda = P(\lambda + \eta A u_t)$, $P(y) = y - S(y)$ the projection onto the friction
    disc $|\lambda| \le T$; the row $\eta A u_t = S_\gamma$ is $\lambda = P(\lambda +
    \gamma\,\eta A u_t)$, the same Coulomb complementarity with the slip rate weighted
    $\gamma$ times more in the stick/slip decision (the complementarity parameter $c$ of
    primal-dual active-set contact solvers, Hueber, Stadler and Wohlmuth 2008). With the
    smoothing too, the row $\eta A u_t = \gamma\Psi_\gamma(y) - (\gamma - 1)\eta A u_t$
    has exactly the law's roots for every $\gamma > 0$ ($\gamma = 1$ is the law's own form):
    only Newton's path to them changes. A stuck node's row becomes $\gamma$ times its
    tangential displacement.

    That reads the node's tangential rate as the ball law's alone, $\eta A u_t = S$: where a
    frictional held body's friction acts on the node too (``alone`` False; None: nowhere), it
    adds to $u_t$ and the weighted row would have other roots, so the node keeps the law's own
    form ($\gamma = 1$). ``area``: the node's reference area; ``a_law``: the area the law
    reads its pressure on (None: ``area``)."""
    eta_a = inc.args.drag * area
    gamma, shift = _weighting(inc, i, q, t, eta_a, alone)
    return friction.slip_force(ft + shift, normal, delta_mu, eps=eps,
                               area=area if a_law is None else a_law, weight=gamma) - shift


def _held_frame(model: SheetModel, x, f, area, args, live, zb, delta=None, projections=None,
                corners=None):
    """The held bodies' friction frame at absolute node positions ``x`` (one node or all), the
    ball at ``zb``, the held slip distances ``delta`` (K_mem, ...) (None: no law has memory),
    the held bodies' ``projections`` of ``x`` (None: projected here)."""
    return held_frame(
        model.bodies,
        x,
        f,
        lambda d: penalty_pressure(model.penalty, -d),
        area,
        args.drag,
        args.eps,
        live,
        zb,
        delta,
        projections,
        corners,
    )


def sheet_held_frame(model: SheetModel, args, q, zb, g, delta=None, projections=None):
    """The held bodies' friction frame of the whole sheet at relative positions ``q`` under the
    energy gradient ``g`` (not the pole nor the clamped edge), the ball at ``zb``, the held slip
    distances ``delta`` (K_mem, n), the held bodies' ``projections``
    (:func:`dynslip.physics.terms.held_projections`; None: projected here)."""
    n = q.shape[0]
    idx = jnp.arange(n)
    x = q + jnp.stack([jnp.zeros(()), zb])
    return _held_frame(model, x, -g, model.mesh.area, args, (idx > 0) & (idx < n - 1), zb,
                       delta, projections, held_corner_normal(model.bodies, x, model.penalty,
                                                              zb))


def ball_velocity(model: SheetModel, inc: Increment, q, zb, g, load, projections=None):
    """The ball's velocity at the increment's end in the stage's ball mode
    (:func:`dynslip.physics.conditions.ball_velocity`), under the clamp's axial force on the
    sheet less the held bodies' ``load``, with the held bodies' friction where one has any (its
    frame is built only where the mode reads it); ``projections`` the held bodies' of the nodes
    (None: projected here)."""
    args = inc.args
    pull = conditions.clamp_force(args, inc.t1, g[-1])[1] - load
    if not frictional(model.bodies):
        return conditions.ball_velocity(args, inc.t1, zb, pull)

    def frame():
        return sheet_held_frame(model, args, q, zb, g, inc.held_delta0, projections)

    return conditions.ball_velocity(args, inc.t1, zb, pull, frame)


def ball_rate(inc: Increment, g_edge, zb, load):
    """The ball's velocity without held friction: :func:`ball_velocity`'s from the clamped
    edge's energy gradient ``g_edge`` alone."""
    pull = conditions.clamp_force(inc.args, inc.t1, g_edge)[1] - load
    return conditions.ball_velocity(inc.args, inc.t1, zb, pull)


def edge_rate(model: SheetModel, inc: Increment, g_edge, zb, load, vb=None, rho_edge=0.0):
    """Rate relative to the ball of the clamped edge in the stage's clamp mode
    (:func:`dynslip.physics.conditions.edge_motion`), at the edge's radius ``rho_edge``;
    ``vb`` the ball's velocity (None: :func:`ball_rate`'s)."""
    if vb is None:
        vb = ball_rate(inc, g_edge, zb, load)
    args = inc.args
    edge = Edge(g_edge, rho_edge, args.drag * model.mesh.area[-1])
    force = conditions.clamp_force(args, inc.t1, g_edge)
    return conditions.edge_motion(model, args, edge, force, vb).u


def increment_rates(model, friction, inc: Increment, q, zb, g, load, projections=None):
    """Every node's rate relative to the ball (n, 2), the ball's velocity and the slip
    distances at the increment's end, from the relative positions and energy gradient (and the
    held bodies' ``projections`` of the nodes, :func:`held_projections`; None: projected
    where needed)."""
    idx = jnp.arange(q.shape[0])
    d0 = inc.delta0
    ps = projections
    if inc.areal_stretch is not None:
        # the law's pressure at the increment's end, as every other force of implicit Euler
        inc = eqx.tree_at(lambda c: c.areal_stretch, inc, model.areal_stretch(q[:, 0], q[:, 1]))
    vb = ball_velocity(model, inc, q, zb, g, load, ps)
    cs, hs = corner_shares(model, q), held_shares(model, q, zb)
    if d0 is None:
        u, _ = jax.vmap(lambda i, qi, gi, pi, ci, hi: node_rate(
            model, friction, inc, i, qi, gi, None, zb, vb, projections=pi, corner=ci,
            held_corner=hi))(idx, q, g, ps, cs, hs)
        delta1 = None
    else:
        u, delta1 = jax.vmap(
            lambda i, qi, gi, di, pi, ci, hi: node_rate(model, friction, inc, i, qi, gi, di, zb,
                                                        vb, projections=pi, corner=ci,
                                                        held_corner=hi)
        )(idx, q, g, d0, ps, cs, hs)
        delta1 = delta1.at[-1].set(d0[-1])
    u = u.at[-1].set(edge_rate(model, inc, g[-1], zb, load, vb, q[-1, 0]))
    return u, vb, delta1


def residual_and_state(model, friction, inc: Increment, q, zb):
    """:func:`residual` and what the increment's end reads from the same evaluation: the
    energy gradient ``g`` (n, 2), the ball's velocity, the slip distances at the increment's
    end (None: memoryless law), the held bodies' load and their projections of the nodes
    (:func:`held_projections`; None without held bodies), ``(r_q, r_z, (g, vb, delta1, load,
    projections))``. Newton carries the last
    accepted trial's, so the converged state's rates are not evaluated again (each call site of
    the residual is compiled anew: docs/speed.md)."""
    # the held bodies' projections once, for the penalty and the held friction
    ps = held_projections(model, q, zb) if model.bodies else None
    g, load = forces(model, q, zb, ps)
    u, vb, delta1 = increment_rates(model, friction, inc, q, zb, g, load, ps)
    return q - inc.q0 - inc.h * u, zb - inc.zb0 - inc.h * vb, (g, vb, delta1, load, ps)


def residual(model, friction, inc: Increment, q, zb):
    """The increment's residual: $q - q_0 - \\Delta t\\,u(q)$ (n, 2) and $z_b - z_{b,0} -
    \\Delta t\\,v_b$."""
    return residual_and_state(model, friction, inc, q, zb)[:2]

