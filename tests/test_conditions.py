"""The stage's boundary conditions (:mod:`dynslip.physics.conditions`): each clamp and ball mode
obeys its own law at the clamped edge and the ball, read through the vector field
(:func:`dynslip.physics.field.evaluate`) and the load increment's rates
(:mod:`dynslip.physics.solver.increment`) alike; one compile serves every mode; and a new mode is
one
class entered under a new integer."""

from __future__ import annotations

import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics import conditions as bc
from dynslip.physics.driver.member import stage_args
from dynslip.physics.field import Layout, StageArgs, evaluate
from dynslip.physics.friction import Coulomb
from dynslip.physics.protocols import (
    BALL_FORCE,
    BALL_HOLD,
    CLAMP_BAND,
    CLAMP_FORCE,
    CLAMP_POSITION,
    Duration,
    Stage,
)
from dynslip.physics.sheet import Penalty, penalty_pressure
from dynslip.physics.solver import increment as ni
from dynslip.physics.terms import forces
from helpers import small_model

N = 9
MODEL = small_model(N)
LAYOUT = Layout(N)
T = 0.7  # inside the stage's ramp (t0 = 0, ramp 2 s)
CLAMPS = (CLAMP_POSITION, CLAMP_FORCE, CLAMP_BAND)
BALLS = (BALL_HOLD, BALL_FORCE)


def _state(zb=0.0):
    """A sheet draped over the ball (nodes near its surface), then a taut span down to the
    edge: the edge's energy gradient is nonzero in both directions."""
    rng = np.random.default_rng(0)
    rbar = np.asarray(MODEL.mesh.rbar)
    th = np.minimum(1.05 * rbar, 1.2)
    rho = np.where(rbar < 1.2, 0.999 * np.sin(th), 1.1 * rbar)
    z = np.where(rbar < 1.2, 0.999 * np.cos(th), 0.999 * np.cos(1.2) - 0.6 * (rbar - 1.2))
    z = z + 0.003 * rng.normal(size=N)
    rho[0] = 0.0
    return LAYOUT.pack(jnp.asarray(rho), jnp.asarray(z + zb), jnp.asarray(zb), jnp.zeros(4))


def _args(ball_mode, clamp_mode, **kw):
    f = jnp.float64
    base = dict(
        t0=f(0.0), clamp_mode=jnp.asarray(clamp_mode, jnp.int32), vzc=f(-0.2), vrhoc=f(0.03),
        fc0=jnp.asarray([0.1, -0.2]), fc1=jnp.asarray([0.4, 0.3]),
        ball_mode=jnp.asarray(ball_mode, jnp.int32), vzb=f(0.05), f0=f(0.3), f1=f(-0.5),
        ramp=f(2.0), friction=Coulomb(mu=jnp.asarray(0.8)), eps=f(0.0), drag=f(0.1),
        ball_drag=f(0.4), weight=f(-0.05), support=f(1.0), support_z=f(0.002),
        support_k=f(1e3),
    )
    base.update(kw)
    return StageArgs(**base)


def _edge_gradient(y):
    rho, z, zb, _ = LAYOUT.unpack(y)
    g = jax.grad(MODEL.energy, argnums=(0, 1))(rho, z, zb)
    return np.array([g[0][-1], g[1][-1]])


def _edge_and_ball(model, y, args):
    """The clamped edge's velocity (absolute) and the ball's, with ``evaluate``'s auxiliaries."""
    dy, aux = evaluate(model, LAYOUT, T, y, args)
    rho_dot, z_dot, vb = LAYOUT.unpack(dy)[:3]
    return np.array([rho_dot[-1], z_dot[-1]]), float(vb), aux


def _increment_edge_and_ball(model, y, args):
    """The same from the load increment's rates (:func:`increment_rates`) at that state."""
    rho, z, zb, _ = LAYOUT.unpack(y)
    q = jnp.stack([rho, z - zb], axis=1)
    inc = ni.Increment(q0=q, zb0=zb, delta0=None, t1=jnp.asarray(T), h=jnp.asarray(0.1),
                       args=args)
    g, load = forces(model, q, zb)
    u, vb, _ = ni.increment_rates(model, args.friction, inc, q, zb, g, load)
    return np.asarray(u[-1]) + np.array([0.0, float(vb)]), float(vb)


def _ramp(a, b):
    return np.asarray(a) + (np.asarray(b) - np.asarray(a)) * (T / 2.0)


