"""Every body drawn (issue 21 item 6): the outlines rebuilt from a trajectory's scenario, the
state map of one held body (``dynslip fronts --body``), the animation's patches moved with the
ball, the export's revolved bodies. On a synthetic trajectory: nothing is simulated."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dynslip.app.drawn import drawn_bodies
from dynslip.app.export import _parts
from dynslip.data.files import write_netcdf
from dynslip.data.vtk import revolved_mesh
from dynslip.physics.bodies import Cylinder
from dynslip.schema import base as schema
from helpers import one_line, synthetic_trajectory

ROOT = Path(__file__).resolve().parents[1]
NAMES = ["tube wall", "bottle"]


def _method2_trajectory(nt=6, nr=12):
    """A synthetic trajectory carrying the main job's scenario and a per-body state: the tube
    wall touched by the outer nodes from frame 2 on, the bottle never. The lab frame: the
    ball at rest; :func:`_tube_moving` adds the tube's saved displacement."""
    state = np.zeros((nt, nr), np.int8)
    state[:, 1:4] = 1
    ds = synthetic_trajectory(state)
    ds.attrs["scenario"] = schema.load(ROOT / "scenarios" / "method2.yaml").to_json()
    ds = ds.assign(ball_z=("time", np.zeros(nt)))
    k = len(NAMES)
    body_state = np.zeros((nt, k, nr), np.int8)
    body_state[2:, 0, -4:-1] = [1, 2, 3]
    s = np.broadcast_to(np.linspace(4.0, 5.0, nr), (nt, k, nr)).copy()
    contact = (body_state > 0).astype(np.int8)
    lo = np.where(contact.any(2), np.where(contact, s, np.inf).min(2), np.nan)
    hi = np.where(contact.any(2), np.where(contact, s, -np.inf).max(2), np.nan)
    unit = {"units": "1", "long_name": "x"}
    return ds.assign_coords(body=("body", NAMES)).assign(
        body_state=(("time", "body", "rbar"), body_state, unit),
        body_contact=(("time", "body", "rbar"), contact, unit),
        body_s=(("time", "body", "rbar"), s, {**unit, "scale": "R"}),
        body_s_min=(("time", "body"), lo, {**unit, "scale": "R"}),
        body_s_max=(("time", "body"), hi, {**unit, "scale": "R"}),
        body_n_contact=(("time", "body"), contact.sum(2), unit),
    )


def _tube_moving(ds):
    """``ds`` with the tube's wall moved down by the stages (``body_z``), the bottle at rest."""
    nt = ds.sizes["time"]
    body_z = np.stack([np.linspace(0.0, -1.0, nt), np.zeros(nt)], 1)
    return ds.assign(body_z=(("time", "body"), body_z))


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "dynslip.cli", *map(str, args)], check=False,
                          cwd=cwd, capture_output=True, text=True, timeout=300)


def test_drawn_bodies_of_the_main_job_and_of_the_coin():
    ds = _method2_trajectory()
    d = drawn_bodies(ds)
    assert d["ball"] is None  # the unit sphere: drawn as the circle
    assert [n for n, _, _ in d["held"]] == NAMES
    # in the lab frame nothing is carried with the ball: a file without body_z draws both at rest
    assert [w is not None for _, _, w in d["held"]] == [False, False]
    # a file with body_z: every body at its saved displacement (here the wall moved by a stage)
    moved = drawn_bodies(_tube_moving(ds))
    np.testing.assert_array_equal(moved["held"][0][2], _tube_moving(ds)["body_z"].values[:, 0])
    assert moved["held"][1][2] is None  # the bottle, at rest: drawn once
    sc = schema.load(ROOT / "scenarios" / "method2.yaml")
    wall = d["held"][0][1]
    # the tube's outer wall: the rim's radius (the sheet's clamp circle) over the ball's
    assert wall[:, 0].max() == pytest.approx(sc.physics.rim_radius_mm / sc.physics.ball_radius_mm)
    coin = schema.load(ROOT / "scenarios" / "coin.yaml")
    ds.attrs["scenario"] = coin.to_json()
    c = drawn_bodies(ds)
    assert c["ball"] is not None and c["held"] == []
    o = c["ball"]  # a disc of the coin's thickness, its radius the length unit R
    assert o[:, 0].max() == pytest.approx(1.0)
    assert np.ptp(o[:, 1]) == pytest.approx(1.75 / 12.13)
    ds.attrs["scenario"] = "{not json"
    assert drawn_bodies(ds) is None


