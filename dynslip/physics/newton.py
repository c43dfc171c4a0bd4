r"""Load increments by Newton on the motion alone (issue 23).

The same implicit Euler increment as :mod:`dynslip.physics.loadstep`,
$x_1 = x_0 + \Delta t\, f(t_1, x_1)$ with the overdamped law of
:func:`dynslip.physics.field.evaluate`, solved for fewer unknowns:

- **Unknowns.** The node positions *relative to the ball*, $q_i = x_i - z_b e_z$
  ($n$ blocks of 2; the pole's $\rho_0 = 0$ stays a trivial row), and the ball height
  $z_b$, the only border unknown. A node's rate relative to the ball, $u_i$, depends on
  its relative position and on the elastic and penalty forces, i.e. on its neighbours
  (the energy is invariant under a common vertical shift), so the $q$ rows are block
  tridiagonal. The ball's rate $v_b$ couples only to the clamped edge (the clamp's force
  $C_z = \partial E/\partial z_{n-1}$ on a force-controlled ball) and to itself (the
  support), so the border is one unknown touching one block. Implicit Euler is invariant
  under this linear change of variables: the increment is the one the full state would
  give.
- **Slip distance by a local return map.** Per node, given the trial forces,
  $\delta_1 = \delta_0 + \Delta t\,|S(F_t, \mu(\delta_1) N)|/(\eta A)$ in contact
  ($\delta_1 = \delta_0$ out of contact), solved node by node (:func:`return_map`: the
  closed form of the ideal threshold on the piece of $\mu(\delta)$ it lands on, polished by
  local Newton steps on the smoothed law). Its consistent tangent
  $\partial\delta_1/\partial x = -g_x/g_\delta$ enters the Jacobian by the implicit function
  theorem (:func:`_implicit`). It is the same equation the global unknown satisfied.
- **Energy accumulators by quadrature.** After an increment is accepted, the work and
  dissipation rates of :func:`dynslip.physics.field.evaluate` at $x_1$ times $\Delta t$ (the
  rectangle rule at the increment's end: exactly what the implicit accumulators gave).
- **Jacobian from element and node derivatives.** Per element, the value, gradient and
  Hessian of its energy in its four coordinates (``vmap`` of ``jacfwd`` of ``grad``); per
  node, the penalty's, and the Jacobian of the node's rate in its own position (``vmap`` of
  ``jacfwd``) and force (closed form, :func:`node_force_jacobian`; ``jacfwd`` with held
  friction); the chain rule assembles the $2\times 2$ blocks
  $\partial u_i/\partial q_j = L^q_i\delta_{ij} + L^g_i H_{ij}$. No pass over the whole field.
- **Backtracking** as :class:`dynslip.physics.loadstep.DampedNewton` (a correction that
  raises the residual's max norm is halved, at most ``backtrack`` times); the residual of
  the accepted trial is the next iteration's residual (one evaluation per trial).
- **Predictor.** Newton starts from the last accepted increment's rate extrapolated over
  the new increment (zero at a segment's start).

The linear solve is :func:`dynslip.physics.linalg.block_solve` (block cyclic reduction or
block Thomas, with the one-unknown border by a Schur complement).

**Bodies.** The contact geometry is asked of the model's bodies through :func:`contact_gap`
(the ball, :attr:`SheetModel.ball`, at the relative position $q$; the held bodies,
:attr:`SheetModel.bodies`, at $q + z_b e_z$, each with its own friction law or none:
:mod:`dynslip.physics.bodies.held`, docs/bodies.md).

Longer than 400 lines: the increment's residual, its Newton matrix and the solver object
share the node and element terms at the top, and the matrix is checked block by block
against the residual (tests/test_newton.py, tests/test_bodies_sheet.py); split, the three
would import each other's private terms. The active-set pass (``MotionNewton.freeze``) lives in
the increment's loop because it changes the residual and matrix that loop evaluates. Cuts worth
making, not yet made: the free bodies' system (:func:`free_system`, which the increment calls
and which calls the residual: a module of its own needs a local import) and the element and
node terms (:func:`forces`, :func:`forces_and_hessians`), which nothing else shares.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics.bodies.held import (
    free_ball_velocity,
    frictional,
    held_entries,
    held_frame,
    place_bodies,
    place_free,
)
from dynslip.physics.field import Layout, StageArgs, evaluate, heal
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.linalg import bordered_solve, small_matmul
from dynslip.physics.materials import relaxed_energy
from dynslip.physics.protocols import BALL_HOLD, CLAMP_BAND, CLAMP_POSITION
from dynslip.physics.sheet import SheetModel, penalty_energy, penalty_pressure

__all__ = [
    "MotionNewton",
    "SegmentOutput",
    "increment_rates",
    "newton_blocks",
    "residual",
    "slip_update",
    "zero_rate",
]

GROW = 1.5
CUT = 0.5
SHRINK = 0.7
MIN_FRACTION = 1e-10


def increment_cap(args, max_increment, max_increment_free):
    """$\\Delta t_{max}$ (s): ``max_increment`` drag times in driven stages, ``max_increment_free``
    where the ball or the clamp moves under a force (``args.drag`` is the drag time)."""
    free = (args.ball_mode != BALL_HOLD) | (args.clamp_mode != CLAMP_POSITION)
    return args.drag * jnp.where(free, max_increment_free, max_increment)


class SegmentOutput(eqx.Module):
    """What a segment solve returns (both solvers): the end state, whether it reached the
    segment's end, the steps (accepted + rejected), accepted, rejected, Newton iterations
    (0 for the time-stepped solvers)."""

    y: jax.Array
    ok: jax.Array
    steps: jax.Array
    accepted: jax.Array
    rejected: jax.Array
    newton_iterations: jax.Array
    rate: (
        tuple  # the last accepted increment per unit time on (q, zb): the next segment's predictor
    )


# --------------------------------------------------------------------------- element / node terms


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
    ``1 - |q|`` about its centre and the tangent toward the equator). The one place the
    contact geometry is asked for: the ball at ``q`` relative to its reference placement,
    the held bodies at the node's absolute position."""
    p = body.project(q, z)
    return -p.distance, p.normal, p.tangent


