"""A held body free along the axis (issue 21 item 2, dynslip/physics/bodies/held.py
``Held.free``, docs/bodies.md).

A frictionless post under the clamped sheet, pushed up by an applied force F against its drag:
at rest the sheet's pressure on it balances F (L + F = 0) and the clamp carries F (the sheet's
own balance: the ball is out of reach); the energy balance closes with the applied force's
work (``work_bodies``) and the post's drag; Newton's matrix with the post's height in the
border is the derivative of the residual. N = 24, load stepping.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Cylinder
from dynslip.physics.bodies.held import Held
from dynslip.physics.driver.member import stage_args
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.field import free_body_rates
from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import Duration, Protocol, Stage
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.solver import increment as ni
from dynslip.physics.solver import newton_matrix as nm
from dynslip.physics.solver.methods import Settings
from numerics import named_solver
from test_newton import _dense

N = 24
RIM, PRE, TAU, EPS = 2.54, 1.05, 0.1, 1e-3
MAT = make_material("gent", jm=50.0)
PEN = Penalty(jnp.asarray(1e4), jnp.asarray(1e-3))
POST = Cylinder(radius=1.0, z_bottom=-3.0, z_top=-0.2, edge_radius=0.25)
F_UP, ETA = 0.3, TAU * 4 * math.pi
FRICTION = Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(EPS))
MODEL = SheetModel(
    make_mesh(N, RIM / PRE), MAT, PEN,
    bodies=(Held(POST, free=True, force=jnp.asarray(F_UP), drag=jnp.asarray(ETA)),),
)
# the same post with Coulomb friction against the sheet (mu = 0.5)
MODEL_FRICTION = SheetModel(
    make_mesh(N, RIM / PRE), MAT, PEN,
    bodies=(Held(POST, FRICTION, free=True, force=jnp.asarray(F_UP), drag=jnp.asarray(ETA)),),
)


def _rise(model, settings=None):
    # the post settles exponentially (time constant about 1.4 s): 24 s leave 1e-7 of F
    stages = (Stage("rise", Duration(duration=24.0)),)
    protocol = Protocol(stages, clamp_rho0=RIM, clamp_z0=0.0, ball_z0=6.0)
    res = simulate(
        model, protocol, friction=FRICTION, eps=EPS, drag=TAU, ball_drag=ETA,
        pre_stretch=PRE, z_sheet=0.0,
        settings=settings or Settings(solver=named_solver(), save_interval=1.0),
    )
    assert res.failed is None, res.failed
    return res


@pytest.fixture(scope="module")
def run():
    return _rise(MODEL)


@pytest.fixture(scope="module")
def run_friction():
    return _rise(MODEL_FRICTION)


def test_at_rest_the_sheet_balances_the_applied_force(run):
    from dynslip.physics.bodies.held import place_free

    end = run.frames[-1]
    rho, z, zb = (jnp.asarray(end[k]) for k in ("rho", "z", "ball_z"))
    zk = jnp.asarray(end["body_z"])
    # the post rose by more than its starting gap and lifted the sheet's centre
    assert float(zk[0]) > 0.25 and float(z[0]) > 0.05, (float(zk[0]), float(z[0]))
    v, f, _ = free_body_rates(place_free(MODEL, zk), rho, z, zb)
    load = float(v[0] * ETA - f[0])  # L = eta v - F: the sheet's pressure on the post
    assert abs(load + F_UP) < 1e-5 * F_UP, load
    assert abs(float(end["clamp_force"]) + F_UP) < 1e-5 * F_UP, float(end["clamp_force"])


@pytest.mark.slow
def test_with_friction_the_clamp_still_carries_the_applied_force(run, run_friction):
    """The post with friction (mu = 0.5) against the sheet: the friction acts (it dissipates,
    and the sheet comes to rest elsewhere than on the frictionless post), yet at rest the
    sheet's own balance holds whatever the friction: the clamp carries F, and the post's
    equation (eta v = L - A + F, A the friction's axial reaction) leaves it at rest."""
    end, plain = run_friction.frames[-1], run.frames[-1]
    assert abs(float(end["clamp_force"]) + F_UP) < 1e-5 * F_UP, float(end["clamp_force"])
    # the friction dissipates (measured 1.1e-4 of the post's work 0.12: the sheet is mostly
    # carried with the post, stuck), where the frictionless post dissipates nothing by friction
    assert float(end["dissipation_friction"]) > 1e-5
    assert float(plain["dissipation_friction"]) == 0.0
    moved = max(np.max(np.abs(np.asarray(end[k]) - np.asarray(plain[k]))) for k in ("rho", "z"))
    assert moved > 1e-3, moved
    # the post at rest: its last two saved heights agree to the settling's 1e-7 of F / eta
    z1, z0 = (float(run_friction.frames[i]["body_z"][0]) for i in (-1, -2))
    assert abs(z1 - z0) < 1e-6, (z1, z0)


@pytest.mark.slow
def test_power_balance_with_a_frictional_free_body_is_exact(run_friction):
    """At saved states of the frictional post's rise (pressing the sheet, friction acting), with
    the post moving at its own velocity v (the root of v = (L - A(v) + F)/eta, as the load
    step's converged increment), the rate of stored energy equals the accumulators' rates:
    dE/dt = P_clamp + P_ball + F v - D_drag (eta v^2 included) - D_friction (the slip relative
    to the post) to round-off. (Without the post's own velocity in its friction the two part by
    about the friction's dissipation.)"""
    from scipy.optimize import brentq

    from dynslip.physics.bodies.held import place_free
    from dynslip.physics.field import N_ACC_MOVED, Layout, evaluate, place_free_moving

    stage = Stage("rise", Duration(duration=24.0))
    args = stage_args(stage, 0.0, 6.0, 0.0, (0.0, 0.0), FRICTION, EPS, TAU, ETA, 0.0)
    lay = Layout(N, 0, N_ACC_MOVED, 1)

    @jax.jit
    def rates(y, t, vk):
        return evaluate(place_free(MODEL_FRICTION, lay.free(y), vk), lay, t, y, args)[0]

    @jax.jit
    def stored_rate(y, dy):
        def energy(rho, z, zk):
            return place_free(MODEL_FRICTION, zk).energy(rho, z, lay.unpack(y)[2])

        rho, z, _, _ = lay.unpack(y)
        vr, vz, _, _ = lay.unpack(dy)
        gr, gz, gk = jax.grad(energy, argnums=(0, 1, 2))(rho, z, lay.free(y))
        return gr @ vr + gz @ vz + gk @ lay.free(dy)

    checked = 0
    for f in run_friction.frames[1:5]:
        y = lay.pack(*(jnp.asarray(f[k]) for k in ("rho", "z", "ball_z")),
                     jnp.zeros(N_ACC_MOVED), None, jnp.asarray(f["body_z"]))
        t = jnp.asarray(f["time"])
        v = brentq(lambda v, y=y, t=t: float(lay.free(rates(y, t, jnp.array([v])))[0]) - v,
                   -5.0, 5.0, xtol=1e-15)
        # the frame record's own root (bisection) is the same velocity
        placed = place_free_moving(MODEL_FRICTION, lay, t, y, args)
        np.testing.assert_allclose(float(placed.bodies[0].velocity), v, rtol=1e-9, atol=1e-12)
        dy = rates(y, t, jnp.array([v]))
        _, _, _, dacc = lay.unpack(dy)
        power = dacc[0] + dacc[1] + dacc[4] - dacc[2] - dacc[3]
        de = float(stored_rate(y, dy))
        np.testing.assert_allclose(de, float(power), rtol=1e-10, atol=1e-14)
        checked += float(dacc[3]) > 1e-6  # friction acting at this state
    assert checked >= 1


def _run(max_increment, model=MODEL):
    newton = named_solver(max_increment=max_increment, max_increment_free=max_increment)
    return _rise(model, Settings(solver=newton, save_interval=1.0))


def _balance(res):
    s = {k: np.array([float(f[k]) for f in res.frames]) for k in (
        "work_clamp", "work_ball", "work_bodies", "energy_elastic", "energy_penalty",
        "dissipation_drag", "dissipation_friction")}
    w = s["work_clamp"] + s["work_ball"] + s["work_bodies"]
    e = s["energy_elastic"] + s["energy_penalty"] - res.e0
    d = s["dissipation_drag"] + s["dissipation_friction"]
    return np.max(np.abs(w - e - d)), s["work_bodies"][-1], np.max(np.abs(w))


@pytest.mark.slow
@pytest.mark.parametrize("model", [MODEL, MODEL_FRICTION], ids=["frictionless", "friction"])
def test_energy_balance_with_the_applied_force_converges_at_first_order(model):
    """W_c + W_b + W_bodies = dE + D_drag (the post's drag counted) to the accuracy of the
    accumulators' rectangle rule (first order in the increment, as implicit Euler): the
    residual falls about tenfold when the increments are capped ten times smaller (measured
    3.1e-3 at a cap of 2 s, 3.5e-4 at 0.2 s, of a work of 0.123; with the post's friction,
    mu = 0.5: 2.6e-3 and 3.5e-4 of 0.122), and the applied force's work is most of the work
    (leaving it out cannot close the balance)."""
    coarse, fine = _run(2.0, model), _run(0.2, model)
    r_c, w_bodies, work = _balance(coarse)
    r_f, _, _ = _balance(fine)
    assert w_bodies > 0.5 * work, (w_bodies, work)
    assert r_c / r_f > 5.0, (r_c, r_f)
    assert r_f < 5e-3 * work, (r_f, work)


@pytest.mark.slow
@pytest.mark.parametrize("model", [MODEL, MODEL_FRICTION], ids=["frictionless", "friction"])
def test_newton_matrix_with_a_free_body_equals_jacfwd(model):
    """The bordered matrix (sheet blocks, the ball's and the post's rows and columns) against
    jax.jacfwd of the increment's residual, at a state where the post presses the sheet; with
    the post's friction too (its velocity, the increment's, enters the nodes' slip relative to
    it and its own row)."""
    stage = Stage("rise", Duration(duration=1.0))
    args = stage_args(stage, 0.0, 6.0, 0.0, (0.0, 0.0), FRICTION, EPS, TAU, ETA, 0.0)
    mesh = model.mesh
    rho = PRE * mesh.rbar
    zb = jnp.asarray(6.0)
    bump = 0.05 * jnp.cos(0.5 * jnp.pi * jnp.clip(mesh.rbar / 1.3, 0.0, 1.0))
    q = jnp.stack([rho, -bump - zb], axis=1)
    zk0 = jnp.array([0.17])  # the post's top at -0.03: 0.02 into the sagging sheet
    inc = ni.Increment(q0=q, zb0=zb, delta0=None, t1=jnp.asarray(0.2), h=jnp.asarray(0.2),
                       args=args)
    res, blocks, _ = nm.free_system(model, FRICTION, inc, zk0 - 0.01)
    w = jnp.concatenate([zb[None], zk0])
    dense = _dense(*blocks(q, w))
    n = q.shape[0]

    def flat(x):
        rq, rw = res(x[:2 * n].reshape(n, 2), x[2 * n:])
        return jnp.concatenate([rq.reshape(-1), rw])

    ref = np.asarray(jax.jacfwd(flat)(jnp.concatenate([q.reshape(-1), w])))
    # the post's rows and columns, and the ball's, are exact; the sheet's blocks too (held ball)
    np.testing.assert_allclose(dense, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
    assert np.max(np.abs(ref[:2 * n, -1])) > 0.1  # the post's column is not empty
