"""The friction law's weighted form, in which Newton on the motion iterates
(:func:`dynslip.physics.friction.weighted_form`,
:func:`dynslip.physics.solver.increment.weighted_slip`,
``MotionNewton.weight``): the same curve, so the same roots, and the derivatives Newton reads."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics import terms as nt
from dynslip.physics.field import Layout
from dynslip.physics.friction import soft_threshold, weighted_form
from dynslip.physics.solver import increment as ni
from dynslip.physics.solver import newton as nw
from dynslip.physics.solver import newton_matrix as nm
from helpers import dense_blocks, increment_args, small_model
from test_newton import MODEL, MODES, WEAK, N, _increment, _state, residual_jacobian

C, EPS = 2.0, 0.3  # threshold and smoothing: e = 0.261, a wide band to sample


@pytest.mark.parametrize("eps", [EPS, 0.0])
@pytest.mark.parametrize("gamma", [1.0, 7.0, 1e3])
def test_weighted_form_reads_the_laws_curve(gamma, eps):
    """On the law's curve, $v = S_\\epsilon(f)$ and $y = f + (\\gamma - 1) v$, the weighted form
    gives $\\gamma v$: at every stuck, band and slipping force, either sign. So a node's weighted
    row has exactly the law's roots. It is nondecreasing in y, and the law itself at
    $\\gamma = 1$."""
    f = jnp.linspace(-3 * C, 3 * C, 4001)
    v = soft_threshold(f, C, eps)
    y = f + (gamma - 1.0) * v
    got = weighted_form(y, C, eps, gamma)
    np.testing.assert_allclose(got, gamma * v, rtol=1e-12, atol=1e-12 * gamma)
    e = eps * C / (C + eps)
    if eps:  # the band is sampled: where the two forms would differ without the inversion
        in_band = (jnp.abs(f) > C - e) & (jnp.abs(f) < C + e)
        assert int(jnp.sum(in_band)) > 100
    ys = jnp.linspace(-3 * C * gamma, 3 * C * gamma, 4001)
    assert np.all(np.diff(np.asarray(weighted_form(ys, C, eps, gamma))) >= 0)
    if gamma == 1.0:
        np.testing.assert_array_equal(weighted_form(f, C, eps, 1.0), soft_threshold(f, C, eps))


def test_weighted_form_is_continuously_differentiable_across_the_band():
    """The slope Newton reads ($C^1$ as the law): equal to within the sampling on both sides of
    the band's two edges ($|y| = c - e$, $c + \\gamma e$), 0 below and 1 above it."""
    gamma = 50.0
    e = EPS * C / (C + EPS)
    slope = jax.vmap(jax.grad(lambda y: weighted_form(y, C, EPS, gamma)))
    for edge, (lo, hi) in ((C - e, (0.0, 0.0)), (C + gamma * e, (1.0, 1.0))):
        d = 1e-7
        below, above = slope(jnp.asarray([edge - d, edge + d]))
        assert float(below) == pytest.approx(lo, abs=1e-4)
        assert float(above) == pytest.approx(hi, abs=1e-4)


def _solve(layout, y0, args, **kw):
    solver = nw.MotionNewton(max_iter=60, **kw)
    zero = (jnp.zeros((N, 2)), jnp.zeros(()))
    y1, ok, it, *_ = solver.increment(
        MODEL, layout, jnp.asarray(0.0), jnp.asarray(0.05), y0, args, zero, 1e-12, 1e-12
    )
    return np.asarray(y1), bool(ok), int(it)


