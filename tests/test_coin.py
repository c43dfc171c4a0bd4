"""The coin as the ball and held bodies built from the schema (docs/bodies.md, docs/coin.md).

Through the scenario path (``physics.ball: disc``, ``physics.bodies``, :func:`build_core`, the
driver): a sheet pushed over a frictionless coin lies on its flat top face uniformly and
equibiaxially stretched (the closed form of a membrane on a frictionless plane); at rest the
clamp's pull is the coin's hold; a held cylinder given in mm carries the part of the pull the
closed balance says; the trapped criterion of a disc sits at its edge's mid-height and the
sphere's is today's. Small meshes (N = 24).
"""

from __future__ import annotations

import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.schema.base import load_data, validate_data

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
N = 24


def _push_and_hold(data, depth_mm, speed_mm_s, hold_s=4.0):
    data["physics"]["stages"] = [
        {"name": "push_down", "clamp_to_z_mm": depth_mm, "clamp_speed_mm_s": speed_mm_s},
        {"name": "hold", "duration_s": hold_s},
    ]
    data["numerics"]["nodes"] = N
    data["numerics"]["save_interval_s"] = 1.0
    return data


def _run(data):
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    sc = validate_data(data)
    model, protocol, kw = build_core(sc)
    res = simulate(model, protocol, **kw)
    assert res.failed is None, res.failed
    f = res.frames[-1]
    return sc, model, f, np.asarray(f["rho"]), np.asarray(f["z"])


@pytest.fixture(scope="module")
def coin_run():
    """scenarios/coin.yaml's coin, frictionless, the sheet pushed 30 mm below its centre, held."""
    data = load_data(SCENARIOS / "coin.yaml")
    data["physics"]["friction"] = {"law": "coulomb", "mu": 0.0}
    return _run(_push_and_hold(data, -30.0, 2.0))


@pytest.fixture(scope="module")
def post_run():
    """The ball (held) and a frictionless tube wall given in mm under the sheet's path, the
    sheet pushed to 50 mm below the ball's centre, held."""
    data = load_data(SCENARIOS / "method2_let_go.yaml")
    data["physics"]["bodies"] = [
        {"name": "wall", "kind": "cylinder", "radius_mm": 32.0, "inner_radius_mm": 26.0,
         "height_mm": 40.0, "edge_radius_mm": 2.0, "z_mm": -46.0},
    ]
    return _run(_push_and_hold(data, -50.0, 4.0))


@pytest.mark.slow
def test_coin_top_face_stretches_the_sheet_uniformly_and_equibiaxially(coin_run):
    """On the coin's frictionless flat top the in-plane equilibrium d(rho T_r)/d rho = T_phi holds
    with T_r = T_phi: lambda_theta = lambda_phi, the same at every node on the face (the stretch
    the pull over the edge sets, past the pre-stretch), the sheet flat over the face. The edge is
    a corner (physics/bodies/corners.py): the element over it stands on its circle, so the flat
    sheet lies on the face or above it by at most the edge radius (docs/coin.md)."""
    sc, model, f, rho, z = coin_run
    coin = model.ball
    top = coin.centre_z + coin.thickness / 2
    lt, lp = np.asarray(f["lambda_theta"]), np.asarray(f["lambda_phi"])
    # nodes on the flat face, clear of the rounded edge; the last of them is joined by its outer
    # element to the edge (where the sheet's pull is taken), so the closed form holds inward
    h = z - float(f["ball_z"]) - top
    on = (rho < coin.radius - coin.edge_radius) & (h > -2e-3) & (h < coin.edge_radius + 2e-3)
    assert on[0] and not on[-1]
    last = int(np.argmin(on)) - 1
    face = np.arange(rho.size) < last
    assert face.sum() >= 3 and on[face].all()
    assert np.ptp(z[face]) < 1e-6  # flat
    assert lp[face].min() > sc.physics.pre_stretch + 0.01  # stretched past the start
    np.testing.assert_allclose(lt[face], lp[face], rtol=1e-6)
    np.testing.assert_allclose(lp[face], lp[0], rtol=1e-6)


