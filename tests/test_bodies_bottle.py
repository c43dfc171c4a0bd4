"""The bottle under the ball (issue 22 item 2, docs/bodies.md "The bottle"): held bodies that
move with the ball in the tube's frame.

- The bottle's contact carries load only where the sheet touches it: its axial load is the sum
  of the penalty's axial forces over the nodes that penetrate it, exactly 0 when none does, and
  it sees the nodes relative to the ball (moving nodes and ball together leaves it unchanged).
- A run with a ring that moves with the held ball is the run with the ring fixed at the ball's
  placement, shifted (the sheet's drag and slip are relative to the ball, so both are the same
  problem in two frames); at rest the clamp's pull is the hold's plus the ring's load.
- A bottle the sheet never reaches changes nothing (to rounding).
- Bad input: one line, exit 2, nothing written.
The bottle is one smooth solid (issue 42 item 2; its geometry: tests/test_apparatus.py).
Meshes of N = 24 nodes.
"""

from __future__ import annotations

import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Cylinder, Sphere
from dynslip.physics.bodies.apparatus import bottle
from dynslip.physics.bodies.held import Held
from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh, penalty_pressure
from dynslip.physics.solver.methods import Settings
from helpers import push_and_hold, run_refused, run_sheet, set_field
from numerics import named_solver

# the quick loop (-m 'not slow') leaves these out: each test runs the sheet over the bottle (N = 24)
pytestmark = pytest.mark.slow

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "method2.yaml"
N = 24
RIM, PRE, TAU = 2.54, 1.05, 0.1
MAT = make_material("gent", jm=50.0)
PEN = Penalty(jnp.asarray(1e4), jnp.asarray(1e-3))
COULOMB = Coulomb(mu=jnp.asarray(0.7), eps=jnp.asarray(1e-3))
BOTTLE = bottle(20.0)  # the scenario's default sizes, units of R
MESH = make_mesh(N, RIM / PRE)


def _model(bodies):
    return SheetModel(MESH, MAT, PEN, ball=Sphere(), bodies=bodies)


def test_bottle_carries_load_only_where_the_sheet_touches_it():
    """L = sum_i dE_h/dz_i equals sum over the penetrating nodes of A_i p_i (-n_z) (1e-12), the
    pressure is exactly 0 at every node at a gap, L is exactly 0 with no node touching, and the
    bottle sees the nodes relative to the ball: shifting nodes and ball together leaves L as it
    was, while a bottle that does not move with the ball loses it."""
    moving = tuple(Held(b, COULOMB, moves_with_ball=True) for b in BOTTLE)
    model = _model(moving)
    zb = 0.37
    # start points beside the body and above the shoulder, moved onto the nearest glass and set
    # off it by a gap: 2e-3 R into it at every third node, 0.05 R clear elsewhere
    (glass,) = BOTTLE
    rb = float(glass.outline()[:, 0].max())  # the body's radius: the shoulder meets it here
    z_body = max(p[1] for seg in glass.segments for p in (seg.start, seg.end) if p[0] == rb)
    z_top = z_body + 1.0
    x0 = jnp.stack([jnp.full(N, 2.0), jnp.linspace(z_top - 2.5, z_top, N) + zb], -1)
    proj = [b.project(x0, zb) for b in BOTTLE]
    k = np.argmin(np.stack([np.asarray(p.distance) for p in proj]), axis=0)
    nrm = np.stack([np.asarray(p.normal) for p in proj])[k, np.arange(N)]
    dist0 = np.stack([np.asarray(p.distance) for p in proj])[k, np.arange(N)]
    foot = np.asarray(x0) - dist0[:, None] * nrm
    gap = np.where(np.arange(N) % 3 == 0, -2e-3, 0.05)
    x_in = foot + gap[:, None] * nrm
    r_in, z_in = jnp.asarray(x_in[:, 0]), jnp.asarray(x_in[:, 1])
    load = float(model.held_load(r_in, z_in, zb))
    total = 0.0
    touched = 0
    for b in BOTTLE:
        dist = np.asarray(b.distance(jnp.asarray(x_in), zb))
        p = np.asarray(penalty_pressure(PEN, -dist))
        assert np.all(p[dist >= 0] == 0.0)  # no pressure at a gap, exactly
        touched += int(np.sum(dist < 0))
        nz = np.asarray(b.normal(jnp.asarray(x_in), zb))[:, 1]
        total += float(np.sum(np.asarray(MESH.area) * p * -nz))
    assert touched == int(np.sum(gap < 0)) >= 4
    assert load < 0.0  # the sheet pressed onto the shoulder pushes the bottle down
    np.testing.assert_allclose(load, total, rtol=1e-12)
    # off the glass: exactly no load
    assert float(model.held_load(r_in + 0.01, z_in, zb)) == 0.0
    # relative to the ball: shift nodes and ball by the same amount (2 R: the fixed bottle then
    # lies below every node, the flank under the lowest one)
    np.testing.assert_allclose(float(model.held_load(r_in, z_in + 2.0, zb + 2.0)), load,
                               rtol=1e-12)  # fmt: skip
    fixed = _model(tuple(Held(b, COULOMB) for b in BOTTLE))
    assert float(fixed.held_load(r_in, z_in + 2.0, zb + 2.0)) == 0.0