def _node_penalty(pen, ball, area, q):
    return area * penalty_energy(pen, contact_gap(ball, q)[0])


def _held_penalty(model: SheetModel, area, x, zb=0.0, moving=None):
    """Penalty energy of one node at absolute position ``x`` against every held body (a body
    that moves with the ball displaced by ``zb``); ``moving`` True/False: only those that do /
    do not (None: all)."""
    return sum(
        (
            area * penalty_energy(model.penalty, contact_gap(e.body, x, e.shift(zb))[0])
            for e in held_entries(model.bodies)
            if moving is None or e.moves_with_ball == moving
        ),
        jnp.zeros(()),
    )


def _moves_with_ball(model: SheetModel) -> bool:
    return any(e.moves_with_ball for e in held_entries(model.bodies))


def forces(model: SheetModel, q, zb):
    """$\\partial E/\\partial x$ per node, (n, 2), NaN everywhere where the energy is not finite
    (as :meth:`SheetModel.gradients`), and the held bodies' load
    (:meth:`SheetModel.held_load`; 0 without any). The held bodies see the node at
    $q + z_b e_z$."""
    m = model.mesh
    rsum = m.rbar[1:] + m.rbar[:-1]

    def el(dr, rs, a, xa, xb):
        return jax.value_and_grad(element_energy, argnums=(4, 5))(model.material, dr, rs, a, xa, xb)

    e, (ga, gb) = jax.vmap(el)(m.dr, rsum, m.area_el, q[:-1], q[1:])
    ep, gp = jax.vmap(jax.value_and_grad(_node_penalty, argnums=3), in_axes=(None, None, 0, 0))(
        model.penalty, model.ball, m.area, q
    )
    load = jnp.zeros(())
    if model.bodies:
        x = q + jnp.stack([jnp.zeros(()), zb])
        eh, gh = jax.vmap(
            jax.value_and_grad(lambda a, xi: _held_penalty(model, a, xi, zb), argnums=1)
        )(m.area, x)
        ep, gp, load = ep + eh, gp + gh, jnp.sum(gh[:, 1])
    g = gp.at[:-1].add(ga).at[1:].add(gb)
    bad = ~jnp.isfinite(jnp.sum(e) + jnp.sum(ep))
    return jnp.where(bad, jnp.nan, g), load


def forces_and_hessians(model: SheetModel, q, zb):
    """:func:`forces` and the blocks of the energy's Hessian: ``(g, h_diag, h_up, load, h_held)``,
    ``h_diag[i] = d2E/dx_i^2``, ``h_up[i] = d2E/dx_i dx_{i+1}`` (n-1 of them), ``h_held`` the
    pair ``(hh, hz)``: ``hh[i]`` the held bodies' part of ``h_diag[i]``, ``hz[i]`` its part that
    moves with ``zb`` at fixed ``q`` (the bodies at rest: a body that moves with the ball sees
    ``q`` alone) (None without held bodies)."""
    m = model.mesh
    rsum = m.rbar[1:] + m.rbar[:-1]

    def el(dr, rs, a, x):
        def f(x):
            return element_energy(model.material, dr, rs, a, x[:2], x[2:])

        gfun = jax.grad(f)
        h, g = jax.jacfwd(lambda x: (gfun(x), gfun(x)), has_aux=True)(x)
        return f(x), g, h

    e, ge, he = jax.vmap(el)(m.dr, rsum, m.area_el, jnp.concatenate([q[:-1], q[1:]], axis=1))

    def second(f, x):
        gfun = jax.grad(f)
        h, g = jax.jacfwd(lambda x: (gfun(x), gfun(x)), has_aux=True)(x)
        return f(x), g, h

    ep, gp, hp = jax.vmap(
        lambda a, x: second(lambda x: _node_penalty(model.penalty, model.ball, a, x), x)
    )(m.area, q)
    load, hh = jnp.zeros(()), None
    if model.bodies:
        x = q + jnp.stack([jnp.zeros(()), zb])
        eh, gh, hh = jax.vmap(lambda a, x: second(lambda x: _held_penalty(model, a, x, zb), x))(
            m.area, x
        )
        ep, gp, hp, load = ep + eh, gp + gh, hp + hh, jnp.sum(gh[:, 1])
        hz = hh
        if _moves_with_ball(model):
            hz = jax.vmap(
                lambda a, x: second(lambda x: _held_penalty(model, a, x, moving=False), x)[2]
            )(m.area, x)
        hh = (hh, hz)
    g = gp.at[:-1].add(ge[:, :2]).at[1:].add(ge[:, 2:])
    h_diag = hp.at[:-1].add(he[:, :2, :2]).at[1:].add(he[:, 2:, 2:])
    h_up = he[:, :2, 2:]
    bad = ~jnp.isfinite(jnp.sum(e) + jnp.sum(ep))
    return jnp.where(bad, jnp.nan, g), h_diag, h_up, load, hh


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
    # per node, the friction branch held by the active-set pass (FREE: the law itself)
    frozen: jax.Array | None = None
    # the held bodies' slip distances at the start (K_mem, n): mu of a held law with memory is
    # taken at them (the return map's delta0); None without such a body
    held_delta0: jax.Array | None = None


