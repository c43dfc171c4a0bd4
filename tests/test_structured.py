"""The whole sheet's structured Newton linear algebra against jax.jacfwd and the dense path."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import SCENARIOS
from dynslip.app.forming import build_core
from dynslip.physics.driver.member import stage_args
from dynslip.physics.driver.simulate import segment_step
from dynslip.physics.field import Layout, vector_field
from dynslip.physics.frames import initial_state
from dynslip.physics.solver.linalg import extract_blocks, sheet_structure, to_dense
from dynslip.physics.solver.methods import TimeStepping
from dynslip.physics.solver.newton import zero_rate
from dynslip.schema.base import load

N = 12


def _setup(name="method2_let_go"):
    sc = load(SCENARIOS / f"{name}.yaml", [f"numerics.nodes={N}"])
    model, protocol, kw = build_core(sc)
    layout = Layout(N, kw["friction"].n_internal())  # slip weakening, one state per node
    per_stage = [
        stage_args(
            st,
            0.0,
            float(protocol.ball_z0),
            0.0,
            0.0,
            kw["friction"],
            kw["eps"],
            kw["drag"],
            kw["ball_drag"],
            kw["weight"],
        )
        for st in protocol.stages
    ]
    y0 = initial_state(model, layout, kw["pre_stretch"], kw["z_sheet"], protocol.ball_z0)
    return model, layout, per_stage, y0, kw["settings"]


MODEL, LAYOUT, STAGE_ARGS, Y0, SETTINGS = _setup()
ARGS = STAGE_ARGS[0]  # push-down: ball held
# the pinned-rim tube path's raise: the ball force-controlled (on the support), the clamp moved
FREE_ARGS = _setup("method2_pinned")[2][2]


def _solve(linear_solver, y, t1):
    newton = SETTINGS.solver  # the scenario's load stepping: its step limit and healing
    kvaerno5 = TimeStepping(max_steps=newton.max_steps, linear_solver=linear_solver,
                            heal_rate=newton.heal_rate)
    step = segment_step(kvaerno5)  # the run's step: the segment and its frame
    f = jnp.asarray
    out, _ = step(MODEL, LAYOUT, y, f(0.0), f(t1), f(1e-3), ARGS, f(1e-7), f(1e-9),
                  zero_rate(N), f(SETTINGS.contact_threshold))
    assert bool(out.ok)
    return out.y, int(out.steps)


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["held", "force_controlled"])
def test_structured_jacobian_equals_jacfwd_on_sampled_states(stage):
    """The declared pattern holds the whole Jacobian, with the ball held and with it
    force-controlled (every node then moves with a ball whose velocity depends on the
    clamp's force: the edge nodes are in the border)."""
    s = sheet_structure(LAYOUT)
    vf = vector_field(MODEL, LAYOUT)
    args = ARGS if stage == "held" else FREE_ARGS
    assert int(args.clamp_mode) == 0 and (int(args.ball_mode) == 0) == (stage == "held")

    @jax.jit
    def both(y):
        f = lambda yy: vf(1.0, yy, args)  # noqa: E731
        mv = lambda v: jax.jvp(f, (y,), (v,))[1]  # noqa: E731
        mvT = lambda w: jax.vjp(f, y)[1](w)[0]  # noqa: E731
        return jax.jacfwd(f)(y), to_dense(*extract_blocks(mv, mvT, s), s)

    y_mid, _ = _solve("structured", Y0, 6.0)  # sheet pressed onto the ball, slipping
    rng = np.random.default_rng(3)
    for y in (Y0, y_mid, y_mid + 1e-4 * rng.normal(size=y_mid.shape)):
        jac, dense = both(y)
        scale = float(jnp.max(jnp.abs(jac)))
        assert float(jnp.max(jnp.abs(dense - jac))) <= 1e-10 * scale


@pytest.mark.slow
def test_structured_segment_matches_dense_within_tolerance():
    ys, _ = _solve("structured", Y0, 4.0)
    yd, _ = _solve("dense", Y0, 4.0)
    n_pos = 2 * N - 1
    # positions agree to well within the solver tolerance (rtol 1e-7, lengths ~ 1)
    assert float(jnp.max(jnp.abs(ys[:n_pos] - yd[:n_pos]))) < 1e-6
