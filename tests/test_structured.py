"""The whole sheet's structured Newton linear algebra against jax.jacfwd and the dense path."""

import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.linalg import extract_blocks, to_dense
from dynslip.app.forming import build_core
from dynslip.schema.base import load
from dynslip.physics.simulate import Layout, _stage_args, initial_state, segment_solver, sheet_structure, vector_field

from conftest import SCENARIOS

N = 12


def _setup():
    sc = load(SCENARIOS / "method2_let_go.yaml", [f"numerics.nodes={N}"])
    model, protocol, kw = build_core(sc)
    layout = Layout(N, kw["friction"].n_internal())  # slip weakening, one state per node; stage 0 holds the ball (a force-controlled ball couples every node to the clamp: not this pattern)
    stage = protocol.stages[0]
    args = _stage_args(stage, 0.0, float(protocol.ball_z0), 0.0, 0.0, kw["friction"], kw["eps"], kw["drag"],
                       kw["ball_drag"], kw["weight"])
    y0 = initial_state(model, layout, kw["pre_stretch"], kw["z_sheet"], protocol.ball_z0)
    return model, layout, args, y0, kw["settings"]


MODEL, LAYOUT, ARGS, Y0, SETTINGS = _setup()


def _solve(linear_solver, y, t1):
    import dataclasses

    settings = dataclasses.replace(SETTINGS, linear_solver=linear_solver)
    solve = segment_solver(settings)
    f = jnp.asarray
    y1, ok, steps, _, _ = solve(MODEL, LAYOUT, y, f(0.0), f(t1), f(1e-3), ARGS, f(1e-7), f(1e-9))
    assert bool(ok)
    return y1, int(steps)


def test_structured_jacobian_equals_jacfwd_on_sampled_states():
    s = sheet_structure(LAYOUT)
    vf = vector_field(MODEL, LAYOUT)

    @jax.jit
    def both(y):
        f = lambda yy: vf(1.0, yy, ARGS)  # noqa: E731
        mv = lambda v: jax.jvp(f, (y,), (v,))[1]  # noqa: E731
        mvT = lambda w: jax.vjp(f, y)[1](w)[0]  # noqa: E731
        return jax.jacfwd(f)(y), to_dense(*extract_blocks(mv, mvT, s), s)

    y_mid, _ = _solve("structured", Y0, 6.0)  # sheet pressed onto the ball, slipping
    rng = np.random.default_rng(3)
    for y in (Y0, y_mid, y_mid + 1e-4 * rng.normal(size=y_mid.shape)):
        jac, dense = both(y)
        scale = float(jnp.max(jnp.abs(jac)))
        assert float(jnp.max(jnp.abs(dense - jac))) <= 1e-10 * scale


def test_structured_segment_matches_dense_within_tolerance():
    ys, _ = _solve("structured", Y0, 4.0)
    yd, _ = _solve("dense", Y0, 4.0)
    n_pos = 2 * N - 1
    # positions agree to well within the solver tolerance (rtol 1e-7, lengths ~ 1)
    assert float(jnp.max(jnp.abs(ys[:n_pos] - yd[:n_pos]))) < 1e-6