FREE, STICK, SLIP_UP, SLIP_DOWN = 0, 1, 2, 3  # the active-set pass's branches per node


def _node_contact(model: SheetModel, i, q, g):
    """Node ``i``'s normal and tangential driving forces against the ball, its normal and
    tangent, the penalty's normal force and the node's area."""
    f = -g
    d, n, t = contact_gap(model.ball, q)
    pole = i == 0
    fn = jnp.where(pole, f[1] * jnp.sign(n[1]), f @ n)
    ft = jnp.where(pole, 0.0, f @ t)
    area = model.mesh.area[i]
    return fn, ft, n, t, area * penalty_pressure(model.penalty, d), area


def frozen_slip(friction, mode, s, ft, normal, delta_mu, area):
    r"""The slip force on the branch ``mode`` holds: the law's own ``s`` (FREE), stuck (0), or
    slipping either way along the tangent at the threshold, $F_t \mp T$ (smooth in $F_t$, so
    Newton does not flip the node across its stick boundary)."""
    thr = friction.threshold(normal, delta_mu, area)
    return jnp.where(
        mode == STICK,
        0.0,
        jnp.where(mode == SLIP_UP, ft - thr, jnp.where(mode == SLIP_DOWN, ft + thr, s)),
    )


def slip_signs(model: SheetModel, friction, inc: Increment, q, g):
    """Per node, the sign of the law's own slip force against the ball (0: stuck) at relative
    positions ``q`` under the energy gradient ``g``: the state the active-set pass counts
    flips of."""

    def one(i, qi, gi, di):
        _, ft, _, _, normal, area = _node_contact(model, i, qi, gi)
        eps = inc.args.eps * area
        return jnp.sign(friction.slip_force(ft, normal, di, eps=eps, area=area))

    idx = jnp.arange(q.shape[0])
    if inc.delta0 is None:
        return jax.vmap(lambda i, qi, gi: one(i, qi, gi, None))(idx, q, g).astype(jnp.int32)
    return jax.vmap(one)(idx, q, g, inc.delta0).astype(jnp.int32)


def node_rate(model: SheetModel, friction, inc: Increment, i, q, g, delta0, zb=None, vb=None):
    """Rate relative to the ball of node ``i`` at relative position ``q`` under the energy
    gradient ``g``, and its slip distance at the increment's end (None: memoryless law).
    ``zb`` and ``vb`` (the ball's height and velocity) enter the friction of the held bodies
    (:mod:`dynslip.physics.bodies.held`), needed only when one has friction."""
    args = inc.args
    f = -g
    pole = i == 0
    fn, ft, n, t, normal, area = _node_contact(model, i, q, g)
    eta_a = args.drag * area
    eps = args.eps * area
    delta1, delta_mu = None, None
    if delta0 is not None:
        delta_mu, delta1 = slip_update(friction, ft, normal, eps, delta0, inc.h / eta_a, area)
    s = friction.slip_force(ft, normal, delta_mu, eps=eps, area=area)
    if inc.frozen is not None:
        s = frozen_slip(friction, inc.frozen[i], s, ft, normal, delta_mu, area)
    u = (fn * n + s * t) / eta_a
    if frictional(model.bodies):
        live = (i > 0) & (i < model.mesh.n - 1)
        hd = None if inc.held_delta0 is None else inc.held_delta0[:, i]
        hf = _held_frame(model, q + jnp.stack([jnp.zeros(()), zb]), f, area, args, live, zb, hd)
        u = u + hf.force(vb) / eta_a
    u = u.at[0].set(jnp.where(pole, 0.0, u[0]))
    return u, delta1


def node_force_jacobian(model: SheetModel, friction, inc: Increment, i, q, g, delta0):
    r"""$\partial u_i/\partial g_i$ of :func:`node_rate` without held friction, in closed form:
    the rate reads the force only through $F_n = f\cdot n$ and $F_t = f\cdot t$ ($f = -g$; at
    the pole $F_n = f_z\,{\rm sign}\,n_z$, $F_t = 0$), so
    $\partial u/\partial g = -(n\,\partial F_n/\partial f^T + S'(F_t)\,t\,\partial F_t/
    \partial f^T)/(\eta A)$, with $S'$ the slip law's slope (one scalar forward pass, the
    active-set pass's branch included; $\mu$ at the increment's start, as the return map takes
    it). Two forward directions fewer than ``jacfwd`` in $g$ (the Newton matrix's largest part
    at large N); checked against it in tests/test_newton.py."""
    args = inc.args
    pole = i == 0
    _, ft, n, t, normal, area = _node_contact(model, i, q, g)
    eta_a = args.drag * area
    eps = args.eps * area

    def slip(ft):
        s = friction.slip_force(ft, normal, delta0, eps=eps, area=area)
        if inc.frozen is not None:
            s = frozen_slip(friction, inc.frozen[i], s, ft, normal, delta0, area)
        return s

    _, ds = jax.jvp(slip, (ft,), (jnp.ones_like(ft),))
    dfn = jnp.where(pole, jnp.stack([jnp.zeros(()), jnp.sign(n[1])]), n)
    dft = jnp.where(pole, jnp.zeros(2), t)
    lg = -(jnp.outer(n, dfn) + ds * jnp.outer(t, dft)) / eta_a
    return jnp.where(pole, jnp.stack([jnp.zeros(2), lg[1]]), lg)


