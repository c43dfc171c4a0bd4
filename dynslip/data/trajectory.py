"""Reading ``trajectory.nc``: validation against the contract, time ranges, state codes.

The contract is ``docs/trajectory-contract.md`` (format version :data:`dynslip.FORMAT_VERSION`).
Readers (animations, fronts, comparisons) open a file with :func:`open_trajectory`, which
refuses anything that is not a dynslip trajectory of the supported format version with a
one-line :class:`~dynslip.errors.InputError` (exit 2). :func:`synthetic_trajectory` builds a
small contract-conforming dataset from a prescribed ``state`` field, for tests and
documentation examples.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from dynslip._version import FORMAT_VERSION
from dynslip.errors import InputError
from dynslip.data.files import provenance, variable

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


def synthetic_trajectory(
    state,
    time=None,
    rbar=None,
    stage=None,
    stage_names=("push", "release"),
    theta_of_rbar: float = 2.0,
    clamp_rho: float = 2.54,
    clamp_z=-1.5,
    clamp_force=None,
    attrs: dict | None = None,
) -> xr.Dataset:
    """A small contract-conforming trajectory whose ``state`` field is prescribed.

    For tests and examples: ``state`` (time, rbar) holds the contract's flags; nodes in
    contact sit on the unit ball at ``theta = theta_of_rbar * rbar``; free nodes lie on the
    straight line from the last contact node to the clamp at (``clamp_rho``, ``clamp_z``).
    Pressure is 1 in contact and 0 elsewhere; the other fields are simple but consistent
    placeholders. ``rbar`` defaults to ``linspace(0, clamp_rho, n)``, ``time`` to
    ``arange(n_time)`` s, ``stage`` to 0 for the first half of the frames and 1 after.
    """
    state = np.asarray(state, dtype=np.int8)
    nt, nr = state.shape
    time = np.arange(nt, dtype=float) if time is None else np.asarray(time, dtype=float)
    rbar = np.linspace(0.0, clamp_rho, nr) if rbar is None else np.asarray(rbar, dtype=float)
    if stage is None:
        stage = (np.arange(nt) >= nt // 2).astype(np.int8) if len(stage_names) > 1 else np.zeros(nt)
    stage = np.asarray(stage, dtype=np.int8)
    clamp_z = np.broadcast_to(np.asarray(clamp_z, dtype=float), (nt,)).copy()
    contact = state != FREE
    theta = np.where(contact, theta_of_rbar * rbar[None, :], np.nan)
    rho = np.empty((nt, nr))
    z = np.empty((nt, nr))
    theta_max = np.full(nt, np.nan)
    rbar_max = np.full(nt, np.nan)
    for k in range(nt):
        on = np.flatnonzero(contact[k])
        last = on.max() if on.size else -1
        th = theta_of_rbar * rbar
        rho[k] = np.sin(th)
        z[k] = np.cos(th)
        r0, z0, rb0 = (0.0, 1.0, 0.0) if last < 0 else (rho[k, last], z[k, last], rbar[last])
        if last >= 0:
            theta_max[k], rbar_max[k] = th[last], rbar[last]
        free = np.arange(nr) > last
        frac = (rbar[free] - rb0) / max(rbar[-1] - rb0, 1e-12)
        rho[k, free] = r0 + frac * (clamp_rho - r0)
        z[k, free] = z0 + frac * (clamp_z[k] - z0)
    pressure = np.where(contact, 1.0, 0.0)
    slip_v = np.select([state == SLIP_POLE, state == SLIP_EQUATOR], [-1.0, 1.0], 0.0)
    force = np.zeros(nt) if clamp_force is None else np.asarray(clamp_force, dtype=float)
    tn = ("time", "rbar")
    scen = json.dumps({"kind": "forming", "name": "synthetic"})
    data = {
        "rho": variable(rho, tn, "1", "deformed distance from the axis", scale="R"),
        "z": variable(z, tn, "1", "deformed height", scale="R"),
        "theta": variable(theta, tn, "1", "polar angle on the ball where in contact"),
        "lambda_theta": variable(np.ones((nt, nr)), tn, "1", "meridional stretch"),
        "lambda_phi": variable(np.ones((nt, nr)), tn, "1", "hoop stretch"),
        "T_theta": variable(np.zeros((nt, nr)), tn, "1", "meridional tension", scale="G*h0"),
        "T_phi": variable(np.zeros((nt, nr)), tn, "1", "hoop tension", scale="G*h0"),
        "pressure": variable(pressure, tn, "1", "contact pressure", scale="G*h0/R"),
        "friction": variable(np.zeros((nt, nr)), tn, "1", "meridional friction", scale="G*h0/R"),
        "slip_velocity": variable(slip_v, tn, "1/s", "meridional slip speed", scale="R/s"),
        "mu_mobilised": variable(np.where(contact, 0.5, np.nan), tn, "1", "mobilised friction"),
        "state": variable(
            state,
            tn,
            "1",
            "contact state",
            flag_values=np.array([0, 1, 2, 3], dtype=np.int8),
            flag_meanings=" ".join(STATE_MEANINGS),
        ),
        "stage": variable(stage, ("time",), "1", "index into stage_names"),
        "clamp_z": variable(clamp_z, ("time",), "1", "clamp height", scale="R"),
        "clamp_rho": variable(np.full(nt, clamp_rho), ("time",), "1", "clamp radius", scale="R"),
        "clamp_force": variable(force, ("time",), "1", "clamp axial force", scale="G*h0*R"),
        "ball_z": variable(np.zeros(nt), ("time",), "1", "ball centre height", scale="R"),
        "ball_reaction": variable(force, ("time",), "1", "force of the hold", scale="G*h0*R"),
        "theta_max": variable(theta_max, ("time",), "1", "largest polar angle in contact"),
        "rbar_max": variable(rbar_max, ("time",), "1", "outermost contact radius", scale="R"),
    }
    coords = {
        "time": variable(time, ("time",), "s", "time"),
        "rbar": variable(rbar, ("rbar",), "1", "undeformed radius", scale="R"),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(provenance(scen, "trajectory"))
    ds.attrs.update(
        complete=1,
        R_m=0.02,
        G_Pa=2e6 / 3,
        h0_m=150e-6,
        force_scale_N=2.0,
        stage_names=json.dumps(list(stage_names)),
        contact_threshold=1e-6,
    )
    ds.attrs.update(attrs or {})
    return ds
