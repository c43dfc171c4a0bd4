"""The held friction's part of Newton's matrix in closed form
(dynslip/physics/solver/newton_matrix.py,
``_held_node_terms``): each node's rate's derivatives in its position, its force, the ball's
height and velocity, and those of its axial held friction (the ball's velocity reads them), are
``jax.jacfwd``'s of the node's rate (:func:`dynslip.physics.solver.increment.node_rate`) and of its
axial friction, to rounding: with several frictional bodies at once (one at rest, one that
moves with the ball with a slip-weakening law, one moved by the stages), the ball's law
weakening, nodes stuck and slipping on each; and the blocks equal ``jacfwd`` of the residual
(all of it with the ball held; with the ball under force all but the far rank-one coupling,
test_bodies_friction.py).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Torus
from dynslip.physics.bodies.held import Held
from dynslip.physics.driver.member import stage_args
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.protocols import BALL_FORCE, BALL_HOLD, CLAMP_POSITION, Duration, Stage
from dynslip.physics.solver import increment as ni
from dynslip.physics.solver import newton_matrix as nm
from dynslip.physics.terms import forces, held_projections
from helpers import check_newton_matrix, small_model
from test_bodies_friction import _args, _small_state

NS = 9
EPS = 1e-3
ZB = 0.02


def _model():
    coulomb = Coulomb(mu=jnp.asarray(0.7), eps=jnp.asarray(EPS))
    weak = SlipWeakening(mu_s=jnp.asarray(0.9), mu_k=jnp.asarray(0.1), d_c=jnp.asarray(0.01),
                         eps=jnp.asarray(EPS))
    return small_model(
        NS,
        bodies=(
            Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2), coulomb),
            # the same ring carried with the ball: at the ball's height ZB it sits where the
            # first one does, so the nodes touch both
            Held(Torus(ring_radius=1.4, minor_radius=0.3, centre_z=0.2 - ZB), weak,
                 moves_with_ball=True),
            Held(Torus(ring_radius=1.1, minor_radius=0.3, centre_z=0.45), coulomb, stage=True,
                 offset=jnp.asarray(0.01), velocity=jnp.asarray(-0.3)),
        ),
    )


MODEL = _model()


def _setup(ball_mode, memory=True):
    rho, z = _small_state()
    args = _args(ball_mode)
    q = jnp.stack([jnp.asarray(rho), jnp.asarray(z) - ZB], axis=1)
    zb = jnp.asarray(ZB)
    hd = jnp.asarray(np.linspace(0.0, 0.02, NS))[None]
    d0 = jnp.asarray(np.linspace(0.0, 0.3, NS)) if memory else None  # the ball's law's
    inc = ni.Increment(q0=q, zb0=zb, delta0=d0,
                       t1=jnp.asarray(0.3), h=jnp.asarray(0.3), args=args, held_delta0=hd)
    return args, inc, q, zb


@eqx.filter_jit
def _node_terms_and_jacfwd(friction, inc, q, g, zb, vb):
    """``_held_node_terms`` of every node and jacfwd of the node's rate and axial held friction,
    compiled once for both parameters (op by op it took 18 s)."""
    idx = jnp.arange(NS)
    moving = (False, True, False)

    def rate(i, qi, gi, di, z, v):
        return ni.node_rate(MODEL, friction, inc, i, qi, gi, di, z, v)[0]

    def axial(i, qi, gi, z, v):
        return ni.node_held_frame(MODEL, inc, i, qi, gi, z).force(v)[1]

    ref = jax.vmap(jax.jacfwd(rate, argnums=(1, 2, 4, 5)), in_axes=(0, 0, 0, 0, None, None))(
        idx, q, g, inc.delta0, zb, vb)
    ref_a = jax.vmap(jax.jacfwd(axial, argnums=(1, 2, 3, 4)), in_axes=(0, 0, 0, None, None))(
        idx, q, g, zb, vb)
    # the held bodies' projections computed once and moved with each node to first order (the
    # reference projects inside every derivative)
    got = jax.vmap(
        lambda i, qi, gi, di, pi: nm._held_node_terms(MODEL, friction, inc, moving, i, qi, gi,
                                                      di, zb, vb, pi)
    )(idx, q, g, inc.delta0, held_projections(MODEL, q, zb))
    return got, ref, ref_a


@pytest.mark.parametrize("push", [0.0, 3000.0])
def test_held_node_terms_equal_jacfwd(push):
    """Each node's rate's derivatives and its axial held friction's, in (q, g, zb, vb), equal
    jacfwd's to 1e-12 of their largest: the nodes pressed into the bodies and stuck (the
    energy's forces), and pushed along them by random forces of the normal forces' size, so
    that some slip."""
    friction = SlipWeakening(mu_s=jnp.asarray(0.99), mu_k=jnp.asarray(0.82),
                             d_c=jnp.asarray(0.4), eps=jnp.asarray(EPS))
    args, inc, q, zb = _setup(BALL_HOLD)
    rng = np.random.default_rng(3)
    g = forces(MODEL, q, zb)[0] + push * jnp.asarray(rng.normal(size=(NS, 2)))
    vb = jnp.asarray(0.07)
    got, ref, ref_a = _node_terms_and_jacfwd(friction, inc, q, g, zb, vb)
    # the last three: the derivatives in the nodes' shares of corner normal forces (none here:
    # the rings' minor radius 0.3 R is no corner; tests/test_sharp_edges_newton.py has them)
    assert all(x is None for x in got[8:])
    for a, b in zip(got[:8], (*ref, *ref_a), strict=True):
        a, b = np.asarray(a), np.asarray(b)
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * max(np.abs(b).max(), 1e-300))
    # every body carries friction here, on stuck and on slipping nodes
    hf = ni.sheet_held_frame(MODEL, args, q, zb, g, inc.held_delta0)
    _, _, ds, dgv = hf.slopes(vb)
    touching = np.asarray(hf.normal > 0) & np.asarray(hf.live)[None]
    ds = np.asarray(ds)
    assert touching.sum(axis=1).min() >= 2
    assert np.abs(np.asarray(ref[3])).max() > 0  # the rates read the ball's velocity
    assert np.any(touching & (ds < 0.5))  # some stick
    if push > 0:
        assert np.any(touching & (ds > 0.5))  # some slip
    # a body that moves with the ball drags nothing with the ball's motion
    np.testing.assert_array_equal(np.asarray(dgv)[1], 0.0)


def _supported(args):
    # the ball pressed onto its support (the support's penalty's width is 1e-3)
    stage = Stage("s", Duration(duration=5.0), clamp_vz=-0.2, ball_mode=BALL_FORCE,
                  clamp_mode=CLAMP_POSITION, ball_force_end=0.0, support=True)
    return stage_args(stage, 0.0, 0.0, 0.3, (0.1, -0.2), args.friction, 1e-3, 0.1, 0.4, 0.05,
                       support_z=ZB + 4e-4, support_k=1e3)


# with the slow tests: the block Jacobian's compile with three bodies (10 s). The quick loop
# checks the held node terms (above) and the blocks with a frictional held body against jacfwd
# (test_weighted_friction.py::test_a_node_pinched_by_a_held_body_keeps_the_laws_form)
@pytest.mark.slow
@pytest.mark.parametrize("ball_mode", [BALL_HOLD, BALL_FORCE, "supported"])
def test_newton_blocks_with_several_frictional_bodies_equal_jacfwd(ball_mode):
    """Newton's matrix with three frictional held bodies (at rest, with the ball, moved by the
    stages) against jax.jacfwd of the residual: exact, the ball held or under force (free, or
    pressed onto its support); the border of one all but the far rank-one coupling."""
    args, inc, q, zb = _setup(BALL_FORCE if ball_mode == "supported" else ball_mode,
                              memory=False)  # the ball's law: Coulomb
    if ball_mode == "supported":
        args = _supported(args)
        assert float(args.support_force(zb)) > 0
        inc = eqx.tree_at(lambda i: i.args, inc, args)

    ref = check_newton_matrix(MODEL, args.friction, inc, q, zb, ball_mode != BALL_HOLD, 1e-12)
    if ball_mode != BALL_HOLD:
        assert np.abs(ref[-1, :-1]).max() > 0  # the ball's velocity reads the nodes