def _held_frame(model: SheetModel, x, f, area, args, live, zb, delta=None):
    """The held bodies' friction frame at absolute node positions ``x`` (one node or all), the
    ball at ``zb``, the held slip distances ``delta`` (K_mem, ...) (None: no law has memory)."""
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
    )


def _sheet_held_frame(model: SheetModel, args, q, zb, g, delta=None):
    """The held bodies' friction frame of the whole sheet at relative positions ``q`` under the
    energy gradient ``g`` (not the pole nor the clamped edge), the ball at ``zb``, the held slip
    distances ``delta`` (K_mem, n)."""
    n = q.shape[0]
    idx = jnp.arange(n)
    x = q + jnp.stack([jnp.zeros(()), zb])
    return _held_frame(model, x, -g, model.mesh.area, args, (idx > 0) & (idx < n - 1), zb,
                       delta)


def ball_velocity(model: SheetModel, inc: Increment, q, zb, g, load):
    """The ball's velocity: :func:`ball_rate`, with the held bodies' friction (its axial part
    depends on the velocity itself: :func:`dynslip.physics.bodies.held.free_ball_velocity`)."""
    if not frictional(model.bodies):
        return ball_rate(inc, g[-1], zb, load)
    args = inc.args

    def free():
        hf = _sheet_held_frame(model, args, q, zb, g, inc.held_delta0)
        pinned = (args.clamp_mode == CLAMP_POSITION) | (args.clamp_mode == CLAMP_BAND)
        cz = jnp.where(pinned, g[-1, 1], args.clamp_force(inc.t1)[1])
        fb = args.ball_force(inc.t1) + args.support_force(zb)
        return free_ball_velocity(hf, fb + (cz - load) + args.weight, args.ball_drag)

    # a held ball's velocity is prescribed: the sheet's held friction frame and the root search
    # are skipped (lax.cond; under vmap both branches run)
    vzb = jnp.asarray(args.vzb, dtype=jnp.result_type(float))
    return jax.lax.cond(args.ball_mode == BALL_HOLD, lambda: vzb, free)


def ball_rate(inc: Increment, g_edge, zb, load):
    """The ball's velocity from the clamp's force on the sheet $C_z$ less the held bodies'
    ``load`` (held: prescribed; force-controlled: $(F_h + F_s(z_b) + C_z - L + F_g)/\\eta_b$)."""
    args = inc.args
    pinned = (args.clamp_mode == CLAMP_POSITION) | (args.clamp_mode == CLAMP_BAND)
    cz = jnp.where(pinned, g_edge[1], args.clamp_force(inc.t1)[1])
    fb = args.ball_force(inc.t1) + args.support_force(zb)
    return jnp.where(
        args.ball_mode == BALL_HOLD, args.vzb, (fb + (cz - load) + args.weight) / args.ball_drag
    )


def edge_rate(model: SheetModel, inc: Increment, g_edge, zb, load, vb=None, rho_edge=0.0):
    """Rate relative to the ball of the clamped edge: prescribed (pinned clamp), drag under
    the ramped clamp force, or the band's (prescribed radially, sliding along the wall past
    the grip, :meth:`SheetModel.band_slip`, at the edge's radius ``rho_edge``); ``vb`` the
    ball's velocity (None: :func:`ball_rate`'s)."""
    args = inc.args
    pinned = args.clamp_mode == CLAMP_POSITION
    band = args.clamp_mode == CLAMP_BAND
    if vb is None:
        vb = ball_rate(inc, g_edge, zb, load)
    eta_a = args.drag * model.mesh.area[-1]
    free = (args.clamp_force(inc.t1) - g_edge) / eta_a
    w = jnp.where(band, model.band_slip(-g_edge[1], rho_edge, args.eps) / eta_a, 0.0)
    return jnp.where(pinned | band, jnp.stack([args.vrhoc, args.vzc - vb + w]), free)


def increment_rates(model, friction, inc: Increment, q, zb, g, load):
    """Every node's rate relative to the ball (n, 2), the ball's velocity and the slip
    distances at the increment's end, from the relative positions and energy gradient."""
    idx = jnp.arange(q.shape[0])
    d0 = inc.delta0
    vb = ball_velocity(model, inc, q, zb, g, load)
    if d0 is None:
        u, _ = jax.vmap(lambda i, qi, gi: node_rate(model, friction, inc, i, qi, gi, None, zb, vb))(
            idx, q, g
        )
        delta1 = None
    else:
        u, delta1 = jax.vmap(
            lambda i, qi, gi, di: node_rate(model, friction, inc, i, qi, gi, di, zb, vb)
        )(idx, q, g, d0)
        delta1 = delta1.at[-1].set(d0[-1])
    u = u.at[-1].set(edge_rate(model, inc, g[-1], zb, load, vb, q[-1, 0]))
    return u, vb, delta1


def residual(model, friction, inc: Increment, q, zb):
    """The increment's residual: $q - q_0 - \\Delta t\\,u(q)$ (n, 2) and $z_b - z_{b,0} -
    \\Delta t\\,v_b$."""
    g, load = forces(model, q, zb)
    u, vb, _ = increment_rates(model, friction, inc, q, zb, g, load)
    return q - inc.q0 - inc.h * u, zb - inc.zb0 - inc.h * vb


def residual_and_signs(model, friction, inc: Increment, q, zb):
    """:func:`residual` and :func:`slip_signs` from one evaluation of the forces."""
    g, load = forces(model, q, zb)
    u, vb, _ = increment_rates(model, friction, inc, q, zb, g, load)
    return q - inc.q0 - inc.h * u, zb - inc.zb0 - inc.h * vb, slip_signs(model, friction, inc, q, g)


