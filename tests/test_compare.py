"""compare: end states of two runs, their difference on the common contact region."""

import json

import numpy as np

from dynslip.app.compare import run_compare
from dynslip.data.files import write_netcdf
from helpers import synthetic_trajectory


def _run_dir(tmp_path, name, slope, n_contact, nr=21):
    state = np.zeros((3, nr), dtype=np.int8)
    state[:, :n_contact] = 1
    ds = synthetic_trajectory(state, theta_of_rbar=slope)
    d = tmp_path / name
    write_netcdf(ds, d / "trajectory.nc")
    return d, ds


def test_compare_difference_is_slope_difference(tmp_path):
    a, dsa = _run_dir(tmp_path, "a", 2.0, 8)
    b, dsb = _run_dir(tmp_path, "b", 2.1, 6)
    res = run_compare([a, b], out=tmp_path / "cmp")
    # theta = s rbar on both: the difference grows linearly to the common contact edge
    rb_common = float(dsb.rbar[5])
    d = res["differences"][f"{a} - {b}"]
    assert np.isclose(d["common_rbar_max"], rb_common)
    assert np.isclose(d["max_abs_dtheta"], 0.1 * rb_common, rtol=1e-12)
    assert np.isclose(res["runs"][str(a)]["theta_max"], 2.0 * float(dsa.rbar[7]))
    saved = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert saved["runs"][str(b)]["rbar_max"] == float(dsb.rbar[5])
    assert (tmp_path / "cmp" / "compare.png").stat().st_size > 0
