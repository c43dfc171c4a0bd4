"""``dynslip export``: a trajectory revolved into 3D surfaces, read back with meshio and checked
against the dataset (frames, fields, values, the points on the sheet's meridian)."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest
import xarray as xr

from dynslip.data.vtk import CELL_FIELDS, POINT_FIELDS, scales

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "method2_let_go.yaml"

pytestmark = pytest.mark.slow


def dynslip(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "dynslip.cli", *map(str, args)],
        check=False,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    p = dynslip(
        "run",
        SCENARIO,
        "--set",
        "numerics.nodes=12",
        "--set",
        "numerics.max_chord_depth=0.3",
        "--out",
        d / "r",
        cwd=d,
    )
    assert p.returncode == 0, p.stderr
    with xr.open_dataset(d / "r" / "trajectory.nc") as ds:
        return d, ds.load()


def _check_sheet(mesh, ds, k, points=None):
    sc = scales(ds)
    pts = mesh.points if points is None else points
    n = ds.sizes["rbar"]
    rho = ds["rho"].values[k] * sc["R"]
    z = ds["z"].values[k] * sc["R"]
    # every point on the meridian of its node, whatever its angle
    np.testing.assert_allclose(
        np.hypot(pts[:, 0], pts[:, 1]), np.tile(rho, pts.shape[0] // n), atol=1e-9
    )
    np.testing.assert_allclose(pts[:, 2], np.tile(z, pts.shape[0] // n), atol=1e-12)
    assert set(POINT_FIELDS) <= set(mesh.point_data)
    p = mesh.point_data["pressure [MPa]"][:n]
    np.testing.assert_allclose(p, ds["pressure"].values[k] * sc["G*h0/R"], rtol=1e-12)
    np.testing.assert_array_equal(
        mesh.point_data["state [0 free, 1 stuck, 2 slip to pole, 3 slip to equator]"][:n],
        ds["state"].values[k],
    )
    v = ds["slip_velocity"].values[k] * sc["R"]
    np.testing.assert_allclose(
        mesh.point_data["slip_velocity [mm/s]"][:n], v, rtol=1e-12, atol=1e-300
    )
    cell = mesh.cell_data["T_theta [N/mm]"][0][: n - 1]
    t = ds["T_theta"].values[k] * sc["G*h0"]
    np.testing.assert_allclose(cell, 0.5 * (t[:-1] + t[1:]), rtol=1e-12)
    assert set(CELL_FIELDS) <= set(mesh.cell_data)


def test_vtu_series_reads_back(run):
    d, ds = run
    p = dynslip("export", d / "r" / "trajectory.nc", "--out", d / "vtu", cwd=d)
    assert p.returncode == 0, p.stderr
    entries = ET.parse(d / "vtu" / "trajectory.pvd").getroot().find("Collection").findall("DataSet")
    nt = ds.sizes["time"]
    assert len(entries) == 2 * nt
    np.testing.assert_allclose(
        sorted({float(e.get("timestep")) for e in entries}), ds["time"].values
    )
    r_mm = scales(ds)["R"]
    for k in (0, nt // 2, nt - 1):
        sheet = meshio.read(d / "vtu" / f"sheet_{k:04d}.vtu")
        assert sheet.cells[0].type == "quad"
        _check_sheet(sheet, ds, k)
        ball = meshio.read(d / "vtu" / f"ball_{k:04d}.vtu")
        centre = np.array([0.0, 0.0, ds["ball_z"].values[k] * r_mm])
        np.testing.assert_allclose(np.linalg.norm(ball.points - centre, axis=1), r_mm, rtol=1e-12)


def test_xdmf_series_reads_back(run):
    d, ds = run
    p = dynslip("export", d / "r" / "trajectory.nc", "--format", "xdmf", "--out", d / "xdmf", cwd=d)
    assert p.returncode == 0, p.stderr
    with meshio.xdmf.TimeSeriesReader(d / "xdmf" / "sheet.xdmf") as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == ds.sizes["time"]
        for k in (0, reader.num_steps - 1):
            t, pd, cd = reader.read_data(k)
            assert t == pytest.approx(float(ds["time"].values[k]))
            moved = points + pd["displacement [mm]"]
            _check_sheet(
                meshio.Mesh(points, cells, point_data=pd, cell_data=cd), ds, k, points=moved
            )


def test_export_of_a_file_that_is_not_a_trajectory_is_bad_input(tmp_path):
    (tmp_path / "x.nc").write_text("not netcdf")
    p = dynslip("export", tmp_path / "x.nc", cwd=tmp_path)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "paraview").exists()
