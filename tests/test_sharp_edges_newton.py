"""The Newton matrix with two-pass contact (physics/bodies/corners.py) equals ``jax.jacfwd`` of
the increment's residual: the corners' penalty Hessian (block tridiagonal) and the corners'
friction, whose normal force each node shares with its neighbours (the rate's derivative
through the share, physics/solver/newton_matrix.py ``_share_blocks``): a coin as the ball
(its edge's corners under the ball's friction law) and a frictional held ring thin enough to
be a corner (its corners' friction switched on for the test).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Torus
from dynslip.physics.bodies.corners import corner_energy, corner_normal
from dynslip.physics.bodies.disc import Disc
from dynslip.physics.bodies.held import Held
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.protocols import BALL_FORCE, BALL_HOLD
from dynslip.physics.solver import increment as ni
from helpers import check_newton_matrix, small_model
from test_bodies_friction import _args

NS = 9
EPS = 1e-3


def _coin_state():
    """A sheet over a coin's top face and down past its edge, the segment across the corner
    cutting it (no node on the corner)."""
    rho = np.array([0.0, 0.3, 0.6, 0.85, 0.95, 1.012, 1.03, 1.2, 1.5])
    z = np.array([0.1508, 0.1508, 0.1506, 0.1504, 0.1502, 0.02, -0.1, -0.3, -0.5])
    return jnp.stack([jnp.asarray(rho), jnp.asarray(z)], axis=1)


def _ring_state():
    """A sheet over a thin held ring (minor radius 0.05 R), a segment across it."""
    rho = np.array([0.0, 0.3, 0.6, 0.9, 1.15, 1.45, 1.7, 1.9, 2.1])
    z = np.array([0.3, 0.3, 0.3, 0.298, 0.296, 0.2, 0.1, 0.0, -0.1])
    return jnp.stack([jnp.asarray(rho), jnp.asarray(z)], axis=1)


def _inc(args, q, zb, memory):
    d0 = jnp.asarray(np.linspace(0.0, 0.3, NS)) if memory else None
    return ni.Increment(q0=q - 1e-3, zb0=zb, delta0=d0, t1=jnp.asarray(0.3), h=jnp.asarray(0.3),
                        args=args)


@pytest.mark.parametrize("ball_mode", [BALL_HOLD, BALL_FORCE])
def test_coin_corner_friction_newton_matrix(ball_mode):
    coin = Disc(1.0, 0.3, 0.08)
    model = small_model(NS)
    model = type(model)(model.mesh, model.material, model.penalty, ball=coin)
    q = _coin_state()
    assert float(corner_energy(coin, q, model.penalty)) > 0  # the chord cuts the corner
    assert float(jnp.max(corner_normal(coin, q, model.penalty))) > 0
    friction = SlipWeakening(mu_s=jnp.asarray(0.99), mu_k=jnp.asarray(0.82),
                             d_c=jnp.asarray(0.4), eps=jnp.asarray(EPS))
    args = _args(ball_mode)
    inc = _inc(args, q, jnp.asarray(0.0), memory=True)
    # no held friction: the ball's velocity reads the clamped edge alone (no far coupling)
    check_newton_matrix(model, friction, inc, q, jnp.asarray(0.0), False, 1e-10)


@pytest.mark.parametrize("ball_mode", [BALL_HOLD, BALL_FORCE])
def test_held_corner_friction_newton_matrix(ball_mode, monkeypatch):
    """The held corners' friction (off by default: physics/bodies/held.py
    ``HELD_CORNER_FRICTION``) switched on: its Newton matrix terms are exact."""
    from dynslip.physics.bodies import held as held_module

    monkeypatch.setattr(held_module, "HELD_CORNER_FRICTION", True)
    ring = Torus(ring_radius=1.3, minor_radius=0.05, centre_z=0.2)
    model = small_model(NS, bodies=(Held(ring, Coulomb(mu=jnp.asarray(0.5),
                                                       eps=jnp.asarray(EPS))),))
    zb = jnp.asarray(0.02)
    q = _ring_state() - jnp.array([0.0, 0.02])
    x = q + jnp.array([0.0, 0.02])
    assert float(corner_energy(ring, x, model.penalty)) > 0
    args = _args(ball_mode)
    inc = _inc(args, q, zb, memory=False)
    check_newton_matrix(model, args.friction, inc, q, zb, ball_mode != BALL_HOLD, 1e-10)
