"""Newton on the motion alone (:mod:`dynslip.physics.solver.newton`): its blocks against jax.jacfwd,
cyclic reduction against a dense solve, and its increment against the full-state one."""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics import terms as nt
from dynslip.physics.field import Layout, vector_field
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.protocols import (
    BALL_FORCE,
    BALL_HOLD,
    CLAMP_FORCE,
    CLAMP_POSITION,
)
from dynslip.physics.solver import increment as ni
from dynslip.physics.solver import newton as nw
from dynslip.physics.solver import newton_matrix as nm
from dynslip.physics.solver.linalg import bordered_solve, cyclic_reduction
from dynslip.physics.solver.loadstep import load_step_solver
from helpers import dense_blocks, dense_tridiagonal, draped, increment_args, small_model
from numerics import named_solver

N = 9
MODEL = small_model(N)
WEAK = SlipWeakening(mu_s=1.5, mu_k=1.2, d_c=0.02, eps=1e-3)
MODES = [(BALL_HOLD, CLAMP_POSITION), (BALL_FORCE, CLAMP_POSITION), (BALL_FORCE, CLAMP_FORCE)]


def _state(layout, seed=0):
    """A sheet draped over the ball (nodes near its surface, some pressed in), perturbed."""
    rng = np.random.default_rng(seed)
    rho, z = draped(MODEL.mesh.rbar, rng)
    internal = jnp.asarray(rng.uniform(0.0, 0.03, N)) if layout.n_int else None
    return layout.pack(jnp.asarray(rho), jnp.asarray(z), jnp.asarray(0.0), jnp.zeros(4), internal)


def _increment(layout, y0, args, h):
    rho, z, zb0, _ = layout.unpack(y0)
    q0 = jnp.stack([rho, z - zb0], axis=1)
    return ni.Increment(
        q0=q0, zb0=zb0, delta0=layout.internal(y0), t1=jnp.asarray(h), h=jnp.asarray(h), args=args
    )


_dense = dense_blocks  # the name the other test modules import


def residual_jacobian(inc, q, zb):
    """``jax.jacfwd`` of the increment's residual (WEAK friction) at ``(q, zb)``, flattened (the
    q rows, then zb), and the flattened residual there."""

    def flat(x):
        rq, rz = ni.residual(MODEL, WEAK, inc, x[:-1].reshape(N, 2), x[-1])
        return jnp.concatenate([rq.reshape(-1), rz[None]])

    x = jnp.concatenate([q.reshape(-1), zb[None]])
    return np.asarray(jax.jacfwd(flat)(x)), np.asarray(flat(x))


@pytest.mark.slow
@pytest.mark.parametrize("modes", MODES)
def test_blocks_from_element_derivatives_equal_jacfwd(modes):
    """The assembled Newton matrix (element Hessians, node Jacobians, the slip update's
    tangent, the ball's border) is the derivative of the increment's residual, to rounding."""
    layout = Layout(N, 1)
    y0 = _state(layout)
    inc = _increment(layout, y0, increment_args(WEAK, *modes), 0.5)
    rng = np.random.default_rng(1)
    q = inc.q0 + 1e-3 * rng.normal(size=inc.q0.shape)
    q = q.at[0, 0].set(0.0)
    zb = inc.zb0 + 1e-3
    jac, r = residual_jacobian(inc, q, zb)
    blocks = nm.newton_blocks(MODEL, WEAK, inc, q, zb)
    np.testing.assert_allclose(_dense(*blocks), jac, rtol=0, atol=1e-12 * np.abs(jac).max())
    # and the bordered solve of those blocks is the dense solve, by either elimination
    for method in ("cyclic", "thomas"):
        dq, dz = bordered_solve(
            *blocks, jnp.asarray(r[:-1]).reshape(N, 2), jnp.asarray(r[-1]), method
        )
        np.testing.assert_allclose(
            np.concatenate([np.asarray(dq).reshape(-1), [float(dz)]]),
            np.linalg.solve(jac, r),
            rtol=1e-9,
            atol=1e-12,
        )


