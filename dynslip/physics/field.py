r"""The whole sheet's state vector and vector field (the physics the solvers integrate).

:class:`Layout` (:mod:`dynslip.physics.layout`) names the slices of the flat state,
:class:`StageArgs` carries a stage's loads, :func:`evaluate` is the overdamped law with the
clamp and the ball (see :mod:`dynslip.physics.driver.simulate` for the state's contents and the
energy accumulators), :func:`vector_field` its diffrax form; the sparsity that
:class:`dynslip.physics.solver.linalg.BorderedBlockTridiagonal` exploits is
:func:`dynslip.physics.solver.linalg.sheet_structure`. Both solvers
(:mod:`dynslip.physics.driver.simulate`'s time stepping and :mod:`dynslip.physics.solver.loadstep`)
import from here, and nothing here imports a solver.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics import conditions
from dynslip.physics.bodies.held import held_entries, place_bodies, place_free
from dynslip.physics.conditions import Edge
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.layout import N_ACC, N_ACC_MOVED, Layout
from dynslip.physics.sheet import Penalty, SheetModel, penalty_pressure

# nodes of the clamped edge's element, in the dense border
# (dynslip.physics.solver.linalg.sheet_structure)
EDGE_NODES = 2

__all__ = [
    "Observed",
    "N_ACC",
    "N_ACC_MOVED",
    "EDGE_NODES",
    "Layout",
    "StageArgs",
    "evaluate",
    "vector_field",
    "heal",
]


class StageArgs(eqx.Module):
    """Everything the vector field needs besides the state: all arrays (one compile)."""

    t0: jnp.ndarray
    clamp_mode: jnp.ndarray  # CLAMP_POSITION, CLAMP_FORCE or CLAMP_BAND
    vzc: jnp.ndarray
    vrhoc: jnp.ndarray
    fc0: jnp.ndarray  # (2,) clamp force on the sheet (rho, z) at the ramp's start (force mode)
    fc1: jnp.ndarray  # (2,) ... at its end
    ball_mode: jnp.ndarray
    vzb: jnp.ndarray
    f0: jnp.ndarray
    f1: jnp.ndarray
    ramp: jnp.ndarray
    friction: AbstractFriction
    eps: jnp.ndarray  # friction smoothing, force density (G h0 / R)
    drag: jnp.ndarray  # eta per reference area: seconds (time unit tau = eta R^2/(G h0))
    ball_drag: jnp.ndarray  # eta_b (G h0 R s / R)
    weight: jnp.ndarray  # gravity force on the ball along +z (G h0 R), 0 when off
    # 1 where the ball rests on the rigid support (bottle neck), else 0
    support: jnp.ndarray | float = 0.0
    # ball-centre height at which the support's contact begins (R)
    support_z: jnp.ndarray | float = 0.0
    # support contact stiffness (G h0 R per R), C^1 over a width 1e-3 R
    support_k: jnp.ndarray | float = 1e3
    # the held bodies' heights at the stage's start and their axial velocities over it, (K,)
    # per held entry (R, R/s): None when no body is moved by the stages
    body_z0: jnp.ndarray | None = None
    body_v: jnp.ndarray | None = None

    def frac(self, t):
        return jnp.clip((t - self.t0) / self.ramp, 0.0, 1.0)

    def ball_force(self, t):
        return self.f0 + (self.f1 - self.f0) * self.frac(t)

    def clamp_force(self, t):
        return self.fc0 + (self.fc1 - self.fc0) * self.frac(t)

    def support_force(self, zb):
        r"""Upward force of the support on the ball: $k\,\phi'(z_s - z_b)$ with the C^1 penalty
        of :func:`dynslip.physics.sheet.penalty_pressure` (width 1e-3 R); zero off the support
        (unilateral: the pocket may lift the ball off) and where ``support`` is 0."""
        return self.support * penalty_pressure(Penalty(self.support_k, 1e-3), self.support_z - zb)


class Observed(eqx.Module):
    """What :func:`evaluate` derives on the way to the rates (forces in G h0 R per radian of
    the axisymmetric sheet, as the frames record them): the clamp's force on the sheet
    (``clamp_force`` along z, ``clamp_force_rho`` along rho) and its static part, the ball's
    reaction and its static part, the ball's velocity ``ball_v``, the positions it read, the
    sheet's per-node mechanics ``kin`` (:class:`dynslip.physics.sheet.Kinematics`) and the held
    bodies' friction frame (None without held bodies)."""

    clamp_force: jnp.ndarray
    clamp_force_rho: jnp.ndarray
    ball_reaction: jnp.ndarray
    ball_reaction_static: jnp.ndarray
    clamp_force_static: jnp.ndarray
    ball_v: jnp.ndarray
    rho: jnp.ndarray
    z: jnp.ndarray
    zb: jnp.ndarray
    kin: object
    held_frame: object


