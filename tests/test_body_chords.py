"""The mesh check against every held body (issue 21 item 4; dynslip/physics/bodies/chords.py,
dynslip/analysis/resolution.py, the run's stop rule in dynslip/physics/driver/simulate.py;
docs/bodies.md, "The mesh check against every body").

A chord between two points of a circular arc of radius r, a half-angle a apart, dips r(1 - cos a)
below the arc (the sagitta): on a held cylinder's rounded edge and on a torus rim, for the body
at its reference height and displaced along the axis. The summary's check places each held body
where it is in each saved frame (``body_z``, or the ball's height for one carried with it). A
run whose chord dips past ``max_chord_depth`` into a held body stops there as failed, naming the
body. Small meshes (N <= 24).

The relative test: the profile's local radius of curvature (every kind, closed forms), a chord's
depth relative to the radius of the part it cuts off: on the unit ball the absolute depth, on
any arc 1 - cos a; a chord straight across a thin wall with a rounded rim (or a thin torus)
flagged by it but not by the absolute limit.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from dynslip.analysis.resolution import body_chord_check
from dynslip.physics.bodies import Arc, Cone, Cylinder, Disc, Line, Profile, Sphere, Torus
from dynslip.physics.bodies.chords import (
    chord_depths,
    deepest_chord_in,
    deepest_relative_chord_in,
    relative_chord_depths,
)
from dynslip.physics.driver.failures import ContactUnresolved
from numerics import named_solver

EDGE = 0.25
POST = Cylinder(radius=1.0, z_bottom=-3.0, z_top=-0.2, edge_radius=EDGE)
RING = Torus(ring_radius=1.75, minor_radius=0.35, centre_z=-0.7)


def _on_arc(centre, r, phi):
    """Points (rho, z) at angles ``phi`` on the circle of radius ``r`` about ``centre``."""
    return centre[0] + r * np.cos(phi), centre[1] + r * np.sin(phi)


def _arc_chords(centre, r, lo, hi, n=40, seed=0):
    """``n`` random chords between two points of the arc of angles [lo, hi]: node positions
    (n, 2) and the half-angles a (n,)."""
    rng = np.random.default_rng(seed)
    p = np.sort(rng.uniform(lo, hi, (n, 2)), axis=1)
    rho, z = _on_arc(centre, r, p)
    return rho, z, 0.5 * (p[:, 1] - p[:, 0])


@pytest.mark.parametrize("shift", [0.0, 0.37, -1.2])
@pytest.mark.parametrize(
    "body, centre, r, lo, hi",
    [
        # the post's rounded edge: the quarter circle from the side (0) to the top (pi/2)
        (POST, (1.0 - EDGE, -0.2 - EDGE), EDGE, 0.0, math.pi / 2),
        # the torus rim: its whole meridian circle (the chords short of a half circle)
        (RING, (1.75, -0.7), 0.35, -math.pi, math.pi),
    ],
    ids=["cylinder edge", "torus rim"],
)
def test_a_chord_on_a_curved_part_dips_the_sagitta(body, centre, r, lo, hi, shift):
    """Two nodes on a circular arc of the body's profile, a half-angle a apart: the chord's
    deepest point is r(1 - cos a) inside, the body at its height or displaced by ``shift``
    with the nodes (the depth moves with the body, not with the nodes' absolute height)."""
    rho, z, a = _arc_chords(centre, r, lo, hi)
    keep = a < 0.45 * math.pi  # half-angles short of a half circle: one maximum along the chord
    rho, z, a = rho[keep], z[keep], a[keep]
    d = chord_depths(body, rho, z + shift, np.full(a.size, shift))
    assert d.shape == (a.size, 1)
    np.testing.assert_allclose(d[:, 0], r * (1 - np.cos(a)), rtol=1e-9, atol=1e-13)


def test_a_body_moved_along_the_axis_moves_the_depth_with_it():
    """A flat chord across the post's flat top, delta below it: depth delta. The nodes fixed and
    the post raised by s, the depth is delta + s (the top face is the nearest surface while
    delta + s is small against the flat top's half width); lowered past delta, the chord is
    outside by s - delta. Three frames, the deepest found with its element."""
    delta = 0.01
    rho = np.linspace(0.0, 0.6, 7)  # within the flat top (radius 1 - EDGE)
    z = np.full(7, -0.2 - delta)
    shifts = np.array([0.0, 0.03, -0.05])
    depth, k = deepest_chord_in(POST, np.tile(rho, (3, 1)), np.tile(z, (3, 1)), shifts)
    np.testing.assert_allclose(depth, delta + shifts, rtol=0, atol=1e-13)
    assert k.shape == (3,)


def _dataset(rho, z, ball_z, body_z, names):
    nt, n = rho.shape
    return xr.Dataset(
        {
            "rho": (("time", "rbar"), rho),
            "z": (("time", "rbar"), z),
            "ball_z": ("time", ball_z),
            "body_z": (("time", "body"), body_z),
        },
        coords={"time": np.arange(nt) * 2.0, "rbar": np.linspace(0.0, 1.0, n),
                "body": names},
    )


def test_the_summary_places_each_held_body_at_its_height_in_each_frame():
    """A trajectory whose sheet lies at rest over the ring's top (two nodes on its rim a
    half-angle a apart), the ring moved by the stages (``body_z``): at rest in frames 0 and 2,
    lowered by 0.5 R in frame 1 (the chord then clear of it). The deepest chord is the
    sagitta, first at frame 0, on the element of the two rim nodes. A post carried with the
    ball, 5 R above its place, is never reached, also read from a file without ``body_z``."""
    a = 0.3
    phi = np.array([math.pi / 2 - a, math.pi / 2 + a])  # about the rim's top
    r_rim, z_rim = _on_arc((1.75, -0.7), 0.35, phi)
    rho = np.concatenate([[0.0, 0.7], r_rim[::-1]])  # pole, inner node, then the rim's two
    z = np.concatenate([[-0.35 + 0.2, -0.35 + 0.1], z_rim[::-1]])
    frames = 3
    ring_z = np.array([0.0, -0.5, 0.0])
    ball_z = np.full(frames, 5.0)
    names = ["ring", "post"]
    # the post's body_z is the ball's height (carried with it), as the frame record writes it
    ds = _dataset(np.tile(rho, (frames, 1)), np.tile(z, (frames, 1)), ball_z,
                  np.stack([ring_z, ball_z], axis=1), names)
    entries = [("ring", RING, False), ("post", POST, True)]
    c = body_chord_check(ds, entries, limit=0.1, length_mm=20.0)
    assert list(c) == names
    ring = c["ring"]
    sagitta = 0.35 * (1 - math.cos(a))
    assert ring["max_chord_depth"] == pytest.approx(sagitta, rel=1e-9)
    assert ring["max_chord_depth_mm"] == pytest.approx(20.0 * sagitta, rel=1e-9)
    assert ring["time_s"] == 0.0 and ring["resolved"]
    assert ring["element_rbar"] == [pytest.approx(2 / 3), pytest.approx(1.0)]
    assert ring["end_max_chord_depth"] == pytest.approx(sagitta, rel=1e-9)
    lowered, _ = deepest_chord_in(RING, rho, z, -0.5)
    assert lowered < 0.0  # frame 1 is clear of the lowered ring
    # the post's bottom, raised with the ball, is the nearest surface, over the pole (the
    # sheet's highest point under it)
    assert c["post"]["max_chord_depth"] == pytest.approx(-(-3.0 + 5.0 - z[0]), rel=1e-12)
    assert c["post"]["resolved"]
    # relative to the rim's radius: 1 - cos a; the post, never entered, reads its depth, no radius
    assert ring["max_relative_chord_depth"] == pytest.approx(1 - math.cos(a), rel=1e-9)
    assert ring["radius_R"] == pytest.approx(0.35) and ring["radius_mm"] == pytest.approx(7.0)
    assert ring["span_rad"] == pytest.approx(2 * a, rel=1e-9)
    assert ring["relative_time_s"] == 0.0
    assert ring["relative_element_rbar"] == [pytest.approx(2 / 3), pytest.approx(1.0)]
    post = c["post"]
    assert post["max_relative_chord_depth"] == post["max_chord_depth"]
    assert post["radius_R"] is None and post["span_rad"] is None
    assert not body_chord_check(ds, entries, limit=0.5 * sagitta, length_mm=20.0)["ring"][
        "resolved"]
    # a file without body_z: the post carried with the ball still placed at the ball's height
    c_old = body_chord_check(ds.drop_vars(["body_z", "body"]), [("post", POST, True)], 0.1, 20.0)
    assert c_old["post"]["max_chord_depth"] == pytest.approx(c["post"]["max_chord_depth"])


@pytest.mark.slow
def test_a_chord_past_the_limit_in_a_held_body_stops_the_run_naming_it():
    """A sheet pushed down over the post's rounded edge (N = 24, the ball held 6 R above, out of
    reach) with a chord limit of 1e-3 R: the run stops at the first saved frame whose chord
    dips deeper into the post, as failed, with ContactUnresolved naming the post; that frame's
    deepest chord into the post is the failure's depth, the frame before is within the limit.
    Where the failed frame is the last of a stage that another follows, the run still fails in
    that stage, at that frame, with the same counts (the check comes before the stop rule)."""
    from dynslip.physics.driver.simulate import simulate
    from dynslip.physics.friction import Coulomb
    from dynslip.physics.materials import make_material
    from dynslip.physics.protocols import Duration, Protocol, Stage
    from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
    from dynslip.physics.solver.methods import Settings

    limit, tau, eps = 1e-3, 0.1, 1e-3
    model = SheetModel(make_mesh(24, 2.54 / 1.05), make_material("gent", jm=50.0),
                       Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)), bodies=(POST,))
    stages = (Stage("push", Duration(duration=6.0), clamp_vz=-0.2),)
    protocol = Protocol(stages, clamp_rho0=2.54, clamp_z0=0.0, ball_z0=6.0)
    def run(protocol=protocol):
        return simulate(
            model, protocol, friction=Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(eps)),
            eps=eps, drag=tau, ball_drag=tau * 4 * math.pi, pre_stretch=1.05, z_sheet=0.0,
            settings=Settings(solver=named_solver(), save_interval=0.5, max_chord_depth=limit,
                              body_names=("post",)),
        )

    res = run()
    f = res.failure
    assert isinstance(f, ContactUnresolved), res.failed
    assert f.body == "post" and "'post'" in res.failed and not f.pole_crossed
    assert f.depth > limit and f.t < 6.0
    last, before = res.frames[-1], res.frames[-2]
    depth, k = deepest_chord_in(POST, last["rho"], last["z"], 0.0)
    assert float(depth) == pytest.approx(f.depth, rel=1e-12)
    rbar = np.asarray(model.mesh.rbar)
    assert f.element == (pytest.approx(rbar[k]), pytest.approx(rbar[k + 1]))
    assert float(deepest_chord_in(POST, before["rho"], before["z"], 0.0)[0]) <= limit
    assert res.frames[-1]["time"] == f.t == res.stage_end[-1]["t_end"]
    assert len(res.stage_end) == 1

    # the failed frame made the last of a stage that another follows: the run fails in this one
    hold = Stage("hold", Duration(duration=1.0), clamp_vz=0.0)
    two = Protocol((dataclasses.replace(stages[0], stop=Duration(duration=f.t)), hold),
                   clamp_rho0=2.54, clamp_z0=0.0, ball_z0=6.0)
    cut = run(two)
    assert str(cut.failure) == str(f) and cut.stage_end == res.stage_end
    assert [r["time"] for r in cut.frames] == [r["time"] for r in res.frames]
    np.testing.assert_array_equal(cut.frames[-1]["rho"], last["rho"])
    for k in ("steps", "accepted", "rejected", "segments", "newton_iterations"):
        assert cut.stats[k] == res.stats[k], k
    assert [e["name"] for e in cut.stage_end] == ["push"]


