"""The bottle neck: a rigid, unilateral support under the ball (``ball: support``).

The support pushes the ball up with the C^1 penalty force k phi'(z_s - z_b) where the
ball's centre is below the support height, and never pulls it down. Checked on the
shortened push-down path of test_forming (N = 40, shared compiled solve): the ball at
rest on the support carries the clamp's pull (overdamped ball: F_support = -C_z) and
sinks by the closed-form penetration; pulled up harder than the sheet holds it down, it
lifts off and the support force is then exactly zero; the energy balance closes.
"""

import math

import jax.numpy as jnp
import numpy as np

from dynslip.physics.friction import Coulomb
from dynslip.physics.protocols import BALL_FORCE, Protocol, Stage, StopRule
from dynslip.physics.simulate import Settings, StageArgs, simulate

from test_forming import MODEL, PRE, RIM, Z0, residual

K = 1e3
W = 1e-3


def _args(support):
    z = jnp.asarray(0.0)
    return StageArgs(t0=z, clamp_mode=jnp.asarray(0), vzc=z, vrhoc=z, fc0=jnp.zeros(2), fc1=jnp.zeros(2),
                     ball_mode=jnp.asarray(BALL_FORCE), vzb=z, f0=z, f1=z, ramp=jnp.asarray(1.0),
                     friction=Coulomb(mu=jnp.asarray(1.0)), eps=z, drag=jnp.asarray(0.1),
                     ball_drag=jnp.asarray(1.0), weight=z, support=jnp.asarray(support),
                     support_z=jnp.asarray(0.0), support_k=jnp.asarray(K))


def test_support_force_is_unilateral_closed_form():
    zb = jnp.array([0.5, 1e-9, 0.0, -0.5 * W, -W, -0.01])
    f = np.asarray(_args(1.0).support_force(zb))
    d = -np.asarray(zb)
    expect = np.where(d <= 0, 0.0, np.where(d < W, K * d**2 / (2 * W), K * (d - W / 2)))
    np.testing.assert_allclose(f, expect, rtol=1e-12, atol=0)
    assert np.all(f[:3] == 0.0)  # never pulls the ball down
    assert np.all(np.asarray(_args(0.0).support_force(zb)) == 0.0)  # no support, no force


def test_ball_on_support_carries_the_pull_and_lifts_off():
    speed, depth = 0.2, -1.5
    pull_up = 20.0  # G h0 R, more than the sheet's pull at the end of the push (about 8.8)
    stages = (
        Stage("push_down", StopRule("duration", duration=(Z0 - depth) / speed), clamp_vz=-speed,
              ball_mode=BALL_FORCE, ball_force_start=0.0, ball_force_end=0.0, support=True),
        Stage("hold", StopRule("duration", duration=2.0), ball_mode=BALL_FORCE, ball_force_start=0.0,
              ball_force_end=0.0, support=True),
        Stage("lift", StopRule("duration", duration=4.0), ball_mode=BALL_FORCE, ball_force_start=0.0,
              ball_force_end=pull_up, support=True),
    )
    res = simulate(MODEL, Protocol(stages, clamp_rho0=RIM, clamp_z0=Z0, ball_z0=0.0),
                   friction=Coulomb(mu=jnp.asarray(0.8), eps=jnp.asarray(1e-3)), eps=1e-3, drag=0.1,
                   ball_drag=0.1 * 4 * math.pi, pre_stretch=PRE, z_sheet=Z0,
                   settings=Settings(rtol=1e-5, atol=1e-7, save_interval=1.0), support_stiffness=K)
    assert res.failed is None, res.failed
    hold = [f for f in res.frames if f["stage"] == 1][-1]
    cz, fs, zb = float(hold["clamp_force"]), float(hold["ball_reaction"]), float(hold["ball_z"])
    # at rest on the support: the support carries the sheet's pull on the ball
    assert cz < -0.1, cz  # the sheet pulls the ball down
    assert abs(fs + cz) < 1e-3 * abs(cz), (fs, cz)
    # and the ball sinks by the closed-form penetration of the penalty: d = F/k + w/2
    d = fs / K + W / 2
    assert abs(-zb - d) < 1e-2 * d, (zb, d)
    # pulled up past the sheet's pull, the ball lifts off: support force exactly zero
    end = res.frames[-1]
    assert float(end["ball_z"]) > 0.0, (cz, float(end["ball_z"]), float(end["clamp_force"]))
    assert abs(float(end["ball_reaction"]) - pull_up) < 1e-12  # only the applied pull, no support
    r, _ = residual(res)
    assert r < 1e-2, r
    print(f"support: clamp pull {cz:.4f}, support force {fs:.4f}, sink {-zb:.3e} R (closed form {d:.3e}); "
          f"lift-off to z_b = {float(end['ball_z']):.3e} R; energy residual / work {r:.2e}")