@pytest.mark.slow
def test_coin_hold_carries_the_clamp_pull_at_rest(coin_run):
    """No held bodies: at rest the clamp's axial pull on the sheet is the hold's force on the
    coin (C_z = -F_h), which is the coin's pressure load sum_i A_i p_i (-n_z), none at a gap,
    plus its corners' (the edge's circles against the segments: the sum of their energy's
    gradient in the nodes, physics/bodies/corners.py)."""
    from dynslip.physics.sheet import penalty_pressure

    _, model, f, rho, z = coin_run
    np.testing.assert_allclose(f["clamp_force"], -f["ball_reaction"], rtol=1e-8)
    x = jnp.stack([jnp.asarray(rho), jnp.asarray(z)], -1)
    proj = model.ball.project(x, f["ball_z"])
    d = np.asarray(proj.distance)
    p = np.asarray(penalty_pressure(model.penalty, -jnp.asarray(d)))
    assert np.all(p[d > 0] == 0.0)
    load = np.sum(np.asarray(model.mesh.area) * p * -np.asarray(proj.normal)[:, 1])
    from dynslip.physics.bodies.corners import corner_terms

    _, gc = corner_terms(model.ball, x, model.penalty, f["ball_z"])
    load = load + float(jnp.sum(gc[:, 1]))
    np.testing.assert_allclose(load, f["clamp_force"], rtol=1e-6)
    assert load < -1.0


@pytest.mark.slow
def test_held_cylinder_from_the_schema_shares_the_clamp_pull(post_run):
    """The schema's cylinder (mm over R) is a held body the sheet lies on: at rest the clamp's
    pull is the hold's plus its load, C_z = L - F_h; its pressure only where the sheet
    penetrates it, and it carries part of the pull: at its nodes, or (its rounded top's radius
    0.1 R is a corner, physics/bodies/corners.py) between them."""
    from dynslip.physics.sheet import penalty_pressure

    _, model, f, rho, z = post_run
    (wall,) = model.bodies
    load = float(model.held_load(jnp.asarray(rho), jnp.asarray(z), f["ball_z"]))
    np.testing.assert_allclose(f["clamp_force"], load - f["ball_reaction"], rtol=1e-8)
    x = jnp.stack([jnp.asarray(rho), jnp.asarray(z)], -1)
    d = np.asarray(wall.body.distance(x))
    p = np.asarray(penalty_pressure(model.penalty, -jnp.asarray(d)))
    assert np.all(p[d > 0] == 0.0)
    from dynslip.physics.bodies.corners import corner_normal

    corner = float(jnp.max(corner_normal(wall.body, x, model.penalty)))
    # the sheet presses down on the wall's rounded top
    assert max(p.max(), corner) > 1.0 and load < -0.1


def test_disc_trap_threshold_is_its_edge_mid_height_and_the_sphere_is_today():
    """The disc's threshold s* is the surface coordinate of its edge's mid-height point
    (a, z_c); the unit sphere's criterion is theta_max > pi/2 exactly, s_max = theta_max."""
    from dynslip.analysis.summary import contact_reach, trap_criterion
    from dynslip.physics.bodies import Disc, Sphere

    coin = Disc(1.0, 1.75 / 12.13, 0.3 / 12.13)
    crit = trap_criterion(coin)
    s_edge = float(coin.project(jnp.array([1.0 + 1e-3, 0.0])).s)
    np.testing.assert_allclose(crit.threshold(), s_edge, rtol=0, atol=1e-12)
    ball = trap_criterion(Sphere())
    assert ball.threshold() == math.pi / 2
    for theta in (1.2, math.pi / 2, 1.9):
        assert contact_reach(Sphere(), None, theta) == theta