@pytest.mark.parametrize("modes", MODES[:2])
def test_weighted_newton_ends_on_the_laws_own_root(modes):
    """Newton on the weighted form (c = 1e3, the default) ends where Newton on the law's own
    form does, to the tolerance, slip distances included, along another path (other
    iterations: 11 against 12 here; the let-go path's counts are in docs/speed.md)."""
    layout = Layout(N, 1)
    y0 = _state(layout, seed=3)
    args = increment_args(WEAK, *modes)
    y_law, ok, it_law = _solve(layout, y0, args)
    assert ok
    y_w, ok_w, it_w = _solve(layout, y0, args, weight=1e3)
    assert ok_w
    np.testing.assert_allclose(y_w, y_law, rtol=0, atol=1e-9)
    print("iterations (law, c = 1e3):", it_law, it_w)
    assert it_w != it_law


def _weighted(inc, c, seed=5):
    """``inc`` with the weight ``c``, and relative positions off its start: nodes 1-5 pressed
    5e-4 R into the ball (in contact, with a friction threshold), every node moved by 1e-5 R (a
    nonzero tangential displacement, so the trial is shifted)."""
    rng = np.random.default_rng(seed)
    q = np.asarray(inc.q0).copy()
    r = np.linalg.norm(q, axis=1)
    q[1:6] *= (0.9995 / r[1:6])[:, None]
    q = jnp.asarray(q + 1e-5 * rng.normal(size=q.shape)).at[0, 0].set(0.0)
    return eqx.tree_at(lambda i: i.weight, inc, c, is_leaf=lambda x: x is None), q


def test_weighted_node_force_jacobian_equals_jacfwd():
    """The closed form of d u_i / d g_i in the weighted form (the curve's slope at the shifted
    trial) is jacfwd of the node's rate in its force, on stuck and slipping nodes (the band's
    slope: :func:`test_weighted_form_is_continuously_differentiable_across_the_band`)."""
    layout = Layout(N, 1)
    y0 = _state(layout)
    inc, q = _weighted(_increment(layout, y0, increment_args(WEAK, *MODES[0]), 0.5),
                       1e3)
    g = 5.0 * nt.forces(MODEL, q, inc.zb0)[0]
    idx = jnp.arange(N)
    # both branches occur: nodes stuck and slipping against the ball
    _, ft, _, _, normal, area = jax.vmap(lambda i, qi, gi: ni.node_contact(MODEL, i, qi, gi))(
        idx, q, g)
    thr = jax.vmap(WEAK.threshold)(normal, inc.delta0, area)
    assert np.any((thr > 0) & (jnp.abs(ft) < 0.9 * thr)) and np.any(jnp.abs(ft) > 1.1 * thr)

    def rate(i, qi, gi, di):
        return ni.node_rate(MODEL, WEAK, inc, i, qi, gi, di)[0]

    ref = jax.vmap(jax.jacfwd(rate, argnums=2))(idx, q, g, inc.delta0)
    got = jax.vmap(lambda i, qi, gi, di: ni.node_force_jacobian(MODEL, WEAK, inc, i, qi, gi, di))(
        idx, q, g, inc.delta0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * float(jnp.abs(ref).max()))
    # the shift is live: the weighted rates differ from the law's at these positions (on the
    # stuck nodes, whose weighted row reads their displacement)
    law = jax.vmap(lambda i, qi, gi, di: ni.node_rate(MODEL, WEAK, eqx.tree_at(
        lambda x: x.weight, inc, None), i, qi, gi, di)[0])(idx, q, g, inc.delta0)
    assert float(jnp.max(jnp.abs(jax.vmap(rate)(idx, q, g, inc.delta0) - law))) > 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("modes", MODES)
def test_weighted_blocks_equal_jacfwd(modes):
    """The assembled Newton matrix of the weighted residual (the shift's own-position
    derivative included) is jacfwd of that residual, to rounding."""
    layout = Layout(N, 1)
    y0 = _state(layout)
    inc, q = _weighted(_increment(layout, y0, increment_args(WEAK, *modes), 0.5), 1e3)
    zb = inc.zb0 + 1e-3
    jac, _ = residual_jacobian(inc, q, zb)
    blocks = nm.newton_blocks(MODEL, WEAK, inc, q, zb)
    np.testing.assert_allclose(dense_blocks(*blocks), jac, rtol=0,
                               atol=1e-12 * np.abs(jac).max())


