"""Friction per held body (issue 21 item 3, dynslip/physics/bodies/held.py, docs/bodies.md).

A sheet pulled over two held bodies with different Coulomb coefficients (a post's rounded edge
and a torus ring below it; the ball out of reach): while it slides, every slipping node on a
body carries exactly that body's mu N, and at rest none carries more; the friction changes the
clamp's pull as the per-body capstan says (more friction, more pull); the energy balance closes
with the held bodies' friction dissipation counted; the free ball's velocity solves its
equation with the held friction; Newton's matrix is the derivative of its residual.
Small meshes (N = 32, 9); one model per body set, compiled once.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Cylinder, Torus
from dynslip.physics.bodies.held import Held, free_ball_velocity
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import (
    BALL_FORCE,
    BALL_HOLD,
    Protocol,
)
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.solver import increment as ni
from dynslip.physics.solver.methods import Settings
from helpers import (
    check_newton_matrix,
    draped,
    increment_args,
    push_and_hold,
    run_sheet,
    small_model,
)
from numerics import named_solver
from test_forming import residual

N = 32
RIM, PRE, TAU, EPS = 2.54, 1.05, 0.1, 1e-3
MAT = make_material("gent", jm=50.0)
PEN = Penalty(jnp.asarray(1e4), jnp.asarray(1e-3))
POST = Cylinder(radius=1.0, z_bottom=-3.0, z_top=0.0, edge_radius=0.25)
RING = Torus(ring_radius=1.75, minor_radius=0.35, centre_z=-0.7)
MU_POST, MU_RING = 0.15, 0.6


def _coulomb(mu):
    return Coulomb(mu=jnp.asarray(mu), eps=jnp.asarray(EPS))


def _model(mu_post, mu_ring):
    def held(body, mu):
        return body if mu is None else Held(body, _coulomb(mu))

    return SheetModel(
        make_mesh(N, RIM / PRE), MAT, PEN, bodies=(held(POST, mu_post), held(RING, mu_ring))
    )


FRICTIONAL = _model(MU_POST, MU_RING)
FRICTIONLESS = _model(None, None)
SPEED = 0.2


def _run(model, solver="load_step", hold=4.0, depth=-1.5, heal_rate=0.0):
    """The flat sheet pulled down over the held bodies to ``depth`` (R) at SPEED and held for
    ``hold`` s, the ball far above; frames every 0.5 s; the segment solver ``solver`` heals
    slip distances at ``heal_rate`` (R/s)."""
    protocol = Protocol(
        push_and_hold(0.0, depth, SPEED, hold), clamp_rho0=RIM, clamp_z0=0.0, ball_z0=6.0
    )
    settings = Settings(solver=named_solver(solver, heal_rate=heal_rate), save_interval=0.5)
    return run_sheet(model, protocol, _coulomb(0.5), settings, pre=PRE, z_sheet=0.0, tau=TAU,
                     eps=EPS)


@pytest.fixture(scope="module")
def frictional_run():
    return _run(FRICTIONAL)


@pytest.fixture(scope="module")
def frictionless_run():
    return _run(FRICTIONLESS)


def _held_state(model, frame):
    """Per body (2, N): normal force N, friction force f = S - G along the body's tangent, the
    slip force S, and the smoothing's half width e (slipping past it: |f| = mu N exactly)."""
    rho, z = jnp.asarray(frame["rho"]), jnp.asarray(frame["z"])
    g_rho, g_z, _ = model.gradients(rho, z, jnp.asarray(frame["ball_z"]))
    hf = model.held_friction(rho, z, -jnp.stack([g_rho, g_z]), TAU, EPS)
    g, s = hf.slip(0.0)  # the ball is held at rest
    live = np.asarray(hf.live)
    normal = np.where(live, np.asarray(hf.normal), 0.0)
    eps = np.asarray(hf.eps)
    mu = np.array([[MU_POST], [MU_RING]])
    c = mu * normal
    e = np.where(c + eps > 0, eps * c / np.where(c + eps > 0, c + eps, 1.0), 0.0)
    return normal, np.where(live, np.asarray(s - g), 0.0), np.asarray(s), e, mu


