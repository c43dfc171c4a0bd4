r"""Quasi-static load stepping: implicit Euler increments controlled by Newton's iteration count.

The forming path is slow loading of a rate-independent problem (stages of 10-90 s
against a drag time $\tau = \eta R^2/(G h_0) = 0.1$ s). Implicit Euler on the overdamped law
of :func:`dynslip.physics.simulate.evaluate`,

$$x_1 = x_0 + \Delta t\, f(t_1, x_1),\qquad
  \eta A\,(\dot x - \dot z_b e_z) = F_n n + S(F_t, \mu N)\, t ,$$

is, for $\Delta t \gg \tau$, the trial-state and return-map update of incremental frictional
contact (FEBio's, Abaqus/Standard's): the increment's slip is $\Delta t\,S/(\eta A)$ with
$S$ evaluated at the end of the increment. JAX's derivative of the soft threshold is a
generalised Jacobian, so Newton on it is a semi-smooth Newton method. The whole state is
advanced by the same rule, so

- the slip distance gains the increment's slip, $\delta_1 = \delta_0 + |\Delta u_t|$ (its
  rate $|u_t|$ at $x_1$ times $\Delta t$); the friction law's reset (healing) is applied
  by the driver at the end of each save segment, as for the time-stepped solvers;
- the energy accumulators gain the increment's backward-Euler work and dissipation
  ($C(x_1)\cdot\Delta x_c$, $\eta A|\Delta x|^2/\Delta t$, $(F_t - S)\,\Delta u_t$ at $x_1$);
  the energy balance's residual is then implicit Euler's own numerical dissipation,
  $\tfrac12 \Delta x^T H \Delta x$ per increment, first order in $\Delta t$ overall
  (``tests/test_loadstep.py`` measures it).

**Solver.** :class:`dynslip.physics.upstream.ImplicitEuler` (diffrax's, with the fix of
diffrax PR #753: a failed Newton solve rejects the increment) with an
:class:`optimistix.Newton` root finder (``rtol``, ``atol`` of the scenario's numerics,
max norm, Cauchy termination: the last Newton correction below
``atol + rtol |dx|`` *and* the residual below ``atol``) whose linear solver is
:class:`dynslip.physics.linalg.BorderedBlockTridiagonal`. Newton starts from
ImplicitEuler's predictor $\Delta t\,f(t_0, x_0)$, which after an accepted implicit
Euler increment is exactly the previous increment rescaled to the new $\Delta t$
($f(t_0, x_0) = (x_0 - x_{-1})/\Delta t_{-1}$); at a stage start or after a reset of the
slip distance it is the rate of the restarted state.

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

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import optimistix as optx

from dynslip.physics.linalg import BorderedBlockTridiagonal
from dynslip.physics.protocols import BALL_HOLD, CLAMP_POSITION
from dynslip.physics.upstream import ImplicitEuler

__all__ = ["load_step_solver", "segment_solver", "GROW", "CUT", "GROW_BELOW", "SHRINK_ABOVE"]

GROW = 1.5  # increment growth after a fast Newton solve
GROW_BELOW = 4  # ... of at most this many iterations
SHRINK = 0.7  # increment shrink after a slow Newton solve
SHRINK_ABOVE = 8  # ... of at least this many iterations
CUT = 0.5  # cut-back after a failed Newton solve
MIN_FRACTION = 1e-10  # smallest increment, as a fraction of the segment


def load_step_solver(layout, rtol, atol, linear_solver: str = "structured", max_iter: int = 10):
    """The implicit Euler solver of a load increment: Newton with explicit tolerances."""
    from dynslip.physics.simulate import sheet_structure

    lin = (BorderedBlockTridiagonal(sheet_structure(layout)) if linear_solver == "structured"
           else lx.AutoLinearSolver(well_posed=None))
    newton = optx.Newton(rtol=rtol, atol=atol, norm=optx.max_norm, linear_solver=lin, cauchy_termination=True)
    return ImplicitEuler(root_finder=newton, root_find_max_steps=max_iter)


def increment_cap(args, max_increment, max_increment_free):
    """$\\Delta t_{max}$ (s): ``max_increment`` drag times in driven stages, ``max_increment_free``
    where the ball or the clamp moves under a force (``args.drag`` is the drag time)."""
    free = (args.ball_mode != BALL_HOLD) | (args.clamp_mode != CLAMP_POSITION)
    return args.drag * jnp.where(free, max_increment_free, max_increment)


def run_segment(model, layout, y0, t0, t1, dt0, args, rtol, atol, *, max_steps: int, max_iter: int,
                max_increment: float, max_increment_free: float, linear_solver: str = "structured"):
    """Load increments from ``t0`` to ``t1``: ``(y1, ok, steps, accepted, rejected, newton_iterations)``.

    Not jitted (see :func:`segment_solver`). ``dt0`` is the first increment tried.
    """
    from dynslip.physics.simulate import vector_field

    term = diffrax.ODETerm(vector_field(model, layout))
    solver = load_step_solver(layout, rtol, atol, linear_solver, max_iter)
    cap = increment_cap(args, max_increment, max_increment_free)
    dt_min = MIN_FRACTION * (t1 - t0)
    zero = jnp.array(0, dtype=jnp.int32)

    def cond(c):
        t, _, dt, nacc, nrej, _ = c
        return (t < t1) & (nacc + nrej < max_steps) & (dt >= dt_min)

    def body(c):
        t, y, dt, nacc, nrej, nit = c
        left = t1 - t
        last = left <= 1.25 * dt  # stretch the increment to the save time rather than leave a sliver
        h = jnp.where(last, left, dt)
        t_next = jnp.where(last, t1, t + h)
        y1, y_err, _, iters, result = solver.step(term, t, t_next, y, args, solver.init(term, t, t_next, y, args),
                                                  False)
        ok = diffrax.is_okay(result) & jnp.all(jnp.isfinite(y_err)) & jnp.all(jnp.isfinite(y1))
        factor = jnp.where(iters <= GROW_BELOW, GROW, jnp.where(iters >= SHRINK_ABOVE, SHRINK, 1.0))
        # an increment clipped to the save time does not shrink the next one
        dt_ok = jnp.minimum(jnp.maximum(dt, h) * factor, cap)
        dt_new = jnp.where(ok, dt_ok, CUT * h)
        return (jnp.where(ok, t_next, t), jnp.where(ok, y1, y), dt_new, nacc + ok, nrej + (~ok), nit + iters)

    init = (t0, y0, jnp.minimum(dt0, cap), zero, zero, zero)
    t, y, _, nacc, nrej, nit = jax.lax.while_loop(cond, body, init)
    ok = (t >= t1) & jnp.all(jnp.isfinite(y))
    return y, ok, nacc + nrej, nacc, nrej, nit


_CACHE: dict = {}


def segment_solver(settings):
    """Jitted ``solve(model, layout, y0, t0, t1, dt0, args, rtol, atol)`` for ``numerics.solver:
    load_step``, the signature of :func:`dynslip.physics.simulate.segment_solver` with the
    Newton iteration count as a sixth output; one per setting of the increment control."""
    key = (settings.max_steps, settings.linear_solver, settings.newton_max_iter, settings.max_increment,
           settings.max_increment_free)
    if key in _CACHE:
        return _CACHE[key]

    @eqx.filter_jit
    def solve(model, layout, y0, t0, t1, dt0, args, rtol, atol):
        return run_segment(model, layout, y0, t0, t1, dt0, args, rtol, atol, max_steps=settings.max_steps,
                           max_iter=settings.newton_max_iter, max_increment=settings.max_increment,
                           max_increment_free=settings.max_increment_free, linear_solver=settings.linear_solver)

    _CACHE[key] = solve
    return solve
