"""Slip weakening with healing on a held body (issue 21 item 3, dynslip/physics/bodies/held.py,
docs/bodies.md).

A held body's law may carry memory: one slip distance per node relative to that body, in the
state after the ball's own (``Layout.held_internal``). With mu_s = mu_k it is Coulomb at that mu
exactly (a load-stepped run); a node dragged over the body carries mu(delta) N, falling from
mu_s N to mu_k N as its slip distance passes d_c (the closed form, and in a run, where the
weakening lowers the clamp's pull); healing resets the slip distance; Newton's matrix is the
derivative of its residual; a run without such a body keeps today's state. Tiny meshes
(N = 16, 9); one model per law, compiled once.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Torus
from dynslip.physics.bodies.held import Held, held_frame, n_memory
from dynslip.physics.field import N_ACC, Layout, heal
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.protocols import BALL_FORCE, BALL_HOLD
from dynslip.physics.sheet import SheetModel, make_mesh, penalty_pressure
from dynslip.physics.solver import increment as ni
from helpers import check_newton_matrix, small_model
from test_bodies_friction import (
    EPS,
    MAT,
    MU_POST,
    MU_RING,
    PEN,
    POST,
    PRE,
    RIM,
    RING,
    TAU,
    _args,
    _small_state,
)
from test_bodies_friction import _run as _pulled_over_bodies

# test_bodies_friction's post and ring, sheet and drag: the same bodies with other laws
N = 16
MU_K = 0.05  # the post's kinetic coefficient in the weakening run
D_C = 0.005  # R: the post's weakening length (the push slides the sheet about 0.02 R on it)
HEAL = 1e-3  # R/s: the push slides at about 0.1 R/s; after the hold the sheet has stopped


def _f(x):
    return jnp.asarray(x, dtype=float)


def _coulomb(mu):
    return Coulomb(mu=_f(mu), eps=_f(EPS))


def _weakening(mu_s, mu_k, d_c=D_C):
    return SlipWeakening(mu_s=_f(mu_s), mu_k=_f(mu_k), d_c=_f(d_c), eps=_f(EPS))


def _model(post_law, ring_law):
    return SheetModel(
        make_mesh(N, RIM / PRE), MAT, PEN, bodies=(Held(POST, post_law), Held(RING, ring_law))
    )


COULOMB = _model(_coulomb(MU_POST), _coulomb(MU_RING))
EQUAL = _model(_weakening(MU_POST, MU_POST), _weakening(MU_RING, MU_RING))
WEAK = _model(_weakening(MU_POST, MU_K), _coulomb(MU_RING))


def _run(model, heal_rate=0.0, solver="load_step"):
    return _pulled_over_bodies(model, solver, hold=2.0, depth=-0.5, heal_rate=heal_rate)


@pytest.fixture(scope="module")
def coulomb_run():
    return _run(COULOMB)


@pytest.fixture(scope="module")
def weak_run():
    return _run(WEAK, heal_rate=HEAL)


KEYS = ("rho", "z", "ball_z", "clamp_force", "work_clamp", "dissipation_friction", "body_state")


def test_equal_coefficients_are_coulomb(coulomb_run):
    """mu_s = mu_k on both held bodies: the load-stepped run is the Coulomb run at that mu, every
    saved frame to 1e-12 (the slip distances grow, but mu does not depend on them)."""
    eq = _run(EQUAL)
    assert len(eq.frames) == len(coulomb_run.frames)
    for a, b in zip(coulomb_run.frames, eq.frames, strict=True):
        for k in KEYS:
            np.testing.assert_allclose(np.asarray(b[k]), np.asarray(a[k]), rtol=0, atol=1e-12)
    assert np.nanmax(eq.frames[-1]["body_slip_distance"]) > 1e-3  # the memory did move
    assert "body_slip_distance" not in coulomb_run.frames[-1]


def _frame_friction(model, frame):
    """Per frictional body (2, N): normal force N, friction force f = S - G, slip force S, the
    smoothing's half width at the threshold, and mu of the state's slip distance (NaN: none)."""
    rho, z = jnp.asarray(frame["rho"]), jnp.asarray(frame["z"])
    g_rho, g_z, _ = model.gradients(rho, z, jnp.asarray(frame["ball_z"]))
    delta = np.asarray(frame["body_slip_distance"])[:1]  # the post's (the ring is Coulomb)
    hf = model.held_friction(rho, z, -jnp.stack([g_rho, g_z]), TAU, EPS, 0.0, jnp.asarray(delta))
    g, s = hf.slip(0.0)  # the ball is held at rest
    live = np.asarray(hf.live)
    normal = np.where(live, np.asarray(hf.normal), 0.0)
    mu = np.stack([MU_K + (MU_POST - MU_K) * np.clip(1 - delta[0] / D_C, 0, 1),
                   np.full(N, MU_RING)])
    c, eps = mu * normal, np.asarray(hf.eps)
    e = np.where(c + eps > 0, eps * c / np.where(c + eps > 0, c + eps, 1.0), 0.0)
    return normal, np.where(live, np.asarray(s - g), 0.0), np.asarray(s), e, mu, delta[0]


@pytest.mark.slow  # a third run (14 s); the quick loop keeps the law's closed form and identity
def test_weakening_in_a_run(weak_run, coulomb_run):
    """The sheet drawn over a post with slip weakening (mu_s 0.15 -> mu_k 0.05 over d_c):
    at the end of the push every node slipping on the post carries mu(delta) N of its own slip
    distance (exactly, past the smoothing), some at mu_k (delta past d_c), none above its
    limit; the weakening lowers the clamp's pull below the Coulomb run's at mu_s; healing
    (1e-3 R/s) leaves the sliding nodes' slip distances and resets every one once the sheet
    has stopped."""
    push = [f for f in weak_run.frames if f["stage"] == 0][-1]
    normal, fric, s, e, mu, delta = _frame_friction(WEAK, push)
    contact = normal[0] > 1e-6
    slipping = contact & (np.abs(s[0]) > e[0] * (1 + 1e-9))
    assert slipping.sum() >= 2, slipping.sum()
    np.testing.assert_allclose(np.abs(fric[0][slipping]), mu[0][slipping] * normal[0][slipping],
                               rtol=1e-10)
    assert np.all(np.abs(fric[0][contact]) <= mu[0][contact] * normal[0][contact] * (1 + 1e-10))
    assert np.any(delta[slipping] > D_C)  # weakened to mu_k ...
    assert np.all(delta[~contact] == 0.0)  # ... and nothing where the node is off the post
    assert np.all(np.isnan(push["body_slip_distance"][1]))  # the ring: Coulomb, no memory
    pull_c = abs(float([f for f in coulomb_run.frames if f["stage"] == 0][-1]["clamp_force"]))
    assert abs(float(push["clamp_force"])) < pull_c
    # healing: the sliding nodes kept their slip distances (above), the stopped sheet has none
    assert np.all(np.asarray(weak_run.frames[-1]["body_slip_distance"][0]) == 0.0)


@pytest.mark.slow
def test_time_stepped_weakening(weak_run):
    """The reference solver (Kvaerno5: the slip distances' rates in the vector field, healing
    at each save) on the weakening run: the energy balance closes to 1e-6 of the work, and at
    the push's end the slip distances on the post agree with load stepping's (first order in
    the increment) to 10% of the largest, the positions to 1e-4 R; both heal to 0 after the
    hold."""
    from test_forming import residual

    ref = _run(WEAK, heal_rate=HEAL, solver="kvaerno5")
    r, work = residual(ref)
    assert r < 1e-6, (r, work)
    push_ref = [f for f in ref.frames if f["stage"] == 0][-1]
    push = [f for f in weak_run.frames if f["stage"] == 0][-1]
    d_ref = np.asarray(push_ref["body_slip_distance"][0])
    d = np.asarray(push["body_slip_distance"][0])
    assert d_ref.max() > 2 * D_C
    np.testing.assert_allclose(d, d_ref, atol=0.1 * d_ref.max())
    np.testing.assert_allclose(push["z"], push_ref["z"], atol=1e-4)
    assert np.all(np.asarray(ref.frames[-1]["body_slip_distance"][0]) == 0.0)


def test_dragged_node_closed_form():
    """One node dragged over a held slip-weakening body at a constant driving force G > mu_s N:
    the friction it carries is mu(delta) N with mu(delta) = mu_k + (mu_s - mu_k)(1 - delta/
    d_c)^+, falling from mu_s N to mu_k N as delta passes d_c; the return map's increments
    delta1 = delta0 + h (G - mu(delta0) N)/(eta A) converge to the closed form of
    d(delta)/dt = (G - mu(delta) N)/(eta A): delta(t) = (a/b)(e^{bt} - 1) before d_c
    (a = (G - mu_s N)/(eta A), b = (mu_s - mu_k) N/(d_c eta A)); and the vector field's rate is
    that right-hand side."""
    mu_s, mu_k, d_c = 0.6, 0.2, 0.01
    model = small_model(bodies=(Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2),
                                     SlipWeakening(mu_s=_f(mu_s), mu_k=_f(mu_k), d_c=_f(d_c))),))
    x = jnp.asarray([[1.4, 0.2 + 0.3 - 5e-4]])  # one node pressed into the top of the tube
    area, drag = jnp.asarray([0.05]), 0.1
    tangent = model.bodies[0].body.project(x, 0.0).tangent

    def frame(delta, g_t):
        return held_frame(model.bodies, x, g_t * tangent, lambda d: penalty_pressure(PEN, -d),
                          area, drag, 0.0, jnp.asarray([True]), 0.0, jnp.asarray([[delta]]))

    @jax.jit
    def friction_and_next(delta, g_t, h):
        """The friction the node carries at ``delta`` and its slip distance one return-map
        increment ``h`` later (compiled once: the loops below take 600 increments)."""
        hf = frame(delta, g_t)
        return -(hf.slip(0.0)[1] - g_t)[0, 0], hf.advance(0.0, h)[0, 0]

    big_n = float(frame(0.0, 1.0).normal[0, 0])
    assert big_n > 0
    g_t = 0.8 * big_n  # mu_s N < G: the node slips from the start
    eta_a = drag * float(area[0])
    for delta in (0.0, 0.3 * d_c, d_c, 2 * d_c):
        hf = frame(delta, g_t)
        g, s = hf.slip(0.0)
        mu = mu_k + (mu_s - mu_k) * max(0.0, 1 - delta / d_c)
        np.testing.assert_allclose(float(g[0, 0]), g_t, rtol=1e-14)
        np.testing.assert_allclose(float(-(s - g)[0, 0]), mu * big_n, rtol=1e-12)
        rate = (g_t - mu * big_n) / eta_a
        np.testing.assert_allclose(float(hf.internal_rates(0.0)[0, 0]), rate, rtol=1e-12)
        np.testing.assert_allclose(float(hf.advance(0.0, 0.01)[0, 0]), delta + 0.01 * rate,
                                   rtol=1e-12)
    a = (g_t - mu_s * big_n) / eta_a
    b = (mu_s - mu_k) * big_n / (d_c * eta_a)
    t_c = math.log(1 + b * d_c / a) / b  # delta reaches d_c
    for steps in (200, 400):
        h, delta, t, fr = t_c / steps, 0.0, 0.0, []
        while t < 0.999 * t_c:
            f_now, d_next = friction_and_next(delta, g_t, h)
            fr.append(float(f_now))
            delta = float(d_next)
            t += h
        err = abs(delta - (a / b) * math.expm1(b * t)) / d_c
        if steps == 200:
            err200 = err
    assert err < 0.6 * err200 and err < 1e-2, (err, err200)  # first order in h
    assert fr[0] == pytest.approx(mu_s * big_n, rel=1e-12)
    assert np.all(np.diff(fr) < 0)  # the friction falls ...
    assert fr[-1] < (mu_k + 0.01 * (mu_s - mu_k)) * big_n  # ... to mu_k N at d_c
    # past d_c: mu_k N for ever
    np.testing.assert_allclose(float(-(frame(5 * d_c, g_t).slip(0.0)[1] - g_t)[0, 0]),
                               mu_k * big_n, rtol=1e-12)


def test_healing_resets_the_held_slip_distance():
    """field.heal on a sheet pressed onto a held slip-weakening torus, each node's slip distance
    past d_c (mu = mu_k = 0: every node touching the body slips): the slip distance relative to
    the body is reset where the node is off the body, or slips no faster than the heal rate
    (0: none; then the median speed: the slower half), kept elsewhere; the rest of the state is
    untouched."""
    model = small_model(bodies=(Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2),
                                     _weakening(0.7, 0.0, 0.01)),))
    layout = Layout(9, 0, N_ACC, 0, n_memory(model.bodies))
    rho, z = _small_state()
    args = _args(BALL_HOLD)
    y = layout.pack(jnp.asarray(rho), jnp.asarray(z), 0.0, jnp.zeros(N_ACC), None, None,
                    jnp.full((1, 9), 0.02))
    rho_, z_, zb, _ = layout.unpack(y)
    g_rho, g_z, _ = model.gradients(rho_, z_, zb)
    hf = model.held_friction(rho_, z_, -jnp.stack([g_rho, g_z]), args.drag, args.eps, zb,
                             layout.held_internal(y))
    _, s = hf.slip(float(args.vzb))  # the ball held, moving at vzb
    speed = np.abs(np.asarray(s[0]) / np.asarray(hf.eta_a))
    touching = np.asarray(hf.live) & (np.asarray(hf.normal[0]) > 0)
    assert touching.sum() >= 3 and np.all(speed[touching] > 0)
    assert np.any(~touching & np.asarray(hf.live))
    for rate in (0.0, float(np.median(speed[touching]))):
        y1 = heal(model, layout, y, args, rate, t=jnp.asarray(0.3))
        d1 = np.asarray(layout.held_internal(y1))[0]
        keep = touching & (speed > rate)
        np.testing.assert_array_equal(d1, np.where(keep, 0.02, 0.0))
        assert np.any(keep) and np.any(touching & ~keep) == (rate > 0)
        np.testing.assert_array_equal(np.asarray(y1[: layout.held_start]),
                                      np.asarray(y[: layout.held_start]))


@pytest.mark.slow  # the heaviest jacfwd cross-check (14 s); the quick loop keeps the node terms'
@pytest.mark.parametrize("ball_mode", [BALL_HOLD, BALL_FORCE])
def test_newton_blocks_with_held_weakening_equal_jacfwd(ball_mode):
    """Newton's matrix with a held slip-weakening body (slip distances spread over [0, 2 d_c],
    mu_k = 0: the nodes past d_c slip) against jax.jacfwd of the increment's residual: exact
    with the ball held or under force, and the border of one all but the far rank-one coupling
    (as with Coulomb, test_bodies_friction.py).
    The slip distances matter: the residual differs from the one at delta0 = 0."""
    ns = 9
    model = small_model(ns, bodies=(Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2),
                                         _weakening(0.9, 0.0, 0.01)),))
    rho, z = _small_state()
    args = _args(ball_mode)
    q = jnp.stack([jnp.asarray(rho), jnp.asarray(z) - 0.02], axis=1)
    zb = jnp.asarray(0.02)
    hd = jnp.asarray(np.linspace(0.0, 0.02, ns))[None]
    inc = ni.Increment(q0=q, zb0=zb, delta0=None, t1=jnp.asarray(0.3), h=jnp.asarray(0.3),
                       args=args, held_delta0=hd)

    check_newton_matrix(model, args.friction, inc, q, zb, ball_mode == BALL_FORCE, 1e-9)
    fresh = ni.Increment(q0=q, zb0=zb, delta0=None, t1=jnp.asarray(0.3), h=jnp.asarray(0.3),
                         args=args, held_delta0=jnp.zeros_like(hd))
    res = [ni.residual(model, args.friction, i, q, zb) for i in (inc, fresh)]
    assert max(float(jnp.max(jnp.abs(a - b))) for a, b in zip(*res, strict=True)) > 1e-6


def test_without_memory_the_state_is_unchanged():
    """Without a held law with memory the state has no held block: the layout's size is
    today's, a MemberRun's layout has n_held_int = 0 (Coulomb bodies), and one slip distance
    per node per weakening body otherwise, after the ball's own block."""
    assert Layout(N, 1).size == (N - 1) + N + 1 + N_ACC + N
    assert Layout(N, 0, N_ACC, 1).size == (N - 1) + N + 1 + N_ACC + 1
    assert n_memory(COULOMB.bodies) == 0 and n_memory(WEAK.bodies) == 1
    assert n_memory(EQUAL.bodies) == 2
    lay = Layout(N, 1, N_ACC, 1, 2)
    assert lay.size == (N - 1) + N + 1 + N_ACC + N + 2 * N + 1
    assert lay.held_start == lay.internal_start + N
    y = lay.pack(jnp.arange(N, dtype=float), jnp.zeros(N), 0.0, jnp.zeros(N_ACC),
                 jnp.full(N, 7.0), jnp.asarray([9.0]), jnp.arange(2 * N, dtype=float))
    np.testing.assert_array_equal(np.asarray(lay.held_internal(y)),
                                  np.arange(2 * N).reshape(2, N))
    np.testing.assert_array_equal(np.asarray(lay.internal(y)), np.full(N, 7.0))
    assert float(lay.free(y)[0]) == 9.0
    assert Layout(N, 1).held_internal(y) is None



def test_schema_builds_a_held_slip_weakening_law():
    """physics.bodies[].friction {law: slip_weakening, mu_s, mu_k, d_c_mm} builds the body's
    SlipWeakening law, d_c in R (d_c_mm / ball_radius_mm), the smoothing the ball's; the run's
    state holds one slip distance per node for it."""
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load_data, validate_data
    from test_bodies_schema import LET_GO
    from test_bodies_schema import POST as POST_SPEC

    data = load_data(LET_GO)
    data["physics"]["bodies"] = [
        {**POST_SPEC, "friction": {"law": "slip_weakening", "mu_s": 0.9, "mu_k": 0.6,
                                   "d_c_mm": 0.4}}]
    sc = validate_data(data)
    model, _, _ = build_core(sc)
    law = model.bodies[0].friction
    assert isinstance(law, SlipWeakening)
    r = sc.physics.ball_radius_mm
    np.testing.assert_allclose([float(law.mu_s), float(law.mu_k), float(law.d_c)],
                               [0.9, 0.6, 0.4 / r], rtol=1e-15)
    assert n_memory(model.bodies) == 1
