"""Does the mesh resolve the contact: element chord depths inside the ball
(dynslip.analysis.resolution), and what a run does when it does not."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from dynslip.analysis.resolution import ball_chord_depths, chord_check


@pytest.mark.parametrize("zb", [0.0, -0.37])
def test_a_chord_between_two_surface_points_dips_one_minus_cos_half_angle(zb):
    """Nodes on the unit sphere about (0, zb) at polar angles a and a + alpha: the chord's
    deepest point is 1 - cos(alpha/2) inside (the sagitta), for any a and alpha < pi."""
    rng = np.random.default_rng(3)
    a = rng.uniform(0.0, 1.5, 50)
    alpha = rng.uniform(1e-3, 1.6, 50)
    th = np.stack([a, a + alpha], axis=-1)
    d = ball_chord_depths(np.sin(th), zb + np.cos(th), np.full(50, zb))
    assert d.shape == (50, 1)
    np.testing.assert_allclose(d[:, 0], 1 - np.cos(alpha / 2), rtol=1e-10, atol=1e-14)


def test_cap_depth_falls_at_second_order_and_a_piercing_element_reads_near_one():
    """A cap laid on the sphere (theta = 2 rbar) has depth alpha^2/8 per element: measured order 2
    under refinement. One element joining the pole to the far side (the coarse-mesh artefact of
    the low-friction neo-Hookean runs) passes within 0.02 of the centre: depth 0.98."""
    depths = []
    for n in (11, 21, 41):
        th = np.linspace(0.0, 2.0, n)
        depths.append(float(np.max(ball_chord_depths(np.sin(th), np.cos(th), 0.0))))
    order = np.log2(np.array(depths[:-1]) / np.array(depths[1:]))
    assert np.all(np.abs(order - 2.0) < 0.02), order
    th = np.array([0.0, 3.12, 3.13])
    assert float(np.max(ball_chord_depths(np.sin(th), np.cos(th), 0.0))) == pytest.approx(
        1 - np.sin(0.01), abs=1e-3
    )
    flat = ball_chord_depths(
        np.linspace(0, 2, 5), np.full(5, 1.5), 0.0
    )  # a flat sheet 0.5 R above the ball
    assert np.all(flat <= -0.5 + 1e-12)


def test_chord_check_reports_the_worst_frame_and_element():
    """Over the frames of a trajectory, the worst chord, when and where it is, and the verdict."""
    rbar = np.linspace(0.0, 1.0, 4)
    good = np.linspace(0.0, 1.2, 4)  # a cap, 0.4 rad per element
    bad = np.array([0.0, 3.1, 3.12, 3.14])  # the pole element through the ball
    th = np.stack([good, bad, good])
    ds = xr.Dataset(
        {
            "rho": (("time", "rbar"), np.sin(th)),
            "z": (("time", "rbar"), np.cos(th) + 0.1),
            "ball_z": ("time", np.full(3, 0.1)),
        },
        coords={"time": [0.0, 2.0, 4.0], "rbar": rbar},
    )
    c = chord_check(ds, 0.1)
    assert (
        not c["resolved"]
        and c["time_s"] == 2.0
        and c["element_rbar"] == [0.0, pytest.approx(1 / 3)]
    )
    assert c["end_max_chord_depth"] == pytest.approx(1 - np.cos(0.2), rel=1e-10)
    assert chord_check(ds.isel(time=[0, 2]), 0.1)["resolved"]
    assert not c["pole_crossed_ball"]


def test_a_pole_that_passed_through_the_ball_between_frames_is_caught():
    """Saved frames every 2 s can miss the piercing itself: the sheet is above the ball, then
    below it, never inside in a saved frame. The pole changed sides of the centre on the axis,
    which the ball fills, so it went through: depth 1 at the first frame below."""
    rbar = np.linspace(0.0, 1.0, 4)
    th = np.linspace(0.0, 1.2, 4)
    above = np.stack([np.sin(th), np.cos(th) + 0.01])  # a cap on the ball
    below = np.stack([rbar, np.full(4, -5.0)])  # flat, 5 R below the centre
    frames = np.stack([above, above, below])
    ds = xr.Dataset(
        {
            "rho": (("time", "rbar"), frames[:, 0]),
            "z": (("time", "rbar"), frames[:, 1]),
            "ball_z": ("time", np.zeros(3)),
        },
        coords={"time": [0.0, 2.0, 4.0], "rbar": rbar},
    )
    c = chord_check(ds, 0.1)
    assert c["pole_crossed_ball"] and not c["resolved"]
    assert c["max_chord_depth"] == 1.0 and c["time_s"] == 4.0 and c["end_max_chord_depth"] < -3.9
    assert chord_check(ds.isel(time=[0, 1]), 0.1)["resolved"]


def test_a_window_search_counts_an_unresolved_run_as_failed_not_as_an_answer(tmp_path):
    """A member whose summary says the mesh does not resolve the contact is a failed point with
    the reason, never read as trapped (the coarse-mesh piercing reads trapped) or not trapped."""
    import io

    import yaml
    from rich.console import Console

    from dynslip.app.window import run_window

    def member(data, out_dir, console=None):
        mu = data["physics"]["friction"]["mu_s"]
        unresolved = mu < 0.45
        return {
            "trapped": None if unresolved else mu > 0.7,
            "mesh_check": {
                "resolved": not unresolved,
                "max_chord_depth": 0.97 if unresolved else 0.02,
                "time_s": 98.0,
                "limit": 0.1,
            },
        }

    s = tmp_path / "s.yaml"
    s.write_text(yaml.safe_dump({"kind": "forming", "physics": {"friction": {
        "law": "slip_weakening", "mu_s": 1.0, "mu_k": 0.8, "d_c_mm": 0.4}}}))
    res = run_window(s, lo=0.2, hi=1.0, coarse=5, tol=1e-2, out=tmp_path / "w", member_fn=member,
                     console=Console(file=io.StringIO()))
    assert abs(res["critical_mu"]["value"] - 0.7) <= 1e-2
    failed = dict((m, why) for m, why in res["failed"])
    assert failed and all(m < 0.45 for m in failed)
    assert all("not resolved by the mesh" in why and "0.97 R" in why for why in failed.values())


@pytest.mark.slow
def test_the_low_friction_neo_hookean_tube_path_pierces_the_ball_and_stops_without_an_answer(
    tmp_path,
):
    """The rim-feed tube path at mu_s = 0.3 on 40 nodes: the neo-Hookean pole stretches without
    bound in the push-down, and its element's chord sinks into the ball (at the end of that
    run, unchecked, it joins the pole to the far side and reads "trapped" with no friction
    mobilised). The run stops at the first saved frame past the limit, as a failure with the
    reason; the partial trajectory and summary are kept and agree with the check."""
    import json

    import xarray as xr

    from conftest import SCENARIOS
    from dynslip.app.kinds import run as run_scenario
    from dynslip.errors import ComputationError
    from dynslip.schema.base import load

    sc = load(SCENARIOS / "method2_rim_feed.yaml",
              ["numerics.nodes=40", "physics.friction.mu_s=0.3", "physics.friction.mu_k=0.2484"])
    with pytest.raises(ComputationError, match="contact not resolved by the mesh"):
        run_scenario(sc, tmp_path, None)
    s = json.loads((tmp_path / "summary.json").read_text())
    c = s["mesh_check"]
    assert s["status"] == "failed" and s["trapped"] is None and not c["resolved"]
    assert (
        c["max_chord_depth"] > sc.numerics.max_chord_depth
        and c["end_max_chord_depth"] == c["max_chord_depth"]
    )
    with xr.open_dataset(tmp_path / "trajectory.nc") as ds:
        assert int(ds.attrs["complete"]) == 0
        before = chord_check(ds.isel(time=slice(0, -1)), sc.numerics.max_chord_depth)
        assert before["resolved"]  # it stopped at the first frame past the limit
        assert float(ds["lambda_theta"].isel(time=-1).max()) > 10  # the pole running away
