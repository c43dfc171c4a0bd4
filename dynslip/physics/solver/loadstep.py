r"""Quasi-static load stepping on the whole state: implicit Euler increments controlled by Newton's
iteration count.

``numerics.solver: load_step`` runs :mod:`dynslip.physics.solver.newton` (Newton on the motion
alone). This module is Newton on the whole state: :class:`FullStateLoadStep`, a solver object
given as ``Settings.solver`` (no schema choice names it; the baseline of the tests and of
``benchmarks/speed.py``), and its increment loop over any diffrax term (:func:`increments`).

The forming path is slow loading of a rate-independent problem (stages of 10-90 s
against a drag time $\tau = \eta R^2/(G h_0) = 0.1$ s). Implicit Euler on the overdamped law
of :func:`dynslip.physics.field.evaluate`,

$$x_1 = x_0 + \Delta t\, f(t_1, x_1),\qquad
  \eta A\,(\dot x - \dot z_b e_z) = F_n n + S(F_t, \mu N)\, t ,$$

is, for $\Delta t \gg \tau$, the trial-state and return-map update of incremental frictional
contact (FEBio's, Abaqus/Standard's): the increment's slip is $\Delta t\,S/(\eta A)$ with
$S$ evaluated at the end of the increment. JAX's derivative of the soft threshold is a
generalised Jacobian, so Newton on it is a semi-smooth Newton method. The whole state is
advanced by the same rule, so

- the slip distance gains the increment's slip, $\delta_1 = \delta_0 + |\Delta u_t|$ (its
  rate $|u_t|$ at $x_1$ times $\Delta t$), and after every accepted increment the friction
  law's reset (healing) is applied where the increment's slip rate $|\Delta u_t|/\Delta t$ at
  $x_1$ is at most ``heal_rate`` (:func:`dynslip.physics.field.heal`: the criterion the
  time-stepped solvers apply at the end of each save segment, since a reset inside their
  steps would be a discontinuity in an adaptive error-controlled step);
- the energy accumulators gain the increment's backward-Euler work and dissipation
  ($C(x_1)\cdot\Delta x_c$, $\eta A|\Delta x|^2/\Delta t$, $(F_t - S)\,\Delta u_t$ at $x_1$);
  the energy balance's residual is then implicit Euler's own numerical dissipation,
  $\tfrac12 \Delta x^T H \Delta x$ per increment, first order in $\Delta t$ overall
  (``tests/test_loadstep.py`` measures it).

**Solver.** :class:`LoadStepEuler`, a :class:`dynslip.physics.solver.upstream.ImplicitEuler`
(diffrax's, with the fix of diffrax PR #753: a failed Newton solve rejects the increment) with an
:class:`optimistix.Newton` root finder (``rtol``, ``atol`` of the scenario's numerics,
max norm, Cauchy termination: the last Newton correction below
``atol + rtol |dx|`` *and* the residual below ``atol``) whose linear solver is
:class:`dynslip.physics.solver.linalg.BorderedBlockTridiagonal`, safeguarded by backtracking
(:class:`DampedNewton`, ``numerics.newton_backtrack`` halvings, default 4): a correction
that would raise the residual's max norm (over the motion, not the energy accumulators)
is halved. Without it Newton falls into stick/slip cycles at the contact edge, where the
soft threshold's band $e \approx \mu N$ is narrow (docs/speed.md, "Why the steps grew with
N"), and each cycle costs a rejected, halved increment. Newton starts from
the previous increment rescaled to the new $\Delta t$, and from zero at the start of a
save segment (see :class:`LoadStepEuler` for why not diffrax's $\Delta t\,f(t_0, x_0)$).

**Increments** (as Abaqus/FEBio): a ``lax.while_loop`` over ``solver.step``; a failed
Newton solve (iteration limit, divergence, non-finite state) rejects the increment and
halves it; an accepted one grows it by 1.5 when Newton needed at most
``GROW_BELOW`` iterations, shrinks it by 0.7 when it needed at least ``SHRINK_ABOVE``,
bounded by $\Delta t_{max}$; increments end exactly on the save times.

**Regularisation of Newton's matrix.** The matrix is $\Delta t\,\partial f/\partial x - I$;
scaled by $-\eta A_i/\Delta t$ per node it is $\eta A_i/\Delta t\, I + K_t$, with $K_t$ the
tangent stiffness (elastic and penalty Hessian through the friction law's generalised
derivative). A slack, free node has $K_t = 0$: only the drag term $\eta A/\Delta t$ keeps the
matrix regular, and it vanishes as $\Delta t/\tau \to \infty$. The regularisation is
therefore the drag itself at a *bounded* increment,
$\Delta t \le \Delta t_{max} = c\,\tau$, ``Settings.max_increment`` $= c$ in driven stages
(the clamp position and the ball held: the path is rate independent and only Newton's
convergence limits the increment), ``Settings.max_increment_free`` in stages where time
matters (the ball force-controlled or free, the clamp letting go: the ball and the
clamped edge move with drag, so the increment must resolve the drag time). With
$c = 20$ the smallest diagonal $\eta A/\Delta t$ is 5% of a unit membrane stiffness
$G h_0 A/R^2$: the matrix stays well conditioned in float64 and nothing else is added.
It changes no equilibrium: it is the overdamped law's own drag.

First order in time: load stepping is for slow paths (stages $\gg \tau$); Kvaerno5 stays
the reference (``numerics.solver: kvaerno5``).
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx
from diffrax._solver.implicit_euler import _implicit_relation
from equinox.internal import ω

from dynslip.physics.field import heal, vector_field
from dynslip.physics.solver.linalg import BorderedBlockTridiagonal, sheet_structure
from dynslip.physics.solver.newton import (
    AbstractSegmentSolver,
    SegmentOutput,
    increment_cap,
    segment_output,
    zero_rate,
)
from dynslip.physics.solver.upstream import ImplicitEuler, reject_failed

__all__ = [
    "LoadStepEuler",
    "IncrementLoop",
    "IncrementState",
    "load_step_solver",
    "increments",
    "FullStateLoadStep",
    "GROW",
    "CUT",
    "GROW_BELOW",
    "SHRINK_ABOVE",
]

GROW = 1.5  # increment growth after a fast Newton solve
GROW_BELOW = 12  # ... of at most this many iterations
SHRINK = 0.7  # increment shrink after a slow Newton solve
SHRINK_ABOVE = 18  # ... of at least this many iterations
CUT = 0.5  # cut-back after a failed Newton solve
MIN_FRACTION = 1e-10  # smallest increment, as a fraction of the segment


class IncrementState(eqx.Module):
    """Solver state of :class:`LoadStepEuler`: the last accepted increment per unit time
    (zero at a restart) and the Newton iterations of the last step."""

    rate: jax.Array
    iterations: jax.Array


class LoadStepEuler(ImplicitEuler):
    r"""Implicit Euler (:class:`dynslip.physics.solver.upstream.ImplicitEuler`, diffrax PR #753's
    rejection of a failed solve) with Newton started from the previous increment.

    $x_1 = x_0 + \Delta t f(t_1, x_1)$ is solved for the increment $k = x_1 - x_0$ by the root
    finder, starting from $k^{(0)} = \Delta t\,r$, $r$ the last accepted increment per unit
    time (zero after a restart: a save segment's or a stage's start, where the slip
    distance is reset or the loads change). diffrax's own predictor $\Delta t f(t_0, x_0)$
    equals this after an accepted increment with unchanged loads, but not after a restart,
    where it can throw a slack free edge far enough that Newton cycles between its slack
    and taut branches; zero is then the safe start. The solver state carries the root
    finder's iteration count (diffrax drops it), which the increment control reads. The
    error estimate $(k - k^{(0)})/2$ (the predictor's error) is infinite where Newton failed.
    """

    def init(self, terms, t0, t1, y0, args):
        del terms, t0, t1, args
        return IncrementState(rate=jnp.zeros_like(y0), iterations=jnp.array(0, dtype=jnp.int32))

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del made_jump
        control = terms.contr(t0, t1)
        k0 = solver_state.rate * (t1 - t0)
        sol = optx.root_find(
            _implicit_relation,
            self.root_finder,
            k0,
            (terms.vf_prod, t1, y0, args, control),
            throw=False,
            max_steps=self.root_find_max_steps,
        )
        k1 = sol.value
        y1 = (y0**ω + k1**ω).ω
        result = diffrax.RESULTS.promote(sol.result)
        y_error = reject_failed((0.5 * (k1**ω - k0**ω)).ω, result)
        state = IncrementState(
            rate=k1 / (t1 - t0), iterations=jnp.asarray(sol.stats["num_steps"], jnp.int32)
        )
        return y1, y_error, dict(y0=y0, y1=y1), state, result


class DampedNewton(optx.Newton):
    r"""optimistix's Newton with a backtracking safeguard on the residual.

    The Newton correction $d$ is taken in full when the residual's max norm over the
    ``weights``-selected components does not grow, $\|w F(y - d)\| \le \|w F(y)\|$, or is
    already below ``atol``; otherwise it is halved, at most ``max_backtrack`` times. The
    halvings are not Newton iterations (``num_steps`` counts corrections only).
    """

    weights: jax.Array | None = None
    max_backtrack: int = 4

    def step(self, fn, y, args, options, state, tags):
        new_y, new_state, aux = super().step(fn, y, args, options, state, tags)
        w = 1.0 if self.weights is None else self.weights
        merit = lambda v: self.norm(w * fn(v, args)[0])  # noqa: E731
        f0 = self.norm(w * new_state.f) if self.cauchy_termination else merit(y)
        diff = new_state.diff

        def cond(c):
            alpha, f1, i = c
            # written so a non-finite residual (a stretch past the material's range) backtracks too
            return ~((f1 <= f0) | (f1 <= self.atol)) & (i < self.max_backtrack)

        def body(c):
            alpha, _, i = c
            alpha = 0.5 * alpha
            return alpha, merit(y - alpha * diff), i + 1

        alpha, _, _ = jax.lax.while_loop(cond, body, (jnp.array(1.0), merit(new_y), jnp.array(0)))
        diff = alpha * diff
        scale = self.atol + self.rtol * jnp.abs(y - diff)
        diffsize = self.norm(diff / scale)
        new_state = eqx.tree_at(
            lambda s: (s.diff, s.diffsize),
            new_state,
            (diff, jnp.asarray(diffsize, new_state.diffsize.dtype)),
        )
        return y - diff, new_state, aux


def load_step_solver(
    layout, rtol, atol, linear_solver: str = "structured", max_iter: int = 20, backtrack: int = 4
):
    """The implicit Euler solver of a load increment: Newton with explicit tolerances, and
    :class:`DampedNewton`'s backtracking (at most ``backtrack`` halvings; 0: plain Newton)."""
    lin = (
        BorderedBlockTridiagonal(sheet_structure(layout))
        if linear_solver == "structured"
        else lx.AutoLinearSolver(well_posed=None)
    )
    newton: optx.Newton
    if backtrack:
        # the energy accumulators do not feed back into the motion: left out of the merit
        w = jnp.ones(layout.size).at[layout.accumulators].set(0.0)
        newton = DampedNewton(
            rtol=rtol,
            atol=atol,
            norm=optx.max_norm,
            linear_solver=lin,
            cauchy_termination=True,
            weights=w,
            max_backtrack=backtrack,
        )
    else:
        newton = optx.Newton(
            rtol=rtol, atol=atol, norm=optx.max_norm, linear_solver=lin, cauchy_termination=True
        )
    return LoadStepEuler(root_finder=newton, root_find_max_steps=max_iter)


class FullStateLoadStep(AbstractSegmentSolver):
    """The segment solver of this module (a ``Settings.solver`` object): load increments of the
    sheet by :class:`LoadStepEuler` (Newton on the whole state) at most ``max_steps`` per
    segment, at most ``newton_max_iter`` Newton corrections each, ``newton_backtrack`` halvings
    (:class:`DampedNewton`), ``linear_solver`` ``"structured"`` or ``"dense"``, increments
    bounded by :func:`increment_cap`, the friction law's healing (``heal_rate``) after every
    increment. ``max_increment`` and ``max_increment_free`` may be traced (a test sweeps
    them)."""

    max_steps: int = eqx.field(static=True, default=20000)
    newton_max_iter: int = eqx.field(static=True, default=20)
    newton_backtrack: int = eqx.field(static=True, default=4)
    linear_solver: str = eqx.field(static=True, default="structured")
    heal_rate: float = eqx.field(static=True, default=0.0)
    max_increment: float = 20.0
    max_increment_free: float = 5.0

    #: the run's ``method`` in its statistics, and the schema's ``numerics.solver``
    name: ClassVar[str] = "load_step_full"
    counts_newton: ClassVar[bool] = True

    def segment(self, model, layout, y0, t0, t1, dt0, args, rtol, atol, rate=None) -> SegmentOutput:
        """Increments from ``t0`` to ``t1`` (``dt0`` the first tried), ending exactly on ``t1``;
        Newton starts from zero at the segment's start (``rate`` is not used: its output is
        zero)."""
        del rate
        term = diffrax.ODETerm(vector_field(model, layout))
        solver = load_step_solver(
            layout, rtol, atol, self.linear_solver, self.newton_max_iter, self.newton_backtrack
        )
        cap = increment_cap(args, self.max_increment, self.max_increment_free)
        out = increments(
            term,
            solver,
            y0,
            t0,
            t1,
            dt0,
            args,
            cap,
            self.max_steps,
            after=lambda t, y: heal(model, layout, y, args, self.heal_rate, t),
        )
        return eqx.tree_at(lambda o: o.rate, out, zero_rate(layout.n))


class IncrementLoop(NamedTuple):
    """The carry of :func:`increments`: the time ``t`` and state ``y`` reached, the solver's
    state (:class:`IncrementState`), the next increment's size ``dt``, whether the last
    increment failed (``was_cut``), and the counts (``accepted``, ``rejected``, Newton
    ``iterations``)."""

    t: jax.Array
    y: jax.Array
    state: IncrementState
    dt: jax.Array
    was_cut: jax.Array
    accepted: jax.Array
    rejected: jax.Array
    iterations: jax.Array


def increments(
    term, solver, y0, t0, t1, dt0, args, cap, max_steps: int, after=None
) -> SegmentOutput:
    """The increment loop over ``solver.step`` (a :class:`LoadStepEuler`) for any diffrax term:
    a :class:`dynslip.physics.solver.newton.SegmentOutput` (its ``rate``: the last accepted
    increment
    per unit time of the whole state); increments at most ``cap``.
    ``after(t, y)`` (e.g. the friction law's healing) maps each increment's end state."""
    dt_min = MIN_FRACTION * (t1 - t0)
    zero = jnp.array(0, dtype=jnp.int32)

    def cond(c: IncrementLoop):
        return (c.t < t1) & (c.accepted + c.rejected < max_steps) & (c.dt >= dt_min)

    def body(c: IncrementLoop) -> IncrementLoop:
        left = t1 - c.t
        # stretch the increment to the save time rather than leave a sliver
        last = left <= 1.25 * c.dt
        h = jnp.where(last, left, c.dt)
        t_next = jnp.where(last, t1, c.t + h)
        y1, y_err, _, new_state, result = solver.step(term, c.t, t_next, c.y, args, c.state,
                                                      False)
        if after is not None:
            y1 = after(t_next, y1)
        iters = new_state.iterations
        ok = diffrax.is_okay(result) & jnp.all(jnp.isfinite(y_err)) & jnp.all(jnp.isfinite(y1))
        factor = jnp.where(iters <= GROW_BELOW, GROW, jnp.where(iters >= SHRINK_ABOVE, SHRINK, 1.0))
        # no growth right after a cut-back
        factor = jnp.where(c.was_cut, jnp.minimum(factor, 1.0), factor)
        # an increment clipped to the save time does not shrink the next one
        dt_ok = jnp.minimum(jnp.maximum(c.dt, h) * factor, cap)
        dt_new = jnp.where(ok, dt_ok, CUT * h)
        state = jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), new_state, c.state)
        return IncrementLoop(
            t=jnp.where(ok, t_next, c.t),
            y=jnp.where(ok, y1, c.y),
            state=state,
            dt=dt_new,
            was_cut=~ok,
            accepted=c.accepted + ok,
            rejected=c.rejected + (~ok),
            iterations=c.iterations + iters,
        )

    init = IncrementLoop(
        t=t0,
        y=y0,
        state=solver.init(term, t0, t1, y0, args),
        dt=jnp.minimum(dt0, cap),
        was_cut=jnp.array(False),
        accepted=zero,
        rejected=zero,
        iterations=zero,
    )
    end = jax.lax.while_loop(cond, body, init)
    return segment_output(end, t1, end.state.rate)
