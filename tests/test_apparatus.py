"""The apparatus as bodies (bottle, tube wall) and the sheet's clearance from them.

The bottle is one closed smooth solid (issue 42 item 2): its profile valid and C1, no face of
it inside matter (the three bodies it was shared the shoulder's base with the body's top), its
lip touching the resting ball, its sizes the scenario's; fillets that do not fit and bodies of
one world sharing a face are refused (one line, exit 2). Geometry only: nothing simulated.
"""

import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr
import yaml

from dynslip.analysis.clearance import clearance
from dynslip.physics.bodies import Cone, Cylinder, Profile, Sphere, shared_face
from dynslip.physics.bodies.apparatus import bottle, deepest_rim, tube_wall
from dynslip.physics.bodies.base import BodyGeometryError, check_profile
from dynslip.physics.bodies.segments import Line
from helpers import cli_in_process, one_line, run_refused, set_field

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
R = 20.0
W = 2.0 / R  # the neck's wall
RC = 12.7 / R - W / 2  # the lip's torus centre
ZC = -math.sqrt((1 + W / 2) ** 2 - RC**2)
Z_TOP = ZC + W / 2  # the lip's top
Z_SHOULDER = Z_TOP - 65.0 / R  # the neck meets the shoulder (and the bore's floor)
Z_BODY = Z_SHOULDER - 18.6 / R  # the shoulder meets the body
Z_BASE = Z_BODY - 140.0 / R


def _glass():
    (glass,) = bottle(R)
    return glass


def _three_part_bottle():
    """The bottle as it was before issue 42: a neck tube with a rounded lip, a cone, a
    cylinder (the cone's base face on the body's top face, the neck's bottom inside the cone)."""
    ro, rb = 12.7 / R, 35.0 / R
    neck = Cylinder(ro, Z_SHOULDER - W, Z_TOP, inner_radius=ro - W, edge_radius=W / 2)
    apex = Z_BODY + rb * (Z_SHOULDER - Z_BODY) / (rb - ro)
    return neck, Cone(rb, Z_BODY, apex), Cylinder(rb, Z_BASE, Z_BODY)


