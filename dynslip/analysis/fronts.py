r"""Stick fronts: the boundaries between stuck and slipping sheet, tracked through time.

A *stick front* sits between two adjacent nodes ``i, i+1`` that are both in contact with
the ball, one stuck (``state == 1``) and the other slipping (``state`` 2 or 3; the
contract's flags, :mod:`dynslip.data.trajectory`; or, with ``rest_speed``, stuck or slower
than it, :func:`motion_state`). Its position is the midpoint of the two
nodes, in the material radius and in the polar angle:

.. math::  \bar r_f = (\bar r_i + \bar r_{i+1})/2, \qquad \theta_f = (\theta_i + \theta_{i+1})/2 .

The boundary between slipping toward the pole and slipping toward the equator is not a
stick front, and neither is the contact edge (contact/free).

Fronts are linked from one saved frame to the next into *tracks*. Along the meridian the
stuck/slipping field is a sequence of *domains* (maximal runs of stuck or of slipping
in-contact nodes). A front at frame ``k`` (between domains ``L`` and ``R``) continues as a
front at frame ``k+1`` (between ``L'`` and ``R'``) only if the stuck side is on the same
side and ``L'`` overlaps ``L`` and ``R'`` overlaps ``R`` (node sets), or lies within
``reach`` nodes of it (default one node: a one-node stuck band travelling through slipping
sheet moves by more than its width between frames). Among the allowed pairings an
order-preserving one (fronts cannot cross in 1D) with the most links and then the least
cost is chosen by dynamic programming; the cost is the displacement in nodes, plus 0.5 if
the slip direction beside the front changed, plus 0.25 per side linked only by reach.
Apart from ``reach``, no speed limit is assumed. Speeds are finite differences along a track (``numpy.gradient``, second order inside).

Events: a track is born ``run_start`` (present in the first frame), ``nucleated`` (a new
domain appeared inside another), ``nucleated_at_contact_edge`` (a new domain at the outer
end of the contact region), ``nucleated_at_pole``, ``contact_gained`` (one of its
nodes was free the frame before), or ``domain_switched`` (a domain wider than
``reach + 1`` nodes beside it changed state as a whole between two frames). It dies
``merged`` (the interior domain beside it vanished, so the domains on either side merged;
its neighbour front dies with it),
``reached_contact_edge`` (the outermost domain vanished), ``reached_pole`` (the domain
holding the pole vanished), ``contact_lost`` (one of its nodes left contact),
``domain_switched`` (a domain wider than ``reach + 1`` nodes beside it changed state as a
whole, for example all the slipping sheet coming to rest at once), or
``run_end`` (still present in the last frame). ``unresolved`` marks a change the rules
above do not explain (for example a front jumping further than a domain's width between
two saved frames); its presence says the frames are too far apart.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import xarray as xr

from dynslip.errors import InputError
from dynslip.data.files import provenance, variable
from dynslip.data.trajectory import (
    FREE,
    SLIP_EQUATOR,
    SLIP_POLE,
    STUCK,
    stage_names,
    state_array,
)

BIRTH_EVENTS = (
    "run_start",
    "nucleated",
    "nucleated_at_contact_edge",
    "nucleated_at_pole",
    "contact_gained",
    "domain_switched",
    "unresolved",
)
DEATH_EVENTS = (
    "run_end",
    "merged",
    "reached_contact_edge",
    "reached_pole",
    "contact_lost",
    "domain_switched",
    "unresolved",
)
STUCK_SIDES = ("stuck_toward_pole", "stuck_toward_equator")
"""``stuck_side`` flags 1, 2: which neighbour of the front is the stuck one."""

_MOVING = 2  # category of a slipping node (either direction)


@dataclass(frozen=True)
class _Front:
    node: int  # the front lies between node and node + 1
    stuck_side: int  # 1: stuck node toward the pole (node), 2: toward the equator (node + 1)
    left: tuple[int, int]  # domain on the pole side, inclusive node range
    right: tuple[int, int]  # domain on the equator side
    left_at_pole: bool
    right_at_edge: bool  # the equator-side domain ends at the contact edge (or the sheet edge)
    slip_state: int  # state flag of the slipping node beside the front (2 or 3)


def _categories(state_row: np.ndarray) -> np.ndarray:
    """0 free, 1 stuck, 2 slipping (either direction)."""
    return np.where(state_row == FREE, 0, np.where(state_row == STUCK, 1, _MOVING))


def _runs(cat: np.ndarray) -> list[tuple[int, int, int]]:
    """Maximal runs of equal category: (start, end inclusive, category)."""
    edges = np.flatnonzero(np.diff(cat) != 0)
    starts = np.r_[0, edges + 1]
    ends = np.r_[edges, cat.size - 1]
    return [(int(a), int(b), int(cat[a])) for a, b in zip(starts, ends, strict=True)]


def fronts_in_frame(state_row) -> list[_Front]:
    """The stick fronts of one frame, ordered from the pole outward."""
    state_row = np.asarray(state_row)
    cat = _categories(state_row)
    runs = _runs(cat)
    out = []
    for j in range(len(runs) - 1):
        (a, b, c), (d, e, c2) = runs[j], runs[j + 1]
        if {c, c2} != {STUCK, _MOVING}:
            continue
        right_at_edge = j + 2 >= len(runs) or runs[j + 2][2] == 0
        out.append(
            _Front(
                node=b,
                stuck_side=1 if c == STUCK else 2,
                left=(a, b),
                right=(d, e),
                left_at_pole=a == 0,
                right_at_edge=right_at_edge,
                slip_state=int(state_row[d] if c == STUCK else state_row[b]),
            )
        )
    return out


def _gap(p: tuple[int, int], q: tuple[int, int]) -> int:
    """Nodes between two node ranges (0 when they overlap, 1 when adjacent, ...)."""
    return max(0, q[0] - p[1], p[0] - q[1])


def _link_cost(a: _Front, b: _Front, reach: int) -> float | None:
    """Cost of continuing front ``a`` as ``b`` one frame later; None when not allowed.

    Allowed: same stuck side, and each side's domain overlaps its predecessor or lies
    within ``reach`` nodes of it (a domain narrower than its step, such as a one-node stuck
    band travelling through slipping sheet). Cost: the displacement in nodes, plus 0.5 if
    the slip direction beside the front changed, plus 0.25 per side linked only by reach.
    """
    if a.stuck_side != b.stuck_side:
        return None
    gl, gr = _gap(a.left, b.left), _gap(a.right, b.right)
    if gl > reach or gr > reach:
        return None
    return (
        abs(a.node - b.node) + 0.5 * (a.slip_state != b.slip_state) + 0.25 * ((gl > 0) + (gr > 0))
    )


def _link(prev: list[_Front], new: list[_Front], reach: int = 1) -> dict[int, int]:
    """Order-preserving pairing of fronts in consecutive frames: {index in prev: index in new}.

    Maximises the number of links, then minimises the total cost (:func:`_link_cost`).
    """
    n, m = len(prev), len(new)
    # best[i][j] = (links, -displacement) using prev[i:] and new[j:]
    best = [[(0, 0)] * (m + 1) for _ in range(n + 1)]
    choice = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(n - 1, -1, -1):
        for j in range(m - 1, -1, -1):
            cands = [(best[i + 1][j], 1), (best[i][j + 1], 2)]
            cost = _link_cost(prev[i], new[j], reach)
            if cost is not None:
                links, neg = best[i + 1][j + 1]
                cands.append(((links + 1, neg - cost), 3))
            best[i][j], choice[i][j] = max(cands, key=lambda c: c[0])
    out, i, j = {}, 0, 0
    while i < n and j < m:
        c = choice[i][j]
        if c == 3:
            out[i] = j
            i, j = i + 1, j + 1
        elif c == 1:
            i += 1
        else:
            j += 1
    return out


def _vanished(dom: tuple[int, int], cat: int, cat_next: np.ndarray) -> bool:
    return not np.any(cat_next[dom[0] : dom[1] + 1] == cat)


def _switched(dom: tuple[int, int], cat_other: np.ndarray, reach: int) -> bool:
    """A domain wider than ``reach + 1`` nodes, all in contact in the other frame."""
    return dom[1] - dom[0] + 1 > reach + 1 and bool(np.all(cat_other[dom[0] : dom[1] + 1] != 0))


def _event(f: _Front, cat_other: np.ndarray, reach: int, names: tuple[str, str, str, str]) -> str:
    """What happened to a front's domains between its frame and ``cat_other`` (the frame
    before for a birth, after for a death); ``names`` are the event's names for (contact
    changed, at the contact edge, at the pole, inside) in that direction."""
    contact, at_edge, at_pole, inside = names
    if cat_other[f.node] == 0 or cat_other[f.node + 1] == 0:
        return contact
    lcat = STUCK if f.stuck_side == 1 else _MOVING
    rcat = _MOVING if f.stuck_side == 1 else STUCK
    left = _vanished(f.left, lcat, cat_other)
    right = _vanished(f.right, rcat, cat_other)
    if (left and _switched(f.left, cat_other, reach)) or (
        right and _switched(f.right, cat_other, reach)
    ):
        return "domain_switched"
    if right and f.right_at_edge:
        return at_edge
    if left and f.left_at_pole:
        return at_pole
    if left or right:
        return inside
    return "unresolved"


def _birth_event(f: _Front, cat_prev: np.ndarray, reach: int = 1) -> str:
    names = ("contact_gained", "nucleated_at_contact_edge", "nucleated_at_pole", "nucleated")
    return _event(f, cat_prev, reach, names)


def _death_event(f: _Front, cat_next: np.ndarray, reach: int = 1) -> str:
    names = ("contact_lost", "reached_contact_edge", "reached_pole", "merged")
    return _event(f, cat_next, reach, names)


@dataclass
class Track:
    """One stick front followed through consecutive saved frames."""

    frames: list[int]
    nodes: list[int]
    stuck_side: int
    slip_states: list[int]
    birth_event: str = "run_start"
    death_event: str = "run_end"


def track_fronts(state, reach: int = 1) -> list[Track]:
    """Find and link the stick fronts of a ``state`` field (time, rbar) of contract flags.

    ``reach``: how many nodes beyond overlap a domain may move between two frames and still
    be the same domain (see :func:`_link_cost`).

    Returns the tracks in order of birth (then of position). Pure numpy; the positions
    are node indices (the front of a track at ``frames[k]`` lies between ``nodes[k]`` and
    ``nodes[k] + 1``).
    """
    state = np.asarray(state)
    nt = state.shape[0]
    tracks: list[Track] = []
    prev: list[_Front] = []
    prev_ids: list[int] = []
    cats = [_categories(row) for row in state]

    for k in range(nt):
        cur = fronts_in_frame(state[k])
        links = _link(prev, cur, reach) if k > 0 else {}
        cur_ids = [-1] * len(cur)
        for i, j in links.items():
            cur_ids[j] = prev_ids[i]
        for i, f in enumerate(prev):
            if i not in links:
                tracks[prev_ids[i]].death_event = _death_event(f, cats[k], reach)
        for j, f in enumerate(cur):
            if cur_ids[j] < 0:
                event = "run_start" if k == 0 else _birth_event(f, cats[k - 1], reach)
                tracks.append(Track([], [], f.stuck_side, [], birth_event=event))
                cur_ids[j] = len(tracks) - 1
            t = tracks[cur_ids[j]]
            t.frames.append(k)
            t.nodes.append(f.node)
            t.slip_states.append(f.slip_state)
        prev, prev_ids = cur, cur_ids
    return tracks


def _flag_attrs(meanings, start=0) -> dict:
    return {
        "flag_values": np.arange(start, start + len(meanings), dtype=np.int8),
        "flag_meanings": " ".join(meanings),
    }


def motion_state(ds: xr.Dataset, rest_speed: float | None = None) -> np.ndarray:
    """The state flags (time, rbar) the analysis uses.

    ``rest_speed=None``: the trajectory's ``state`` (the force criterion: a node at the
    friction limit counts as slipping even where it does not move). A number (R/s): nodes
    flagged slipping whose ``|slip_velocity|`` is at most ``rest_speed`` count as stuck
    (at rest), so that fronts separate moving from resting sheet.
    """
    state = state_array(ds)
    if rest_speed is None:
        return state
    if not (np.isfinite(rest_speed) and rest_speed >= 0):
        raise InputError(f"rest_speed: {rest_speed!r}; allowed: a speed >= 0 in R/s, or None")
    v = np.abs(np.asarray(ds["slip_velocity"].transpose("time", "rbar").values, dtype=float))
    at_rest = ((state == SLIP_POLE) | (state == SLIP_EQUATOR)) & ~(v > float(rest_speed))
    return np.where(at_rest, STUCK, state).astype(np.int8)


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
            "time the node comes to rest for the last time in the stage (NaN: did not slip then stick)",
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
        else f"state flags, slipping nodes with |slip_velocity| <= {float(rest_speed):g} R/s counted stuck"
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
    rest_speed = _rest_speed(fronts)
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
        disp = {1: [], 2: []}
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


def summary_lines(stages: list[dict]) -> list[str]:
    """One line per stage for the command line: front direction and rest order."""
    out = []
    for e in stages:
        if not e.get("frames"):
            out.append(f"{e['name']}: no saved frame")
            continue
        line = (
            f"{e['name']} ({e['t_start_s']:.4g}-{e['t_end_s']:.4g} s): {e['n_tracks']} front(s), "
            f"travel {e['front_direction'].replace('_', ' ')}"
        )
        if e.get("last_to_rest_rbar"):
            n_last = len(e["last_to_rest_rbar"])
            at_once = f" ({n_last} nodes at once)" if n_last > 1 else ""
            line += (
                f"; last to come to rest at rbar = {max(e['last_to_rest_rbar']):.3g}{at_once} "
                f"(t = {e['last_rest_time_s']:.4g} s); outermost contact rests last: "
                f"{'yes' if e['outermost_contact_rests_last'] else 'no'}"
            )
        if e.get("n_nodes_slipping_at_end"):
            line += f"; {e['n_nodes_slipping_at_end']} node(s) still slipping at the end"
        out.append(line)
    return out


def _spearman(x: np.ndarray, y: np.ndarray) -> float | None:
    if x.size < 2 or np.all(y == y[0]) or np.all(x == x[0]):
        return None
    from scipy.stats import spearmanr

    rho = spearmanr(x, y).statistic
    return float(rho) if np.isfinite(rho) else None


def _rest_speed(fronts: xr.Dataset | None) -> float | None:
    v = None if fronts is None else fronts.attrs.get("rest_speed", "none")
    return None if v is None or isinstance(v, str) else float(v)