@pytest.mark.slow
def test_each_body_slips_at_its_own_limit(frictional_run):
    """While the clamp pulls the sheet over both bodies, the nodes slipping on the post carry
    |f| = 0.15 N and those on the ring |f| = 0.6 N (exactly, past the smoothing), no node more
    than its body's mu N; several nodes slip on each body."""
    push_end = [f for f in frictional_run.frames if f["stage"] == 0][-1]
    normal, fric, s, e, mu = _held_state(FRICTIONAL, push_end)
    for k in range(2):
        contact = normal[k] > 1e-6
        slipping = contact & (np.abs(s[k]) > e[k] * (1 + 1e-9))
        assert slipping.sum() >= 2, (k, slipping.sum())
        np.testing.assert_allclose(
            np.abs(fric[k][slipping]), mu[k] * normal[k][slipping], rtol=1e-10
        )
        assert np.all(np.abs(fric[k][contact]) <= mu[k] * normal[k][contact] * (1 + 1e-10))
        assert np.all(fric[k][~contact] == 0.0)
        # friction opposes the slip: the sheet is drawn outward and down over both bodies,
        # toward increasing arc length, so the friction points backward
        assert np.all(fric[k][slipping] * s[k][slipping] < 0)


@pytest.mark.slow
def test_at_rest_every_node_is_inside_its_cone(frictional_run):
    """After the hold the sheet has stopped on both bodies: every node inside its body's cone
    (|f| <= mu N), and on the ring (mu 0.6) nodes hold a friction force well above the post's
    limit (0.15 N): each body stops the sheet at its own coefficient."""
    end = frictional_run.frames[-1]
    normal, fric, s, e, mu = _held_state(FRICTIONAL, end)
    for k in range(2):
        contact = normal[k] > 1e-6
        assert np.all(np.abs(fric[k][contact]) <= mu[k] * normal[k][contact] * (1 + 1e-10))
    ring = normal[1] > 1e-6
    ratio = np.abs(fric[1][ring]) / normal[1][ring]
    assert ratio.max() > 2 * MU_POST, ratio  # the ring holds past what the post could


@pytest.mark.slow  # two runs (17 s); the quick loop runs held Coulomb friction in
# test_bodies_weakening.py::test_equal_coefficients_are_coulomb
def test_friction_raises_the_pull(frictional_run, frictionless_run):
    """The clamp's pull while sliding over two frictional bodies exceeds the frictionless one,
    and each body's friction force, summed along the axis, makes up the difference at the end
    of the push (global balance: C_z = L_pressure - sum f_z, the held bodies carry both)."""
    fr = [f for f in frictional_run.frames if f["stage"] == 0][-1]
    fl = [f for f in frictionless_run.frames if f["stage"] == 0][-1]
    assert abs(float(fr["clamp_force"])) > 1.1 * abs(float(fl["clamp_force"]))
    rho, z = jnp.asarray(fr["rho"]), jnp.asarray(fr["z"])
    normal, fric, s, e, mu = _held_state(FRICTIONAL, fr)
    g_rho, g_z, _ = FRICTIONAL.gradients(rho, z, jnp.asarray(fr["ball_z"]))
    hf = FRICTIONAL.held_friction(rho, z, -jnp.stack([g_rho, g_z]), TAU, EPS)
    load = float(FRICTIONAL.held_load(rho, z)) - float(hf.axial(0.0))
    # quasi-static sliding: the drag's share is small (speed 0.2 R/s, drag time 0.1 s)
    np.testing.assert_allclose(float(fr["clamp_force"]), load, rtol=2e-2)


@pytest.mark.slow
def test_energy_balance_with_frictional_bodies():
    """The reference solver (Kvaerno5) closes W_c + W_b = dE + D_drag + D_fric with two
    frictional held bodies to 1e-6 of the work, D_fric being all held-body friction (the ball
    is out of reach) and a sizeable part of the work (> 5%): leaving it out fails."""
    ref = _run(FRICTIONAL, solver="kvaerno5")
    r, work = residual(ref)
    assert work > 1.0
    d_fric = float(ref.frames[-1]["dissipation_friction"])
    assert d_fric > 0.05 * work, (d_fric, work)
    assert r < 1e-6, r


