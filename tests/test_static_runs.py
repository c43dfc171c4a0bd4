"""Every static scenario smoke-run at small resolution through the scenario loader, the
files it writes, the failure path (exit 3 with partial results) and the netCDF round trip."""

import json
from pathlib import Path

import numpy as np
import pint
import pytest
import xarray as xr
from rich.console import Console

from dynslip.app.kinds import run as run_scenario
from dynslip.data import files as io
from dynslip.errors import ComputationError, InputError
from dynslip.schema.base import load

SMALL = ["numerics.n_nodes=40"]
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
UREG = pint.UnitRegistry()


def _run(scenarios_dir, tmp_path_factory, name, overrides):
    out = tmp_path_factory.mktemp(name)
    sc = load(scenarios_dir / f"{name}.yaml", overrides)
    summary = run_scenario(sc, out, Console(width=120, record=True))
    return out, summary


@pytest.fixture(scope="module")
def neo(tmp_path_factory):
    return _run(SCENARIOS, tmp_path_factory, "paper_neohookean", SMALL)


def _check_units(ds):
    for name, var in {**ds.coords, **ds.data_vars}.items():
        assert "units" in var.attrs and "long_name" in var.attrs, name
        UREG.parse_units(var.attrs["units"] if var.attrs["units"] != "1" else "dimensionless")


def test_static_run_writes_result_summary_and_figure(neo):
    out, summary = neo
    ds = xr.open_dataset(out / "result.nc")
    for v in (
        "theta",
        "lambda_theta",
        "lambda_phi",
        "T_theta",
        "T_phi",
        "F_m",
        "F_N",
        "mu_mobilised",
        "friction_direction",
        "mu",
    ):
        assert v in ds, v
    assert "rbar" in ds.coords
    _check_units(ds)
    assert ds["theta"].attrs["units"] == "rad"
    assert ds["T_theta"].attrs["scale"] == "G*h0"
    for a in ("scenario", "dynslip_version", "git_commit", "format_version"):
        assert a in ds.attrs
    assert ds.attrs["complete"] == 1
    assert json.loads(ds.attrs["scenario"])["kind"] == "static"
    s = json.loads((out / "summary.json").read_text())
    for k in (
        "mu",
        "F_v",
        "lambda_theta_max",
        "lambda_theta_max_rbar",
        "lambda_phi_max",
        "saturated_fraction",
        "selection_rule",
    ):
        assert k in s, k
    assert s == json.loads(json.dumps(summary, default=float)) or s["mu"] == pytest.approx(
        summary["mu"]
    )
    assert (out / "figure4_row.png").stat().st_size > 10_000
    # the result is an equilibrium at its mu, with the mobilised friction at most mu
    mu = float(ds["mu"])
    assert np.nanmax(ds["mu_mobilised"].values[1:-1]) <= mu * (1 + 1e-5)
    assert s["equilibrium_ok"] and s["F_v"] <= s["fv_tolerance"]
    ds.close()


def test_netcdf_round_trip(neo, tmp_path):
    out, _ = neo
    with xr.open_dataset(out / "result.nc") as ds:
        ds = ds.load()
    io.write_netcdf(ds, tmp_path / "again.nc")
    with xr.open_dataset(tmp_path / "again.nc") as back:
        xr.testing.assert_identical(ds, back.load())


# the quick loop runs one hyperelastic model's scenario through the command line; the other two
# (about 10 s each, the static search compiled per model) run with the slow tests
@pytest.mark.parametrize("name", [
    "paper_hookean",
    pytest.param("paper_gent", marks=pytest.mark.slow),
    pytest.param("paper_mooney_rivlin", marks=pytest.mark.slow),
])
def test_other_static_scenarios(scenarios_dir, tmp_path_factory, name):
    out, s = _run(scenarios_dir, tmp_path_factory, name, SMALL)
    assert s["status"] == "ok" and s["equilibrium_ok"]
    assert s["mu"] > 0 and s["saturated_fraction"] > 0.5
    assert (out / "result.nc").exists() and (out / "figure4_row.png").exists()


def test_figure4_scenario(scenarios_dir, tmp_path_factory):
    out, s = _run(scenarios_dir, tmp_path_factory, "paper_figure4", SMALL)
    mu = s["mu"]
    assert mu["hookean"] > mu["gent"] > mu["neo_hookean"]
    with xr.open_dataset(out / "result.nc") as ds:
        assert ds["theta"].dims == ("model", "rbar")
        _check_units(ds)
    assert (out / "figure4.png").stat().st_size > 30_000


def test_family_scenario(scenarios_dir, tmp_path_factory):
    out, s = _run(scenarios_dir, tmp_path_factory, "paper_family", ["numerics.n_members=4"])
    with xr.open_dataset(out / "result.nc") as ds:
        mu = ds["mu"].values
        _check_units(ds)
    # mu grows as the switch point moves out, for every model
    assert np.all(np.diff(mu, axis=1) > 0)
    assert (out / "family.png").exists()


def test_cylinder_scenario(scenarios_dir, tmp_path_factory):
    out, s = _run(scenarios_dir, tmp_path_factory, "cylinder",
                  ["numerics.n_profiles=20", "numerics.n_angles=5", "numerics.n_nodes=201"])
    assert s["all_F_v_positive"] and s["min_F_v"] > 0
    assert s["max_capstan_bound_violation"] <= 1e-12
    assert (out / "cylinder.png").exists()


def test_no_root_is_exit_3_with_partial_results(scenarios_dir, tmp_path):
    """From theta = 2 rbar there is no root: ComputationError (exit 3), F_v at both ends in
    the message, and a partial result.nc (complete = 0) and summary (status failed) kept."""
    sc = load(scenarios_dir / "paper_neohookean.yaml",
              ["numerics.n_nodes=30", "physics.initial_shape=linear", "numerics.max_steps=20000",
               "numerics.mu_bracket=[1.0, 3.0]"])
    with pytest.raises(ComputationError, match=r"F_v\(1\) = .*F_v\(3\) = ") as exc:
        run_scenario(sc, tmp_path, Console())
    assert exc.value.exit_code == 3
    with xr.open_dataset(tmp_path / "result.nc") as ds:
        assert ds.attrs["complete"] == 0 and ds.attrs["status"] == "failed"
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "failed" and len(s["F_v_at_bracket_ends"]) == 2
    assert all(f > 0 for f in s["F_v_at_bracket_ends"])


@pytest.mark.parametrize("override, field", [
    ("physics.theta_max=3.5", "theta_max"),
    ("physics.rbar_max=-1", "rbar_max"),
    ("physics.material.model=gent", None),
    ("numerics.mu_bracket=[2.0, 1.0]", "mu_bracket"),
])
def test_schema_ranges(scenarios_dir, override, field):
    if field is None:  # switching the discriminator picks the Gent defaults
        assert load(scenarios_dir / "paper_neohookean.yaml", [override]).physics.material.jm == 50.0
        return
    with pytest.raises(InputError, match=field):
        load(scenarios_dir / "paper_neohookean.yaml", [override])


def test_mooney_rivlin_constraint(scenarios_dir):
    with pytest.raises(InputError, match="2 c1 \\+ 2 c2"):
        load(scenarios_dir / "paper_mooney_rivlin.yaml", ["physics.material.c2=0.3"])