def _pinched():
    """test_held_friction_jacobian's sheet with one frictional ring pressed onto node 1 from
    above: node 1 is pinched between it and the ball (both normal forces positive); the held
    ball's increment data, weighted (c = 1e3) or not."""
    from dynslip.physics.bodies import Torus
    from dynslip.physics.bodies.held import Held
    from dynslip.physics.friction import Coulomb
    from test_held_friction_jacobian import NS, ZB, _setup

    args, inc, q, zb = _setup(MODES[0][0], memory=False)
    x1 = np.asarray(q[1]) + np.array([0.0, ZB])
    ring = Torus(ring_radius=float(x1[0]), minor_radius=0.3, centre_z=float(x1[1]) + 0.2995)
    coulomb = Coulomb(mu=jnp.asarray(0.7), eps=jnp.asarray(1e-3))
    model = small_model(NS, bodies=(Held(ring, coulomb),))
    return model, args, inc, q, zb


def test_a_node_pinched_by_a_held_body_keeps_the_laws_form():
    """Where a frictional held body's friction acts on a node that touches the ball too, the
    node's tangential rate is not the ball law's alone, so the weighted row would have other
    roots: that node keeps the law's own form (``alone`` False), the others are weighted. The
    weighted rates equal the law's there, and the Newton matrix with held friction is jacfwd of
    the weighted residual."""
    from helpers import check_newton_matrix

    model, args, inc, q, zb = _pinched()
    rng = np.random.default_rng(7)
    q = (q + 1e-5 * rng.normal(size=q.shape)).at[0, 0].set(0.0)
    g = nt.forces(model, q, zb)[0]
    ball_n = jax.vmap(lambda i, qi, gi: ni.node_contact(model, i, qi, gi)[4])(
        jnp.arange(q.shape[0]), q, g)
    hf = ni.sheet_held_frame(model, args, q, zb, g)
    assert float(ball_n[1]) > 0 and float(hf.normal[0, 1]) > 0 and bool(hf.live[1])
    assert float(ball_n[0]) > 0  # the pole: on the ball alone
    law = ni.residual(model, args.friction, inc, q, zb)
    weighted = eqx.tree_at(lambda i: i.weight, inc, 1e3, is_leaf=lambda x: x is None)
    r_w = ni.residual(model, args.friction, weighted, q, zb)
    np.testing.assert_array_equal(np.asarray(r_w[0][1]), np.asarray(law[0][1]))
    check_newton_matrix(model, args.friction, weighted, q, zb, False, 1e-12)


@pytest.mark.slow  # two increments' compiles with held friction (about 20 s)
def test_weighted_newton_with_a_pinched_node_ends_on_the_laws_root():
    """With node 1 pinched between the ball and a frictional held body, one increment by Newton
    on the weighted form ends where Newton on the law's own form does (held slip distances
    included): the pinched node's law-form row keeps the roots the law's."""
    model, args, inc, q, zb = _pinched()
    layout = Layout(q.shape[0], 0)
    y0 = layout.pack(q[:, 0], q[:, 1] + zb, zb, jnp.zeros(4), None)
    zero = (jnp.zeros_like(q), jnp.zeros(()))
    out = []
    for c in (0.0, 1e3):
        solver = nw.MotionNewton(max_iter=60, weight=c)
        y1, ok, it, *_ = solver.increment(model, layout, jnp.asarray(0.0), jnp.asarray(0.3), y0,
                                          args, zero, 1e-12, 1e-12)
        assert bool(ok)
        out.append((np.asarray(y1), int(it)))
    print("iterations (law, c = 1e3):", [it for _, it in out])
    np.testing.assert_allclose(out[1][0], out[0][0], rtol=0, atol=1e-9)
