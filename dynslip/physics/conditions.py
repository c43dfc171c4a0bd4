r"""The stage's boundary conditions, each written once: the clamp's modes (:class:`Pinned`,
:class:`ForceClamp`, :class:`Band`) and the ball's (:class:`HeldBall`, :class:`ForcedBall`).

Both solvers read them through the functions at the end (:func:`clamp_force`,
:func:`edge_motion`, :func:`edge_carried`, :func:`ball_load`, :func:`ball_velocity`,
:func:`ball_compliance`, :func:`ball_reaction`): the vector field
(:func:`dynslip.physics.field.evaluate`) and the load increment's residual
(:mod:`dynslip.physics.solver.increment`) call the same ones, and the Newton matrix
(:mod:`dynslip.physics.solver.newton_matrix`) differentiates them.

The mode is a traced integer of :class:`~dynslip.physics.field.StageArgs` (``clamp_mode``,
``ball_mode``; the constants of :mod:`dynslip.physics.protocols`), so that one compiled step
serves every stage: :func:`dispatch` computes every mode's closed form and selects the
stage's (``jnp.where``), and runs only the stage's mode (``jax.lax.switch``) where a branch is
costly (a free ball's root search against held friction). Why not ``switch`` throughout: XLA
contracts products and sums into fused multiply-adds as each compiled branch allows, so the
rates would move in the last bit against the select, and a stick-slip path amplifies that (to
3e-9 on ``scenarios/method1.yaml``); the select keeps the runs equal to 1e-14. A new mode is a
subclass of :class:`AbstractClamp` or :class:`AbstractBall` entered in :data:`CLAMPS` or
:data:`BALLS` under the next integer.

Signs and units (nondimensional, see :mod:`dynslip.physics.field`): forces in G h0 R, + up
(+z) and outward (+rho); ``g`` is the energy's gradient at the clamped edge, so the sheet pulls
the clamp with $-g$ and a clamp that holds the edge pushes back with $g$; velocities in R/s.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics.bodies.held import HeldFrame, free_ball_velocity
from dynslip.physics.protocols import (
    BALL_FORCE,
    BALL_HOLD,
    CLAMP_BAND,
    CLAMP_FORCE,
    CLAMP_POSITION,
)

__all__ = [
    "AbstractBall",
    "AbstractClamp",
    "BALLS",
    "Band",
    "CLAMPS",
    "Edge",
    "EdgeMotion",
    "ForceClamp",
    "ForcedBall",
    "HeldBall",
    "Pinned",
    "ball_compliance",
    "ball_load",
    "ball_reaction",
    "ball_velocity",
    "clamp_force",
    "dispatch",
    "edge_carried",
    "edge_motion",
]


class Edge(NamedTuple):
    """The clamped edge node as a clamp mode reads it."""

    g: jax.Array  # (2,) the energy's gradient there, dE/d(rho, z) (G h0 R)
    rho: jax.Array  # its radius (R)
    eta_a: jax.Array  # its drag coefficient eta A (G h0 R s / R)


class EdgeMotion(NamedTuple):
    """What a clamp mode makes of the edge."""

    u: jax.Array  # (2,) the edge's velocity relative to the ball (R/s)
    slip: jax.Array  # its slip along the wall relative to the clamp (R/s)
    friction: jax.Array  # the power the wall's friction dissipates in that slip (G h0 R / s)


# --------------------------------------------------------------------------- the clamp's modes


class AbstractClamp(eqx.Module):
    """A clamp mode: the clamp's force on the sheet and the edge's motion under it."""

    #: the edge moves with the clamp (no constitutive drag of its own): the clamp's force is
    #: whatever holds it there, and its reaction net of drag is read (``clamp_force_static``)
    carried: ClassVar[bool]
    #: the edge's motion is prescribed (load stepping bounds the increment by
    #: ``max_increment``); else it moves under a force (``max_increment_free``)
    driven: ClassVar[bool] = False

    @abc.abstractmethod
    def force(self, args, t, g) -> jax.Array:
        """The clamp's force on the sheet (2,), (rho, z), the energy's gradient at the edge
        ``g``."""

    @abc.abstractmethod
    def motion(self, model, args, edge: Edge, force, vb) -> EdgeMotion:
        """The edge's motion under the clamp's ``force`` (:meth:`force`'s), the ball at
        velocity ``vb``."""


class Pinned(AbstractClamp):
    r"""The edge moves with the clamp: $\dot x_c = (v_{\rho c}, v_{zc})$, held by the force
    $g$."""

    carried: ClassVar[bool] = True
    driven: ClassVar[bool] = True

    def force(self, args, t, g):
        return g

    def motion(self, model, args, edge, force, vb):
        zero = jnp.zeros_like(edge.rho)
        return EdgeMotion(jnp.stack([args.vrhoc, args.vzc - vb]), zero, zero)


class ForceClamp(AbstractClamp):
    r"""The clamp lets go gradually: a ramped force $F_c(t)$ on the edge, which moves like any
    free node, $\eta A\,u = F_c - g$ (drag relative to the ball)."""

    carried: ClassVar[bool] = False

    def force(self, args, t, g):
        return args.clamp_force(t)

    def motion(self, model, args, edge, force, vb):
        zero = jnp.zeros_like(edge.rho)
        return EdgeMotion((force - edge.g) / edge.eta_a, zero, zero)


class Band(AbstractClamp):
    r"""The band on the tube's wall: it carries the edge radially with the clamp and holds it
    along the wall while the sheet's pull there, $F_z = -g_z$, is below the grip; beyond it the
    edge slides at $w = S(F_z, g_b\,2\pi\rho_c)/(\eta A)$ relative to the clamp
    (:meth:`dynslip.physics.sheet.SheetModel.band_slip`), dissipating $(F_z - S)\,w$ in the
    wall's friction (and $\eta A w^2$ in drag). The band holds the edge with $g$."""

    carried: ClassVar[bool] = True

    def force(self, args, t, g):
        return g

    def motion(self, model, args, edge, force, vb):
        s = model.band_slip(-edge.g[1], edge.rho, args.eps)
        w = s / edge.eta_a
        return EdgeMotion(jnp.stack([args.vrhoc, args.vzc - vb + w]), w, (-edge.g[1] - s) * w)


# --------------------------------------------------------------------------- the ball's modes


class AbstractBall(eqx.Module):
    """A ball mode: the ball's velocity and the hold's reaction."""

    #: the ball's motion is prescribed (as :attr:`AbstractClamp.driven`)
    driven: ClassVar[bool] = False

    @abc.abstractmethod
    def velocity(self, args, t, zb, pull, frame: Callable[[], HeldFrame | None]) -> jax.Array:
        """The ball's velocity (R/s) under the sheet's ``pull`` on it by pressure, $C_z - L$
        (the clamp's axial force on the sheet less the held bodies' load); ``frame()``: the held
        bodies' friction frame (None: frictionless), called only where the velocity reads it."""

    @abc.abstractmethod
    def compliance(self, args, slope) -> jax.Array:
        r"""$\partial v_b/\partial A$: the velocity's change per force on the ball, with the held
        friction's axial force changing by ``slope`` per velocity (the Newton matrix's)."""

    @abc.abstractmethod
    def reaction(self, args, t, zb, vb, pull, drag_z) -> tuple[jax.Array, jax.Array]:
        """The hold's force on the ball (+ up) and the same net of drag (``drag_z``: the sheet's
        axial drag reaction, which acts on the ball), with ``pull`` the sheet's whole axial
        force on it (held friction's part included)."""


def ball_load(args, t, zb, pull):
    r"""$A_0 = F_h(t) + F_s(z_b) + (C_z - L) + F_g$: the force on a force-controlled ball besides
    its drag and the held bodies' friction (the ramped force, the support, the sheet's pull by
    pressure and the weight)."""
    return args.ball_force(t) + args.support_force(zb) + pull + args.weight


class HeldBall(AbstractBall):
    r"""The ball's centre moves at the prescribed $v_{zb}$; the hold carries
    $F = \eta_b v_b - C - F_g$."""

    driven: ClassVar[bool] = True

    def velocity(self, args, t, zb, pull, frame):
        return jnp.asarray(args.vzb, dtype=jnp.result_type(float))

    def compliance(self, args, slope):
        return jnp.zeros_like(slope)

    def reaction(self, args, t, zb, vb, pull, drag_z):
        f = args.ball_drag * vb - pull - args.weight
        # net of the ball's drag and the sheet's (a support at rest would carry this)
        return f, f - args.ball_drag * vb + drag_z


class ForcedBall(AbstractBall):
    r"""The ball is driven by the ramped force $F_h(t)$, resting on its support (a unilateral
    penalty, :meth:`~dynslip.physics.field.StageArgs.support_force`) under its weight: $\eta_b
    v_b = A_0 + \sum_i f_i\,t_{z}(v_b)$ (:func:`ball_load`; the held friction's axial part,
    solved by :func:`dynslip.physics.bodies.held.free_ball_velocity`). With $F_h = 0$, no
    support and no weight the ball is free."""

    def velocity(self, args, t, zb, pull, frame):
        return free_ball_velocity(frame(), ball_load(args, t, zb, pull), args.ball_drag)

    def compliance(self, args, slope):
        return 1.0 / (args.ball_drag - slope)

    def reaction(self, args, t, zb, vb, pull, drag_z):
        f = args.ball_force(t) + args.support_force(zb)
        return f, f


#: the clamp's modes by their integer (:mod:`dynslip.physics.protocols`)
CLAMPS: dict[int, AbstractClamp] = {
    CLAMP_POSITION: Pinned(),
    CLAMP_FORCE: ForceClamp(),
    CLAMP_BAND: Band(),
}
#: the ball's modes by their integer
BALLS: dict[int, AbstractBall] = {BALL_HOLD: HeldBall(), BALL_FORCE: ForcedBall()}


# --------------------------------------------------------------------------- dispatch


def dispatch(mode, modes: dict, fn: Callable, skip: bool = False):
    """``fn(modes[mode])`` for a traced integer ``mode`` (the modes' integers run 0, 1, ...),
    so one compile serves every mode: every mode's branch is computed and the mode's result
    selected (``jnp.where``), or with ``skip`` only the mode's branch runs
    (``jax.lax.switch``; under ``vmap`` with batched modes every branch runs again)."""
    order = [modes[i] for i in range(len(modes))]
    if skip:
        return jax.lax.switch(mode, [lambda m=m: fn(m) for m in order])
    outs = [fn(m) for m in order]

    def select(*xs):
        out = xs[-1]
        for i in range(len(xs) - 2, -1, -1):
            out = jnp.where(mode == i, xs[i], out)
        return out

    return jax.tree.map(select, *outs)


def clamp_force(args, t, g):
    """The clamp's force on the sheet (2,), (rho, z), in the stage's clamp mode, ``g`` the
    energy's gradient at the edge."""
    return dispatch(args.clamp_mode, CLAMPS, lambda m: m.force(args, t, g))


def edge_motion(model, args, edge: Edge, force, vb) -> EdgeMotion:
    """The edge's motion in the stage's clamp mode under the clamp's ``force``
    (:func:`clamp_force`'s), the ball at velocity ``vb``."""
    return dispatch(args.clamp_mode, CLAMPS, lambda m: m.motion(model, args, edge, force, vb))


def edge_carried(args):
    """Whether the stage's clamp carries the edge (:attr:`AbstractClamp.carried`)."""
    return dispatch(args.clamp_mode, CLAMPS, lambda m: jnp.asarray(m.carried))


def driven(args):
    """Whether the stage's clamp and ball are both driven (:attr:`AbstractClamp.driven`,
    :attr:`AbstractBall.driven`): nothing in it moves under a force."""
    return (dispatch(args.clamp_mode, CLAMPS, lambda m: jnp.asarray(m.driven))
            & dispatch(args.ball_mode, BALLS, lambda m: jnp.asarray(m.driven)))


def ball_velocity(args, t, zb, pull, frame: Callable[[], HeldFrame] | None = None):
    """The ball's velocity in the stage's ball mode (:meth:`AbstractBall.velocity`); ``frame``
    builds the held bodies' friction frame (None: no held body has friction). With one, only
    the stage's mode runs, so a held ball skips the frame and the root search."""
    if frame is None:
        return dispatch(args.ball_mode, BALLS,
                        lambda m: m.velocity(args, t, zb, pull, lambda: None))
    return dispatch(args.ball_mode, BALLS, lambda m: m.velocity(args, t, zb, pull, frame),
                    skip=True)


def ball_compliance(args, slope):
    """:meth:`AbstractBall.compliance` in the stage's ball mode."""
    return dispatch(args.ball_mode, BALLS, lambda m: m.compliance(args, slope))


def ball_reaction(args, t, zb, vb, pull, drag_z):
    """:meth:`AbstractBall.reaction` in the stage's ball mode."""
    return dispatch(args.ball_mode, BALLS,
                    lambda m: m.reaction(args, t, zb, vb, pull, drag_z))
