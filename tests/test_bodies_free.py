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

from dynslip.physics import newton as nw
from dynslip.physics.bodies import Cylinder
from dynslip.physics.bodies.held import Held
from dynslip.physics.field import free_body_rates
from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import Protocol, Stage, StopRule
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.simulate import Settings, _stage_args, simulate
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


@pytest.fixture(scope="module")
def run():
    # the post settles exponentially (time constant about 1.4 s): 24 s leave 1e-7 of F
    stages = (Stage("rise", StopRule("duration", duration=24.0)),)
    protocol = Protocol(stages, clamp_rho0=RIM, clamp_z0=0.0, ball_z0=6.0)
    res = simulate(
        MODEL, protocol, friction=FRICTION, eps=EPS, drag=TAU, ball_drag=ETA,
        pre_stretch=PRE, z_sheet=0.0, settings=Settings(solver="load_step", save_interval=1.0),
    )
    assert res.failed is None, res.failed
    return res


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


def _run(max_increment):
    # the post settles exponentially (time constant about 1.4 s): 24 s leave 1e-7 of F
    stages = (Stage("rise", StopRule("duration", duration=24.0)),)
    protocol = Protocol(stages, clamp_rho0=RIM, clamp_z0=0.0, ball_z0=6.0)
    settings = Settings(solver="load_step", save_interval=1.0, max_increment=max_increment,
                        max_increment_free=max_increment)
    res = simulate(
        MODEL, protocol, friction=FRICTION, eps=EPS, drag=TAU, ball_drag=ETA,
        pre_stretch=PRE, z_sheet=0.0, settings=settings,
    )
    assert res.failed is None, res.failed
    return res


def _balance(res):
    s = {k: np.array([float(f[k]) for f in res.frames]) for k in (
        "work_clamp", "work_ball", "work_bodies", "energy_elastic", "energy_penalty",
        "dissipation_drag", "dissipation_friction")}
    w = s["work_clamp"] + s["work_ball"] + s["work_bodies"]
    e = s["energy_elastic"] + s["energy_penalty"] - res.e0
    d = s["dissipation_drag"] + s["dissipation_friction"]
    return np.max(np.abs(w - e - d)), s["work_bodies"][-1], np.max(np.abs(w))


@pytest.mark.slow
def test_energy_balance_with_the_applied_force_converges_at_first_order(run):
    """W_c + W_b + W_bodies = dE + D_drag (the post's drag counted) to the accuracy of the
    accumulators' rectangle rule (first order in the increment, as implicit Euler): the
    residual falls about tenfold when the increments are capped ten times smaller (measured
    3.1e-3 at a cap of 2 s, 3.5e-4 at 0.2 s, of a work of 0.123), and the applied force's work
    is most of the work (leaving it out cannot close the balance)."""
    coarse, fine = _run(2.0), _run(0.2)
    r_c, w_bodies, work = _balance(coarse)
    r_f, _, _ = _balance(fine)
    assert w_bodies > 0.5 * work, (w_bodies, work)
    assert r_c / r_f > 5.0, (r_c, r_f)
    assert r_f < 5e-3 * work, (r_f, work)


@pytest.mark.slow
def test_newton_matrix_with_a_free_body_equals_jacfwd():
    """The bordered matrix (sheet blocks, the ball's and the post's rows and columns) against
    jax.jacfwd of the increment's residual, at a state where the post presses the sheet."""
    stage = Stage("rise", StopRule("duration", duration=1.0))
    args = _stage_args(stage, 0.0, 6.0, 0.0, (0.0, 0.0), FRICTION, EPS, TAU, ETA, 0.0)
    mesh = MODEL.mesh
    rho = PRE * mesh.rbar
    zb = jnp.asarray(6.0)
    bump = 0.05 * jnp.cos(0.5 * jnp.pi * jnp.clip(mesh.rbar / 1.3, 0.0, 1.0))
    q = jnp.stack([rho, -bump - zb], axis=1)
    zk0 = jnp.array([0.17])  # the post's top at -0.03: 0.02 into the sagging sheet
    inc = nw.Increment(q0=q, zb0=zb, delta0=None, t1=jnp.asarray(0.2), h=jnp.asarray(0.2),
                       args=args)
    res, blocks, _ = nw.free_system(MODEL, FRICTION, inc, zk0 - 0.01)
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