@pytest.mark.parametrize("n", [1, 2, 3, 8, 13, 64])
def test_cyclic_reduction_equals_dense_solve(n):
    rng = np.random.default_rng(n)
    low, up = (jnp.asarray(rng.normal(size=(n, 3, 3))) for _ in range(2))
    dia = jnp.asarray(rng.normal(size=(n, 3, 3))) + 8 * jnp.eye(3)
    f = jnp.asarray(rng.normal(size=(n, 3, 2)))
    a = dense_tridiagonal(np.asarray(low), np.asarray(dia), np.asarray(up))
    x = cyclic_reduction(low, dia, up, f)
    np.testing.assert_allclose(
        np.asarray(x).reshape(-1, 2),
        np.linalg.solve(a, np.asarray(f).reshape(-1, 2)),
        rtol=1e-10,
        atol=1e-13,
    )


@pytest.mark.slow
@pytest.mark.parametrize("modes", MODES)
def test_motion_newton_increment_is_the_full_state_increment(modes):
    """With a memoryless law both solve the same implicit Euler equations in different
    variables (positions relative to the ball; accumulators by the rectangle rule at x1):
    the increments agree to Newton's tolerance, accumulators included."""
    coulomb = Coulomb(mu=1.2, eps=1e-3)
    layout = Layout(N, 0)
    y0 = _state(layout, seed=2)
    args = increment_args(coulomb, *modes)
    h = jnp.asarray(0.05)
    full = load_step_solver(layout, 1e-12, 1e-12, max_iter=40)
    term = diffrax.ODETerm(vector_field(MODEL, layout))
    y_full, _, _, _, res = full.step(
        term, jnp.asarray(0.0), h, y0, args, full.init(term, 0.0, h, y0, args), False
    )
    assert diffrax.is_okay(res)
    solver = nw.MotionNewton(max_iter=40)
    zero = (jnp.zeros((N, 2)), jnp.zeros(()))
    y_mot, ok, _it, *_ = solver.increment(
        MODEL, layout, jnp.asarray(0.0), h, y0, args, zero, 1e-12, 1e-12
    )
    assert bool(ok)
    np.testing.assert_allclose(np.asarray(y_mot), np.asarray(y_full), rtol=0, atol=1e-9)


def test_slip_update_adds_the_increments_slip_and_sticks_below_the_threshold():
    """One node: delta1 = delta0 + dt |S(F_t, mu(delta0) N)|/(eta A); nothing added while
    |F_t| <= mu(delta0) N - eps or out of contact."""
    fr = SlipWeakening(mu_s=1.5, mu_k=1.0, d_c=0.02, eps=0.0)
    d0, c = jnp.asarray(0.01), jnp.asarray(2.0)
    mu0 = float(fr.coefficient(d0))
    _, d1 = ni.slip_update(fr, jnp.asarray(2.0), jnp.asarray(1.0), 0.0, d0, c)
    assert float(d1) == pytest.approx(0.01 + 2.0 * (2.0 - mu0))
    _, d1 = ni.slip_update(fr, jnp.asarray(0.99 * mu0), jnp.asarray(1.0), 0.0, d0, c)
    assert float(d1) == 0.01
    _, d1 = ni.slip_update(fr, jnp.asarray(2.0), jnp.asarray(0.0), 0.0, d0, c)
    assert float(d1) == 0.01


@pytest.mark.slow
def test_slip_weakening_push_down_agrees_with_the_full_state_newton():
    """The return map takes mu at the increment's start (first order in time, as implicit Euler);
    on a short push-down with slip weakening the end state stays within 1e-6 R of the full-state
    Newton's, whose slip distance is implicit, and the slip distances agree where they are large."""
    import math

    from dynslip.physics.driver.simulate import simulate
    from dynslip.physics.solver.loadstep import FullStateLoadStep
    from dynslip.physics.solver.methods import Settings
    from test_forming import MODEL as SHEET
    from test_forming import PRE, Z0, push_protocol

    def run(solver):
        fr = SlipWeakening(mu_s=1.0, mu_k=0.8, d_c=0.02, eps=1e-3)
        return simulate(
            SHEET,
            push_protocol(),
            friction=fr,
            eps=1e-3,
            drag=0.1,
            ball_drag=0.4 * math.pi,
            pre_stretch=PRE,
            z_sheet=Z0,
            settings=Settings(solver=solver, save_interval=1.0),
        )

    a, b = run(named_solver()), run(FullStateLoadStep())
    assert a.failed is None and b.failed is None
    fa, fb = a.frames[-1], b.frames[-1]
    d = max(np.max(np.abs(fa["rho"] - fb["rho"])), np.max(np.abs(fa["z"] - fb["z"])))
    print(f"motion-only vs full-state Newton, slip weakening: max |dx| = {d:.2e} R")
    assert d < 1e-6
    assert np.max(fb["slip_distance"]) > 0.02  # the push-down weakens the contact


