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

__all__ = ["VeryChord", "ImplicitEuler", "reject_failed"]


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
    r"""``diffrax.ImplicitEuler`` whose failed root find rejects the step (diffrax issue #752,
    PR #753).

    diffrax 0.7.2's ``ImplicitEuler.step`` returns the root finder's failure code but a
    finite error estimate when the nonlinear solve fails (iteration limit, divergence, a
    failed linear solve); ``diffeqsolve`` hands the estimate to the step-size controller,
    which accepts the unconverged step, and the failure surfaces only at the end of the
    solve. PR #753 (merged, unreleased) sets the error estimate to infinity on failure, as
    ``AbstractRungeKutta`` does, so that the controller rejects the step and retries a
    smaller one. This class is diffrax's ``step`` followed by that line.

    Drop this class (use ``diffrax.ImplicitEuler``) once the pinned diffrax contains PR #753:
    ``tests/test_loadstep.py::test_pinned_implicit_euler_still_accepts_a_failed_solve``
    fails then.
    """

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        y1, y_error, dense_info, solver_state, result = super().step(
            terms, t0, t1, y0, args, solver_state, made_jump
        )
        y_error = reject_failed(y_error, result)
        return y1, y_error, dense_info, solver_state, result


def reject_failed(y_error, result):
    """diffrax PR #753: an infinite error estimate where the implicit solve failed."""
    return jax.tree_util.tree_map(lambda e: jnp.where(diffrax.is_okay(result), e, jnp.inf), y_error)