def test_fronts_body_state_map_and_a_bad_name_exits_2_writing_nothing(tmp_path):
    traj = write_netcdf(_method2_trajectory(), tmp_path / "run" / "trajectory.nc")
    p = _cli("fronts", traj, "--body", "tube", "--out", tmp_path / "bad", cwd=tmp_path)
    assert p.returncode == 2
    line = one_line(p.stderr)
    assert "body" in line and "'tube'" in line and all(f"'{n}'" in line for n in NAMES)
    assert not (tmp_path / "bad").exists()
    assert sorted(x.name for x in (tmp_path / "run").iterdir()) == ["trajectory.nc"]
    p = _cli("fronts", traj, "--body", "tube wall", "--out", tmp_path / "ok", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert [x.name for x in (tmp_path / "ok").iterdir()] == ["state_map_tube_wall.png"]
    assert (tmp_path / "ok" / "state_map_tube_wall.png").stat().st_size > 10_000


def test_animation_draws_each_body_and_moves_those_carried_by_the_ball():
    from dynslip.analysis.front_summary import fronts_dataset
    from dynslip.plot.animate import _Renderer

    ds = _tube_moving(_method2_trajectory())
    bodies = drawn_bodies(ds)
    r = _Renderer(ds, fronts_dataset(ds), np.arange(ds.sizes["time"]), (480, 240), bodies=bodies)
    try:
        assert len(r.moving) == 2 * 1  # the tube's wall, moved by the stages: both halves
        wall = bodies["held"][0][1]
        k = ds.sizes["time"] - 1
        r.draw(k)
        zt = float(ds["body_z"].values[k, 0])
        np.testing.assert_allclose(r.moving[0][0].get_xy()[: len(wall)], wall + [0.0, zt])
        static = [p for p in r.ax.patches if all(p is not m for m, *_ in r.moving)]
        assert len(static) == 2 + 1  # the bottle's halves, and the ball
    finally:
        r.close()


def test_export_revolves_each_body_and_moves_the_carried_ones():
    ds = _tube_moving(_method2_trajectory())
    parts = _parts(ds)
    assert [n for _, n, _ in parts] == ["sheet", "ball", *NAMES]
    r_mm = float(ds.attrs["R_m"]) * 1e3
    k = ds.sizes["time"] - 1
    wall = parts[2][2](ds, k)
    sc = schema.load(ROOT / "scenarios" / "method2.yaml")
    radius = np.hypot(wall.points[:, 0], wall.points[:, 1])
    assert radius.max() == pytest.approx(sc.physics.rim_radius_mm, rel=1e-12)
    wall0 = parts[2][2](ds, 0)
    np.testing.assert_allclose(wall.points[:, 2] - wall0.points[:, 2],
                               float(ds["body_z"].values[k, 0]) * r_mm)  # the tube moved down
    glass0, glass = parts[3][2](ds, 0), parts[3][2](ds, k)
    np.testing.assert_allclose(glass.points, glass0.points)  # the bottle stays put


def test_revolved_cylinder_is_on_its_radius_and_height():
    c = Cylinder(1.5, -2.0, 0.5)
    m = revolved_mesh(c.outline(), 10.0, shift=1.0, n_phi=16)
    radius = np.hypot(m.points[:, 0], m.points[:, 1])
    assert radius.max() == pytest.approx(15.0) and radius.min() == pytest.approx(0.0)
    assert m.points[:, 2].min() == pytest.approx(-10.0) and m.points[:, 2].max() == pytest.approx(
        15.0)
    assert m.cells[0].data.shape == ((len(c.outline()) - 1) * 16, 4)