def test_the_local_radius_of_each_kind_of_profile():
    """``curvature_radius`` in closed form: a sphere its radius everywhere, a torus its tube's
    radius, a coin its edge radius on the rounded corners and inf on its flat faces and edge;
    at a joint of a line and an arc the arc's; a cone's apex (a point on the axis) 0. Between two
    arc lengths: the smallest over the part between them, a ring the shorter way round."""
    s = np.linspace(0.0, 1.0, 7)
    np.testing.assert_array_equal(Sphere(radius=0.7).curvature_radius(s * 0.7 * math.pi), 0.7)
    ring = Torus(ring_radius=2.0, minor_radius=0.3)
    np.testing.assert_array_equal(ring.curvature_radius(s * ring.length), 0.3)
    a, h, e = 2.0, 0.4, 0.1
    coin = Disc(radius=a, thickness=h, edge_radius=e)
    corner = math.pi * e / 2
    top, upper, edge = 0.5 * (a - e), a - e + 0.5 * corner, a - e + corner + 0.5 * (h - 2 * e)
    lower, bottom = a - e + 1.5 * corner + h - 2 * e, coin.length - 0.5 * (a - e)
    got = coin.curvature_radius(np.array([top, upper, edge, lower, bottom]))
    np.testing.assert_array_equal(got, [np.inf, e, np.inf, e, np.inf])
    assert coin.curvature_radius(a - e) == e  # where the flat top meets the corner's arc
    assert coin.curvature_radius(top, edge) == e  # from the top face over the corner
    assert coin.curvature_radius(0.1, top) == np.inf  # on the flat top alone
    cone = Cone(radius=1.0, z_base=0.0, z_apex=1.0)
    np.testing.assert_array_equal(cone.curvature_radius(np.array([0.0, 0.5, 2.0])),
                                  [0.0, np.inf, np.inf])
    assert cone.curvature_radius(1.0, 2.0) == 0.0  # over the base's sharp rim
    # a capsule: a quarter ball, a cylinder of length 1 and a quarter ball, joined C1
    capsule = Profile([Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0), Line((1.0, 0.0), (1.0, -1.0)),
                       Arc((0.0, -1.0), 1.0, 0.0, -math.pi / 2)])
    q = math.pi / 2
    np.testing.assert_array_equal(capsule.curvature_radius(np.array([0.5, q, q + 0.5, q + 1.0])),
                                  [1.0, 1.0, np.inf, 1.0])
    sharp = Cylinder(radius=1.0, z_bottom=-1.0, z_top=0.0)  # sharp corners
    np.testing.assert_array_equal(sharp.curvature_radius(np.array([0.5, 1.0, 1.5])),
                                  [np.inf, 0.0, np.inf])
    # a tube wall's ring: from the inner wall to the outer over the rounded rim, the rim's
    # radius; along the outer wall alone, inf; the inner wall's top to the outer wall's foot,
    # the shorter way round, through the rim
    tube = Cylinder(radius=1.0, z_bottom=-4.0, z_top=0.0, inner_radius=0.9, edge_radius=0.05)
    outer_mid = math.pi * 0.05 / 2 + 2.0  # the profile starts at the rim's top
    inner_mid = tube.length - math.pi * 0.05 / 2 - 2.0
    assert tube.curvature_radius(inner_mid, outer_mid) == pytest.approx(0.05)
    assert tube.curvature_radius(outer_mid - 1.0, outer_mid + 1.0) == np.inf
    assert tube.curvature_radius(tube.length - 0.01, outer_mid) == pytest.approx(0.05)


