"""What the stick fronts of a trajectory did, from their tracks
(:func:`dynslip.analysis.fronts.track_fronts`): per track and frame as a dataset
(:func:`fronts_dataset`, ``fronts.nc``), per node the time it comes to rest
(:func:`rest_times`), and per stage the fronts' travel and the order of coming to rest
(:func:`stage_summary`).
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from dynslip.analysis.fronts import (
    BIRTH_EVENTS,
    DEATH_EVENTS,
    STUCK_SIDES,
    motion_state,
    track_fronts,
)
from dynslip.data.files import provenance, variable
from dynslip.data.trajectory import FREE, SLIP_EQUATOR, SLIP_POLE, STUCK, stage_names


def _flag_attrs(meanings, start=0) -> dict:
    return {
        "flag_values": np.arange(start, start + len(meanings), dtype=np.int8),
        "flag_meanings": " ".join(meanings),
    }


def rest_times(ds: xr.Dataset, rest_speed: float | None = None) -> np.ndarray:
    """When each node comes to rest for the last time in each stage: array (stage, rbar), s.

    A node *comes to rest* at the first frame of its final run of ``stuck`` frames within
    the stage, provided it was slipping in the frame before (which may be the last frame of
    the previous stage). NaN where the node did not slip and then stick in the stage: at
    rest throughout, still slipping, or free at the end of the stage. ``rest_speed``: see
    :func:`motion_state`.
    """
    state = motion_state(ds, rest_speed)
    t = np.asarray(ds["time"].values, dtype=float)
    stage = np.asarray(ds["stage"].values).astype(int)
    n_stage = max(len(stage_names(ds)), int(stage.max()) + 1)
    out = np.full((n_stage, state.shape[1]), np.nan)
    slipping = (state == SLIP_POLE) | (state == SLIP_EQUATOR)
    for s in range(n_stage):
        idx = np.flatnonzero(stage == s)
        if idx.size == 0:
            continue
        last = idx[-1]
        for node in np.flatnonzero(state[last] == STUCK):
            k = last
            while k - 1 >= idx[0] and state[k - 1, node] == STUCK:
                k -= 1
            if k - 1 >= 0 and slipping[k - 1, node]:
                out[s, node] = t[k]
    return out


def fronts_dataset(ds: xr.Dataset, rest_speed: float | None = None) -> xr.Dataset:
    """The stick fronts of a trajectory as a dataset (dims ``track``, ``time``, ``stage``).

    Per track and time (NaN where the track does not exist): position in ``rbar`` and in
    ``theta``, speeds, the slip direction of the slipping neighbour. Per track: stuck side,
    birth and death times and events (CF flags). Per stage and node: the rest time
    (:func:`rest_times`). The stage summary (:func:`stage_summary`) is the JSON attribute
    ``stage_summary``. ``rest_speed`` (R/s, optional): slipping nodes slower than this count
    as stuck (:func:`motion_state`); recorded in the attribute ``rest_speed``.
    """
    state = motion_state(ds, rest_speed)
    t = np.asarray(ds["time"].values, dtype=float)
    rbar = np.asarray(ds["rbar"].values, dtype=float)
    theta = np.asarray(ds["theta"].transpose("time", "rbar").values, dtype=float)
    tracks = track_fronts(state)
    nk, nt = len(tracks), t.size
    pos_r = np.full((nk, nt), np.nan)
    pos_t = np.full((nk, nt), np.nan)
    spd_r = np.full((nk, nt), np.nan)
    spd_t = np.full((nk, nt), np.nan)
    node = np.full((nk, nt), -1, dtype=np.int32)
    slip = np.zeros((nk, nt), dtype=np.int8)
    for k, tr in enumerate(tracks):
        f = np.asarray(tr.frames)
        n = np.asarray(tr.nodes)
        node[k, f] = n
        slip[k, f] = tr.slip_states
        pos_r[k, f] = 0.5 * (rbar[n] + rbar[n + 1])
        pos_t[k, f] = 0.5 * (theta[f, n] + theta[f, n + 1])
        if f.size >= 2:
            spd_r[k, f] = np.gradient(pos_r[k, f], t[f])
            spd_t[k, f] = np.gradient(pos_t[k, f], t[f])
    birth_t = np.array([t[tr.frames[0]] for tr in tracks])
    death_t = np.array([t[tr.frames[-1]] for tr in tracks])
    birth_e = np.array([BIRTH_EVENTS.index(tr.birth_event) for tr in tracks], dtype=np.int8)
    death_e = np.array([DEATH_EVENTS.index(tr.death_event) for tr in tracks], dtype=np.int8)
    side = np.array([tr.stuck_side for tr in tracks], dtype=np.int8)
    names = stage_names(ds)
    rest = rest_times(ds, rest_speed)
    tt, kt, st = ("track", "time"), ("track",), ("stage", "rbar")
    data = {
        "front_rbar": variable(
            pos_r,
            tt,
            "1",
            "material radius of the stick front (midpoint of its two nodes)",
            scale="R",
        ),
        "front_theta": variable(
            pos_t, tt, "rad", "polar angle of the stick front (midpoint of its two nodes)"
        ),
        "front_rbar_speed": variable(
            spd_r,
            tt,
            "1/s",
            "speed of the stick front in material radius, positive toward the equator",
            scale="R/s",
        ),
        "front_theta_speed": variable(
            spd_t,
            tt,
            "rad/s",
            "speed of the stick front in polar angle, positive toward the equator",
        ),
        "front_node": variable(
            node, tt, "1", "index of the pole-side node of the front (-1 where absent)"
        ),
        "front_slip_state": variable(
            slip,
            tt,
            "1",
            "state of the slipping node beside the front (0 where absent)",
            flag_values=np.array([0, 2, 3], dtype=np.int8),
            flag_meanings="absent slipping_toward_pole slipping_toward_equator",
        ),
        "stuck_side": variable(
            side, kt, "1", "which neighbour of the front is stuck", **_flag_attrs(STUCK_SIDES, 1)
        ),
        "birth_time": variable(birth_t, kt, "s", "time of the first frame holding the front"),
        "death_time": variable(death_t, kt, "s", "time of the last frame holding the front"),
        "birth_event": variable(
            birth_e, kt, "1", "event that created the front", **_flag_attrs(BIRTH_EVENTS)
        ),
        "death_event": variable(
            death_e, kt, "1", "event that removed the front", **_flag_attrs(DEATH_EVENTS)
        ),
        "n_fronts": variable(np.sum(node >= 0, axis=0), ("time",), "1", "number of stick fronts"),
        "rest_time": variable(
            rest,
            st,
            "s",
            "time the node comes to rest for the last time in the stage (NaN: did not slip then "
            "stick)",
        ),
    }
    coords = {
        "track": variable(np.arange(nk), kt, "1", "front track id"),
        "time": variable(t, ("time",), "s", "time"),
        "rbar": variable(rbar, ("rbar",), "1", "undeformed radius of the node", scale="R"),
        "stage": variable(np.arange(rest.shape[0]), ("stage",), "1", "index into stage_names"),
    }
    out = xr.Dataset(data, coords=coords)
    out.attrs.update(provenance(ds.attrs.get("scenario", "{}"), "fronts"))
    out.attrs["source_git_commit"] = ds.attrs.get("git_commit", "unknown")
    out.attrs["stage_names"] = json.dumps(names)
    jumps = [int(np.max(np.abs(np.diff(tr.nodes)))) for tr in tracks if len(tr.nodes) > 1]
    out.attrs["max_front_step_nodes"] = max(jumps, default=0)
    out.attrs["unresolved_events"] = sum(
        (tr.birth_event == "unresolved") + (tr.death_event == "unresolved") for tr in tracks
    )
    out.attrs["rest_speed"] = "none" if rest_speed is None else float(rest_speed)
    out.attrs["classification"] = (
        "state flags (force criterion)"
        if rest_speed is None
        else f"state flags, slipping nodes with |slip_velocity| <= {float(rest_speed):g} R/s "
            f"counted stuck"
    )
    out.attrs["stage_summary"] = json.dumps(stage_summary(ds, out))
    return out


def _direction(disp: float, tol: float) -> str:
    if not np.isfinite(disp):
        return "none"
    if disp > tol:
        return "toward_equator"
    if disp < -tol:
        return "toward_pole"
    return "stationary"


def stage_summary(ds: xr.Dataset, fronts: xr.Dataset | None = None) -> list[dict]:
    """Per stage: how the stick fronts travel and in which order nodes come to rest.

    For each stage: the net displacement in ``rbar`` of the fronts (summed over tracks,
    within the stage; the front's first frame in the stage to its last) and its direction
    (``toward_equator``, ``toward_pole``, ``stationary``, ``none`` without fronts), the
    same for each stuck side; then the nodes that come to rest (:func:`rest_times`), the
    ones that do so last, the outermost node in contact at the end of the stage, whether
    it is among the last to come to rest, and the Spearman rank correlation between rbar
    and rest time (positive: rest spreads outward).
    """
    fronts = fronts_dataset(ds) if fronts is None else fronts
    rest_speed = rest_speed_of(fronts)
    names = stage_names(ds)
    t = np.asarray(ds["time"].values, dtype=float)
    stage = np.asarray(ds["stage"].values).astype(int)
    rbar = np.asarray(ds["rbar"].values, dtype=float)
    state = motion_state(ds, rest_speed)
    pos = np.asarray(fronts["front_rbar"].values)
    side = np.asarray(fronts["stuck_side"].values)
    rest = np.asarray(fronts["rest_time"].values)
    tol = 1e-9 * max(1.0, float(rbar[-1] - rbar[0]))
    out = []
    for s in range(rest.shape[0]):
        idx = np.flatnonzero(stage == s)
        name = names[s] if s < len(names) else f"stage {s}"
        if idx.size == 0:
            out.append({"stage": s, "name": name, "frames": 0})
            continue
        disp: dict[int, list[float]] = {1: [], 2: []}
        for k in range(pos.shape[0]):
            p = pos[k, idx]
            p = p[np.isfinite(p)]
            if p.size:
                disp[int(side[k])].append(float(p[-1] - p[0]))
        all_d = disp[1] + disp[2]
        net = float(np.sum(all_d)) if all_d else float("nan")
        entry = {
            "stage": s,
            "name": name,
            "frames": int(idx.size),
            "t_start_s": float(t[idx[0]]),
            "t_end_s": float(t[idx[-1]]),
            "n_tracks": len(all_d),
            "front_displacement_rbar": net,
            "front_direction": _direction(net, tol),
            "front_travel_toward_equator_rbar": float(sum(d for d in all_d if d > 0)),
            "front_travel_toward_pole_rbar": float(-sum(d for d in all_d if d < 0)),
        }
        for code, label in ((1, "stuck_toward_pole"), (2, "stuck_toward_equator")):
            d = float(np.sum(disp[code])) if disp[code] else float("nan")
            entry[f"direction_{label}"] = _direction(d, tol)
        r = rest[s]
        came = np.flatnonzero(np.isfinite(r))
        contact_end = np.flatnonzero(state[idx[-1]] != FREE)
        outer = int(contact_end.max()) if contact_end.size else None
        entry["n_nodes_came_to_rest"] = int(came.size)
        entry["outermost_contact_rbar_at_end"] = None if outer is None else float(rbar[outer])
        entry["n_nodes_slipping_at_end"] = int(
            np.sum(np.isin(state[idx[-1]], (SLIP_POLE, SLIP_EQUATOR)))
        )
        entry["stuck_inside_fraction"] = _stuck_inside_fraction(state[idx])
        if came.size:
            t_last = float(np.max(r[came]))
            last_nodes = came[r[came] == t_last]
            entry["last_rest_time_s"] = t_last
            entry["last_to_rest_rbar"] = [float(rbar[i]) for i in last_nodes]
            entry["first_rest_time_s"] = float(np.min(r[came]))
            entry["outermost_contact_rests_last"] = bool(outer is not None and outer in last_nodes)
            entry["rest_order_spearman"] = _spearman(rbar[came], r[came])
        out.append(entry)
    return out


def _stuck_inside_fraction(state: np.ndarray) -> float | None:
    """Of the frames with both stuck and slipping sheet off the pole (node 0 excluded: it
    cannot slip), the fraction in which every stuck node lies inward of every slipping
    node (the sheet near the pole at rest while the outer sheet slips). None if no frame
    has both."""
    s = state[:, 1:]
    slipping = (s == SLIP_POLE) | (s == SLIP_EQUATOR)
    stuck = s == STUCK
    both = slipping.any(axis=1) & stuck.any(axis=1)
    if not both.any():
        return None
    n = s.shape[1]
    idx = np.arange(n)
    last_stuck = np.where(stuck, idx, -1).max(axis=1)
    first_slip = np.where(slipping, idx, n).min(axis=1)
    return float(np.mean(last_stuck[both] < first_slip[both]))


def _spearman(x: np.ndarray, y: np.ndarray) -> float | None:
    if x.size < 2 or np.all(y == y[0]) or np.all(x == x[0]):
        return None
    from scipy.stats import spearmanr

    rho = spearmanr(x, y).statistic
    return float(rho) if np.isfinite(rho) else None


def rest_speed_of(fronts: xr.Dataset | None) -> float | None:
    v = None if fronts is None else fronts.attrs.get("rest_speed", "none")
    return None if v is None or isinstance(v, str) else float(v)