def newton_blocks(model, friction, inc: Increment, q, zb):
    """The Newton matrix of :func:`residual` as blocks ``(lower, diag, upper, B, C, D)``
    (shapes (n,2,2) x3, (n,2,1), (1,n,2), (1,1)) from element and node derivatives."""
    if frictional(model.bodies):
        return _blocks_with_held_friction(model, friction, inc, q, zb)
    n = q.shape[0]
    g, h_diag, h_up, load, hh = forces_and_hessians(model, q, zb)
    idx = jnp.arange(n)
    d0 = inc.delta0 if inc.delta0 is not None else jnp.zeros(n)
    mem = inc.delta0 is not None

    def local(i, qi, gi, di):
        return node_rate(model, friction, inc, i, qi, gi, di if mem else None)[0]

    lq = jax.vmap(jax.jacfwd(local, argnums=1))(idx, q, g, d0)  # (n, 2, 2)
    lg = jax.vmap(
        lambda i, qi, gi, di: node_force_jacobian(model, friction, inc, i, qi, gi,
                                                  di if mem else None)
    )(idx, q, g, d0)
    # the clamped edge: rate from its force and the ball height only
    eg, ez, el, er = jax.jacfwd(
        lambda ge, z, ld, r: edge_rate(model, inc, ge, z, ld, None, r), argnums=(0, 1, 2, 3)
    )(g[-1], zb, load, q[-1, 0])
    bg, bz, bl = jax.jacfwd(lambda ge, z, ld: ball_rate(inc, ge, z, ld), argnums=(0, 1, 2))(
        g[-1], zb, load
    )
    lq = lq.at[-1].set(jnp.zeros((2, 2)).at[:, 0].set(er))  # the band's grip reads rho_edge
    lg = lg.at[-1].set(eg)
    h_low = jnp.swapaxes(h_up, 1, 2)  # d2E/dx_{i+1} dx_i
    h = inc.h
    eye = jnp.eye(2)
    diag = eye - h * (lq + small_matmul(lg, h_diag))
    upper = jnp.concatenate([-h * small_matmul(lg[:-1], h_up), jnp.zeros((1, 2, 2))])
    lower = jnp.concatenate([jnp.zeros((1, 2, 2)), -h * small_matmul(lg[1:], h_low)])
    B = jnp.zeros((n, 2, 1)).at[-1, :, 0].set(-h * ez)
    C = jnp.zeros((1, n, 2))
    C = C.at[0, -1].set(-h * bg @ h_diag[-1]).at[0, -2].set(-h * bg @ h_low[-1])
    D = jnp.reshape(1.0 - h * bz, (1, 1))
    if hh is not None:
        # the held bodies see q + zb: every node's force moves with zb (d g_i/d zb = hh_i e_z;
        # not a body that moves with the ball), and the load L = sum_i dE_h/dz_i enters the
        # ball's and the edge's rates
        hh, hz = hh
        dg_dz = hz[:, :, 1]  # (n, 2)
        dl_dq = hh[:, 1, :]  # (n, 2)
        dl_dz = jnp.sum(hz[:, 1, 1])
        col = jnp.einsum("nij,nj->ni", lg, dg_dz).at[-1].set(eg @ dg_dz[-1] + el * dl_dz)
        B = B - h * col[:, :, None]
        C = C - h * bl * dl_dq[None]
        D = D - h * (bg @ dg_dz[-1] + bl * dl_dz)
        # a pinned edge on a free ball moves with the ball, whose rate reads every node's load:
        # the edge's and its neighbour's part is kept (the rest is not block tridiagonal and
        # is left out: an inexact Newton matrix, the residual exact; exact for a held ball)
        diag = diag.at[-1].add(-h * jnp.outer(el, dl_dq[-1]))
        lower = lower.at[-1].add(-h * jnp.outer(el, dl_dq[-2]))
    return lower, diag, upper, B, C, D