def test_the_bottle_is_one_closed_smooth_profile():
    """One Profile from the axis (the bore's floor) to the axis (the base): check_profile passes
    it as smooth, and at every joint the ends meet (1e-12 R) and the tangents agree (measured,
    1e-12), the lines and arcs in the order of the module's docstring."""
    parts = bottle(R)
    assert len(parts) == 1 and isinstance(parts[0], Profile)
    segs = parts[0].segments
    check_profile(segs, smooth=True)
    kinds = "".join("L" if isinstance(s, Line) else "A" for s in segs)
    assert kinds == "LALALALALAL"  # floor, fillet, bore, lip, neck, fillet, shoulder, ..., base
    assert segs[0].start == (0.0, pytest.approx(Z_SHOULDER, abs=1e-12))
    assert segs[-1].end == (0.0, pytest.approx(Z_BASE, abs=1e-12))
    for a, b in zip(segs[:-1], segs[1:], strict=True):
        assert math.dist(a.end, b.start) < 1e-12
        np.testing.assert_allclose(a.tangent_at(1.0), b.tangent_at(0.0), atol=1e-12)
    # the ends on the axis are flat (no point there): the floor and the base are horizontal
    np.testing.assert_allclose(segs[0].tangent_at(0.0), [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(segs[-1].tangent_at(1.0), [-1.0, 0.0], atol=1e-15)


def test_the_bottle_sizes_are_the_scenarios():
    """Lip top to base 65 + 18.6 + 140 mm, the neck 25.4 mm across with a 2 mm wall (the bore
    21.4 mm), the body 70 mm across, the bore's floor at the shoulder's height, the fillets of
    the given radii (defaults 5, 10, 5 mm) and of others when asked."""
    glass = _glass()
    o = glass.outline()
    np.testing.assert_allclose([o[:, 1].max(), o[:, 1].min()], [Z_TOP, Z_BASE], atol=1e-12)
    np.testing.assert_allclose((o[:, 1].max() - o[:, 1].min()) * R, 223.6, atol=1e-10)
    np.testing.assert_allclose(o[:, 0].max() * R, 35.0, atol=1e-12)
    segs = glass.segments
    np.testing.assert_allclose([segs[2].start[0] * R, segs[4].start[0] * R], [10.7, 12.7],
                               atol=1e-12)  # the bore's wall, the neck's outer wall
    np.testing.assert_allclose(segs[3].radius * R, 1.0, atol=1e-12)  # the lip: w / 2
    np.testing.assert_allclose([segs[k].radius * R for k in (5, 7, 9)], [5.0, 10.0, 5.0],
                               atol=1e-12)
    np.testing.assert_allclose(segs[8].start[0] * R, 35.0, atol=1e-12)  # the body's wall
    other = bottle(R, neck_fillet_mm=3.0, shoulder_fillet_mm=20.0, base_fillet_mm=8.0)[0]
    np.testing.assert_allclose([other.segments[k].radius * R for k in (5, 7, 9)],
                               [3.0, 20.0, 8.0], atol=1e-12)
    # the flank of the shoulder lies on the line from (r_o, z_shoulder) to (r_b, z_body)
    flank = segs[6]
    for p in (flank.start, flank.end):
        u = (p[0] - 12.7 / R) / ((35.0 - 12.7) / R)
        assert p[1] == pytest.approx(Z_SHOULDER + u * (Z_BODY - Z_SHOULDER), abs=1e-12)


def test_the_bottle_has_no_face_inside_matter():
    """The signed distance of the bottle is 0 only on its profile: every point sampled on the
    profile is on the surface (1e-12 R), a point 1e-3 R inside along the outward normal is at
    -1e-3, one outside at +1e-3 (1e-12); and at the joints of the old three parts (the
    shoulder's base on the body's top, the neck's bottom inside the shoulder) every point of a
    grid is strictly inside (< -1e-3 R). The three-part bottle fails this: its distance (the
    least over its parts) is 0 on the face its cone and body shared, inside the glass."""
    glass = _glass()
    u = np.linspace(0.0, 1.0, 201)
    pts = np.concatenate([s.point_at(u) for s in glass.segments])
    t = np.concatenate([s.tangent_at(u) for s in glass.segments])
    n = np.stack([-t[:, 1], t[:, 0]], -1)  # outward: the tangent turned counter-clockwise
    np.testing.assert_allclose(np.asarray(glass.distance(pts)), 0.0, atol=1e-12)
    d = 1e-3
    np.testing.assert_allclose(np.asarray(glass.distance(pts - d * n)), -d, atol=1e-12)
    np.testing.assert_allclose(np.asarray(glass.distance(pts + d * n)), d, atol=1e-12)
    # grids through the old joints, each holding the old shared face's height exactly
    rho, z = np.meshgrid(np.linspace(0.05, 1.5, 30), np.r_[np.linspace(-0.2, 0.02, 12), 0.0])
    body_joint = np.stack([rho.ravel(), Z_BODY + z.ravel()], -1)
    rho, z = np.meshgrid(np.linspace(0.02, 0.6, 30), np.r_[np.linspace(-0.3, -0.02, 12), -W])
    neck_joint = np.stack([rho.ravel(), Z_SHOULDER + z.ravel()], -1)
    for grid in (body_joint, neck_joint):
        assert float(jnp.max(glass.distance(grid))) < -1e-3
    old = np.min([np.asarray(b.distance(body_joint)) for b in _three_part_bottle()], axis=0)
    assert old.max() == 0.0  # the old cone's base on the body's top: distance 0 in the glass


def test_the_neck_lip_touches_the_resting_ball():
    neck = _glass()
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
    "kwargs, words",
    [
        ({"neck_wall_mm": 20.0}, ("neck wall",)),
        ({"neck_od_mm": 50.0}, ("neck radius",)),
        ({"body_od_mm": 20.0}, ("wider than the neck",)),
        # the flank is 29.04 mm long and turns by 50.2 degrees at each end: a fillet of r takes
        # 0.468 r of it; the neck's outer wall is 64 mm, the body 140 mm, its radius 35 mm
        ({"neck_fillet_mm": 70.0}, ("neck_fillet_mm = 70", "does not fit", "below 62.")),
        ({"shoulder_fillet_mm": 60.0},
         ("shoulder_fillet_mm = 60", "beside neck_fillet_mm = 5", "below 57.03 mm")),
        ({"base_fillet_mm": 35.0}, ("base_fillet_mm = 35", "does not fit", "below 35 mm")),
        ({"body_height_mm": 8.0, "base_fillet_mm": 4.0},
         ("base_fillet_mm = 4", "beside shoulder_fillet_mm = 10", "below 3.319 mm")),
        ({"base_fillet_mm": 0.0}, ("base_fillet_mm = 0", "> 0")),
    ],
)
def test_impossible_bottles_are_refused(kwargs, words):
    with pytest.raises(BodyGeometryError) as err:
        bottle(20.0, **kwargs)
    line = str(err.value)
    assert "\n" not in line and all(w in line for w in words), line


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("neck_fillet_mm", 70.0, ("physics.bottle: neck_fillet_mm = 70", "below 62.03 mm")),
        ("shoulder_fillet_mm", 60.0, ("physics.bottle: shoulder_fillet_mm = 60", "does not fit")),
        ("base_fillet_mm", 40.0, ("physics.bottle: base_fillet_mm = 40", "does not fit")),
        ("base_fillet_mm", 0.0, ("physics.bottle.base_fillet_mm", "greater than 0")),
    ],
)
def test_a_bottle_whose_fillets_do_not_fit_is_refused(tmp_path, capsys, field, value, words):
    run_refused(tmp_path, capsys, SCENARIOS / "method2.yaml",
                set_field(f"physics.bottle.{field}", value), *words)


