r"""Forming runs that start from a formed pocket (``start_from``), and the release test.

``start_from`` names a saved ``trajectory.nc`` (its last frame is the start) or a
forming scenario, which is run first into ``outputs/<stem>/`` unless a complete result
of the same resolved scenario, made by the same dynslip version at the same commit, is
already there (then it is reused). The start must
share the run's geometry, material and mesh; a missing file, another format version, an
incomplete run or another geometry is bad input (exit 2).

The release (``scenarios/release.yaml``; physics.md Section 4, "Loads in time"): the
clamp holds the edge where the formed pocket left it; the held ball is moved along the
axis at a slow, constant speed. Moving it toward its pole (up, away from the pocket's
opening) draws the sheet off the lower hemisphere; the force the hold needs, until the
opening radius reaches R ($\theta_{max} = \pi/2$), peaks at the release force (the
paper measured 2.3 N). Moving it toward the opening is not resisted by a membrane: the
pocket travels with the ball and the free span goes slack. Its numbers are
:mod:`dynslip.analysis.release`'s, its figure :mod:`dynslip.plot.release`'s; the forming
runner writes both (``summary.json`` "release", ``release_force.png``).
"""

from __future__ import annotations

import json
from pathlib import Path

from dynslip.data.files import provenance
from dynslip.data.folders import StagedRun
from dynslip.data.trajectory import TRAJECTORY_FILE, open_trajectory
from dynslip.errors import InputError
from dynslip.schema import base as scn
from dynslip.schema.paths import get_path

__all__ = ["load_start", "reusable", "GEOMETRY_FIELDS"]

GEOMETRY_FIELDS = (
    "physics.ball_radius_mm",
    "physics.thickness_um",
    "physics.youngs_modulus_MPa",
    "physics.material.model",
    "physics.material.jm",
    "physics.material.c1",
    "physics.rim_radius_mm",
    "physics.pre_stretch",
    "numerics.nodes",
    "numerics.mesh_grading",
    "numerics.edge_grading",
)


def _resolve(path: str, base: Path | None) -> Path:
    p = Path(path)
    if p.is_absolute() or base is None or (Path.cwd() / p).exists():
        return p
    return base / p


def reusable(attrs, scenario_json: str) -> bool:
    """Whether a saved run with the global attributes ``attrs`` can stand for a run of the
    resolved scenario ``scenario_json`` now: it finished, and the same scenario was run by
    the same dynslip version at the same commit (another package may form another pocket)."""
    here = provenance(scenario_json, "forming")
    return int(attrs.get("complete", 0)) == 1 and all(
        attrs.get(k) == here[k] for k in ("scenario", "dynslip_version", "git_commit")
    )


def _start_dataset(sc, console, run) -> tuple:

    src = _resolve(sc.start_from, getattr(sc, "_source_dir", None))
    if src.suffix == ".nc":
        return open_trajectory(src), src
    if src.suffix not in (".yaml", ".yml"):
        raise InputError(
            f"start_from: {str(src)!r}: expected a {TRAJECTORY_FILE} or a scenario .yaml"
        )

    start_sc = scn.load(src)
    if getattr(start_sc, "kind", None) != "forming":
        raise InputError(
            f"start_from: {str(src)!r} is a '{start_sc.kind}' scenario; allowed: a forming scenario"
        )
    if getattr(start_sc, "start_from", None):
        raise InputError(
            f"start_from: {str(src)!r} itself starts from another run; allowed: a scenario that "
            f"forms"
        )
    out = Path("outputs") / src.stem
    traj = out / TRAJECTORY_FILE
    if traj.is_file():
        try:
            ds = open_trajectory(traj)
            if reusable(ds.attrs, start_sc.to_json()):
                if console is not None:
                    console.print(f"start_from: reusing {traj} (same resolved scenario, "
                                  "dynslip version and commit)")
                return ds, traj
        except InputError:
            pass
    staged = StagedRun(out, what=f"start_from: {str(src)!r} runs into", force_hint=False)
    staged.check()  # the same rule as --out: only a dynslip result is replaced, after success
    if console is not None:
        console.print(f"start_from: running {src} first -> {out}/")
    if run is None:
        raise TypeError("load_start: start_from names a scenario; give run= to run it")
    with staged as staging:
        run(start_sc, staging, console)
    return open_trajectory(traj), traj


def load_start(sc, console=None, run=None) -> tuple[dict, dict]:
    """(start state for :func:`dynslip.physics.driver.simulate.simulate`, provenance) of
    ``sc.start_from``;
    ``run(scenario, out, console)`` runs a start scenario that has no reusable result (needed
    only when ``start_from`` names a scenario)."""
    ds, src = _start_dataset(sc, console, run)
    if int(ds.attrs.get("complete", 0)) != 1:
        raise InputError(
            f"start_from: {str(src)!r} is an incomplete run (complete = 0); allowed: a finished run"
        )
    try:
        start_res = json.loads(ds.attrs["scenario"])
    except (KeyError, json.JSONDecodeError):
        raise InputError(f"start_from: {str(src)!r} carries no resolved scenario") from None
    mine = json.loads(sc.to_json())
    for field in GEOMETRY_FIELDS:
        a, b = get_path(mine, field), get_path(start_res, field)
        if a != b:
            raise InputError(
                f"start_from: field '{field}' = {json.dumps(a)} differs from the start state's "
                f"{json.dumps(b)} ({src}); allowed: the start's value"
            )
    end = ds.isel(time=-1)
    # a start whose tube was moved by its stages (the lab frame): translated along the axis so
    # that the tube sits at its reference placement, where this run's tube is (no gravity: a
    # translation changes nothing else)
    shift = 0.0
    if "body_z" in ds and "tube wall" in list(ds["body"].values) and sc.physics.tube is not None:
        shift = float(end["body_z"].values[list(ds["body"].values).index("tube wall")])
    start = {"rho": end["rho"].values, "z": end["z"].values - shift,
             "zb": float(end["ball_z"]) - shift}
    if "slip_distance" in ds:
        start["slip_distance"] = end["slip_distance"].values
    info = {
        "start_from": str(src),
        "start_time_s": float(end["time"]),
        "start_theta_max": float(end["theta_max"]),
        "start_rbar_max": float(end["rbar_max"]),
        "start_trapped_ball_z": float(end["ball_z"]) - shift,
        "start_shift_R": -shift,
    }
    return start, info