def evaluate(model: SheetModel, layout: Layout, t, y, args: StageArgs, vb=None, forces=None):
    """Rates and the quantities derived on the way (:class:`Observed`; shared by the vector field
    and frames).
    ``vb``: the ball's velocity where the caller has solved for it at this state (the load
    step's converged increment), so the root search of a free ball with held friction is not
    run again (None: solved here). ``forces``: ``(g, load, projections)``, the energy gradient
    (n, 2), the held bodies' load and their projections of the nodes (None without held
    bodies) at this state where the caller has them (:func:`dynslip.physics.terms.forces`,
    :func:`dynslip.physics.terms.held_projections`; None: computed here)."""
    model = place_state(model, layout, y, args, t)
    rho, z, zb, _ = layout.unpack(y)
    internal = layout.internal(y)
    k = model.kinematics(rho, z, zb, args.friction, args.eps, args.drag, internal,
                         grads=None if forces is None else _grads(forces))
    g_rho, g_z, _ = k.grads
    eta_a = k.eta_a
    u = k.u
    # the clamp (its force on the sheet, conditions.clamp_force) and the ball
    # (conditions.ball_velocity): the modes of the stage (dynslip.physics.conditions)
    edge = Edge(jnp.stack([g_rho[-1], g_z[-1]]), rho[-1], eta_a[-1])
    carried = conditions.edge_carried(args)
    f_clamp = conditions.clamp_force(args, t, edge.g)
    crho, cz = f_clamp
    # the sheet's pull on the ball: the held bodies carry the rest, by pressure (held_load) and
    # by friction (its axial part, which depends on the ball's velocity: bodies.held); a body
    # that moves with the ball (the bottle) is displaced by zb, and its load goes to the lab
    c_pen = cz - (model.held_load(rho, z, zb) if forces is None else forces[1])
    hdelta = layout.held_internal(y)
    hf = model.held_friction(rho, z, -jnp.stack([g_rho, g_z]), args.drag, args.eps, zb, hdelta,
                             None if forces is None else forces[2])
    if hf is None or vb is None:
        vb = conditions.ball_velocity(args, t, zb, c_pen, None if hf is None else lambda: hf)
    c_ball = c_pen
    if hf is not None:
        c_ball = c_pen + hf.axial(vb)
        u = u + hf.force(vb).T / eta_a
    em = conditions.edge_motion(model, args, edge, f_clamp, vb)
    u = u.at[:, -1].set(em.u)
    v = u + jnp.stack([jnp.zeros_like(rho), jnp.full_like(z, vb)])
    moving = (jnp.arange(layout.n) < layout.n - 1) | ~carried  # nodes with constitutive drag
    d_drag = (
        jnp.sum(jnp.where(moving, eta_a * (u[0] ** 2 + u[1] ** 2), 0.0)) + args.ball_drag * vb**2
    )
    last = jnp.arange(layout.n) == layout.n - 1
    d_fric = jnp.sum(jnp.where(last, 0.0, (k.ft - k.slip) * k.slip / eta_a))
    if hf is not None:
        d_fric = d_fric + jnp.sum(hf.dissipation(vb))  # friction on the held bodies
    # the edge's slip along the wall relative to the clamp: its drag (and its friction, below);
    # the clamp's work is at the clamp's velocity
    d_drag = d_drag + eta_a[-1] * em.slip**2
    # the reactions net of drag: the sheet's drag is relative to the ball, so its reaction
    # (eta A u on every node with constitutive drag) acts on the ball (in c_ball), as it acts on
    # a clamp that carries the edge; a stop rule reads them, so a slack span's drag does not end
    # a stage
    drag_z = jnp.sum(jnp.where(moving, eta_a * u[1], 0.0))
    f_hold, f_static = conditions.ball_reaction(args, t, zb, vb, c_ball, drag_z)
    cz_static = jnp.where(carried, cz - drag_z, cz)
    d_fric = d_fric + em.friction
    w_clamp = cz * (v[1, -1] - em.slip) + crho * v[0, -1]
    w_ball = (f_hold + args.weight) * vb
    v_free = None
    w_bodies = jnp.zeros(())
    if layout.n_free:
        v_free, f_free, eta_free = free_body_rates(model, rho, z, zb, hf, vb)
        d_drag = d_drag + jnp.sum(eta_free * v_free**2)
        w_bodies = w_bodies + jnp.sum(f_free * v_free)  # the applied forces' work
    parts = [w_clamp, w_ball, d_drag, d_fric]
    if layout.n_acc > N_ACC:
        parts.append(w_bodies + bodies_power(model, rho, z, zb, vb, hf))
    dacc = jnp.stack(parts)
    dint = None
    if internal is not None:
        dint = jnp.where(last, 0.0, args.friction.internal_rate(k.slip / eta_a, k.normal, internal))
    dheld = None if hdelta is None else hf.internal_rates(vb)  # held slip distances' rates
    dy = layout.pack(v[0], v[1], vb, dacc, dint, v_free, dheld)
    return dy, Observed(
        clamp_force=cz, clamp_force_rho=crho, ball_reaction=f_hold, ball_reaction_static=f_static,
        clamp_force_static=cz_static, ball_v=vb, rho=rho, z=z, zb=zb, kin=k, held_frame=hf,
    )


