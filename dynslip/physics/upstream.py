"""Local fixes of bugs in the pinned libraries, each naming its upstream fix.

These subclasses are the one allowed exception to "no overriding of concrete methods"
(equinox's abstract/final pattern): each overrides exactly what upstream changed and is
to be deleted once a release with the fix is pinned in ``constraints.txt``.
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import optimistix as optx
from diffrax._root_finder._verychord import _converged, _diverged, _small
from diffrax._solver.implicit_euler import _implicit_relation
from equinox.internal import ω

__all__ = ["VeryChord", "ImplicitEuler"]


class VeryChord(diffrax.VeryChord):
    r"""``diffrax.VeryChord`` with the termination result of diffrax PR #754.

    diffrax 0.7.2 reports ``nonlinear_divergence`` for any iterate after the second that
    has not yet converged (``at_least_two & ~small & (diverged | ~converged)``), and
    optimistix 0.1.0 stops its loop on the first failure code (optimistix PR #230), so
    every implicit stage solve that needs a third chord iteration fails, the Runge-Kutta
    solver sets the error estimate to infinity and the controller rejects the step. The
    upstream condition reports failure only on divergence (``at_least_two & ~small &
    diverged``); a solve that simply has not converged keeps iterating.

    Drop this class (use ``diffrax.VeryChord``) once the pinned diffrax contains PR #754:
    ``tests/test_upstream.py::test_pinned_verychord_still_has_the_bug`` fails then.
    """

    def terminate(self, fn, y, args, options, state, tags):
        del fn, y, args, options, tags
        at_least_two = state.step >= 2
        rate = state.diffsize / state.diffsize_prev
        factor = state.diffsize * rate / (1 - rate)
        small = _small(state.diffsize)
        diverged = _diverged(rate)
        converged = _converged(factor, self.kappa)
        terminate = at_least_two & (small | diverged | converged)
        terminate_result = optx.RESULTS.where(
            at_least_two & jnp.invert(small) & diverged,
            optx.RESULTS.nonlinear_divergence,
            optx.RESULTS.successful,
        )
        linsolve_fail = state.result != optx.RESULTS.successful
        result = optx.RESULTS.where(linsolve_fail, state.result, terminate_result)
        return linsolve_fail | terminate, result


class ImplicitEuler(diffrax.ImplicitEuler):
    r"""``diffrax.ImplicitEuler`` whose failed root find rejects the step (diffrax issue #752, PR #753).

    diffrax 0.7.2's ``ImplicitEuler.step`` returns the root finder's result but a finite
    error estimate when the nonlinear solve fails (iteration limit, divergence, a failed
    linear solve); ``diffeqsolve`` hands the estimate to the step-size controller, which
    accepts the unconverged step, and the failure surfaces only as an error at the end.
    PR #753 (merged, unreleased) sets the error estimate to infinity on failure, as
    ``AbstractRungeKutta`` does, so that a controller rejects the step and retries a
    smaller one. This class is the 0.7.2 ``step`` with that line.

    One addition that is not upstream: the solver state (``None`` in diffrax) is the root
    finder's iteration count in the last step, which diffrax drops and an increment
    controller driven by Newton's iteration count needs
    (:mod:`dynslip.physics.loadstep`). When a diffrax release with PR #753 is pinned,
    ``tests/test_loadstep.py::test_pinned_implicit_euler_still_accepts_a_failed_solve``
    fails: keep only the iteration count here (or in ``loadstep``) then.
    """

    def init(self, terms, t0, t1, y0, args):
        del terms, t0, t1, y0, args
        return jnp.array(0, dtype=jnp.int32)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del made_jump, solver_state
        control = terms.contr(t0, t1)
        k0 = terms.vf_prod(t0, y0, args, control)
        rargs = (terms.vf_prod, t1, y0, args, control)
        nonlinear_sol = optx.root_find(_implicit_relation, self.root_finder, k0, rargs, throw=False,
                                       max_steps=self.root_find_max_steps)
        k1 = nonlinear_sol.value
        y1 = (y0**ω + k1**ω).ω
        result = diffrax.RESULTS.promote(nonlinear_sol.result)
        y_error = (0.5 * (k1**ω - k0**ω)).ω
        # diffrax PR #753: an unconverged implicit solve must not pass the controller
        y_error = jax.tree_util.tree_map(lambda e: jnp.where(diffrax.is_okay(result), e, jnp.inf), y_error)
        dense_info = dict(y0=y0, y1=y1)
        iterations = jnp.asarray(nonlinear_sol.stats["num_steps"], dtype=jnp.int32)
        return y1, y_error, dense_info, iterations, result