def _blocks_with_held_friction(model, friction, inc: Increment, q, zb):
    r""":func:`newton_blocks` with friction on the held bodies. The node rates depend on the
    ball's velocity $v_b$ (:func:`ball_velocity`), which reads every node in contact with a
    frictional body: with $V_j = dv_b/dq_j$ and $V_z = dv_b/dz_b$ (by reverse-mode autodiff
    of :func:`ball_velocity` and the chain rule through the energy's Hessian), the border row
    is $-h V$, the column $-h(\ell^g_i\,\partial g_i/\partial z_b + \ell^z_i + \ell^v_i V_z)$,
    and the rank-one coupling $\ell^v_i V_j$ of the node rates is kept where $|i - j| \le 1$
    (the rest is not block tridiagonal and is left out: an inexact Newton matrix, the residual
    exact; with the ball held $V = 0$ and the matrix is exact)."""
    n = q.shape[0]
    g, h_diag, h_up, load, hh = forces_and_hessians(model, q, zb)
    def value_and_grads():
        return jax.value_and_grad(
            lambda q, zb, g, ld: ball_velocity(model, inc, q, zb, g, ld), argnums=(0, 1, 2, 3)
        )(q, zb, g, load)

    def held():
        vzb = jnp.asarray(inc.args.vzb, dtype=jnp.result_type(float))
        return vzb, jax.tree_util.tree_map(jnp.zeros_like, (q, zb, g, load))

    # a held ball's velocity is prescribed: its derivatives are zero, and the root search and
    # the reverse pass through the held friction are skipped (lax.cond; under vmap both
    # branches run); the free ball's velocity and its derivatives in one pass (the root search
    # traced once here)
    vb, (vq, vz, vg, vl) = jax.lax.cond(
        inc.args.ball_mode == BALL_HOLD, held, value_and_grads
    )
    idx = jnp.arange(n)
    mem = inc.delta0 is not None
    d0 = inc.delta0 if mem else jnp.zeros(n)

    def local(i, qi, gi, di, z, v):
        return node_rate(model, friction, inc, i, qi, gi, di if mem else None, z, v)[0]

    lq, lg, lz, lv = jax.vmap(
        jax.jacfwd(local, argnums=(1, 2, 4, 5)), in_axes=(0, 0, 0, 0, None, None)
    )(idx, q, g, d0, zb, vb)
    eg, ev, er = jax.jacfwd(
        lambda ge, v, r: edge_rate(model, inc, ge, zb, load, v, r), argnums=(0, 1, 2)
    )(g[-1], vb, q[-1, 0])
    lq, lz = lq.at[-1].set(jnp.zeros((2, 2)).at[:, 0].set(er)), lz.at[-1].set(0.0)
    lg, lv = lg.at[-1].set(eg), lv.at[-1].set(ev)
    h_low = jnp.swapaxes(h_up, 1, 2)  # h_low[j] = d2E/dx_{j+1} dx_j
    hh, hz = hh
    dg_dz = hz[:, :, 1]  # (n, 2): the held bodies at rest see q + zb
    dl_dq = hh[:, 1, :]
    dl_dz = jnp.sum(hz[:, 1, 1])
    # dv_b/dq_j through the forces: sum_i (dv_b/dg_i) H_ij, H tridiagonal
    big_v = vq + jnp.einsum("ni,nij->nj", vg, h_diag) + vl * dl_dq
    big_v = big_v.at[1:].add(jnp.einsum("ni,nij->nj", vg[:-1], h_up))
    big_v = big_v.at[:-1].add(jnp.einsum("ni,nij->nj", vg[1:], h_low))
    v_z = vz + jnp.sum(vg * dg_dz) + vl * dl_dz
    h = inc.h
    eye = jnp.eye(2)
    rank1 = jnp.einsum("ni,nj->nij", lv, big_v)
    diag = eye - h * (lq + small_matmul(lg, h_diag) + rank1)
    upper = -h * (small_matmul(lg[:-1], h_up) + jnp.einsum("ni,nj->nij", lv[:-1], big_v[1:]))
    lower = -h * (small_matmul(lg[1:], h_low) + jnp.einsum("ni,nj->nij", lv[1:], big_v[:-1]))
    upper = jnp.concatenate([upper, jnp.zeros((1, 2, 2))])
    lower = jnp.concatenate([jnp.zeros((1, 2, 2)), lower])
    col = jnp.einsum("nij,nj->ni", lg, dg_dz) + lz + lv * v_z
    B = -h * col[:, :, None]
    C = -h * big_v[None]
    D = jnp.reshape(1.0 - h * v_z, (1, 1))
    return lower, diag, upper, B, C, D


def free_system(model, friction, inc: Increment, zk0):
    r"""The increment's residual and Newton matrix with free held bodies
    (:attr:`dynslip.physics.bodies.held.Held.free`): the border unknowns are $(z_b, z_1 ..
    z_K)$, the bodies' residuals $z_k - z_{k,0} - \Delta t\,v_k$ with $v_k = (L_k + F_k)/\eta_k$
    (:func:`dynslip.physics.field.free_body_rates`). The block-tridiagonal part and the ball's
    border are :func:`newton_blocks`' at the bodies' heights; the bodies' columns (K forward
    passes of the residual) and rows (K reverse passes) are exact. Returns ``(res, blocks,
    placed)``, ``placed(zk)`` the model with the bodies at ``zk``."""
    from dynslip.physics.field import free_body_rates

    def placed(zk):
        # at the increment's end, moving at the increment's velocity (the slip relative to a
        # frictional free body)
        return place_free(model, zk, (zk - zk0) / inc.h)

    def body_res(q, zb, zk):
        m = placed(zk)
        hf = vb = None
        if frictional(m.bodies):
            g, load = forces(m, q, zb)
            hf = _sheet_held_frame(m, inc.args, q, zb, g, inc.held_delta0)
            vb = ball_velocity(m, inc, q, zb, g, load)
        v, _, _ = free_body_rates(m, q[:, 0], q[:, 1] + zb, zb, hf, vb)
        return zk - zk0 - inc.h * v

    def res(q, w):
        zb, zk = w[0], w[1:]
        r_q, r_z = residual(placed(zk), friction, inc, q, zb)
        return r_q, jnp.concatenate([jnp.reshape(r_z, (1,)), body_res(q, zb, zk)])

    def blocks(q, w):
        zb, zk = w[0], w[1:]
        lower, diag, upper, b, c, d = newton_blocks(placed(zk), friction, inc, q, zb)
        cq, cz = jax.jacfwd(lambda zk: residual(placed(zk), friction, inc, q, zb))(zk)
        rq, rzb, rzk = jax.jacrev(body_res, argnums=(0, 1, 2))(q, zb, zk)
        b = jnp.concatenate([b, cq], axis=-1)  # (n, 2, 1 + K)
        c = jnp.concatenate([c, rq], axis=0)  # (1 + K, n, 2)
        d = jnp.block([[d, cz[None, :]], [rzb[:, None], rzk]])
        return lower, diag, upper, b, c, d

    return res, blocks, placed


# --------------------------------------------------------------------------- the solver object