@pytest.mark.parametrize("law", ["slip_weakening", "coulomb"])
def test_node_force_jacobian_equals_jacfwd(law):
    """The closed form of d u_i / d g_i (the normal part, and the slip law's slope on the
    tangent) is jacfwd of the node's rate in its force: at the pole, on stuck and slipping
    nodes."""
    friction = WEAK if law == "slip_weakening" else Coulomb(mu=0.3, eps=1e-3)
    layout = Layout(N, friction.n_internal())
    y0 = _state(layout)
    inc = _increment(layout, y0, increment_args(friction, BALL_HOLD, CLAMP_POSITION), 0.5)
    g = 50.0 * nt.forces(MODEL, inc.q0, inc.zb0)[0]  # the forces scaled: some nodes slip
    idx = jnp.arange(N)
    d0 = inc.delta0 if inc.delta0 is not None else jnp.zeros(N)
    mem = inc.delta0 is not None

    def rate(i, qi, gi, di):
        return ni.node_rate(MODEL, friction, inc, i, qi, gi, di if mem else None)[0]

    ref = jax.vmap(jax.jacfwd(rate, argnums=2))(idx, inc.q0, g, d0)
    got = jax.vmap(
        lambda i, qi, gi, di: ni.node_force_jacobian(
            MODEL, friction, inc, i, qi, gi, di if mem else None)
    )(idx, inc.q0, g, d0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * float(jnp.abs(ref).max()))
    # both slopes of the law occur (stuck: the tangent's part 0; slipping: 1)
    fn, ft, n, t, normal, area = jax.vmap(lambda i, qi, gi: ni.node_contact(MODEL, i, qi, gi))(
        idx, inc.q0, g)
    def slip(f, nn, di, a):
        return friction.slip_force(f, nn, di if mem else None, eps=inc.args.eps * a, area=a)

    s = jax.vmap(slip)(ft, normal, d0, area)
    assert np.any(np.asarray(s)[1:] == 0.0) and np.any(np.asarray(s)[1:] != 0.0)


@pytest.mark.parametrize("modes", MODES[:2])
def test_residual_floor_accepts_the_motion_resolved_to_the_step_tolerance(modes):
    """With ``atol`` at the residual's rounding floor (1e-13 here) Newton's corrections fall far
    below the step tolerance while the residual stays above ``atol``: without the residual floor
    the increment fails after ``max_iter`` iterations; with it (10 atol after two full
    corrections below the step tolerance, the default) it is accepted, at the motion plain Newton
    reaches with an ``atol`` above the floor."""
    layout = Layout(N, 1)
    y0 = _state(layout, seed=3)
    args = increment_args(WEAK, *modes)
    zero = (jnp.zeros((N, 2)), jnp.zeros(()))

    def solve(atol, **kw):
        solver = nw.MotionNewton(max_iter=60, **kw)
        y1, ok, it, *_ = solver.increment(
            MODEL, layout, jnp.asarray(0.0), jnp.asarray(0.05), y0, args, zero, 1e-9, atol
        )
        return np.asarray(y1), bool(ok), int(it)

    _, ok_off, it_off = solve(1e-13, floor_factor=0.0)
    y_on, ok_on, it_on = solve(1e-13, floor_factor=10.0, floor_count=2)
    y_ref, ok_ref, _ = solve(1e-11, floor_factor=0.0)
    print(f"atol 1e-13: floor off {ok_off} ({it_off} its), on {ok_on} ({it_on} its)")
    assert not ok_off and it_off == 60
    assert ok_on and it_on < 60
    assert ok_ref
    np.testing.assert_allclose(y_on, y_ref, rtol=0, atol=1e-9)


