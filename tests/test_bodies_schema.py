"""Bad input of the tube and band (issue 22 item 1's schema): one line, exit 2, nothing written.

Also: the band scenario builds the tube as a held body with its friction and the band's grip
in G h0 (the file's N/mm divided by G h0 = 0.1 N/mm at the defaults).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dynslip.schema.base import load
from helpers import run_refused, set_field

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
BAND = SCENARIOS / "method2_band.yaml"


@pytest.mark.parametrize(
    "dotted, value, words",
    [
        ("physics.tube.wall_mm", 60.0, ("tube.wall_mm", "thicker than the tube")),
        ("physics.tube.wall_mm", 0.0, ("wall_mm",)),
        ("physics.tube.wall_mm", -3.0, ("wall_mm",)),
        ("physics.tube.height_mm", 0.0, ("height_mm",)),
        ("physics.tube.mu", -0.1, ("mu",)),
        ("physics.band_grip_N_per_mm", -1.0, ("band_grip_N_per_mm",)),
        ("physics.tube", None, ("tube_velocity_mm_s", "allowed only with physics.tube")),
        ("physics.stages.3.until.force_N", None, ("physics.stages.3.until.force_N",)),
        ("physics.stages.3.ball", "support", ("ball_reaction_below", "ball: hold")),
    ],
)
def test_bad_tube_and_band_input(tmp_path, capsys, dotted, value, words):
    run_refused(tmp_path, capsys, BAND, set_field(dotted, value), *words)


def test_band_scenario_builds_the_tube_and_the_grip():
    from dynslip.app.forming import build_core
    from dynslip.physics.bodies.held import Held
    from dynslip.physics.protocols import CLAMP_BAND

    sc = load(BAND)
    model, protocol, _ = build_core(sc)
    (tube,) = model.bodies
    assert isinstance(tube, Held)
    np.testing.assert_allclose(float(tube.friction.mu), 0.5)
    wall = tube.body
    r = 20.0
    np.testing.assert_allclose(wall.radius, 50.8 / r)
    np.testing.assert_allclose(wall.edge_radius, 3.0 / r)  # the 6 mm wall, fully rounded
    np.testing.assert_allclose(wall.z_bottom, (20.0 + 0.4 + 0.2) / r)  # 0.2 mm above the sheet
    np.testing.assert_allclose(float(model.band_grip), 1.0)  # 0.1 N/mm over G h0 = 0.1 N/mm
    assert [s.clamp_mode for s in protocol.stages].count(CLAMP_BAND) == 5
    # the flat sheet starts below the rim, outside the wall
    z0 = (20.0 + 0.4) / r
    rbar = np.asarray(model.mesh.rbar)
    x = np.stack([sc.physics.pre_stretch * rbar, np.full_like(rbar, z0)], -1)
    assert float(np.min(np.asarray(wall.distance(x)))) > 0.0


# ---- physics.bodies (issue 21): held bodies by kind and size in mm ----------------------------

LET_GO = SCENARIOS / "method2_let_go.yaml"
POST = {"name": "post", "kind": "cylinder", "radius_mm": 10.0, "height_mm": 30.0,
        "edge_radius_mm": 2.0, "z_mm": -60.0}


def _bodies(*bodies):
    def edit(data):
        data["physics"]["bodies"] = [dict(b) for b in bodies]

    return edit


def _profile(*segments, z_mm=-60.0):
    return {"name": "shape", "kind": "profile", "z_mm": z_mm, "segments": list(segments)}


def _line(a, b):
    return {"type": "line", "start_mm": list(a), "end_mm": list(b)}


def _arc(c, r, a0, a1):
    return {"type": "arc", "centre_mm": list(c), "radius_mm": r, "start_deg": a0, "end_deg": a1}


@pytest.mark.parametrize(
    "bodies, words",
    [
        # a profile not connected
        ((_profile(_line((0, 5), (5, 5)), _line((5, 4), (0, 0))),),
         ("bodies.0", "'shape'", "profile not connected")),
        # a smooth profile whose full loop crosses its closing line
        ((_profile(_line((0, 3), (4, 3)), _arc((4, 1.5), 1.5, 90, -270), _line((4, 3), (6, 3)),
                   _arc((6, 2), 1.0, 90, -90), _line((6, 1), (0, 1))),),
         ("bodies.0", "crosses itself")),
        # zero or negative sizes
        (({**POST, "radius_mm": -5.0},), ("physics.bodies.0.radius_mm", "-5", "greater than 0")),
        (({**POST, "height_mm": 0.0},), ("physics.bodies.0.height_mm", "greater than 0")),
        (({"name": "coin", "kind": "disc", "radius_mm": 5.0, "thickness_mm": 0.0,
           "edge_radius_mm": 0.1, "z_mm": -60.0},), ("physics.bodies.0.thickness_mm", "0")),
        (({"name": "coin", "kind": "disc", "radius_mm": 5.0, "thickness_mm": 1.0,
           "edge_radius_mm": 0.0, "z_mm": -60.0},), ("bodies.0", "edge radius 0", "> 0")),
        (({"name": "ring", "kind": "torus", "ring_radius_mm": 30.0, "minor_radius_mm": -1.0,
           "z_mm": -60.0},), ("physics.bodies.0.minor_radius_mm", "-1")),
        # overlapping the ball, or each other, at the start
        (({"name": "bead", "kind": "sphere", "radius_mm": 5.0, "z_mm": -22.0},),
         ("bodies.0", "'bead'", "overlaps the ball", "3 mm", "apart or touching")),
        ((POST, {**POST, "name": "post2", "z_mm": -55.0}),
         ("bodies.1", "'post2'", "overlaps body 'post'")),
        # the flat sheet (20.4 mm above the centre, out to the rim) starting inside a body
        (({"name": "ring", "kind": "torus", "ring_radius_mm": 30.0, "minor_radius_mm": 3.0,
           "z_mm": 21.0},), ("bodies.0", "'ring'", "the flat sheet starts inside it")),
        # an unknown kind, a motion or friction law that is not built
        (({**POST, "kind": "box"},), ("physics.bodies.0.kind", "box", "'cylinder'", "'profile'")),
        (({**POST, "motion": "orbit"},), ("physics.bodies.0.motion", "orbit", "'free'")),
        # a free body: its force in range, force and drag only with it
        (({**POST, "motion": "free", "force_N": 2e4},), ("physics.bodies.0.force_N", "20000")),
        (({**POST, "motion": "free", "drag": 0.0},), ("physics.bodies.0.drag", "greater than 0")),
        (({**POST, "force_N": 1.0},), ("bodies.0", "force_N goes with motion: free", "held")),
        (({**POST, "friction": {"law": "sticky", "mu": 0.5}},),
         ("physics.bodies.0.friction.law", "sticky", "'slip_weakening'", "'pressure'")),
        # each law's own parameters (the ball's friction spec), in range, mu_k <= mu_s
        (({**POST, "friction": {"law": "slip_weakening", "mu_x": 0.5}},),
         ("physics.bodies.0.friction.mu_x", "0.5", "unknown field")),
        (({**POST, "friction": {"law": "slip_weakening", "mu_s": 0.5, "mu_k": 0.6,
                                "d_c_mm": 0.4}},),
         ("bodies.0.friction", "mu_k = 0.6 exceeds mu_s = 0.5")),
        (({**POST, "friction": {"law": "slip_weakening", "mu_s": 0.5, "mu_k": 0.4,
                                "d_c_mm": 0.0}},),
         ("physics.bodies.0.friction.d_c_mm", "greater than 0")),
        (({**POST, "friction": {"law": "pressure", "mu_ref": 0.9, "mu_max": 0.9}},),
         ("bodies.0.friction", "mu_max = 0.9 is below mu_ref")),
        (({**POST, "friction": {"law": "coulomb", "mu": -0.2}},),
         ("physics.bodies.0.friction.mu", "-0.2")),
        # a size of another kind, a duplicated name
        (({**POST, "thickness_mm": 1.0},),
         ("bodies.0", "thickness_mm", "not a size of a cylinder")),
        ((POST, {**POST, "z_mm": -120.0}), ("bodies.name", "'post'", "duplicated")),
    ],
)
def test_bad_bodies_input(tmp_path, capsys, bodies, words):
    run_refused(tmp_path, capsys, LET_GO, _bodies(*bodies), *words)


def _moved(motion, velocities, stage=0):
    def edit(data):
        data["physics"]["bodies"] = [{**POST, "motion": motion}]
        data["physics"]["stages"][stage]["body_velocity_mm_s"] = dict(velocities)

    return edit


@pytest.mark.parametrize(
    "motion, velocities, words",
    [
        # a motion for a body that does not exist, or is not moved by the stages
        ("stage", {"piston": 1.0}, ("body_velocity_mm_s", "'piston'", "allowed", "'post'")),
        ("held", {"post": 1.0}, ("body_velocity_mm_s", "'post'", "no body has motion: stage")),
        ("stage", {"post": 2e4}, ("body_velocity_mm_s", "'post'", "[-1e4, 1e4]")),
    ],
)
def test_bad_stage_motion_input(tmp_path, capsys, motion, velocities, words):
    run_refused(tmp_path, capsys, LET_GO, _moved(motion, velocities), *words)


@pytest.mark.parametrize(
    "dotted, value, words",
    [
        ("numerics.solver", "kvaerno5", ("numerics.solver", "kvaerno5", "'post'",
                                         "allowed: load_step")),
        ("start_from", "formed.nc", ("start_from", "'post'", "no start_from")),
    ],
)
def test_a_free_body_needs_load_stepping_and_no_start_state(tmp_path, capsys, dotted, value,
                                                             words):
    def edit(data):
        data["physics"]["bodies"] = [{**POST, "motion": "free", "force_N": 0.5}]
        set_field(dotted, value)(data)

    run_refused(tmp_path, capsys, LET_GO, edit, *words)


def test_a_free_body_builds_with_its_force_and_drag_in_core_units():
    """motion: free makes the body's Held entry free: its force_N over G h0 R (2.0 N at the
    defaults: E = 2 MPa, h0 = 150 um, R = 20 mm), its drag the ball's eta_b = tau 4 pi times
    the multiple, its friction as given."""
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load_data, validate_data

    data = load_data(LET_GO)
    data["physics"]["bodies"] = [{**POST, "motion": "free", "force_N": 0.5, "drag": 3.0},
                                 {**POST, "name": "base", "z_mm": -120.0, "motion": "free",
                                  "friction": {"law": "coulomb", "mu": 0.4}}]
    sc = validate_data(data)
    model, _, _ = build_core(sc)
    post, base = model.bodies
    assert post.free and base.free and post.friction is None and not post.stage
    np.testing.assert_allclose(float(base.friction.mu), 0.4)
    assert sc.physics.force_scale_N == pytest.approx(2.0, rel=1e-12)
    np.testing.assert_allclose(float(post.force), 0.25, rtol=1e-12)
    tau = sc.numerics.drag_time_s
    np.testing.assert_allclose(float(post.drag), tau * 4 * np.pi * 3.0, rtol=1e-12)
    np.testing.assert_allclose([float(base.force), float(base.drag)], [0.0, tau * 4 * np.pi],
                               rtol=1e-12)


def test_a_stage_moved_body_builds_with_its_velocities_in_r_per_s():
    """motion: stage makes the body's Held entry stage-moved, and each stage's
    body_velocity_mm_s becomes the core stage's body_vz in R/s (0 where not named), one per
    held entry; a scenario without stage-moved bodies has no body_vz at all."""
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load_data
    from dynslip.schema.forming import FormingScenario

    data = load_data(LET_GO)
    _moved("stage", {"post": 2.5}, stage=0)(data)
    sc = FormingScenario.model_validate(data)
    model, protocol, _ = build_core(sc)
    r = sc.physics.ball_radius_mm
    assert [e.stage for e in model.bodies] == [True]
    assert protocol.stages[0].body_vz == (2.5 / r,)
    assert all(st.body_vz == (0.0,) for st in protocol.stages[1:])
    plain = load(LET_GO)
    assert all(st.body_vz == () for st in build_core(plain)[1].stages)


# with the slow tests: validating four bodies of four kinds checks every pair for overlap and
# shared faces, op by op (15 s of small compiles); the quick loop builds the coin, the band's
# tube and a free body below
@pytest.mark.slow
def test_bodies_build_as_held_entries_in_units_of_r():
    """Each entry of physics.bodies becomes a Held entry of the model: its geometry in units of
    R (the file's mm over ball_radius_mm), its friction and its motion as given."""
    from dynslip.app.forming import build_core
    from dynslip.physics.bodies import Cone, Cylinder, Profile, Torus
    from dynslip.schema.base import load_data, validate_data

    data = load_data(LET_GO)
    data["physics"]["bodies"] = [
        {**POST, "friction": {"law": "coulomb", "mu": 0.3}},
        {"name": "ring", "kind": "torus", "ring_radius_mm": 35.0, "minor_radius_mm": 3.0,
         "z_mm": -10.0, "motion": "with_ball"},
        {"name": "spike", "kind": "cone", "radius_mm": 8.0, "apex_mm": 12.0, "z_mm": -140.0},
        _profile(_arc((0, 0), 4.0, 90, 0), _line((4, 0), (4, -4)), _arc((0, -4), 4.0, 0, -90),
                 z_mm=-100.0),
    ]
    model, _, _ = build_core(validate_data(data))
    post, ring, spike, shape = model.bodies
    r = 20.0
    assert isinstance(post.body, Cylinder) and not post.moves_with_ball
    np.testing.assert_allclose([post.body.radius, post.body.z_bottom, post.body.z_top,
                                post.body.edge_radius], [10 / r, -60 / r, -30 / r, 2 / r])
    np.testing.assert_allclose(float(post.friction.mu), 0.3)
    assert isinstance(ring.body, Torus) and ring.moves_with_ball and ring.friction is None
    np.testing.assert_allclose([ring.body.ring_radius, ring.body.minor_radius,
                                ring.body.centre_z], [35 / r, 3 / r, -10 / r])
    assert isinstance(spike.body, Cone)
    np.testing.assert_allclose([spike.body.z_base, spike.body.z_apex], [-140 / r, -128 / r])
    assert isinstance(shape.body, Profile)
    # the capsule's length: two quarter circles and the straight side, in R
    np.testing.assert_allclose(shape.body.length, (np.pi * 4.0 + 4.0) / r, rtol=1e-12)
    np.testing.assert_allclose(float(shape.body.distance(np.array([0.0, -96 / r]))), 0.0,
                               atol=1e-12)


COIN = SCENARIOS / "coin.yaml"


@pytest.mark.parametrize(
    "dotted, value, words",
    [
        ("physics.ball.kind", "cube", ("physics.ball.kind", "cube", "'disc'")),
        ("physics.ball.edge_radius_mm", 1.0, ("ball (kind disc)", "edge radius", "half")),
        ("physics.ball.thickness_mm", 0.0, ("physics.ball.thickness_mm", "greater than 0")),
        ("physics.ball.radius_mm", -12.0, ("physics.ball.radius_mm", "-12")),
        ("physics.ball.edge_radius_mm", None, ("ball", "a disc needs edge_radius_mm")),
        ("physics.rim_radius_mm", 12.0, ("rim_radius_mm", "inside the ball", "12.13")),
    ],
)
def test_bad_ball_input(tmp_path, capsys, dotted, value, words):
    run_refused(tmp_path, capsys, COIN, set_field(dotted, value), *words)


def test_bottle_needs_the_sphere(tmp_path, capsys):
    def edit(data):
        data["physics"]["bottle"] = {}

    run_refused(tmp_path, capsys, COIN, edit, "bottle", "sphere", "kind disc")


def test_coin_scenario_builds_the_disc_and_starts_the_sheet_above_its_top():
    from dynslip.app.forming import build_core
    from dynslip.physics.bodies import Disc

    model, protocol, kw = build_core(load(COIN))
    r = 12.13
    assert isinstance(model.ball, Disc)
    np.testing.assert_allclose([model.ball.radius, model.ball.thickness, model.ball.edge_radius],
                               [1.0, 1.75 / r, 0.3 / r], rtol=1e-15)
    np.testing.assert_allclose([kw["z_sheet"], protocol.clamp_z0], (0.875 + 0.4) / r, rtol=1e-15)
