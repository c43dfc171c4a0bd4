"""The apparatus as bodies (bottle, tube wall) and the sheet's clearance from them."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from dynslip.analysis.clearance import clearance
from dynslip.physics.bodies import Cylinder
from dynslip.physics.bodies.apparatus import bottle, deepest_rim, tube_wall
from dynslip.physics.bodies.base import BodyGeometryError


def test_the_neck_lip_touches_the_resting_ball():
    neck = bottle(20.0)[0]
    # the lip's torus centre is 1 + w/2 from the ball's centre: the ball's surface point on
    # that line is at distance 0 from the neck (closed form), and every other is outside it
    w = 2.0 / 20.0
    rc, zc = 12.7 / 20.0 - w / 2, -math.sqrt((1 + w / 2) ** 2 - (12.7 / 20.0 - w / 2) ** 2)
    u = np.array([rc, zc]) / math.hypot(rc, zc)
    assert abs(float(neck.distance(jnp.asarray(u)))) < 1e-12
    th = np.linspace(0.0, np.pi, 721)
    pts = jnp.asarray(np.stack([np.sin(th), np.cos(th)], -1))
    d = np.array([float(neck.distance(p)) for p in pts])
    assert d.min() > -1e-12


def test_deepest_rim_is_the_tube_height_less_the_ball():
    assert deepest_rim(20.0) == pytest.approx(1.0 - 101.6 / 20.0, abs=1e-15)
    assert tube_wall(20.0).z_top == pytest.approx(101.6 / 20.0)


@pytest.mark.parametrize(
    "kwargs", [{"neck_wall_mm": 20.0}, {"neck_od_mm": 50.0}, {"body_od_mm": 20.0}]
)
def test_impossible_bottles_are_refused(kwargs):
    with pytest.raises(BodyGeometryError):
        bottle(20.0, **kwargs)


def _flat_sheet(z, clamp):
    rbar = np.linspace(0.0, 2.0, 21)
    rho = np.tile(rbar, (len(clamp), 1))
    return xr.Dataset(
        {
            "rho": (("time", "rbar"), rho),
            "z": (("time", "rbar"), np.full_like(rho, z)),
            "clamp_z": (("time",), np.asarray(clamp, float)),
        },
        coords={"time": np.arange(len(clamp), dtype=float), "rbar": rbar},
    )


def test_clearance_of_a_flat_sheet_above_a_cylinder_is_the_height_gap():
    cyl = Cylinder(1.0, -3.0, -2.0)
    c = clearance(_flat_sheet(-1.0, [0.0, 0.0]), (cyl,))
    np.testing.assert_allclose(c["per_frame"], 1.0, atol=1e-12)
    assert not c["touched"]
    # moving with the clamp: displaced up by 0.5 and by 1.5 (the second frame cuts the sheet)
    c = clearance(_flat_sheet(-1.0, [0.5, 1.5]), (cyl,), moves_with_clamp=True)
    np.testing.assert_allclose(c["per_frame"][0], 0.5, atol=1e-12)
    assert c["per_frame"][1] < 0 and c["touched"] and c["time"] == 1.0


def test_body_contacts_per_held_body_with_and_without_the_ball():
    """Per held body: the closest approach of the sheet over the path against the closed form
    (a flat sheet at z = -1 over a cylinder's top), a body held in the lab and one displaced by
    the ball's height at each frame; only the one the sheet reaches is touched."""
    from dynslip.analysis.clearance import body_contacts

    ds = _flat_sheet(-1.0, [0.0, 0.0]).assign(ball_z=("time", np.array([0.25, 1.5])))
    held, carried = Cylinder(1.0, -3.0, -2.0), Cylinder(0.5, -4.0, -2.5)
    out = body_contacts(ds, [("post", held, False), ("ring", carried, True)], 20.0)
    post, ring = out
    assert post["name"] == "post" and not post["touched"]
    np.testing.assert_allclose([post["closest_R"], post["closest_mm"]], [1.0, 20.0], atol=1e-12)
    # carried up by 0.25 then 1.5: its top at -2.25 then -1.0 (the sheet's height: touched)
    assert ring["moves_with_ball"] and ring["touched"] and ring["time_s"] == 1.0
    np.testing.assert_allclose(ring["closest_R"], 0.0, atol=1e-12)


def test_the_world_scenario_names_its_held_bodies_as_the_solver_holds_them():
    """``physics.named_bodies()`` (summary.json's ``bodies``) lists the tube's wall and the
    bottle's parts in the order and with the motion of the solver's own entries."""
    from pathlib import Path

    from dynslip.app.forming import build_core
    from dynslip.schema.base import load

    sc = load(Path(__file__).resolve().parents[1] / "scenarios" / "method2.yaml")
    named = sc.physics.named_bodies()
    model, _, _ = build_core(sc)
    assert [n for n, _, _ in named] == ["tube wall", "bottle neck", "bottle shoulder",
                                        "bottle body"]
    assert [w for _, _, w in named] == [e.moves_with_ball for e in model.bodies]
    assert all(b == e.body for (_, b, _), e in zip(named, model.bodies, strict=True))


def _with_bodies(ds, body_z):
    """``ds`` with the per-body variables of ``len(body_z[0])`` held bodies, none touched, and
    their saved displacements ``body_z`` (time, body)."""
    body_z = np.asarray(body_z, float)
    nt, k = body_z.shape
    nan = np.full((nt, k), np.nan)
    return ds.assign(
        body_z=(("time", "body"), body_z), body_s_min=(("time", "body"), nan),
        body_s_max=(("time", "body"), nan),
        body_n_contact=(("time", "body"), np.zeros((nt, k), int)),
        body_state=(("time", "body", "rbar"), np.zeros((nt, k, ds.sizes["rbar"]), np.int8)),
    )


def test_a_moving_body_is_met_at_its_saved_displacement_and_checked_against_the_ball():
    """A body moved by the stages or free is at its saved ``body_z``: a bead (radius 0.5,
    centred 2 below the ball's centre) raised by 0.8 reaches 0.3 past the flat sheet at z = -1
    (closest approach -0.3; at rest it would stay 0.5 below) and 0.3 into the unit ball (1 + 0.5
    - 1.2: the model has no contact between rigid bodies, so the summary has no answer); a post
    far below, moved by 0.5, overlaps nothing; a body at rest is not checked."""
    from dynslip.analysis.clearance import body_contacts, body_overlaps
    from dynslip.physics.bodies import Sphere

    ds = _flat_sheet(-1.0, [0.0, 0.0]).assign(ball_z=("time", np.zeros(2)))
    ds = _with_bodies(ds, [[0.0, 0.0, 0.0], [0.8, 0.5, 0.0]])
    bead, post, base = Sphere(0.5, centre_z=-2.0), Cylinder(1.0, -10.0, -9.0), Cylinder(
        3.0, -30.0, -20.0)
    entries = [("bead", bead, False), ("post", post, False), ("base", base, False)]
    out = body_contacts(ds, entries, 20.0)
    assert out[0]["touched"] and out[0]["time_s"] == 1.0
    np.testing.assert_allclose(out[0]["closest_R"], -0.3, atol=1e-12)
    np.testing.assert_allclose(out[1]["closest_R"], 7.5, atol=1e-12)  # its top at -8.5
    np.testing.assert_allclose(out[2]["closest_R"], 19.0, atol=1e-12)
    (o,) = body_overlaps(ds, entries, Sphere(), 20.0)
    assert o["name"] == "bead" and o["into"] == "ball" and o["time_s"] == 1.0
    np.testing.assert_allclose([o["depth_R"], o["depth_mm"]], [0.3, 6.0], atol=1e-9)
    # raised by 0.45 only: 0.05 clear of the ball, no overlap
    assert body_overlaps(_with_bodies(ds, [[0.0, 0.0, 0.0], [0.45, 0.5, 0.0]]), entries,
                         Sphere(), 20.0) == []