def test_a_chord_across_a_thin_rounded_wall_is_flagged_only_by_the_relative_test():
    """A tube's wall 0.15 R thick with a fully rounded rim (radius 0.075 R, the main job's):
    an element with one node on the inner face and the next on the outer, below the rim's
    centre, runs straight through the wall: depth 0.075 R, its half thickness, under the
    absolute limit 0.1 R; relative to the rim's radius it cuts off, 1: flagged. The same across
    a torus 0.1 R thick through its centre. A chord over the same rim two nodes a half-angle 0.3
    apart: 1 - cos 0.3 relative, under the limit either way."""
    limit, e = 0.1, 0.075
    tube = Cylinder(radius=2.54, z_bottom=-5.0, z_top=0.0, inner_radius=2.54 - 2 * e,
                    edge_radius=e)
    rho = np.array([2.54 - 2 * e - 1e-3, 2.54 + 1e-3])
    z = np.array([-0.2, -0.12])  # below the rim's centre (-e), the faces straight there
    depth, radius, rel = relative_chord_depths(tube, rho, z, 0.0)
    assert depth[0] == pytest.approx(e, rel=1e-9) and depth[0] <= limit  # passes in R
    assert radius[0] == pytest.approx(e) and rel[0] == pytest.approx(1.0, rel=1e-9)  # flagged
    # the tube lowered by 0.5 R with the nodes: the same
    d2, r2, rel2 = relative_chord_depths(tube, rho, z - 0.5, -0.5)
    assert rel2[0] == pytest.approx(1.0, rel=1e-9) and r2[0] == pytest.approx(e)
    ring = Torus(ring_radius=1.5, minor_radius=0.05, centre_z=-0.5)
    depth, radius, rel = relative_chord_depths(ring, np.array([1.4, 1.6]),
                                               np.array([-0.5, -0.5]), 0.0)
    assert depth[0] == pytest.approx(0.05) and depth[0] <= limit
    assert radius[0] == pytest.approx(0.05) and rel[0] == pytest.approx(1.0)
    # over the rim's top, a half-angle 0.3 either side of it: resolved both ways
    r_rim, z_rim = _on_arc((2.54 - e, -e), e, np.array([math.pi / 2 + 0.3, math.pi / 2 - 0.3]))
    depth, radius, rel = relative_chord_depths(tube, r_rim, z_rim, 0.0)
    assert rel[0] == pytest.approx(1 - math.cos(0.3), rel=1e-9)
    assert rel[0] < limit and depth[0] < limit
    # per frame: the crossing element found, the two frames stacked
    # (a node before each pair, clear of the wall: in the tube's bore, then above the rim)
    frames_rho = np.stack([np.concatenate([[2.3], rho]),
                           np.concatenate([[r_rim[1]], r_rim[::-1]])])
    frames_z = np.stack([np.concatenate([[-0.3], z]), np.concatenate([[0.3], z_rim[::-1]])])
    worst, r, k = deepest_relative_chord_in(tube, frames_rho, frames_z, np.zeros(2))
    np.testing.assert_allclose(worst, [1.0, 1 - math.cos(0.3)], rtol=1e-9)
    np.testing.assert_allclose(r, e)
    np.testing.assert_array_equal(k, [1, 1])


