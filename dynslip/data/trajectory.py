"""Reading ``trajectory.nc``: validation against the contract, time ranges, state codes.

The contract is ``docs/trajectory-contract.md`` (format version :data:`dynslip.FORMAT_VERSION`).
Readers (animations, fronts, comparisons) open a file with :func:`open_trajectory`, which
refuses anything that is not a dynslip trajectory of the supported format version with a
one-line :class:`~dynslip.errors.InputError` (exit 2).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from dynslip._version import FORMAT_VERSION
from dynslip.errors import InputError

FREE, STUCK, SLIP_POLE, SLIP_EQUATOR = 0, 1, 2, 3
"""The ``state`` flags of the contract."""
STATE_MEANINGS = ("free", "stuck", "slipping_toward_pole", "slipping_toward_equator")

REQUIRED_VARIABLES = (
    "state",
    "theta",
    "rho",
    "z",
    "stage",
    "clamp_z",
    "clamp_rho",
    "clamp_force",
    "ball_z",
    "theta_max",
    "rbar_max",
)
"""Variables every reader of this module needs (a subset of the contract)."""


def open_trajectory(path) -> xr.Dataset:
    """Open ``path`` as a dynslip trajectory and load it into memory.

    Raises :class:`~dynslip.errors.InputError` (one line) when the file is missing, is not
    netCDF, is not a trajectory (global attribute ``kind``), has another format version
    (``format_version``), or lacks a variable the readers need.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(
            f"trajectory: {str(path)!r} does not exist (expected a trajectory.nc file)"
        )
    try:
        with xr.open_dataset(path, engine="netcdf4") as f:
            ds = f.load()
    except (OSError, ValueError, RuntimeError, KeyError, TypeError) as exc:  # not netCDF
        raise InputError(
            f"trajectory: {str(path)!r} is not a netCDF file ({type(exc).__name__}); "
            "expected a trajectory.nc written by dynslip run"
        ) from None
    validate_trajectory(ds, source=str(path))
    return ds


def validate_trajectory(ds: xr.Dataset, source: str = "<dataset>") -> None:
    """Raise :class:`InputError` unless ``ds`` follows the trajectory contract (format version 1)."""
    kind = ds.attrs.get("kind")
    if kind != "trajectory":
        raise InputError(
            f"trajectory: {source!r} has kind={kind!r}; expected kind='trajectory' "
            "(a file written by dynslip run for a forming scenario)"
        )
    version = str(ds.attrs.get("format_version"))
    if version != FORMAT_VERSION:
        raise InputError(
            f"trajectory: {source!r} has format_version={version!r}; this dynslip reads "
            f"format_version={FORMAT_VERSION!r} only"
        )
    for dim in ("time", "rbar"):
        if dim not in ds.coords:
            raise InputError(f"trajectory: {source!r} lacks the coordinate {dim!r}")
    missing = [v for v in REQUIRED_VARIABLES if v not in ds.variables]
    if missing:
        raise InputError(f"trajectory: {source!r} lacks the variable(s) {', '.join(missing)}")
    if ds.sizes["time"] < 1 or ds.sizes["rbar"] < 2:
        raise InputError(
            f"trajectory: {source!r} has {ds.sizes['time']} frames and {ds.sizes['rbar']} nodes; "
            "expected at least 1 frame and 2 nodes"
        )


def stage_names(ds: xr.Dataset) -> list[str]:
    """The protocol's stage names (global attribute ``stage_names``, a JSON list)."""
    raw = ds.attrs.get("stage_names")
    if raw is None:
        n = int(np.nanmax(ds["stage"].values)) + 1 if ds.sizes["time"] else 0
        return [f"stage {i}" for i in range(n)]
    names = json.loads(raw) if isinstance(raw, str) else list(raw)
    return [str(n) for n in names]


def state_array(ds: xr.Dataset) -> np.ndarray:
    """The ``state`` flags as an int array (time, rbar); missing values count as free."""
    s = np.asarray(ds["state"].transpose("time", "rbar").values, dtype=float)
    return np.where(np.isfinite(s), s, FREE).astype(np.int8)


def time_indices(ds: xr.Dataset, t_range=None) -> np.ndarray:
    """Indices of the saved frames with ``t_start <= time <= t_end``.

    ``t_range`` is ``None`` (all frames) or ``(t_start, t_end)`` in seconds, either of which
    may be ``None``. A range outside the run, reversed, or holding no saved frame raises
    :class:`InputError`.
    """
    t = np.asarray(ds["time"].values, dtype=float)
    if t_range is None:
        return np.arange(t.size)
    t0, t1 = t_range
    lo, hi = float(t[0]), float(t[-1])
    tol = 1e-9 * max(1.0, abs(hi - lo))
    if t0 is not None and not (lo - tol <= t0 <= hi + tol):
        raise InputError(
            f"t_start: {t0!r} s is outside the run; allowed: {lo:g} <= t_start <= {hi:g} s"
        )
    if t1 is not None and not (lo - tol <= t1 <= hi + tol):
        raise InputError(
            f"t_end: {t1!r} s is outside the run; allowed: {lo:g} <= t_end <= {hi:g} s"
        )
    t0 = lo if t0 is None else float(t0)
    t1 = hi if t1 is None else float(t1)
    if t1 < t0:
        raise InputError(f"t_end: {t1!r} s is before t_start = {t0!r} s; allowed: t_end >= t_start")
    idx = np.flatnonzero((t >= t0 - tol) & (t <= t1 + tol))
    if idx.size == 0:
        raise InputError(
            f"t_start, t_end: [{t0:g}, {t1:g}] s holds no saved frame; pick a wider range within "
            f"[{lo:g}, {hi:g}] s"
        )
    return idx
