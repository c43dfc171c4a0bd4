"""``trajectory.nc``: building it from the driver's frames, reading and validating it against
the contract, time ranges, state codes.

The contract is ``docs/trajectory-contract.md`` (format version :data:`dynslip.FORMAT_VERSION`).
The runner builds the dataset with :func:`frames_to_dataset` (plain data in: frames, mesh and the
scenario's values; no schema object). Readers (animations, fronts, comparisons) open a
file with :func:`open_trajectory`, which refuses anything that is not a dynslip trajectory
of the supported format version with a one-line :class:`~dynslip.errors.InputError` (exit 2).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dynslip._version import FORMAT_VERSION
from dynslip.data import files as io
from dynslip.errors import InputError

if TYPE_CHECKING:  # imported where used: a run imports xarray while its step compiles
    import xarray as xr

TRAJECTORY_FILE = "trajectory.nc"
"""The file name of a forming run's dataset in its run folder."""

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

PER_NODE = {
    "rho": ("1", "deformed distance from the axis", "R"),
    "z": ("1", "deformed height (ball centre at the origin when ball_z = 0)", "R"),
    "theta": ("1", "polar angle on the ball where in contact (NaN where free)", None),
    "lambda_theta": ("1", "meridional stretch", None),
    "lambda_phi": ("1", "hoop stretch", None),
    "T_theta": ("1", "relaxed meridional tension per deformed length", "G*h0"),
    "T_phi": ("1", "relaxed hoop tension per deformed length", "G*h0"),
    "pressure": ("1", "contact pressure F_N", "G*h0/R"),
    "friction": (
        "1",
        "meridional friction force density on the sheet, + toward the equator",
        "G*h0/R",
    ),
    "slip_velocity": (
        "1/s",
        "meridional slip speed relative to the ball, + toward the equator (R/s)",
        "R",
    ),
    "mu_mobilised": ("1", "|friction| / pressure where in contact", None),
    "mu_current": (
        "1",
        "friction coefficient of the law at the node (mu; or mu(slip distance) between mu_s and "
        "mu_k) where in contact",
        None,
    ),
    "slip_distance": (
        "1",
        "slip distance since the node last stuck (slip_weakening; 0 for coulomb)",
        "R",
    ),
}
"""Per-node variables (time, rbar) of the contract: name -> (units, long_name, scale)."""
PER_TIME = {
    "stage": ("1", "index into stage_names", None),
    "clamp_z": ("1", "clamp height", "R"),
    "clamp_rho": ("1", "clamp radius", "R"),
    "clamp_force": ("1", "axial force the clamp exerts on the sheet, + along +z", "G*h0*R"),
    "clamp_force_rho": ("1", "radial force the clamp exerts on the sheet, + outward", "G*h0*R"),
    "ball_z": ("1", "ball centre height", "R"),
    "ball_reaction": ("1", "force of the hold on the ball, + along +z (0 once released)", "G*h0*R"),
    "ball_reaction_static": ("1", "the hold's force on the ball net of drag (the sheet's drag "
                             "forces and the ball's own): the reaction a support would carry at "
                             "rest, + along +z (the applied force once released)", "G*h0*R"),
    "clamp_force_static": ("1", "axial force the clamp exerts on the sheet net of the sheet's "
                           "drag (what the sheet's shape alone asks of it), + along +z",
                           "G*h0*R"),
    "theta_max": ("1", "largest polar angle in contact", None),
    "rbar_max": ("1", "material radius of the outermost node in contact", "R"),
    "theta_edge": ("1", "polar angle of the contact edge located between the last node in contact "
                   "and the next, where the contact function (penetration past the threshold's) "
                   "crosses zero: continuous in the parameters (NaN without contact)", None),
    "rbar_edge": ("1", "material radius of the located contact edge (theta_edge's; NaN without "
                  "contact)", "R"),
    "ball_velocity": ("1/s", "the ball's axial velocity, + up (R/s)", "R"),
    "work_clamp": ("1", "accumulated work of the clamp on the sheet", "G*h0*R^2"),
    "work_ball": ("1", "accumulated work of the hold (and gravity) on the ball", "G*h0*R^2"),
    "work_bodies": ("1", "accumulated work on the sheet of the held bodies moved by the stages "
                    "(0 without any)", "G*h0*R^2"),
    "energy_elastic": ("1", "stored relaxed elastic energy (pre-stretch included)", "G*h0*R^2"),
    "energy_penalty": ("1", "contact penalty energy", "G*h0*R^2"),
    "dissipation_friction": ("1", "accumulated friction dissipation", "G*h0*R^2"),
    "dissipation_drag": ("1", "accumulated drag dissipation (ball drag included)", "G*h0*R^2"),
    "energy_residual": ("1", "work - (change of stored energy) - dissipation", "G*h0*R^2"),
}
"""Per-frame variables (time) of the contract: name -> (units, long_name, scale)."""
OPTIONAL_PER_TIME = ("theta_edge", "rbar_edge", "ball_velocity")
"""Per-frame variables that files written before them lack (readers fall back)."""