@pytest.mark.parametrize("ball_mode", BALLS)
def test_pinned_edge_moves_with_the_clamp_held_by_the_sheets_pull(ball_mode):
    """A pinned edge moves at the clamp's velocity whatever the ball does, and the clamp's force
    on the sheet is the energy's gradient there (it balances the sheet's pull)."""
    y = _state()
    v_edge, _, aux = _edge_and_ball(MODEL, y, _args(ball_mode, CLAMP_POSITION))
    np.testing.assert_allclose(v_edge, [0.03, -0.2], rtol=0, atol=1e-14)
    g = _edge_gradient(y)
    assert np.all(np.abs(g) > 1.0)  # the sheet pulls the clamp
    np.testing.assert_allclose([aux.clamp_force_rho, aux.clamp_force], g, rtol=1e-12)


@pytest.mark.parametrize("ball_mode", BALLS)
def test_force_clamp_balances_its_edge(ball_mode):
    r"""Under the force clamp the edge is a free node: $\eta A\,(v - v_b e_z) = F_c(t) - g$, the
    force ramped linearly from ``fc0`` to ``fc1`` over the stage's ramp."""
    y = _state()
    args = _args(ball_mode, CLAMP_FORCE)
    v_edge, vb, aux = _edge_and_ball(MODEL, y, args)
    f_c = _ramp([0.1, -0.2], [0.4, 0.3])
    eta_a = 0.1 * float(MODEL.mesh.area[-1])
    np.testing.assert_allclose(eta_a * (v_edge - [0.0, vb]), f_c - _edge_gradient(y), rtol=1e-12)
    np.testing.assert_allclose([aux.clamp_force_rho, aux.clamp_force], f_c, rtol=1e-14)


@pytest.mark.parametrize("grip", [5.0, 0.02])
def test_band_holds_below_its_grip_and_slides_past_it(grip):
    r"""The band carries the edge with the clamp while the pull along the wall $F_z = -g_z$ is
    below the grip $c = g_b\,2\pi\rho_c$; past it the edge slides along the wall at $w$ with
    $\eta A\,w = F_z - c\,{\rm sign}\,F_z$ (the ideal law, no smoothing), and the wall's friction
    dissipates $c\,|w| \ge 0$."""
    model = eqx.tree_at(lambda m: m.band_grip, MODEL, jnp.asarray(grip))
    y = _state()
    v_edge, _, aux = _edge_and_ball(model, y, _args(BALL_HOLD, CLAMP_BAND))
    g = _edge_gradient(y)
    rho_c = float(LAYOUT.unpack(y)[0][-1])
    c = grip * 2 * np.pi * rho_c
    pull = -g[1]
    eta_a = 0.1 * float(MODEL.mesh.area[-1])
    w = v_edge[1] - (-0.2)  # the edge's slip relative to the clamp
    expect = np.sign(pull) * max(abs(pull) - c, 0.0) / eta_a
    assert (abs(pull) < c) == (grip == 5.0)  # one case on each side of the grip
    np.testing.assert_allclose(w, expect, rtol=1e-12, atol=1e-14)
    assert v_edge[0] == pytest.approx(0.03, abs=1e-15)
    edge = bc.Edge(jnp.asarray(g), jnp.asarray(rho_c), jnp.asarray(eta_a))
    em = bc.Band().motion(model, _args(BALL_HOLD, CLAMP_BAND), edge, jnp.asarray(g), 0.05)
    assert float(em.friction) == pytest.approx(c * abs(expect), rel=1e-12)
    assert float(em.friction) >= 0.0
    np.testing.assert_allclose(aux.clamp_force, g[1], rtol=1e-12)


@pytest.mark.parametrize("clamp_mode", CLAMPS)
def test_held_ball_moves_as_prescribed_and_its_hold_closes_the_balance(clamp_mode):
    r"""A held ball moves at $v_{zb}$; the hold's force closes the ball's balance,
    $\eta_b v_b = F + C_z + F_g$ ($C_z$ the clamp's axial force on the sheet, no held bodies)."""
    y = _state()
    _, vb, aux = _edge_and_ball(MODEL, y, _args(BALL_HOLD, clamp_mode))
    assert vb == 0.05
    balance = float(aux.ball_reaction) + float(aux.clamp_force) - 0.05
    assert 0.4 * vb == pytest.approx(balance, rel=1e-13)


@pytest.mark.parametrize(("clamp_mode", "zb"), list(itertools.product(CLAMPS, [0.0, 0.01])))
def test_forced_ball_moves_under_its_force_support_pull_and_weight(clamp_mode, zb):
    r"""A force-driven ball moves at $v_b = (F(t) + F_s(z_b) + C_z + F_g)/\eta_b$: the ramped
    force, the support's unilateral push (the penalty below ``support_z`` = 0.002, none above),
    the clamp's axial force on the sheet and the weight."""
    y = _state(zb)
    _, vb, aux = _edge_and_ball(MODEL, y, _args(BALL_FORCE, clamp_mode))
    f_s = float(1e3 * penalty_pressure(Penalty(jnp.asarray(1.0), 1e-3), jnp.asarray(0.002 - zb)))
    assert (f_s > 0) == (zb == 0.0)
    f = float(_ramp(0.3, -0.5))
    assert float(aux.ball_reaction) == pytest.approx(f + f_s, rel=1e-14)
    expect = (f + f_s + float(aux.clamp_force) - 0.05) / 0.4
    assert vb == pytest.approx(expect, rel=1e-13)


