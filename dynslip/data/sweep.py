"""The sweep dataset (``sweep.nc``): the member records assembled into one dataset, a
dimension per swept field for a grid, a ``member`` dimension for a list.

The members and the spec are read by duck typing (``spec.grid``, ``spec.grid_values()``,
``spec.window``; ``member.index``, ``member.assign``, ``member.fingerprint``): this layer
knows neither the schema nor the runners. ``unit_of(field)`` gives a swept field's unit,
``base_value(member, field)`` a field's value in a member that does not assign it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import xarray as xr

from dynslip.data.files import variable

MEMBER_DIM = "member"


#: summary keys not turned into variables (kept by ``status`` and ``error``, or declarations)
SUMMARY_SKIP = ("units", "status", "message")


#: wall-clock measures: kept in the member files, left out of the dataset (which must not
#: depend on the runner or the machine's load)
TIMING_SUFFIXES = ("compile_s", "run_s", "wall_s", "time_per_step_ms")


WINDOW_DIM = "window"


#: units and long names of the summary keys the forming runner returns
KNOWN_VARIABLES: dict[str, tuple[str, str]] = {
    "trapped": (
        "1",
        "ball ends trapped (1 yes, 0 no, NaN failed member or contact not resolved by the mesh)",
    ),
    "theta_max": ("rad", "polar angle of the contact edge at the end"),
    "rbar_max": ("1", "material radius reaching the contact edge, by R"),
    "opening_radius": ("1", "radius of the pocket's opening R sin(theta_max), by R"),
    "mu_mobilised_max": ("1", "largest mobilised |F_f| / F_N on the end state"),
    "release_force": ("N", "peak force of the release"),
}


def _flatten(summary: dict, prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in summary.items():
        if k in SUMMARY_SKIP:
            continue
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}_"))
        elif (isinstance(v, (bool, int, float, str)) or v is None) and not (prefix + k).endswith(
            TIMING_SUFFIXES
        ):
            out[prefix + k] = v
    return out


def _coord(values: list) -> np.ndarray:
    arr = np.asarray(values)
    return arr if arr.dtype.kind in "biuf" else np.asarray([str(v) for v in values])


def assemble(
    spec, members: list, records: dict[str, dict], attrs: dict, *,
    unit_of: Callable[[str], str], base_value: Callable[[Any, str], Any],
) -> xr.Dataset:
    """One dataset from the member records: a dimension per swept field (grid) or ``member``."""

    if spec.grid is not None:
        grid = spec.grid_values()
        dims = tuple(grid)
        shape = tuple(len(v) for v in grid.values())
        coords = {k: variable(_coord(v), (k,), "1", f"swept field {k}") for k, v in grid.items()}
        for k in dims:
            coords[k].attrs["units"] = unit_of(k)
    else:
        dims = (MEMBER_DIM,)
        shape = (len(members),)
        keys = list(dict.fromkeys(k for m in members for k in m.assign))
        coords = {MEMBER_DIM: variable(np.arange(len(members)), dims, "1", "member of the list")}
        for k in keys:
            vals = [m.assign.get(k, base_value(m, k)) for m in members]
            coords[k] = variable(
                _coord(vals),
                dims,
                unit_of(k),
                f"swept field {k}",
            )
    flat = {m.fingerprint: _flatten(records[m.fingerprint]["summary"]) for m in members}
    units_decl: dict[str, str] = {}
    for m in members:
        units_decl.update(records[m.fingerprint]["summary"].get("units", {}) or {})
    names = list(
        dict.fromkeys(["trapped", *KNOWN_VARIABLES, *(k for f in flat.values() for k in f)])
    )
    data_vars = {}
    for name in names:
        vals = [flat[m.fingerprint].get(name) for m in members]
        present = [v for v in vals if v is not None]
        if not present and name not in ("trapped",):
            continue
        if present and all(isinstance(v, str) for v in present):
            arr = np.full(shape, "", dtype=object)
            fill: list[str | float] = [v if isinstance(v, str) else "" for v in vals]
        else:
            arr = np.full(shape, np.nan)
            fill = [
                float(v) if isinstance(v, (int, float)) and not isinstance(v, str) else np.nan
                for v in vals
            ]
        for m, v in zip(members, fill, strict=True):
            arr[m.index if spec.grid is not None else m.index[0]] = v
        unit, long_name = KNOWN_VARIABLES.get(
            name, (units_decl.get(name, "1"), f"{name} (from the member's summary)")
        )
        extra = (
            {}
            if name in KNOWN_VARIABLES or name in units_decl
            else {"units_note": "not declared by the simulator"}
        )
        data_vars[name] = variable(
            arr.astype(str) if arr.dtype == object else arr, dims, unit, long_name, **extra
        )
    status = np.full(shape, "missing", dtype=object)
    error = np.full(shape, "", dtype=object)
    for m in members:
        at = m.index if spec.grid is not None else m.index[0]
        status[at] = records[m.fingerprint]["status"]
        error[at] = records[m.fingerprint]["error"]
    data_vars["status"] = variable(
        status.astype(str), dims, "1", "member status: ok, failed (ComputationError) or error"
    )
    data_vars["error"] = variable(error.astype(str), dims, "1", "error of a failed member")
    if spec.window is not None:
        data_vars.update(_window_vars(spec, members, records, dims, shape))
    ds = xr.Dataset(data_vars, coords=coords, attrs=attrs)
    return ds


def _window_vars(spec, members, records, dims, shape) -> dict:

    n_max = max([1] + [len(records[m.fingerprint]["window"]["windows"]) for m in members])
    wdims = (*dims, WINDOW_DIM)
    out = {
        k: np.full((*shape, n_max), np.nan)
        for k in ("window_lo", "window_hi", "window_lo_err", "window_hi_err")
    }
    n = np.full(shape, np.nan)
    nfail = np.full(shape, np.nan)
    for m in members:
        at = m.index if spec.grid is not None else m.index[0]
        w = records[m.fingerprint]["window"]
        n[at] = len(w["windows"])
        nfail[at] = len(w["failed"])
        for j, d in enumerate(w["windows_detail"]):
            out["window_lo"][at][j] = d["lo"]["value"]
            out["window_hi"][at][j] = d["hi"]["value"]
            out["window_lo_err"][at][j] = d["lo"]["err"]
            out["window_hi_err"][at][j] = d["hi"]["err"]
    field_name = records[members[0].fingerprint]["window"]["field"]
    res = {
        name: variable(
            arr, wdims, "1", f"{name.replace('_', ' ')} of the trapping windows of {field_name}"
        )
        for name, arr in out.items()
    }
    res["n_windows"] = variable(n, dims, "1", f"number of trapping windows of {field_name} found")
    res["window_failed_runs"] = variable(nfail, dims, "1", "failed runs of the window search")
    return res