def test_held_body_law_may_carry_a_slip_distance():
    """A held body's law may have memory (slip weakening: one slip distance per node, in the
    state; tests/test_bodies_weakening.py)."""
    from dynslip.physics.bodies.held import n_memory

    held = Held(RING, SlipWeakening(mu_s=0.9, mu_k=0.8, d_c=0.1, eps=0.0))
    assert n_memory((held, Held(POST, _coulomb(0.3)), RING)) == 1


# ----------------------------------------------------------------------------- the free ball

NS = 9
SMALL = small_model(
    NS, bodies=(Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2), _coulomb(0.7)),)
)


def _small_state():
    return draped(SMALL.mesh.rbar, np.random.default_rng(1))


def _args(ball_mode):
    return increment_args(_coulomb(0.5), ball_mode, ball_vz=0.05)


@pytest.mark.slow
def test_free_ball_velocity_solves_its_equation():
    """The force-controlled ball's velocity with held friction is the root of
    eta_b v - A0 - sum f_z(v) = 0 (the friction's axial part depends on v), to rounding; it
    differs from the frictionless A0/eta_b (so the friction's reaction is on the body, not
    the ball); and its derivative is the implicit function theorem's."""
    rho, z = _small_state()
    rho, z = jnp.asarray(rho), jnp.asarray(z)
    g_rho, g_z, _ = SMALL.gradients(rho, z, 0.0)
    f = -jnp.stack([g_rho, g_z])
    hf = SMALL.held_friction(rho, z, f, 0.1, 1e-3)
    assert float(hf.bound()) > 1e-2  # some nodes press on the torus
    bd = 0.4
    for a0 in (-2.0, 0.0, 0.3, 5.0):
        v = free_ball_velocity(hf, jnp.asarray(a0), bd)
        resid = bd * v - a0 - hf.axial(v)
        assert abs(float(resid)) < 1e-12 * (1 + abs(a0))
    v0 = float(free_ball_velocity(hf, jnp.asarray(0.3), bd))
    assert abs(v0 - 0.3 / bd) > 1e-3
    dv = float(jax.grad(lambda a: free_ball_velocity(hf, a, bd))(jnp.asarray(0.3)))
    _, dg = jax.jvp(lambda v: bd * v - 0.3 - hf.axial(v), (jnp.asarray(v0),), (1.0,))
    np.testing.assert_allclose(dv, 1.0 / float(dg), rtol=1e-10)


@pytest.mark.slow
@pytest.mark.parametrize("ball_mode", [BALL_HOLD, BALL_FORCE])
def test_newton_blocks_with_held_friction_equal_jacfwd(ball_mode):
    """Newton's matrix with a frictional held body against jax.jacfwd of the residual: exact,
    the ball held or under force (the node rates' coupling to far nodes through the ball's
    velocity by its second border unknown); the border of one (``exact=False``) exact but for
    that coupling (helpers.check_newton_matrix)."""
    rho, z = _small_state()
    args = _args(ball_mode)
    q = jnp.stack([jnp.asarray(rho), jnp.asarray(z) - 0.02], axis=1)
    zb = jnp.asarray(0.02)
    inc = ni.Increment(
        q0=q, zb0=zb, delta0=None, t1=jnp.asarray(0.3), h=jnp.asarray(0.3), args=args
    )

    ref = check_newton_matrix(SMALL, args.friction, inc, q, zb, ball_mode == BALL_FORCE, 1e-9)
    # the friction couples the node rates to the ball's velocity: the rows differ from the
    # frictionless model's
    free = SheetModel(SMALL.mesh, MAT, PEN, bodies=(SMALL.bodies[0].body,))
    ref0 = np.asarray(
        jax.jacfwd(
            lambda v: jnp.concatenate(
                [
                    ni.residual(free, args.friction, inc, v[:-1].reshape(NS, 2), v[-1])[0].reshape(
                        -1
                    ),
                    ni.residual(free, args.friction, inc, v[:-1].reshape(NS, 2), v[-1])[1][None],
                ]
            )
        )(jnp.concatenate([q.reshape(-1), zb[None]]))
    )
    assert np.abs(ref - ref0).max() > 1e-3
