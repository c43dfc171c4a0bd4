r"""Stick fronts: the boundaries between stuck and slipping sheet, tracked through time (what
the tracks tell per stage, and the fronts as a dataset: :mod:`dynslip.analysis.front_summary`).

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
Apart from ``reach``, no speed limit is assumed. Speeds are finite differences along a track
(``numpy.gradient``, second order inside).

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

from dataclasses import dataclass

import numpy as np
import xarray as xr

from dynslip.data.trajectory import (
    FREE,
    SLIP_EQUATOR,
    SLIP_POLE,
    STUCK,
    state_array,
)
from dynslip.errors import InputError

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
    best: list[list[tuple[int, float]]] = [[(0, 0)] * (m + 1) for _ in range(n + 1)]
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


