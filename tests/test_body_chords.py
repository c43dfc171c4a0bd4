"""The mesh check against every held body (issue 21 item 4; dynslip/physics/bodies/chords.py,
dynslip/analysis/resolution.py, the run's stop rule in dynslip/physics/simulate.py;
docs/bodies.md, "The mesh check against every body").

A chord between two points of a circular arc of radius r, a half-angle a apart, dips r(1 - cos a)
below the arc (the sagitta): on a held cylinder's rounded edge and on a torus rim, for the body
at its reference height and displaced along the axis. The summary's check places each held body
where it is in each saved frame (``body_z``, or the ball's height for one carried with it). A
run whose chord dips past ``max_chord_depth`` into a held body stops there as failed, naming the
body. Small meshes (N <= 24).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from dynslip.analysis.resolution import body_chord_check
from dynslip.physics.bodies import Cylinder, Torus
from dynslip.physics.bodies.chords import chord_depths, deepest_chord_in
from dynslip.physics.failures import ContactUnresolved

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
    deepest chord into the post is the failure's depth, the frame before is within the limit."""
    from dynslip.physics.friction import Coulomb
    from dynslip.physics.materials import make_material
    from dynslip.physics.protocols import Protocol, Stage, StopRule
    from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
    from dynslip.physics.simulate import Settings, simulate

    limit, tau, eps = 1e-3, 0.1, 1e-3
    model = SheetModel(make_mesh(24, 2.54 / 1.05), make_material("gent", jm=50.0),
                       Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)), bodies=(POST,))
    stages = (Stage("push", StopRule("duration", duration=6.0), clamp_vz=-0.2),)
    protocol = Protocol(stages, clamp_rho0=2.54, clamp_z0=0.0, ball_z0=6.0)
    res = simulate(
        model, protocol, friction=Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(eps)), eps=eps,
        drag=tau, ball_drag=tau * 4 * math.pi, pre_stretch=1.05, z_sheet=0.0,
        settings=Settings(solver="load_step", save_interval=0.5, max_chord_depth=limit,
                          body_names=("post",)),
    )
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
