r"""The release test's numbers, from a trajectory dataset (no drawing, no files).

- :func:`release_metrics`: force-displacement of the release (``scenarios/release.yaml``;
  physics.md Section 4, "Loads in time"): the peak force against the sheet until the opening
  radius reaches R ($\theta_{max} = \pi/2$), against the measured release force
  (:data:`dynslip.analysis.paper.MEASURED_RELEASE_FORCE_N`), and the free-span check;
- :func:`force_ramp_metrics`: the release as measured, a force on the ball ramped until it
  tears out (``scenarios/release_pull.yaml``);
- :func:`sheet_force`: the force the hold supplies against the sheet (the hold's less the
  ball's drag); :func:`free_span_check`: the axial force along the free span.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import xarray as xr

from dynslip.analysis.paper import MEASURED_RELEASE_FORCE_N
from dynslip.physics.protocols import ball_drag_coefficient
from dynslip.physics.sheet import mesh_from_radii

__all__ = ["release_metrics", "force_ramp_metrics", "located_event", "sheet_force",
           "free_span_check"]


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
    out: dict[str, Any] = {
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
    force at the located event (N): the instant the event function g = |z_b'| - v_threshold
    crosses zero, located between the last saved frame of the stage with g < 0 and the next one
    by linear interpolation of g in time (:func:`located_event`), the applied force interpolated
    there (exact for the linear ramp). The speed is the saved ``ball_velocity`` (what the stop
    rule reads), or, in a file without it, centred differences of the saved heights.
    ``last_slow_frame``: the force at that saved frame (the bracket's start); ``resolution_N``
    the ramp over one save interval, the bracket's width. The drag's share is the ball's drag
    eta_b |z_b'| over the applied force at that frame (the regularisation's part of the
    measured force). None when the run has no such stage."""
    sc = json.loads(ds.attrs["scenario"])
    stages = sc["physics"]["stages"]
    idx = next(
        (
            i
            for i, st in enumerate(stages)
            if st.get("ball") == "pull" and st["until"]["rule"] == "ball_speed_above"
        ),
        None,
    )
    if idx is None:
        return None
    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    t = ds["time"].values
    if "ball_velocity" in ds:
        speed_mm_s = np.abs(ds["ball_velocity"].values) * r_mm
    else:
        speed_mm_s = (np.abs(np.gradient(ds["ball_z"].values, t)) * r_mm if t.size > 1
                      else np.zeros(1))
    in_stage = ds["stage"].values == idx
    threshold = float(stages[idx]["until"]["speed_mm_s"])
    slow = np.flatnonzero(in_stage & (speed_mm_s < threshold))
    # torn out: a saved frame past the threshold, or the stage's stop rule ended it early (the rule
    # sees
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
    sheet_drag = float(_sheet_drag_force(ds)[i])
    prev = stages[idx - 1] if idx > 0 else {}
    f_from = float(prev["ball_force_N"]) if prev.get("ball") == "pull" else 0.0  # a preload's force
    event = located_event(t, speed_mm_s - threshold, i)
    if event is None:  # no saved frame past the threshold after it: the frame's force
        located = {"located": False, "release_force_N": applied * fs, "time_s": float(t[i])}
    else:
        a = ds["ball_reaction"].values
        j, w = event
        located = {"located": True,
                   "release_force_N": float(((1 - w) * a[j] + w * a[j + 1]) * fs),
                   "time_s": float((1 - w) * t[j] + w * t[j + 1])}
    return {
        **located,
        "last_slow_frame": {"release_force_N": applied * fs, "time_s": float(t[i])},
        "ball_speed_mm_s": float(speed_mm_s[i]),
        "threshold_mm_s": threshold,
        "torn_out": torn,
        "drag_share": abs(drag) / abs(applied) if applied else None,
        "sheet_drag_share": abs(sheet_drag) / abs(applied) if applied else None,
        "resolution_N": float(abs(stages[idx]["ball_force_N"] - f_from) / stages[idx]["duration_s"]
                              * sc["numerics"]["save_interval_s"]),
    }


def located_event(t, g, i):
    """The zero of the event function ``g`` (per saved frame, times ``t``) after frame ``i``
    (g[i] < 0 <= g[i + 1]), by linear interpolation: ``(i, w)`` with the event at
    ``(1 - w) t[i] + w t[i + 1]``, w in (0, 1]; None where no frame follows or g does not
    cross there."""
    if i + 1 >= len(t) or not (g[i] < 0 <= g[i + 1]):
        return None
    return i, float(-g[i] / (g[i + 1] - g[i]))


def _ball_drag_force(ds: xr.Dataset):
    """The ball's drag force eta_b z_b' per frame (G h0 R): a regularisation the hold also pays."""
    nu = json.loads(ds.attrs["scenario"])["numerics"]
    eta_b = ball_drag_coefficient(nu["drag_time_s"], nu["ball_drag"])
    t = ds["time"].values
    v = np.gradient(ds["ball_z"].values, t) if t.size > 1 else np.zeros(1)
    return eta_b * v


def _sheet_drag_force(ds: xr.Dataset):
    r"""The sheet's drag on the ball per frame (G h0 R, + up): the drag acts between sheet and
    ball (:mod:`dynslip.physics.sheet`), so the nodes that do not move with the ball pull on it
    with $\sum_i \eta A_i (\dot z_i - \dot z_b)$ (the held edge excluded), a regularisation
    inside the force the sheet exerts. Node rates from the saved frames (central differences)."""
    nu = json.loads(ds.attrs["scenario"])["numerics"]
    t = ds["time"].values
    if t.size < 2:
        return np.zeros(t.size)
    area = np.array(mesh_from_radii(ds["rbar"].values).area)  # a writable copy
    area[-1] = 0.0  # the held edge: no constitutive drag
    u = np.gradient(ds["z"].values, t, axis=0) - np.gradient(ds["ball_z"].values, t)[:, None]
    return float(nu["drag_time_s"]) * (u @ area)


def sheet_force(ds: xr.Dataset):
    """The force the hold must supply against the sheet (G h0 R, + up): the hold's force less
    the ball's drag; for a held ball it equals minus the clamp's axial force at rest."""
    return ds["ball_reaction"].values - _ball_drag_force(ds)


def free_span_check(ds: xr.Dataset, model) -> dict:
    """Per frame, the axial force 2 pi rho T_theta sin(psi) on the free elements (both ends out
    of contact): its spread relative to its mean, and its mean against the hold force less the
    ball's small drag (a regularisation; the rest is what the sheet exerts on the ball). Frames
    where the hold force is
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
        p = np.asarray(
            model.free_span_axial_force(jnp.asarray(f["rho"].values), jnp.asarray(f["z"].values))
        )[el]
        hold = float(static[i])
        if (
            scale == 0 or abs(hold) < 1e-2 * scale
        ):  # a slack span: relative measures are meaningless
            continue
        mean, ptp = float(np.mean(p)), float(np.ptp(p))
        # a span whose mean force vanishes under a taut hold is spread without bound
        spreads.append(ptp / abs(mean) if mean else math.inf)
        mismatch.append(abs(abs(mean) - abs(hold)) / abs(hold))
    return {"frames": len(spreads), "max_relative_spread": max(spreads) if spreads else None,
            "max_relative_mismatch_to_hold": max(mismatch) if mismatch else None}