def _grads(forces):
    """:meth:`SheetModel.kinematics`' ``grads`` from ``(g, load, projections)`` (its dE/dzb
    unread here)."""
    g = forces[0]
    return g[:, 0], g[:, 1], None


def place_state(model: SheetModel, layout: Layout, y, args: StageArgs, t):
    """``model`` with its stage-moved bodies placed at time ``t`` and its free bodies at the
    heights the state ``y`` holds (:func:`dynslip.physics.bodies.held.place_bodies`)."""
    model = place_bodies(model, args.body_z0, args.body_v, args.t0, t)
    return place_free(model, layout.free(y))


def body_load(model: SheetModel, entry, rho, z, zb):
    r"""$L_k = \sum_i \partial E_{h,k}/\partial z_i$: the axial force of the sheet's pressure on
    one held body ``entry`` (G h0 R, + up)."""
    one = eqx.tree_at(lambda m: m.bodies, model, (entry,))
    return jnp.sum(jax.grad(one.held_penalty_energy, argnums=1)(rho, z, zb))


def free_body_rates(model: SheetModel, rho, z, zb, hf=None, vb=None):
    r"""The free bodies' velocities $v_k = (L_k - A_k + F_k)/\eta_k$ (R/s: the sheet's
    pressure $L_k$, the reaction of its friction $A_k = \sum_i f_{ik} t_{k,z}$ and the applied
    force $F_k$ against the body's drag $\eta_k$), with $F_k$ and $\eta_k$: three (K,) arrays
    in held order. ``hf`` (the held friction's frame, :class:`~dynslip.physics.bodies.held.
    HeldFrame`) and ``vb`` (the ball's velocity) give $A_k$ of a frictional free body, its
    slip relative to the body at the body's own ``velocity`` (the model's entry: the load
    step's increment; it is the unknown $v_k$ itself, so $v_k$ is exact where the increment is
    converged); without them (or frictionless) $A_k = 0$."""
    entries = held_entries(model.bodies)
    fric = [k for k, e in enumerate(entries) if e.friction is not None]
    axial = hf.axial_per_body(vb) if hf is not None and fric else None
    v, f, eta = [], [], []
    for k, e in enumerate(entries):
        if e.free:
            load = body_load(model, e, rho, z, zb)
            if e.friction is not None and axial is not None:
                load = load - axial[fric.index(k)]
            v.append((load + e.force) / e.drag)
            f.append(e.force)
            eta.append(e.drag)
    return jnp.stack(v), jnp.stack(f), jnp.stack(eta)


