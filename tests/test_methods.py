"""Method 1 against method 2 (its let-go path: on the tube the model does not trap) at the
shipped default settings (slow: N = 50, full paths).

The paper reports that both methods end in essentially the same pocket; the numbers are
reported (printed), and the assertions are what the model must show: both trap the
ball, at rest, with the energy balance closed, and theta(rbar) agrees on the common contact
region within a stated bound.
"""

import json
import math

import pytest

from conftest import SCENARIOS, assert_energy_closes
from dynslip.analysis.compare import difference, end_state
from dynslip.app.kinds import run as run_scenario
from dynslip.schema.base import load


@pytest.mark.slow
def test_method1_and_method2_at_default_settings(tmp_path):
    import xarray as xr

    ends, sums = {}, {}
    for m, f in (
        ("method1", "method1.yaml"),
        ("method2", "method2_let_go.yaml"),
    ):  # method 2: the path that traps
        sc = load(SCENARIOS / f)
        s = run_scenario(sc, tmp_path / m, None)
        sums[m] = s
        with xr.open_dataset(tmp_path / m / "trajectory.nc") as ds:
            ends[m] = end_state(ds.load())
    d = difference(ends["method1"], ends["method2"])
    report = {
        m: {k: sums[m][k] for k in ("trapped", "theta_max", "rbar_max", "mu_mobilised_max")}
        for m in sums
    }
    report["max_abs_dtheta"] = d["max_abs_dtheta"]
    report["common_rbar_max"] = d["common_rbar_max"]
    print("method 1 vs method 2:", json.dumps(report, indent=1))
    for m, s in sums.items():
        assert s["status"] == "ok", m
        assert s["trapped"] is True, m
        assert s["theta_max"] > math.pi / 2
        assert_energy_closes(s)
    # The same pocket: on the common contact region (rbar up to 0.97 R) theta(rbar) of the two
    # methods differs by at most 0.1 rad (a stated bound, 5% of theta_max; measured 0.058 rad,
    # theta_max 1.841 and 1.799: ``pytest -s -m slow tests/test_methods.py`` at commit abd10c6
    # merged with speed 0c23bc9), on a common region reaching past the ball's equator radius 0.9 R.
    assert d["common_rbar_max"] > 0.9
    assert d["max_abs_dtheta"] < 0.1