@pytest.mark.parametrize("a", [0.2, 0.4, 0.5, 0.8])
def test_on_the_unit_ball_the_relative_test_is_the_absolute_one(a):
    """Two nodes on the unit ball a half-angle a apart (either side of arccos(1 - 0.1) =
    0.451): relative depth = depth = 1 - cos a, the sheet's closed form, the same verdict."""
    from dynslip.physics.sheet import ball_chord_depths as sheet_chord_depths

    th = np.array([0.3, 0.3 + 2 * a])
    depth, radius, rel = relative_chord_depths(Sphere(), np.sin(th), np.cos(th), 0.0)
    exact = sheet_chord_depths(np.sin(th), np.cos(th), 0.0)
    np.testing.assert_allclose(depth, exact, rtol=1e-12)
    np.testing.assert_allclose(rel, depth, rtol=0, atol=0)
    assert radius[0] == 1.0
    assert (rel[0] <= 0.1) == (depth[0] <= 0.1) == (a < math.acos(0.9))


def test_the_end_table_warns_of_a_held_body_not_resolved():
    """The end table's line for a held body the relative test flags: its radius, the span, the
    mesh needed (N times the span over 2 arccos(1 - limit)); at relative depth 1 the span is a
    lower bound ("at least"); a resolved body gets no line."""
    from dynslip.app.endtable import unresolved_body_words

    c = {"resolved": False, "max_relative_chord_depth": 0.25, "radius_mm": 1.5,
         "span_rad": 2 * math.acos(0.75), "relative_time_s": 55.2}
    line = unresolved_body_words("tube wall", c, 0.1, 50)
    need = math.ceil(50 * 2 * math.acos(0.75) / (2 * math.acos(0.9)))
    assert line.startswith("tube wall: profile not resolved by the mesh where it curves to 1.5 mm")
    assert "spans 1.45 rad" in line and f"N >= about {need} needed" in line
    crossed = dict(c, max_relative_chord_depth=1.0, span_rad=math.pi)
    assert "spans at least 3.14 rad" in unresolved_body_words("tube wall", crossed, 0.1, 30)
    assert unresolved_body_words("tube wall", dict(c, resolved=True), 0.1, 50) is None