# a ring (a bottle's shoulder) under the ball: moving with the ball at zb = ZB, or fixed there
ZB = 0.6
# the ring's rounded edge wider than a corner (physics/bodies/corners.CORNER_RADIUS): the sheet
# lies on it at nodes, where the held friction acts (a held body's corners are frictionless)
RING = dict(radius=1.35, inner_radius=1.05, z_bottom=-3.0, z_top=-0.25, edge_radius=0.15)
RING_AT = Cylinder(**{**RING, "z_bottom": RING["z_bottom"] + ZB, "z_top": RING["z_top"] + ZB})


def _run(model, z_sheet, ball_z0, depth, speed=0.2, hold=4.0):
    stages = push_and_hold(z_sheet, depth, speed, hold)
    protocol = Protocol(stages, clamp_rho0=RIM, clamp_z0=z_sheet, ball_z0=ball_z0)
    friction = Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(1e-3))
    settings = Settings(solver=named_solver(), save_interval=1.0)
    return run_sheet(model, protocol, friction, settings, pre=PRE, z_sheet=z_sheet, tau=TAU)


@pytest.fixture(scope="module")
def fixed_run():
    """The same with the ring fixed at the ball's placement."""
    model = _model((Held(RING_AT, COULOMB),))
    return model, _run(model, 1.02 + ZB, ZB, -2.5 + ZB)


@pytest.fixture(scope="module")
def moving_run():
    """The sheet pushed down past the ball held at ZB onto a ring that moves with it."""
    model = _model((Held(Cylinder(**RING), COULOMB, moves_with_ball=True),))
    return model, _run(model, 1.02 + ZB, ZB, -2.5 + ZB)


def test_ring_moving_with_the_ball_is_the_ring_at_its_placement(moving_run, fixed_run):
    """The ring that moves with the ball held at ZB gives the run of a fixed ring placed at ZB
    (every frame's rho, z to 1e-9 R): the gap and the slip are relative to the ball, as they
    are to a body at rest beside a ball at rest. At rest the clamp's pull is the hold's plus
    the ring's load (the ring's load goes to the lab, not to the hold), and the ring carries
    load (the sheet lies on it)."""
    model, res = moving_run
    fixed, ref = fixed_run
    assert len(res.frames) == len(ref.frames)
    for a, b in zip(res.frames, ref.frames, strict=True):
        np.testing.assert_allclose(np.asarray(a["rho"]), np.asarray(b["rho"]), atol=1e-9)
        np.testing.assert_allclose(np.asarray(a["z"]), np.asarray(b["z"]), atol=1e-9)
    f = res.frames[-1]
    rho, z = jnp.asarray(np.asarray(f["rho"])), jnp.asarray(np.asarray(f["z"]))
    load = float(model.held_load(rho, z, ZB))
    assert load < -1e-2
    np.testing.assert_allclose(float(fixed.held_load(rho, z)), load, rtol=1e-10)
    g_rho, g_z, _ = model.gradients(rho, z, ZB)
    hf = model.held_friction(rho, z, -jnp.stack([g_rho, g_z]), TAU, 1e-3, ZB)
    axial = float(hf.axial(0.0))  # the ring's friction, its reaction on the ring
    assert abs(axial) > 1e-3
    np.testing.assert_allclose(
        float(f["clamp_force"]), load - axial - float(f["ball_reaction"]), rtol=1e-6
    )


