"""The local fix of diffrax's VeryChord termination (diffrax PR #754, optimistix PR #230).

The first test fails on the unpatched class; the second records that the pinned
diffrax still has the bug (when it fails, upstream has released the fix: drop
:class:`dynslip.physics.solver.upstream.VeryChord`); the third shows the effect on a stiff ODE
against
scipy's Radau.
"""

import diffrax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
from scipy.integrate import solve_ivp

from dynslip.physics.solver.upstream import VeryChord


def _kepler(y, args):
    # Kepler's equation y - e sin y = M with e = -0.6: the chord iteration from y = 0 keeps
    # the Jacobian 1 + 0.6 cos 0 = 1.6, so it converges linearly (rate ~0.25) and needs
    # many more than two iterations.
    return y + 0.6 * jnp.sin(y) - 2.0


def _solve(cls):
    return optx.root_find(_kepler, cls(rtol=1e-10, atol=1e-10), jnp.array(0.0), throw=False)


def test_stage_solve_needing_three_iterations_is_accepted():
    sol = _solve(VeryChord)
    assert sol.result == optx.RESULTS.successful
    assert int(sol.stats["num_steps"]) >= 3
    assert abs(float(_kepler(sol.value, None))) < 1e-9


def test_pinned_verychord_still_has_the_bug():
    """diffrax 0.7.2 fails a chord solve still converging after two iterations."""
    sol = _solve(diffrax.VeryChord)
    assert sol.result == optx.RESULTS.nonlinear_divergence
    assert int(sol.stats["num_steps"]) == 2


def _robertson(t, y, args):
    y1, y2, y3 = y
    return jnp.stack(
        [-0.04 * y1 + 1e4 * y2 * y3, 0.04 * y1 - 1e4 * y2 * y3 - 3e7 * y2**2, 3e7 * y2**2]
    )


@pytest.mark.parametrize("t1", [40.0])
def test_kvaerno5_rejects_fewer_steps_and_matches_radau(t1):
    y0 = jnp.array([1.0, 0.0, 0.0])
    out = {}
    for name, chord in (("fixed", VeryChord), ("pinned", diffrax.VeryChord)):
        solver = diffrax.Kvaerno5(root_finder=diffrax.with_stepsize_controller_tols(chord)())
        sol = diffrax.diffeqsolve(diffrax.ODETerm(_robertson), solver, 0.0, t1, 1e-6, y0,
                                  stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-10),
                                  max_steps=100000)
        out[name] = (
            np.asarray(sol.ys[-1]),
            int(sol.stats["num_rejected_steps"]),
            int(sol.stats["num_steps"]),
        )
    ref = solve_ivp(lambda t, y: np.asarray(_robertson(t, jnp.asarray(y), None)), (0.0, t1),
                    np.asarray(y0), method="Radau", rtol=1e-10, atol=1e-14).y[:, -1]
    for name in out:
        np.testing.assert_allclose(out[name][0], ref, rtol=1e-4, atol=1e-9)
    assert out["fixed"][1] < out["pinned"][1], out
