r"""Trapping windows: the ranges of the friction coefficient over which the ball ends trapped.

Trapping need not be monotone in $\mu$ (a prototype trapped the ball at $\mu = 0.8$
and not at 1.0 to 2.5: high friction stops the sheet wrapping past the equator on the
way down), so a single bisection for "the" $\mu$ is wrong. The search here

1. scans ``coarse`` equally spaced values of $\mu$ on $[\mu_{lo}, \mu_{hi}]$
   (plus any values already known, e.g. the scenario's own run);
2. takes every neighbouring pair of scanned values whose outcomes differ as a bracket
   of an edge, and bisects it until its width is at most ``tol``;
3. reports each window $[\mu_a, \mu_b]$ of consecutive trapped values, each edge as
   the midpoint of its final bracket with an uncertainty of half its width. An edge at
   the end of the scanned range is reported as the range's bound and flagged
   ``open`` (the window may extend past it).

A window narrower than the coarse step can fall between two scanned values and be
missed: the coarse step is reported as the search's resolution.

The predicate ``trapped(mu)`` returns ``True``/``False``, or ``None`` for a failed run;
it may also raise :class:`~dynslip.errors.ComputationError` (a scenario run whose contact
the mesh does not resolve, ``summary.json`` ``mesh_check``, counts as failed). A failed point is
never
read as "not trapped": a failed coarse point is replaced by the points a quarter step
either side of it (a bracket spans what still fails), and
a failed bisection point is retried at the quarter points of the bracket; when those
fail too, the edge stays bracketed wider than ``tol`` and is flagged ``unresolved``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

from dynslip.errors import ComputationError, InputError


@dataclass(frozen=True)
class Edge:
    """One edge of a window: ``value`` +- ``err`` (half the final bracket)."""

    value: float
    err: float
    open: bool = False  # the edge is the end of the scanned range, not a found transition
    unresolved: bool = False  # bisection stopped on failed runs before reaching tol
    # the runs beyond this edge failed or did not resolve the contact: it bounds where the model
    # answers "trapped", and the path's own edge may lie beyond it
    failed_side: bool = False


@dataclass(frozen=True)
class Window:
    lo: Edge
    hi: Edge

    def as_list(self) -> list[float]:
        return [self.lo.value, self.hi.value]


@dataclass
class WindowResult:
    """What a window search found, and every evaluation it made."""

    lo: float
    hi: float
    coarse: int
    tol: float
    windows: list[Window] = field(default_factory=list)
    evaluations: dict[float, bool | None] = field(default_factory=dict)
    errors: dict[float, str] = field(default_factory=dict)

    @property
    def failed(self) -> list[float]:
        return sorted(m for m, v in self.evaluations.items() if v is None)

    @property
    def resolution(self) -> float:
        """The coarse step: windows narrower than this may be missed."""
        return (self.hi - self.lo) / max(self.coarse - 1, 1)

    def to_dict(self) -> dict:
        return {
            "range": [self.lo, self.hi],
            "coarse": self.coarse,
            "tol": self.tol,
            "resolution": self.resolution,
            "windows": [w.as_list() for w in self.windows],
            "windows_detail": [{"lo": asdict(w.lo), "hi": asdict(w.hi)} for w in self.windows],
            "n_evaluations": len(self.evaluations),
            "evaluations": [[m, v] for m, v in sorted(self.evaluations.items())],
            "failed": [[m, self.errors.get(m, "")] for m in self.failed],
        }


def _grid(lo: float, hi: float, coarse: int) -> list[float]:
    return [lo + (hi - lo) * i / (coarse - 1) for i in range(coarse)]


#: the most coarse scan points of a window search (each is a full run)
MAX_COARSE = 1000


#: the finest bisection tolerance, relative to max(1, |lo|, |hi|)
MIN_REL_TOL = 1e-9


#: the largest |lo|, |hi| of a search
MAX_ABS_RANGE = 1e6


def check_search(lo: float, hi: float, coarse: int, tol: float, source: str = "window") -> None:
    """Raise :class:`InputError` unless ``lo < hi`` (finite), ``2 <= coarse <= MAX_COARSE`` and
    ``tol`` finite and at least ``MIN_REL_TOL * max(1, |lo|, |hi|)`` (a finer bracket than the
    floats can resolve would bisect for ever)."""
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise InputError(
            f"{source}: range [lo, hi] = [{lo}, {hi}]: need finite lo < hi (an empty range)"
        )
    if max(abs(lo), abs(hi)) > MAX_ABS_RANGE:
        raise InputError(
            f"{source}: range [lo, hi] = [{lo}, {hi}]: allowed: |lo|, |hi| <= {MAX_ABS_RANGE:g}"
        )
    if not 2 <= coarse <= MAX_COARSE:
        raise InputError(f"{source}: coarse = {coarse}: allowed: 2..{MAX_COARSE} scan points")
    tol_min = MIN_REL_TOL * max(1.0, abs(lo), abs(hi))
    if not (math.isfinite(tol) and tol >= tol_min):
        raise InputError(f"{source}: tol = {tol}: allowed: a finite tol >= {tol_min:.3g}")


def find_windows(
    trapped: Callable[[float], bool | None],
    lo: float,
    hi: float,
    *,
    coarse: int = 9,
    tol: float = 0.02,
    known: dict[float, bool | None] | None = None,
    progress: Callable[[float, bool | None], None] | None = None,
) -> WindowResult:
    """Coarse scan of ``trapped`` on ``[lo, hi]``, then bisection of every edge to ``tol``.

    Example::

        >>> r = find_windows(lambda m: 0.3 < m < 0.5 or 1.2 < m < 1.4, 0, 2, coarse=21, tol=1e-3)
        >>> [[round(a, 2), round(b, 2)] for a, b in (w.as_list() for w in r.windows)]
        [[0.3, 0.5], [1.2, 1.4]]
    """
    check_search(lo, hi, coarse, tol)
    res = WindowResult(lo=float(lo), hi=float(hi), coarse=int(coarse), tol=float(tol))

    def ev(mu: float) -> bool | None:
        mu = float(mu)
        if mu in res.evaluations:
            return res.evaluations[mu]
        try:
            out = trapped(mu)
            out = None if out is None else bool(out)
        except ComputationError as err:
            out = None
            res.errors[mu] = str(err)
        res.evaluations[mu] = out
        if progress is not None:
            progress(mu, out)
        return out

    for mu, v in (known or {}).items():
        if lo <= mu <= hi:
            res.evaluations[float(mu)] = v
    grid = _grid(lo, hi, coarse)
    for mu in grid:
        ev(mu)
    # A failed scan point could hide a window: scan a quarter step either side of it.
    quarter = 0.25 * (hi - lo) / (coarse - 1)
    for mu in grid:
        if res.evaluations[mu] is None:
            for alt in (mu - quarter, mu + quarter):
                if lo <= alt <= hi:
                    ev(alt)
    scanned = sorted((m, v) for m, v in res.evaluations.items() if v is not None)
    if not scanned:
        return res

    # Each transition between neighbouring successful scan points: bisect to tol.
    edges: dict[int, tuple[float, float, bool]] = {}  # index of left point -> bracket
    for i in range(len(scanned) - 1):
        (a, va), (b, vb) = scanned[i], scanned[i + 1]
        if va == vb:
            continue
        unresolved = False
        while b - a > tol:
            mid = 0.5 * (a + b)
            vm = ev(mid)
            if vm is None:  # a failed point: try the quarter points before giving up
                for alt in (0.5 * (a + mid), 0.5 * (mid + b)):
                    vm = ev(alt)
                    if vm is not None:
                        mid = alt
                        break
            if vm is None:
                unresolved = True
                break
            if vm == va:
                a = mid
            else:
                b = mid
        edges[i] = (a, b, unresolved)

    # Windows: runs of trapped scan points, closed by the refined edges. A window that reaches
    # failed points (not the range's end) is bisected against them: its edge is where the
    # model stops answering "trapped", flagged failed_side.
    def _range_end(m: float, below: bool) -> Edge:
        beyond = [f for f in res.failed if (f < m if below else f > m)]
        if not beyond:
            return Edge(m, 0.0, open=True)
        return _bisect_against_failed(ev, max(beyond) if below else min(beyond), m, tol)

    start: Edge | None = None
    first_m, first_v = scanned[0]
    if first_v:
        start = _range_end(first_m, below=True)
    for i in range(len(scanned) - 1):
        if i not in edges:
            continue
        a, b, unresolved = edges[i]
        edge = Edge(0.5 * (a + b), 0.5 * (b - a), unresolved=unresolved)
        if scanned[i][1]:  # trapped -> not trapped: a window closes
            # a trapped point's run was opened (at the range's start or at the last edge)
            assert start is not None
            res.windows.append(Window(start, edge))
            start = None
        else:
            start = edge
    if start is not None:
        res.windows.append(Window(start, _range_end(scanned[-1][0], below=False)))
    return res


def _bisect_against_failed(
    ev: Callable[[float], bool | None], failed: float, trapped: float, tol: float
) -> Edge:
    """The edge between a failed point and a trapped one, bisected to ``tol`` on "trapped".
    A not-trapped point met on the way makes it an ordinary edge (``failed_side`` false)."""
    f, t = failed, trapped
    failed_side = True
    while abs(t - f) > tol:
        mid = 0.5 * (f + t)
        vm = ev(mid)
        if vm:
            t = mid
        else:
            f = mid
            failed_side = failed_side and vm is None
    return Edge(0.5 * (f + t), 0.5 * abs(t - f), failed_side=failed_side)
