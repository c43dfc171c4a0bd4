r"""Forming runs that start from a formed pocket (``start_from``), and the release test.

``start_from`` names a saved ``trajectory.nc`` (its last frame is the start) or a
forming scenario, which is run first into ``outputs/<stem>/`` unless a complete result
of the same resolved scenario is already there (then it is reused). The start must
share the run's geometry, material and mesh; a missing file, another format version, an
incomplete run or another geometry is bad input (exit 2).

The release (``scenarios/release.yaml``; physics.md Section 4, "Loads in time"): the
clamp holds the edge where the formed pocket left it; the held ball is moved along the
axis at a slow, constant speed. Moving it toward its pole (up, away from the pocket's
opening) draws the sheet off the lower hemisphere; the force the hold needs, until the
opening radius reaches R ($\theta_{max} = \pi/2$), peaks at the release force (the
paper measured 2.3 N). Moving it toward the opening is not resisted by a membrane: the
pocket travels with the ball and the free span goes slack.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import xarray as xr

from dynslip.analysis.paper import MEASURED_RELEASE_FORCE_N
from dynslip.errors import InputError
from dynslip.schema.paths import get_path

__all__ = ["load_start", "release_metrics", "plot_release", "GEOMETRY_FIELDS"]

GEOMETRY_FIELDS = (
    "physics.ball_radius_mm", "physics.thickness_um", "physics.youngs_modulus_MPa", "physics.material.model",
    "physics.material.jm", "physics.material.c1", "physics.rim_radius_mm", "physics.pre_stretch", "numerics.nodes",
)


def _resolve(path: str, base: Path | None) -> Path:
    p = Path(path)
    if p.is_absolute() or base is None or (Path.cwd() / p).exists():
        return p
    return base / p


def _start_dataset(sc, console, run) -> tuple[xr.Dataset, Path]:
    from dynslip.data.trajectory import open_trajectory

    src = _resolve(sc.start_from, getattr(sc, "_source_dir", None))
    if src.suffix == ".nc":
        return open_trajectory(src), src
    if src.suffix not in (".yaml", ".yml"):
        raise InputError(f"start_from: {str(src)!r}: expected a trajectory.nc or a scenario .yaml")
    from dynslip.schema import base as scn
    from dynslip.data.files import StagedRun

    start_sc = scn.load(src)
    if getattr(start_sc, "kind", None) != "forming":
        raise InputError(f"start_from: {str(src)!r} is a '{start_sc.kind}' scenario; allowed: a forming scenario")
    if getattr(start_sc, "start_from", None):
        raise InputError(f"start_from: {str(src)!r} itself starts from another run; allowed: a scenario that forms")
    out = Path("outputs") / src.stem
    traj = out / "trajectory.nc"
    if traj.is_file():
        try:
            ds = open_trajectory(traj)
            if ds.attrs.get("scenario") == start_sc.to_json() and int(ds.attrs.get("complete", 0)) == 1:
                if console is not None:
                    console.print(f"start_from: reusing {traj} (same resolved scenario)")
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
    """(start state for :func:`dynslip.physics.simulate.simulate`, provenance) of ``sc.start_from``;
    ``run(scenario, out, console)`` runs a start scenario that has no reusable result (needed
    only when ``start_from`` names a scenario)."""
    ds, src = _start_dataset(sc, console, run)
    if int(ds.attrs.get("complete", 0)) != 1:
        raise InputError(f"start_from: {str(src)!r} is an incomplete run (complete = 0); allowed: a finished run")
    try:
        start_res = json.loads(ds.attrs["scenario"])
    except (KeyError, json.JSONDecodeError):
        raise InputError(f"start_from: {str(src)!r} carries no resolved scenario") from None
    mine = json.loads(sc.to_json())
    for field in GEOMETRY_FIELDS:
        a, b = get_path(mine, field), get_path(start_res, field)
        if a != b:
            raise InputError(f"start_from: field '{field}' = {json.dumps(a)} differs from the start state's "
                             f"{json.dumps(b)} ({src}); allowed: the start's value")
    end = ds.isel(time=-1)
    start = {"rho": end["rho"].values, "z": end["z"].values, "zb": float(end["ball_z"])}
    if "slip_distance" in ds:
        start["slip_distance"] = end["slip_distance"].values
    info = {"start_from": str(src), "start_time_s": float(end["time"]), "start_theta_max": float(end["theta_max"]),
            "start_rbar_max": float(end["rbar_max"]), "start_trapped_ball_z": float(end["ball_z"])}
    return start, info


def release_metrics(ds: xr.Dataset, model=None) -> dict:
    """Force-displacement of the release: peak hold force (N) until theta_max < pi/2, and the
    free-span check (axial force constant along the free span and equal to the hold force)."""
    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    zb = ds["ball_z"].values
    disp_mm = (zb - zb[0]) * r_mm
    hold_n = ds["ball_reaction"].values * fs
    force_n = sheet_force(ds) * fs
    th = ds["theta_max"].values
    below = np.flatnonzero(~(th >= math.pi / 2))
    first = int(below[0]) if below.size else len(th)
    upto = slice(0, max(first, 1))
    i_peak = int(np.argmax(np.abs(force_n[upto])))
    out = {
        "peak_force_N": float(force_n[i_peak]),
        "hold_force_at_peak_N": float(hold_n[i_peak]),
        "peak_displacement_mm": float(disp_mm[i_peak]),
        "opening_reached_R": bool(below.size),
        "displacement_at_opening_R_mm": float(disp_mm[first]) if below.size else None,
        "measured_release_force_N": MEASURED_RELEASE_FORCE_N,
        "force_scale_N": fs,
    }
    ramp = force_ramp_metrics(ds)
    if ramp is not None:
        out["force_ramp"] = ramp
    if model is not None:
        out["free_span"] = free_span_check(ds, model)
    return out


def force_ramp_metrics(ds: xr.Dataset) -> dict | None:
    """The release as measured: a force on the ball ramped (``ball: pull``) until the ball's
    speed exceeds a threshold (``until: ball_speed_above``). The release force is the applied
    force at the last saved frame of that stage where the ball's speed is below the threshold
    (N); its resolution is the ramp rate times the save interval. The drag's share is the
    ball's drag eta_b |z_b'| over the applied force there (the regularisation's part of the
    measured force). None when the run has no such stage."""
    sc = json.loads(ds.attrs["scenario"])
    stages = sc["physics"]["stages"]
    idx = next((i for i, st in enumerate(stages) if st.get("ball") == "pull" and st.get("until") == "ball_speed_above"),
               None)
    if idx is None:
        return None
    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    t = ds["time"].values
    speed_mm_s = np.abs(np.gradient(ds["ball_z"].values, t)) * r_mm if t.size > 1 else np.zeros(1)
    in_stage = ds["stage"].values == idx
    threshold = float(stages[idx]["ball_speed_mm_s"])
    slow = np.flatnonzero(in_stage & (speed_mm_s < threshold))
    # torn out: a saved frame past the threshold, or the stage's stop rule ended it early (the rule sees
    # the instantaneous speed; the saved frames only their differences)
    ts = t[in_stage]
    ended_early = bool(ts.size and ts[-1] - t[max(int(np.flatnonzero(in_stage)[0]) - 1, 0)]
                       < float(stages[idx]["duration_s"]) - 1e-9)
    torn = bool(np.any(in_stage & (speed_mm_s >= threshold))) or ended_early
    if slow.size == 0:
        return {"release_force_N": None, "torn_out": torn, "threshold_mm_s": threshold}
    i = int(slow[-1])
    applied = float(ds["ball_reaction"].values[i])
    drag = float(_ball_drag_force(ds)[i])
    return {
        "release_force_N": applied * fs,
        "time_s": float(t[i]),
        "ball_speed_mm_s": float(speed_mm_s[i]),
        "threshold_mm_s": threshold,
        "torn_out": torn,
        "drag_share": abs(drag) / abs(applied) if applied else None,
        "resolution_N": float(abs(stages[idx]["ball_force_N"]) / stages[idx]["duration_s"]
                              * sc["numerics"]["save_interval_s"]),
    }


def _ball_drag_force(ds: xr.Dataset):
    """The ball's drag force eta_b z_b' per frame (G h0 R): a regularisation the hold also pays."""
    from dynslip.schema.forming import ball_drag_coefficient

    nu = json.loads(ds.attrs["scenario"])["numerics"]
    eta_b = ball_drag_coefficient(nu["drag_time_s"], nu["ball_drag"])
    t = ds["time"].values
    v = np.gradient(ds["ball_z"].values, t) if t.size > 1 else np.zeros(1)
    return eta_b * v


def sheet_force(ds: xr.Dataset):
    """The force the hold must supply against the sheet (G h0 R, + up): the hold's force less
    the ball's drag; for a held ball it equals minus the clamp's axial force at rest."""
    return ds["ball_reaction"].values - _ball_drag_force(ds)


def free_span_check(ds: xr.Dataset, model) -> dict:
    """Per frame, the axial force 2 pi rho T_theta sin(psi) on the free elements (both ends out
    of contact): its spread relative to its mean, and its mean against the hold force less the
    ball's small drag (a regularisation; the rest is what the sheet exerts on the ball). Frames where the hold force is
    below 1% of its largest value (slack span) are skipped."""
    import jax.numpy as jnp

    spreads, mismatch = [], []
    static = sheet_force(ds)
    scale = float(np.max(np.abs(static)))
    for i in range(ds.sizes["time"]):
        f = ds.isel(time=i)
        free_nodes = f["state"].values == 0
        el = free_nodes[:-1] & free_nodes[1:]
        if el.sum() < 2:
            continue
        p = np.asarray(model.free_span_axial_force(jnp.asarray(f["rho"].values), jnp.asarray(f["z"].values)))[el]
        hold = float(static[i])
        if scale == 0 or abs(hold) < 1e-2 * scale:  # a slack span: relative measures are meaningless
            continue
        mean = float(np.mean(p))
        spreads.append(float(np.ptp(p) / abs(mean)))
        mismatch.append(abs(abs(mean) - abs(hold)) / abs(hold))
    return {"frames": len(spreads), "max_relative_spread": max(spreads) if spreads else None,
            "max_relative_mismatch_to_hold": max(mismatch) if mismatch else None}


def plot_release(ds: xr.Dataset, metrics: dict, out: Path) -> Path:
    """release_force.png: the hold's force (N) against the ball's displacement (mm), the peak
    up to theta_max = pi/2 marked, the measured 2.3 N drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dynslip.data import files as io

    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    zb = ds["ball_z"].values
    disp = (zb - zb[0]) * r_mm
    fig, (a, b) = plt.subplots(2, 1, figsize=(6.4, 6.4), sharex=True, constrained_layout=True)
    a.plot(disp, sheet_force(ds) * fs, "-", color="C0", label="force against the sheet (hold less ball drag)")
    a.plot(disp, ds["ball_reaction"].values * fs, ":", color="C0", lw=0.8, label="force of the hold")
    a.axhline(MEASURED_RELEASE_FORCE_N, color="k", ls=":",
              label=f"measured release force {MEASURED_RELEASE_FORCE_N:g} N")
    a.plot([metrics["peak_displacement_mm"]], [metrics["peak_force_N"]], "o", color="C3",
           label=f"peak {metrics['peak_force_N']:.2f} N (until opening radius R)")
    if metrics.get("displacement_at_opening_R_mm") is not None:
        for ax in (a, b):
            ax.axvline(metrics["displacement_at_opening_R_mm"], color="0.5", ls="--", lw=0.8)
    a.set_ylabel("force (N)")
    a.legend(fontsize=8)
    b.plot(disp, ds["theta_max"].values, color="C1")
    b.axhline(math.pi / 2, color="0.5", ls=":", lw=0.8)
    b.set_ylabel(r"$\theta_{max}$ (rad)")
    b.set_xlabel("ball displacement along the axis (mm, + toward its pole)")
    path = io.save_figure(fig, Path(out) / "release_force.png")
    plt.close(fig)
    return path