def test_a_frame_searched_again_is_taken_from_the_last_frames_searched():
    """The summary's check of a trajectory takes each frame the run's check searched
    (``chords._SEEN``, by the frame's exact values): the same depths as a fresh search; a frame
    one rounding step away, another body, or another height is searched anew."""
    from dynslip.physics.bodies import chords

    th = np.linspace(0.1, 1.4, 9)
    rho, z = np.stack([1.0 + 0.2 * np.cos(th)] * 3), np.stack([0.2 * np.sin(th)] * 3)
    z[1] += 0.05
    chords._SEEN.clear()
    fresh = chords.chord_depths(POST, rho, z, np.zeros(3))
    assert len(chords._SEEN) == 2  # frames 0 and 2 are one frame
    again = chords.chord_depths(POST, rho, z, np.zeros(3))
    np.testing.assert_array_equal(again, fresh)
    assert len(chords._SEEN) == 2
    nudged = rho.copy()
    nudged[0, 4] = np.nextafter(nudged[0, 4], 2.0)
    chords.chord_depths(POST, nudged[:1], z[:1], 0.0)
    chords.chord_depths(RING, rho[:1], z[:1], 0.0)
    chords.chord_depths(POST, rho[:1], z[:1], 1e-3)
    assert len(chords._SEEN) == 5
    chords._SEEN.clear()
    np.testing.assert_array_equal(chords.chord_depths(POST, rho, z, np.zeros(3)), fresh)
