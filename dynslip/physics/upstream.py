"""Local fixes of bugs in the pinned libraries, each naming its upstream fix.

These subclasses are the one allowed exception to "no overriding of concrete methods"
(equinox's abstract/final pattern): each overrides exactly what upstream changed and is
to be deleted once a release with the fix is pinned in ``constraints.txt``.
"""

from __future__ import annotations

import diffrax
import jax.numpy as jnp
import optimistix as optx
from diffrax._root_finder._verychord import _converged, _diverged, _small

__all__ = ["VeryChord"]


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