THETA_AT_RBAR = ("1", "polar angle, seen from the ball's centre, of the material circle of radius "
                 "rbar_at (linear in the material coordinate): theta(rbar) on the contact "
                 "(rbar_at <= rbar_edge), the circle's angle off the ball beyond it", None)
"""The per-frame theta at fixed material radii (time, rbar_at): (units, long_name, scale)."""

BODY_STATE_MEANINGS = ("free", "stuck", "slipping_toward_decreasing_s",
                       "slipping_toward_increasing_s", "touching_frictionless")
"""The ``body_state`` flags 0-4 (:mod:`dynslip.physics.bodies.observe`)."""
PER_BODY_NODE = {
    "body_s": ("1", "the body's surface coordinate (arc length along its profile) of the "
               "node's closest point", "R"),
}
"""Per held body and node (time, body, rbar), floats: name -> (units, long_name, scale)."""
PER_BODY = {
    "body_z": ("1", "the body's axial displacement from its placement in the scenario, + up "
               "(the ball's height for a body carried with it; 0 for one at rest)", "R"),
    "body_s_min": ("1", "lowest surface coordinate s in contact with the body (NaN: none)", "R"),
    "body_s_max": ("1", "highest surface coordinate s in contact with the body (NaN: none)", "R"),
}
"""Per held body and frame (time, body), floats: name -> (units, long_name, scale)."""


def _attrs_scale(scale):
    return {"scale": scale} if scale else {}


def frames_to_dataset(
    frames,
    rbar,
    e0,
    complete: bool,
    stage_names,
    *,
    scenario_json: str,
    scales: dict,
    contact_threshold: float,
    friction: dict,
    friction_smoothing: float,
    extra_attrs=None,
    body_names=None,
    rbar_at=None,
) -> xr.Dataset:
    """The trajectory contract (docs/trajectory-contract.md) from the driver's frames.

    Plain data only: ``frames`` (the driver's records), ``rbar`` (the material radii),
    ``e0`` (stored energy at the start), ``complete``, ``stage_names``; the scenario's
    values as global attributes: ``scenario_json`` (the resolved scenario), ``scales``
    (``R_m``, ``G_Pa``, ``h0_m``, ``force_scale_N``), ``contact_threshold``, ``friction``
    (``mu``, ``friction_law``, ``mu_s``, ``mu_k``, ``d_c``) and ``friction_smoothing``;
    ``extra_attrs`` last (e.g. the provenance of a start state). Frames with per-body fields
    (a model with held bodies) add them on a ``body`` dimension, its coordinate
    ``body_names`` (default ``body 0``, ...); without them there is no ``body`` dimension.
    ``rbar_at``: the frame's keys of theta at fixed material radii, key -> radius (R)
    (:func:`dynslip.physics.observables.theta_key`); frames with them add ``theta_at_rbar`` on
    an ``rbar_at`` dimension, its coordinate the radii."""
    time = np.array([f["time"] for f in frames])
    data = {}
    for name, (units, long_name, scale) in PER_NODE.items():
        arr = np.stack([np.asarray(f[name], float) for f in frames])
        data[name] = io.variable(arr, ("time", "rbar"), units, long_name, **_attrs_scale(scale))
    state = np.stack([np.asarray(f["state"], np.int8) for f in frames])
    data["state"] = io.variable(state, ("time", "rbar"), "1", "contact and slip state of the node",
                                flag_values=np.array([0, 1, 2, 3], np.int8),
                                flag_meanings=" ".join(STATE_MEANINGS))
    scal = {
        k: np.array([float(f[k]) for f in frames])
        for k in PER_TIME
        if k not in ("energy_residual", "stage")
    }
    scal["stage"] = np.array([int(f["stage"]) for f in frames], np.int16)
    scal["energy_residual"] = (scal["work_clamp"] + scal["work_ball"] + scal["work_bodies"]
                               - (scal["energy_elastic"] + scal["energy_penalty"] - e0)
                               - scal["dissipation_friction"] - scal["dissipation_drag"])
    for name, (units, long_name, scale) in PER_TIME.items():
        data[name] = io.variable(scal[name], ("time",), units, long_name, **_attrs_scale(scale))
    coords = {}
    if frames and rbar_at and next(iter(rbar_at)) in frames[0]:
        units, long_name, _ = THETA_AT_RBAR
        data["theta_at_rbar"] = io.variable(
            np.array([[float(f[k]) for k in rbar_at] for f in frames]),
            ("time", "rbar_at"), units, long_name)
        coords["rbar_at"] = io.variable(np.asarray(list(rbar_at.values()), float), ("rbar_at",),
                                        "1", "fixed material radius / R of theta_at_rbar",
                                        scale="R")
    if frames and "body_s" in frames[0]:
        data.update(_per_body(frames))
        k = data["body_s"].shape[1]
        names = [f"body {i}" for i in range(k)] if body_names is None else list(body_names)
        if len(names) != k:
            raise ValueError(f"body_names: {len(names)} names for {k} held bodies")
        coords["body"] = io.variable(np.array(names, dtype=str), ("body",), "1",
                                     "held body (physics.named_bodies order)")
    coords |= {
        "time": io.variable(time, ("time",), "s", "physical time of the saved frame"),
        "rbar": io.variable(
            np.asarray(rbar), ("rbar",), "1", "undeformed (material) radius / R", scale="R"
        ),
    }
    attrs = io.provenance(scenario_json, "trajectory")
    attrs["kind"] = "trajectory"
    attrs.update({
        "complete": int(bool(complete)),
        **{k: scales[k] for k in ("R_m", "G_Pa", "h0_m", "force_scale_N")},
        "stage_names": json.dumps(list(stage_names)),
        "contact_threshold": contact_threshold,
        "energy_initial": float(e0),
        **{k: friction[k] for k in ("mu", "friction_law", "mu_s", "mu_k", "d_c")},
        "friction_smoothing": friction_smoothing,
    })
    if extra_attrs:
        attrs.update(extra_attrs)
    import xarray as xr

    return xr.Dataset(data, coords=coords, attrs=attrs)