def test_the_increment_controller_remembers_a_failed_size():
    """After a failure at h = 1 the retry is at 0.5; with the memory (``fail_cap`` 0.8,
    ``fail_relax`` 1.05) the quick increments that follow grow no further than 0.8 times the
    failed size, a bound relaxed by 1.05 per accepted increment, where without it they grow by
    1.5 past the failed size at the third; a failure always halves, the memory never shrinks an
    increment below the last one taken."""
    cap = jnp.asarray(100.0)
    inf = jnp.asarray(jnp.inf)
    sizes = {}
    for fail_cap in (0.0, 0.8):
        s = nw.MotionNewton(fail_cap=fail_cap, fail_relax=1.05)
        dt, h_fail = s.next_size(1.0, 1.0, 20, jnp.asarray(False), jnp.asarray(False), inf, cap)
        assert float(dt) == 0.5
        out, was_cut = [float(dt)], jnp.asarray(True)
        for _ in range(6):
            dt, h_fail = s.next_size(dt, dt, 3, jnp.asarray(True), was_cut, h_fail, cap)
            out.append(float(dt))
            was_cut = jnp.asarray(False)
        sizes[fail_cap] = out
    print("sizes after a failure at 1 (no memory, memory):", sizes)
    np.testing.assert_allclose(sizes[0.0], [0.5, 0.5, 0.75, 1.125, 1.6875, 2.53125, 3.796875])
    bound = [0.8 * 1.05**k for k in range(2, 6)]
    np.testing.assert_allclose(sizes[0.8], [0.5, 0.5, 0.75, *bound], rtol=1e-12)
    # the memory never takes an increment below the last one taken, nor undoes a shrink
    s = nw.MotionNewton(fail_cap=0.8, fail_relax=1.05)
    dt, _ = s.next_size(0.3, 0.3, 3, jnp.asarray(True), jnp.asarray(False), jnp.asarray(0.2), cap)
    assert float(dt) == pytest.approx(0.3)
    dt, _ = s.next_size(0.3, 0.3, 19, jnp.asarray(True), jnp.asarray(False), inf, cap)
    assert float(dt) == pytest.approx(0.21)


@pytest.mark.slow  # a whole segment's compile (11 s); every run's initial frame goes through it
def test_a_zero_length_segment_keeps_the_state_and_gives_its_forces():
    """A zero-length segment (a run's initial frame) takes one zero-length increment: the state,
    the predictor's rate and the counts stay as they were, and the output carries the energy
    gradient, held load and ball velocity at the start, which the frame takes instead of
    evaluating them again (``SegmentOutput.forces``, ``.ball_velocity``): equal to
    ``terms.forces`` there and to the vector field's ball velocity."""
    from dynslip.physics.field import evaluate

    layout = Layout(N, 1)
    y0 = _state(layout, seed=4)
    args = increment_args(WEAK, BALL_FORCE, CLAMP_POSITION)
    rate = (jnp.full((N, 2), 0.3), jnp.asarray(0.2))
    t = jnp.asarray(0.7)
    segment = eqx.filter_jit(nw.MotionNewton().segment)
    out = segment(MODEL, layout, y0, t, t, jnp.asarray(0.05), args, 1e-9, 1e-9, rate)
    assert bool(out.ok) and int(out.steps) == 0 and int(out.newton_iterations) == 0
    np.testing.assert_array_equal(np.asarray(out.y), np.asarray(y0))
    for got, was in zip(out.rate, rate, strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(was))
    rho, z, zb, _ = layout.unpack(y0)
    g, load = nt.forces(MODEL, jnp.stack([rho, z - zb], axis=1), zb)
    scale = float(jnp.max(jnp.abs(g)))
    np.testing.assert_allclose(np.asarray(out.forces[0]), np.asarray(g), rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(float(out.forces[1]), float(load), rtol=0, atol=1e-12 * scale)
    vb = evaluate(MODEL, layout, t, y0, args)[1].ball_v
    assert abs(float(vb)) > 0
    np.testing.assert_allclose(float(out.ball_velocity), float(vb), rtol=1e-10)