class MotionNewton(eqx.Module):
    """Implicit Euler load increments, Newton on the motion alone (module docstring).

    ``rtol``/``atol`` (max norm; converged when the last correction is below
    ``atol + rtol |x|`` and the residual below ``atol``), at most ``max_iter`` corrections
    per increment, ``backtrack`` halvings of a correction that raises the residual,
    ``linear``: ``"cyclic"`` (block cyclic reduction) or ``"thomas"``. Increments grow by 1.5
    after at most ``grow_below`` iterations and shrink by 0.7 after at least ``shrink_above``.
    ``freeze`` (0: off, the default): the active-set pass, a node whose friction against the
    ball flipped between stick and slip ``freeze`` times within an increment is held on its
    branch (:func:`frozen_slip`) until Newton converges, then the law is given back and Newton
    goes on to the law's own root (not with free bodies); docs/speed.md measures it (more
    iterations on the let-go path, hence off).
    """

    max_iter: int = eqx.field(static=True, default=20)
    backtrack: int = eqx.field(static=True, default=4)
    linear: str = eqx.field(static=True, default="cyclic")
    grow_below: int = eqx.field(static=True, default=12)
    shrink_above: int = eqx.field(static=True, default=18)
    max_increment: float = eqx.field(static=True, default=20.0)
    max_increment_free: float = eqx.field(static=True, default=5.0)
    heal_rate: float = eqx.field(static=True, default=0.0)
    max_steps: int = eqx.field(static=True, default=20000)
    freeze: int = eqx.field(static=True, default=0)

    def increment(self, model, layout: Layout, t0, t1, y0, args, rate, rtol, atol):
        """One increment from ``y0`` at ``t0`` to ``t1``, Newton started from ``y0 + (t1 - t0)
        rate``
        (``rate`` on the unknowns ``(q, zb)``): ``(y1, ok, iterations, (q1 - q0, zb1 - zb0))``."""
        friction = args.friction
        # the stage-moved bodies where they are at the increment's end (implicit Euler)
        model = place_bodies(model, args.body_z0, args.body_v, args.t0, t1)
        h = t1 - t0
        rho, z, zb0, acc0 = layout.unpack(y0)
        q0 = jnp.stack([rho, z - zb0], axis=1)
        delta0 = layout.internal(y0)
        hdelta0 = layout.held_internal(y0)
        inc = Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args,
                        held_delta0=hdelta0)
        rq, rz = rate
        q = q0 + h * rq
        nf = layout.n_free
        # the active-set pass (``freeze``): not with free bodies, whose border it would not see
        active = self.freeze > 0 and not nf
        n = q0.shape[0]
        if nf:
            # free bodies: the border is (zb, z_1 .. z_K), placed into the model by res/blocks
            res0, blocks0, placed = free_system(model, friction, inc, layout.free(y0))
            zb = jnp.concatenate([jnp.reshape(zb0 + h * rz, (1,)), layout.free(y0)])

            def res(q, zb, mode):
                return (*res0(q, zb), jnp.zeros(n, jnp.int32))

            def blocks(q, zb, mode):
                return blocks0(q, zb)
        else:
            zb = zb0 + h * rz

            def held(mode):
                return Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args, frozen=mode,
                                 held_delta0=hdelta0)

            def res(q, zb, mode):
                if not active:
                    return (*residual(model, friction, inc, q, zb), jnp.zeros(n, jnp.int32))
                return residual_and_signs(model, friction, held(mode), q, zb)

            def blocks(q, zb, mode):
                return newton_blocks(model, friction, held(mode) if active else inc, q, zb)

        def size(rq, rz):
            return jnp.maximum(jnp.max(jnp.abs(rq)), jnp.max(jnp.abs(rz)))

        free_mode = jnp.zeros(n, jnp.int32)
        r_q, r_z, sgn = res(q, zb, free_mode)

        def cond(c):
            it, done, bad = c[4], c[5], c[6]
            return (~done) & (~bad) & (it < self.max_iter)

        def body(c):
            q, zb, r_q, r_z, it, _, _, mode, flips, sgn, final = c
            dq, dz = bordered_solve(*blocks(q, zb, mode), r_q, r_z, self.linear)
            f0 = size(r_q, r_z)

            # the full step, then up to ``backtrack`` halvings while the residual rises: one
            # loop whose first pass is the full step, so the residual is traced once here (each
            # call site of it is compiled anew: 2 s of the world's compile per copy)
            def bt_cond(b):
                _alpha, tq, tz, _, k = b
                f1 = size(tq, tz)
                return ~((f1 <= f0) | (f1 <= atol)) & (k <= self.backtrack)

            def bt_body(b):
                alpha, _, _, _, k = b
                alpha = jnp.where(k == 0, 1.0, 0.5 * alpha)
                tq, tz, ts = res(q - alpha * dq, zb - alpha * dz, mode)
                return alpha, tq, tz, ts, k + 1

            unset = (jnp.full_like(r_q, jnp.inf), jnp.full_like(r_z, jnp.inf), sgn)
            alpha, tq, tz, ts, _ = jax.lax.while_loop(
                bt_cond, bt_body, (jnp.array(1.0), *unset, jnp.array(0))
            )
            qn, zbn = q - alpha * dq, zb - alpha * dz
            if active:
                # a node whose law flipped between stick and slip ``freeze`` times is held on
                # the branch it is on; once Newton converges so, the law is given back to every
                # node and Newton goes on to the law's own root (``final``: no more freezing)
                flips = flips + ((ts != sgn) & (mode == FREE)).astype(jnp.int32)
                hold = (~final) & (mode == FREE) & (flips >= self.freeze)
                branch = jnp.where(ts == 0, STICK, jnp.where(ts > 0, SLIP_UP, SLIP_DOWN))
                new_mode = jnp.where(hold, branch, mode)
                tq, tz, ts = jax.lax.cond(
                    jnp.any(new_mode != mode),
                    lambda: res(qn, zbn, new_mode),
                    lambda: (tq, tz, ts),
                )
                mode = new_mode
            step = jnp.maximum(
                jnp.max(jnp.abs(alpha * dq) / (atol + rtol * jnp.abs(qn))),
                jnp.max(jnp.abs(alpha * dz) / (atol + rtol * jnp.abs(zbn))),
            )
            done = (step < 1.0) & (size(tq, tz) <= atol)
            if active:
                release = done & jnp.any(mode != FREE)
                tq, tz, ts = jax.lax.cond(
                    release, lambda: res(qn, zbn, free_mode), lambda: (tq, tz, ts)
                )
                mode = jnp.where(release, free_mode, mode)
                final = final | release
                done = done & ~release
            bad = ~(
                jnp.all(jnp.isfinite(qn)) & jnp.all(jnp.isfinite(zbn)) & jnp.isfinite(size(tq, tz))
            )
            return qn, zbn, tq, tz, it + 1, done, bad, mode, flips, ts, final

        init = (
            q, zb, r_q, r_z, jnp.array(0, jnp.int32), jnp.array(False), jnp.array(False),
            free_mode, jnp.zeros(n, jnp.int32), sgn, jnp.array(False),
        )
        q, zb, _, _, it, done, bad, *_ = jax.lax.while_loop(cond, body, init)
        zk = None
        if nf:
            zb, zk = zb[0], zb[1:]
            model = placed(zk)
        g, load = forces(model, q, zb)
        _, vb1, delta1 = increment_rates(model, friction, inc, q, zb, g, load)
        hdelta1 = None
        if hdelta0 is not None:
            # the held bodies' return map: delta1 = delta0 + h |S(G, mu(delta0) N)|/(eta A) in
            # contact with the body, the slip relative to it at the converged motion
            hdelta1 = _sheet_held_frame(model, args, q, zb, g, hdelta0).advance(vb1, h)
        y1 = layout.pack(q[:, 0], q[:, 1] + zb, zb, acc0, delta1, zk, hdelta1)
        # the accumulators by the rectangle rule at x1, with the friction law the motion used: the
        # return map's coefficient at the increment's start, mu(delta0) (with mu(delta1) the
        # friction power of fully mobilised nodes is counted at the weakened threshold, which
        # the motion never saw: 5x the work on the let-go path)
        y_rates = layout.pack(q[:, 0], q[:, 1] + zb, zb, acc0, delta0, zk, hdelta0)
        dy, _ = evaluate(model, layout, t1, y_rates, args)
        y1 = y1.at[layout.accumulators].set(acc0 + h * dy[layout.accumulators])
        y1 = heal(model, layout, y1, args, self.heal_rate, vb=vb1)
        ok = done & ~bad & jnp.all(jnp.isfinite(y1))
        return y1, ok, it, (q - q0, zb - zb0)

    def segment(
        self, model, layout: Layout, y0, t0, t1, dt0, args, rtol, atol, rate=None
    ) -> SegmentOutput:
        """Increments from ``t0`` to ``t1`` (``dt0`` the first tried), ending exactly on ``t1``;
        ``rate`` (on ``(q, zb)``, zero when None: a stage's start) predicts the first increment."""
        cap = increment_cap(args, self.max_increment, self.max_increment_free)
        dt_min = MIN_FRACTION * (t1 - t0)
        zero = jnp.array(0, dtype=jnp.int32)
        n = layout.n
        rate0 = zero_rate(n) if rate is None else rate

        def cond(c):
            t, _, _, dt, _, nacc, nrej, _ = c
            return (t < t1) & (nacc + nrej < self.max_steps) & (dt >= dt_min)

        def body(c):
            t, y, rate, dt, was_cut, nacc, nrej, nit = c
            left = t1 - t
            last = left <= 1.25 * dt
            h = jnp.where(last, left, dt)
            t_next = jnp.where(last, t1, t + h)
            y1, ok, iters, (dq, dz) = self.increment(
                model, layout, t, t_next, y, args, rate, rtol, atol
            )
            factor = jnp.where(
                iters <= self.grow_below, GROW, jnp.where(iters >= self.shrink_above, SHRINK, 1.0)
            )
            factor = jnp.where(was_cut, jnp.minimum(factor, 1.0), factor)
            dt_ok = jnp.minimum(jnp.maximum(dt, h) * factor, cap)
            dt_new = jnp.where(ok, dt_ok, CUT * h)
            new_rate = (dq / h, dz / h)
            rate = jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), new_rate, rate)
            return (
                jnp.where(ok, t_next, t),
                jnp.where(ok, y1, y),
                rate,
                dt_new,
                ~ok,
                nacc + ok,
                nrej + (~ok),
                nit + iters,
            )

        init = (t0, y0, rate0, jnp.minimum(dt0, cap), jnp.array(False), zero, zero, zero)
        t, y, rate, _, _, nacc, nrej, nit = jax.lax.while_loop(cond, body, init)
        ok = (t >= t1) & jnp.all(jnp.isfinite(y))
        return SegmentOutput(
            y=y,
            ok=ok,
            steps=nacc + nrej,
            accepted=nacc,
            rejected=nrej,
            newton_iterations=nit,
            rate=rate,
        )


def zero_rate(n: int):
    """The predictor's rate at a stage's start: zero on ``(q, zb)``."""
    return (jnp.zeros((n, 2)), jnp.zeros(()))