def place_free_moving(model: SheetModel, layout: Layout, t, y, args: StageArgs,
                      iterations: int = 60):
    r"""``model`` with its free bodies at the state's heights, moving at their own velocities
    $v_k = (L_k - A_k(v_k) + F_k)/\eta_k$ (a frame's record: the slip relative to a frictional
    free body, and its friction, read its velocity; load stepping solves it as the increment's
    unknown). The root is found by bisection, one body per component ($v - v_{free}(v)$ is
    increasing: a faster body drags the sheet more), in $v^0_k \pm (B/\eta_k + 1)$ ($v^0$
    frictionless, $B = \sum\mu N|t_z|$ the largest axial friction); exact for bodies that do
    not share a node. Unchanged without a frictional free body."""
    entries = held_entries(model.bodies)
    if not any(e.free and e.friction is not None for e in entries):
        return model
    zk = layout.free(y)
    placed = place_state(model, layout, y, args, t)

    def v_free(v):
        return layout.free(evaluate(place_free(placed, zk, v), layout, t, y, args)[0])

    rho, z, zb, _ = layout.unpack(y)
    v0, _, eta = free_body_rates(placed, rho, z, zb)
    g_rho, g_z, _ = placed.kinematics(rho, z, zb, args.friction, args.eps, args.drag,
                                      layout.internal(y)).grads
    hf = placed.held_friction(rho, z, -jnp.stack([g_rho, g_z]), args.drag, args.eps, zb,
                              layout.held_internal(y))
    half = hf.bound() / eta + 1.0

    def step(_, bracket):
        lo, hi = bracket
        mid = 0.5 * (lo + hi)
        up = mid - v_free(mid) > 0.0  # past the root: it lies below
        return jnp.where(up, lo, mid), jnp.where(up, mid, hi)

    lo, hi = jax.lax.fori_loop(0, iterations, step, (v0 - half, v0 + half))
    return place_free(placed, zk, 0.5 * (lo + hi))


def bodies_power(model: SheetModel, rho, z, zb, vb, hf):
    r"""The power of the moving held bodies (moved by the stages, or carried with the ball) on
    the sheet (G h0 R^2 / s):
    $\sum_k v_k\,(-\sum_i \partial E_{h,k}/\partial z_i + \sum_i f_{ik} t_{k,z})$, the axial
    force each exerts on the sheet (penalty and friction) times its velocity. (Friction's part
    relative to the body is the dissipation; this is the rest of $f\cdot\dot x$.)"""
    entries = held_entries(model.bodies)
    fric = [k for k, e in enumerate(entries) if e.friction is not None]
    axial = hf.axial_per_body(vb) if hf is not None else None
    total = jnp.zeros(())
    for k, e in enumerate(entries):
        if not (e.stage or e.moves_with_ball):
            continue
        push = -body_load(model, e, rho, z, zb)
        if e.friction is not None:
            assert axial is not None  # a body with friction: hf is a frame
            push = push + axial[fric.index(k)]
        total = total + e.speed(vb) * push
    return total


def vector_field(model: SheetModel, layout: Layout):
    def vf(t, y, args):
        return evaluate(model, layout, t, y, args)[0]

    return vf



def heal(model: SheetModel, layout: Layout, y, args: StageArgs, heal_rate, t=None, vb=None,
         forces=None):
    """The friction laws' reset of the per-node state where a node is stuck again: slip rate
    $|S|/(\\eta A) \\le$ ``heal_rate`` (R/s) or out of contact
    (:func:`dynslip.physics.friction.heals`, the one criterion of both solvers): the ball's
    law's, and each held body's with memory, its slip relative to that body
    (:meth:`dynslip.physics.bodies.held.HeldFrame.reset`). Unchanged for memoryless laws.
    ``t``: the time of ``y``, where the stage-moved bodies are placed (None: ``model`` is
    placed already). ``vb``: the ball's velocity, which the slip relative to a held body reads
    (None: :func:`evaluate`'s at ``t``, or at the stage's start when ``t`` is None);
    ``forces`` as :func:`evaluate`'s."""
    if layout.n_int == 0 and layout.n_held_int == 0:
        return y
    if layout.n_held_int and vb is None:
        vb = evaluate(model, layout, args.t0 if t is None else t, y, args)[1].ball_v
    if t is not None:
        model = place_state(model, layout, y, args, t)
    rho, z, zb, _ = layout.unpack(y)
    internal = layout.internal(y)
    k = model.kinematics(rho, z, zb, args.friction, args.eps, args.drag, internal,
                         grads=None if forces is None else _grads(forces))
    if layout.n_int:
        y = layout.with_internal(
            y, args.friction.reset(internal, k.slip / k.eta_a, k.normal, heal_rate)
        )
    if layout.n_held_int:
        g_rho, g_z, _ = k.grads
        hf = model.held_friction(rho, z, -jnp.stack([g_rho, g_z]), args.drag, args.eps, zb,
                                 layout.held_internal(y), None if forces is None else forces[2])
        y = layout.with_held_internal(y, hf.reset(vb, heal_rate))
    return y