def test_a_bottle_the_sheet_never_reaches_changes_nothing(fixed_run):
    """The scenario's bottle (Coulomb 0.7, moving with the ball) added under the run with the
    frictional ring (as the tube is in the scenario), the sheet never reaching the glass: every
    frame equal to the run without it to rounding (1e-12 R; measured 1.6e-14 R: the compiled
    program differs, so XLA may order the same sums differently; not bit for bit)."""
    _, bare = fixed_run
    parts = tuple(Held(b, COULOMB, moves_with_ball=True) for b in BOTTLE)
    with_bottle = _run(_model((Held(RING_AT, COULOMB),) + parts), 1.02 + ZB, ZB, -2.5 + ZB)
    assert len(bare.frames) == len(with_bottle.frames)
    for a, b in zip(bare.frames, with_bottle.frames, strict=True):
        for key in ("rho", "z", "ball_z", "clamp_force", "ball_reaction"):
            np.testing.assert_allclose(np.asarray(b[key]), np.asarray(a[key]), rtol=0, atol=1e-12)
    f = with_bottle.frames[-1]
    x = jnp.stack([jnp.asarray(np.asarray(f["rho"])), jnp.asarray(np.asarray(f["z"]))], -1)
    assert min(float(jnp.min(b.distance(x, ZB))) for b in BOTTLE) > 0.05  # never reached


@pytest.mark.parametrize(
    "dotted, value, words",
    [
        ("physics.bottle.neck_od_mm", 40.0, ("bottle.neck_od_mm", "overlaps the ball")),
        ("physics.bottle.neck_od_mm", 52.0, ("bottle.neck_od_mm", "overlaps the ball")),
        ("physics.bottle.body_od_mm", 96.0, ("bottle.body_od_mm", "tube")),
        ("physics.bottle.body_od_mm", 20.0, ("bottle.body_od_mm", "neck")),
        ("physics.bottle.neck_wall_mm", 12.7, ("bottle.neck_wall_mm",)),
        ("physics.bottle.neck_length_mm", -5.0, ("neck_length_mm",)),
        ("physics.bottle.body_height_mm", 0.0, ("body_height_mm",)),
        ("physics.bottle.shoulder_height_mm", -1.0, ("shoulder_height_mm",)),
        ("physics.bottle.mu", -0.1, ("mu",)),
        ("physics.bottle.neck_fillet_mm", 70.0, ("neck_fillet_mm = 70", "does not fit")),
        ("physics.bottle.shoulder_fillet_mm", -1.0, ("shoulder_fillet_mm",)),
    ],
)
def test_bad_bottle_input(tmp_path, capsys, dotted, value, words):
    run_refused(tmp_path, capsys, SCENARIO, set_field(dotted, value), *words)


def test_bottle_scenario_builds_the_bottle_at_rest_and_the_tube_moved():
    """The scenario builds the tube (moved by the stages: the lab frame) and the bottle, one
    solid at rest (Coulomb 0.7), the neck's lip tangent-below the resting ball, its body
    inside the tube."""
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load

    model, _, _ = build_core(load(SCENARIO))
    tube, glass = model.bodies
    assert tube.stage and not tube.moves_with_ball
    assert not (glass.stage or glass.moves_with_ball or glass.free)
    assert float(glass.friction.mu) == 0.7
    # the lip touches the unit ball (distance 0 from the sphere of radius 1: the support ring)
    theta = np.linspace(2.4, math.pi, 400)
    pts = jnp.stack([jnp.sin(theta), jnp.cos(theta)], -1)
    np.testing.assert_allclose(float(jnp.min(glass.body.distance(pts))), 0.0, atol=1e-5)
    widest = float(glass.body.outline()[:, 0].max())
    np.testing.assert_allclose(widest, 35.0 / 20.0)
    assert widest < tube.body.inner_radius