def test_shared_face_is_a_length_along_a_face_and_zero_at_a_point():
    """Two cylinders stacked share the narrower one's face (its radius, either way round, to a
    sample's spacing); a ball on a ring, on the bottle's lip or on a flat top shares nothing;
    bodies apart share nothing; the old three-part bottle's cone and body share the body's
    whole top face."""
    low, cap = Cylinder(1.0, -3.0, -2.0), Cylinder(0.5, -2.0, -1.5)
    assert shared_face(cap, low) == pytest.approx(0.5, abs=1e-12)
    assert shared_face(low, cap) == pytest.approx(0.5, abs=2e-3)
    assert shared_face(cap, low, za=-0.25, zb=-0.25) == pytest.approx(0.5, abs=1e-12)
    assert shared_face(cap, low, za=1e-6) == 0.0  # lifted off: apart
    ring = Cylinder(0.9, -3.0, -0.4, inner_radius=0.6, edge_radius=0.15)
    ball, glass = Sphere(), _glass()
    for a, b in ((ball, ring), (ball, glass), (ball, Cylinder(1.0, -3.0, -1.0))):
        assert shared_face(a, b) == 0.0 and shared_face(b, a) == 0.0
    _, cone, body = _three_part_bottle()
    assert shared_face(cone, body) == pytest.approx(35.0 / R, abs=1e-12)


def _validate(tmp_path, capsys, data):
    path = tmp_path / "world.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    rc, _, err = cli_in_process(capsys, ["validate", path])
    return rc, err


@pytest.mark.slow  # three validations of a world with bodies (10 s); the quick loop measures
# shared_face itself (above)
def test_bodies_sharing_a_face_are_refused(tmp_path, capsys):
    """``dynslip validate``: a cap standing on a post (its bottom face on the post's top face)
    is refused, exit 2, one line naming the body, the other and the shared length (the cap's
    flat bottom, 6 - 1 mm); so is a table under the bottle (its top on the bottle's base, the
    base's flat 35 - 5 mm). The cap lifted 0.5 mm off the post is valid."""
    data = yaml.safe_load((SCENARIOS / "method2_let_go.yaml").read_text())
    post = {"name": "post", "kind": "cylinder", "radius_mm": 10.0, "height_mm": 30.0,
            "edge_radius_mm": 2.0, "z_mm": -60.0}
    cap = {"name": "cap", "kind": "cylinder", "radius_mm": 6.0, "height_mm": 8.0,
           "edge_radius_mm": 1.0, "z_mm": -30.0}
    data["physics"]["bodies"] = [post, cap]
    rc, err = _validate(tmp_path, capsys, data)
    assert rc == 2, err
    line = one_line(err)
    for w in ("bodies.1 ('cap', kind cylinder, z_mm = -30.0)", "shares a face with body 'post'",
              "over 5 mm", "a face inside matter", "touching at a point"):
        assert w in line, line
    data["physics"]["bodies"] = [post, {**cap, "z_mm": -29.5}]
    rc, err = _validate(tmp_path, capsys, data)
    assert rc == 0, err
    base_mm = Z_BASE * R
    table = {"name": "table", "kind": "cylinder", "radius_mm": 60.0, "height_mm": 10.0,
             "z_mm": base_mm - 10.0}
    data["physics"]["bottle"] = {}
    data["physics"]["bodies"] = [table]
    rc, err = _validate(tmp_path, capsys, data)
    assert rc == 2, err
    line = one_line(err)
    assert "bodies.0 ('table', kind cylinder" in line and "shares a face with the bottle" in line
    assert "over 30 mm" in line, line


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
    assert [n for n, _, _ in named] == ["tube wall", "bottle"]
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