@pytest.mark.parametrize(("ball_mode", "clamp_mode"), list(itertools.product(BALLS, CLAMPS)))
def test_the_vector_field_and_the_increment_share_the_conditions(ball_mode, clamp_mode):
    """The vector field and the load increment read the edge's and the ball's velocities from
    the same laws: equal at any state, in every mode."""
    model = eqx.tree_at(lambda m: m.band_grip, MODEL, jnp.asarray(0.02))
    y = _state()
    args = _args(ball_mode, clamp_mode)
    v_edge, vb, _ = _edge_and_ball(model, y, args)
    v_edge_i, vb_i = _increment_edge_and_ball(model, y, args)
    assert vb_i == pytest.approx(vb, rel=1e-14, abs=1e-15)
    np.testing.assert_allclose(v_edge_i, v_edge, rtol=1e-13, atol=1e-14)


def test_one_compile_serves_every_mode():
    """The modes are traced integers: one compiled vector field gives every mode's rates, the
    same as evaluated eagerly mode by mode."""
    traces = []

    @jax.jit
    def rates(y, args):
        traces.append(1)
        return evaluate(MODEL, LAYOUT, T, y, args)[0]

    y = _state()
    for ball_mode, clamp_mode in itertools.product(BALLS, CLAMPS):
        args = _args(ball_mode, clamp_mode)
        eager = np.asarray(evaluate(MODEL, LAYOUT, T, y, args)[0])
        # to rounding on the rates' scale (compiled and eager arithmetic round apart)
        np.testing.assert_allclose(rates(y, args), eager, rtol=0,
                                   atol=1e-14 * np.abs(eager).max())
    assert len(traces) == 1


class AxialForce(bc.AbstractClamp):
    """A clamp outside the package: it carries the edge radially at the clamp's radial velocity
    and pulls it axially with the ramped force's axial part alone."""

    carried = False

    def force(self, args, t, g):
        return jnp.stack([g[0], args.clamp_force(t)[1]])

    def motion(self, model, args, edge, force, vb):
        zero = jnp.zeros_like(edge.rho)
        u = jnp.stack([args.vrhoc, (force[1] - edge.g[1]) / edge.eta_a])
        return bc.EdgeMotion(u, zero, zero)


def test_a_new_clamp_mode_is_one_class(monkeypatch):
    """A mode entered under a new integer drives the edge in the vector field and in the load
    increment alike, and its law holds there: radially at the clamp's velocity, axially
    $\\eta A\\,(\\dot z - v_b) = F_{c,z}(t) - g_z$."""
    monkeypatch.setitem(bc.CLAMPS, len(bc.CLAMPS), AxialForce())
    mode = len(bc.CLAMPS) - 1
    y = _state()
    for ball_mode in BALLS:
        args = _args(ball_mode, mode)
        v_edge, vb, aux = _edge_and_ball(MODEL, y, args)
        eta_a = 0.1 * float(MODEL.mesh.area[-1])
        g = _edge_gradient(y)
        f_z = float(_ramp(-0.2, 0.3))
        assert v_edge[0] == pytest.approx(0.03, abs=1e-15)
        assert eta_a * (v_edge[1] - vb) == pytest.approx(f_z - g[1], rel=1e-12)
        assert float(aux.clamp_force) == pytest.approx(f_z, rel=1e-14)
        v_edge_i, vb_i = _increment_edge_and_ball(MODEL, y, args)
        np.testing.assert_allclose(v_edge_i, v_edge, rtol=1e-13)
        assert vb_i == pytest.approx(vb, rel=1e-14)


def test_a_stage_in_an_unknown_mode_is_refused(monkeypatch):
    """A stage whose mode no registry holds is refused where its loads are built (inside the
    compiled step a traced integer outside the registry would select another mode's law); once
    entered, the mode is accepted."""
    def build(clamp_mode):
        stage = Stage("s", Duration(duration=1.0), clamp_mode=clamp_mode)
        return stage_args(stage, 0.0, 0.0, 0.0, (0.0, 0.0), Coulomb(mu=jnp.asarray(0.8)), 0.0,
                          0.1, 0.4, 0.0)

    mode = len(bc.CLAMPS)
    with pytest.raises(ValueError, match=f"clamp mode {mode}"):
        build(mode)
    monkeypatch.setitem(bc.CLAMPS, mode, AxialForce())
    assert int(build(mode).clamp_mode) == mode