def _per_body(frames) -> dict:
    """The per-body variables of frames that carry them (:func:`frames_to_dataset`)."""
    data = {}
    for name, (units, long_name, scale) in PER_BODY_NODE.items():
        arr = np.stack([np.asarray(f[name], float) for f in frames])
        data[name] = io.variable(arr, ("time", "body", "rbar"), units, long_name,
                                 **_attrs_scale(scale))
    for name, (units, long_name, scale) in PER_BODY.items():
        arr = np.stack([np.asarray(f[name], float) for f in frames])
        data[name] = io.variable(arr, ("time", "body"), units, long_name, **_attrs_scale(scale))
    data["body_contact"] = io.variable(
        np.stack([np.asarray(f["body_contact"], np.int8) for f in frames]),
        ("time", "body", "rbar"), "1", "node in contact with the body (penalty pressure above "
        "contact_threshold)", flag_values=np.array([0, 1], np.int8),
        flag_meanings="free in_contact")
    data["body_state"] = io.variable(
        np.stack([np.asarray(f["body_state"], np.int8) for f in frames]),
        ("time", "body", "rbar"), "1", "contact and slip state of the node relative to the body",
        flag_values=np.arange(len(BODY_STATE_MEANINGS), dtype=np.int8),
        flag_meanings=" ".join(BODY_STATE_MEANINGS))
    data["body_n_contact"] = io.variable(
        np.stack([np.asarray(f["body_n_contact"], np.int32) for f in frames]), ("time", "body"),
        "1", "number of nodes in contact with the body")
    return data


def body_shift(ds: xr.Dataset, k: int, moves_with_ball: bool):
    """The per-frame axial displacement (time,) of held body ``k`` (R), or None for a body at
    rest: the saved ``body_z`` (a body carried with the ball, moved by the stages or free),
    else, for a file without it, the ball's height for one carried with the ball."""
    if "body_z" in ds and k < ds.sizes.get("body", 0):
        shift = np.asarray(ds["body_z"].values[:, k], float)
        return shift if moves_with_ball or np.any(shift != 0.0) else None
    return np.asarray(ds["ball_z"].values, float) if moves_with_ball else None


def body_index(ds: xr.Dataset, name: str) -> int:
    """The index of held body ``name`` on the trajectory's ``body`` dimension; an unknown name
    (or a run without held bodies) raises :class:`InputError` naming the allowed ones."""
    names = [str(n) for n in ds["body"].values] if "body" in ds.coords else []
    if name not in names:
        allowed = ", ".join(repr(n) for n in names) if names else "none (the run has no held body)"
        raise InputError(f"body: {name!r} is not a held body of this run; allowed: {allowed}")
    return names.index(name)


def open_trajectory(path) -> xr.Dataset:
    """Open ``path`` as a dynslip trajectory and load it into memory.

    Raises :class:`~dynslip.errors.InputError` (one line) when the file is missing, is not
    netCDF, is not a trajectory (global attribute ``kind``), has another format version
    (``format_version``), or lacks a variable the readers need.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(
            f"trajectory: {str(path)!r} does not exist (expected a {TRAJECTORY_FILE} file)"
        )
    import xarray as xr

    try:
        with xr.open_dataset(path, engine="netcdf4") as f:
            ds = f.load()
    except (OSError, ValueError, RuntimeError, KeyError, TypeError) as exc:  # not netCDF
        raise InputError(
            f"trajectory: {str(path)!r} is not a netCDF file ({type(exc).__name__}); "
            f"expected a {TRAJECTORY_FILE} written by dynslip run"
        ) from None
    validate_trajectory(ds, source=str(path))
    return ds


def validate_trajectory(ds: xr.Dataset, source: str = "<dataset>") -> None:
    """Raise :class:`InputError` unless ``ds`` follows the trajectory contract (format version
    1)."""
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
