"""Observables per held body (issue 21 item 6): the surface coordinate against closed forms,
contact by pressure, stick and slip relative to a frictional body (at rest, moving with the
ball), a body never touched, the dataset's body dimension and units, the summary's extent."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.analysis.clearance import contact_extent
from dynslip.data.files import check_units
from dynslip.data.trajectory import PER_NODE, PER_TIME, frames_to_dataset
from dynslip.physics.bodies import Cone, Cylinder, Torus
from dynslip.physics.bodies.held import Held
from dynslip.physics.bodies.observe import (
    FREE,
    SLIP_BACK,
    SLIP_ON,
    STUCK,
    TOUCHING,
    body_observables,
)
from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import NeoHookean
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh, penalty_pressure

N = 10
DEPTH = 5e-4  # penetration of the nodes placed on a body (R): penalty pressure well above 1e-2
A, ZB, ZT = 1.5, -3.0, 0.0  # the cylinder: radius, bottom, top


def _model(*bodies):
    return SheetModel(make_mesh(N, 2.0), NeoHookean(), Penalty(), bodies=bodies)


def _on_wall():
    """Nodes 1..N-2 just inside the cylinder's outer wall (the pole far above, the edge far
    outside): positions (rho, z) and the wall heights."""
    zw = np.linspace(ZT - 0.3, ZB + 0.3, N - 2)
    rho = np.r_[0.0, np.full(N - 2, A - DEPTH), A + 2.0]
    z = np.r_[ZT + 2.0, zw, ZB]
    return jnp.asarray(rho), jnp.asarray(z), zw


def _obs(model, rho, z, f=None, vb=0.0, zb=0.0):
    f = jnp.zeros((2, N)) if f is None else f
    return {k: np.asarray(v) for k, v in
            body_observables(model, rho, z, zb, f, vb, 1.0, 0.0, 1e-2).items()}


def test_surface_coordinate_on_a_cylinder_wall_is_the_closed_form():
    rho, z, zw = _on_wall()
    o = _obs(_model(Cylinder(A, ZB, ZT)), rho, z)
    # profile: the top face from the axis outward (length A), then down the outer wall
    np.testing.assert_allclose(o["body_s"][0, 1:-1], A + (ZT - zw), rtol=0, atol=1e-12)
    assert o["body_contact"][0].tolist() == [0] + [1] * (N - 2) + [0]
    assert o["body_n_contact"][0] == N - 2
    np.testing.assert_allclose([o["body_s_min"][0], o["body_s_max"][0]],
                               [A + 0.3, A + (ZT - ZB) - 0.3], atol=1e-12)
    # frictionless: touching, not stuck nor slipping
    assert set(o["body_state"][0, 1:-1]) == {TOUCHING}


def test_surface_coordinate_on_a_cone_flank_is_the_distance_from_the_apex():
    cone = Cone(radius=2.0, z_base=-2.0, z_apex=0.0)  # flank from the apex (0, 0) to (2, -2)
    u = np.linspace(0.2, 0.8, N - 2)
    inward = np.array([-1.0, -1.0]) / np.sqrt(2)  # into the solid, normal to the flank
    pts = np.stack([2.0 * u, -2.0 * u], -1) + DEPTH * inward
    rho = jnp.asarray(np.r_[0.0, pts[:, 0], 5.0])
    z = jnp.asarray(np.r_[3.0, pts[:, 1], -5.0])
    o = _obs(_model(cone), rho, z)
    np.testing.assert_allclose(o["body_s"][0, 1:-1], np.hypot(2.0 * u, 2.0 * u), atol=1e-12)
    assert o["body_n_contact"][0] == N - 2


def _tangential(model, rho, z, ratio):
    """Driving forces along the wall's tangent (down: increasing s) of ``ratio`` times mu N at
    each node (N the penalty's normal force), pushing the node onto the wall too."""
    normal = np.asarray(model.mesh.area * penalty_pressure(model.penalty, DEPTH))
    ft = -np.asarray(ratio) * 0.5 * normal  # along -z: the wall's tangent toward increasing s
    return jnp.asarray(np.stack([np.zeros(N), ft]))


def test_stuck_below_mu_n_and_slipping_along_the_force_beyond_it():
    rho, z, _ = _on_wall()
    model = _model(Held(Cylinder(A, ZB, ZT), Coulomb(mu=0.5)))
    ratio = np.r_[0.0, 0.2, 0.5, 0.9, 1.5, 3.0, -3.0, -0.5, 0.0, 0.0]
    o = _obs(model, rho, z, _tangential(model, rho, z, ratio))
    st = o["body_state"][0]
    assert st[0] == FREE and st[-1] == FREE  # out of contact; the edge never counts
    assert st[1:4].tolist() == [STUCK] * 3  # |G| <= mu N: at rest on the body
    assert st[4:6].tolist() == [SLIP_ON] * 2  # pushed down the wall: toward increasing s
    assert st[6] == SLIP_BACK and st[7] == STUCK


def test_a_sheet_at_rest_on_a_body_at_rest_is_stuck_and_the_moving_ball_drags_it_along():
    """No driving force: stuck relative to a body at rest while the ball rests; with the ball
    moving fast the drag relative to the ball slides the nodes over the body at rest, in the
    ball's direction, but not over a body that moves with the ball."""
    rho, z, _ = _on_wall()
    body = Cylinder(A, ZB, ZT)
    at_rest = _model(Held(body, Coulomb(mu=0.5)))
    o = _obs(at_rest, rho, z, vb=0.0)
    assert set(o["body_state"][0, 1:-1]) == {STUCK}
    up = _obs(at_rest, rho, z, vb=1e3)  # ball rising: the node dragged up, toward lower s
    assert set(up["body_state"][0, 1:-1]) == {SLIP_BACK}
    carried = _model(Held(body, Coulomb(mu=0.5), moves_with_ball=True))
    c = _obs(carried, rho, z + 0.7, vb=1e3, zb=0.7)  # the body displaced with the ball
    assert set(c["body_state"][0, 1:-1]) == {STUCK}
    np.testing.assert_allclose(c["body_s"], o["body_s"], atol=1e-12)


def test_a_body_never_touched_has_no_contact_and_nan_extent():
    rho, z, _ = _on_wall()
    o = _obs(_model(Cylinder(A, ZB, ZT), Held(Torus(6.0, 0.3), Coulomb(mu=0.5))), rho, z)
    assert o["body_n_contact"].tolist() == [N - 2, 0]
    assert np.isnan(o["body_s_min"][1]) and np.isnan(o["body_s_max"][1])
    assert set(o["body_state"][1]) == {FREE}
    assert np.isfinite(o["body_s"][1]).all()


def test_a_model_without_held_bodies_records_nothing_per_body():
    rho, z, _ = _on_wall()
    assert body_observables(_model(), rho, z, 0.0, jnp.zeros((2, N)), 0.0, 1.0, 0.0, 1e-2) == {}


def _frames(bodies: bool, nt=3):
    rng = np.random.default_rng(0)
    out = []
    for i in range(nt):
        f = {k: rng.normal(size=N) for k in PER_NODE}
        f |= {k: float(rng.normal()) for k in PER_TIME if k not in ("stage", "energy_residual")}
        f |= {"state": np.zeros(N, np.int8), "time": float(i), "stage": 0}
        if bodies:
            contact = np.zeros((2, N), np.int8)
            contact[0, 2:2 + i + 1] = 1
            f |= {"body_s": np.tile(np.linspace(0, 1, N), (2, 1)), "body_contact": contact,
                  "body_state": contact.copy(), "body_n_contact": contact.sum(1),
                  "body_s_min": np.array([2 / (N - 1), np.nan]),
                  "body_s_max": np.array([(2 + i) / (N - 1), np.nan]),
                  "body_z": np.array([0.0, 0.1 * i])}
        out.append(f)
    return out


def _dataset(frames, names=None):
    return frames_to_dataset(
        frames, np.linspace(0, 2, N), 0.0, True, ["only"], scenario_json="{}",
        scales={"R_m": 0.02, "G_Pa": 1e5, "h0_m": 1e-4, "force_scale_N": 0.2},
        contact_threshold=1e-2,
        friction={"mu": 0.5, "friction_law": "coulomb", "mu_s": 0.5, "mu_k": 0.5, "d_c": 0.0},
        friction_smoothing=0.0, body_names=names)


def test_dataset_body_dimension_names_and_units_parse():
    ds = _dataset(_frames(True), ["tube wall", "ring"])
    assert ds["body"].values.tolist() == ["tube wall", "ring"]
    assert ds["body_state"].dims == ("time", "body", "rbar")
    assert ds["body_n_contact"].dims == ("time", "body")
    check_units(ds)
    for name in ("body_s", "body_s_min", "body_s_max", "body_z"):
        assert ds[name].attrs["scale"] == "R"
    np.testing.assert_array_equal(ds["body_z"].values[:, 1], [0.0, 0.1, 0.2])
    assert len(ds["body_state"].attrs["flag_meanings"].split()) == 5
    plain = _dataset(_frames(False))
    assert "body" not in plain.dims and not [v for v in plain.data_vars if v.startswith("body")]
    with pytest.raises(ValueError, match="body_names"):
        _dataset(_frames(True), ["one"])


def test_summary_extent_from_the_dataset():
    ds = _dataset(_frames(True), ["tube wall", "ring"])
    e = contact_extent(ds, 0, length_mm=20.0)
    h = 1 / (N - 1)
    np.testing.assert_allclose(e["contact_s_end_R"], [2 * h, 4 * h])
    np.testing.assert_allclose(e["contact_s_end_mm"], [40 * h, 80 * h])
    assert e["contact_length_max_R"] == pytest.approx(2 * h)
    assert e["n_contact_end"] == 3 and e["stuck_fraction_end"] == 1.0
    never = contact_extent(ds, 1, length_mm=20.0)
    assert never["contact_s_end_R"] is None and never["contact_length_max_R"] == 0.0
    assert never["stuck_fraction_end"] is None and never["n_contact_max"] == 0
    json.dumps(e), json.dumps(never)  # plain JSON, no NaN
