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
the mesh does not resolve, ``summary.json`` ``mesh_check``, counts as failed). A failed point is never
read as "not trapped": a failed coarse point is replaced by the points a quarter step
either side of it (a bracket spans what still fails), and
a failed bisection point is retried at the quarter points of the bracket; when those
fail too, the edge stays bracketed wider than ``tol`` and is flagged ``unresolved``.

For a scenario (``run_window``), $\mu$ is the ideal law's ``physics.friction.mu``, or
``mu_s`` with ``mu_k / mu_s`` (and every field named in ``tie``) held at its ratio to
``mu_s``.
"""

from __future__ import annotations

import copy
import math
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from dynslip.errors import ComputationError, InputError
from dynslip.schema.paths import get_path, set_path


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


def check_range(lo: float, hi: float, coarse: int, tol: float, source: str = "window") -> None:
    """Raise :class:`InputError` unless ``lo < hi`` (finite), ``2 <= coarse <= MAX_COARSE`` and
    ``tol`` finite and at least ``MIN_REL_TOL * max(1, |lo|, |hi|)`` (a finer bracket than the
    floats can resolve would bisect for ever)."""
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise InputError(
            f"{source}: range [lo, hi] = [{lo}, {hi}]: need finite lo < hi (an empty range)"
        )
    if max(abs(lo), abs(hi)) > MAX_ABS_RANGE:
        raise InputError(f"{source}: range [lo, hi] = [{lo}, {hi}]: allowed: |lo|, |hi| <= {MAX_ABS_RANGE:g}")
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
    check_range(lo, hi, coarse, tol)
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
            res.windows.append(Window(start, edge))
            start = None
        else:
            start = edge
    if start is not None:
        res.windows.append(Window(start, _range_end(scanned[-1][0], below=False)))
    return res


def _bisect_against_failed(ev: Callable[[float], bool | None], failed: float, trapped: float, tol: float) -> Edge:
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


# ---------------------------------------------------------------------------------------
# A scenario's window: the predicate from running the scenario at each mu.


def friction_field(resolved: dict, field_name: str | None = None) -> tuple[str, list[str]]:
    """The swept friction field and the fields tied to it by a fixed ratio.

    ``physics.friction.mu`` for the ideal law; ``physics.friction.mu_s`` when the law
    has a static coefficient, with ``mu_k`` tied (``mu_k / mu_s`` fixed).
    """
    fr = resolved.get("physics", {}).get("friction", {})
    if field_name is None:
        # mu_s when the law has a static coefficient (any law but the ideal one that also has mu)
        if isinstance(fr, dict) and "mu_s" in fr and (fr.get("law") != "coulomb" or "mu" not in fr):
            field_name = "physics.friction.mu_s"
        elif isinstance(fr, dict) and "mu" in fr:
            field_name = "physics.friction.mu"
        else:
            raise InputError(
                "window: the scenario has no field 'physics.friction.mu' or 'physics.friction.mu_s' "
                "to search over"
            )
    try:
        get_path(resolved, field_name)
    except KeyError:
        raise InputError(f"window: field '{field_name}' is not in the scenario") from None
    tied = []
    if field_name.endswith(".mu_s"):
        sib = field_name[: -len("mu_s")] + "mu_k"
        try:
            get_path(resolved, sib)
            tied.append(sib)
        except KeyError:
            pass
    return field_name, tied


def member_at(data: dict, resolved: dict, field_name: str, tied: list[str], mu: float) -> dict:
    """The scenario data with ``field_name = mu`` and every tied field at its base ratio."""
    base = float(get_path(resolved, field_name))
    out = copy.deepcopy(data)
    set_path(out, field_name, float(mu))
    for t in tied:
        ratio = float(get_path(resolved, t)) / base if base else 1.0
        set_path(out, t, float(mu) * ratio)
    return out


def scenario_window(
    data: dict,
    resolved: dict,
    member_fn: Callable,
    *,
    field_name: str,
    tied: list[str],
    lo: float,
    hi: float,
    coarse: int,
    tol: float,
    known: dict[float, bool | None] | None = None,
    work_dir: Path | None = None,
    console=None,
    progress: Callable[[float, bool | None], None] | None = None,
) -> WindowResult:
    """Window search with ``trapped(mu)`` from running ``member_fn`` on the scenario at mu."""

    def trapped(mu: float) -> bool | None:
        member = member_at(data, resolved, field_name, tied, mu)
        with tempfile.TemporaryDirectory(dir=work_dir) as tmp:
            summary = member_fn(member, Path(tmp) / "run", console)
        t = summary.get("trapped")
        check = summary.get("mesh_check") or {}
        if check.get("resolved") is False:  # no answer: recorded with the reason among the failed points
            raise ComputationError(f"contact not resolved by the mesh: a chord {check['max_chord_depth']:.3g} R "
                                   f"inside the ball at t = {check['time_s']:.4g} s (limit {check['limit']:g})")
        if t is None or (isinstance(t, float) and math.isnan(t)):
            return None
        return bool(t)

    return find_windows(trapped, lo, hi, coarse=coarse, tol=tol, known=known, progress=progress)


@dataclass(frozen=True)
class WindowDefaults:
    lo: float = 0.0
    hi: float = 3.0
    coarse: int = 13
    tol: float = 0.02


def run_window(
    scenario,
    overrides: list[str] | tuple[str, ...] = (),
    *,
    lo: float | None = None,
    hi: float | None = None,
    coarse: int | None = None,
    tol: float | None = None,
    field: str | None = None,
    out: Path | None = None,
    console=None,
    member_fn: Callable | None = None,
    validate_fn: Callable | None = None,
    force: bool = False,
    data: dict | None = None,
) -> dict:
    """``dynslip window SCENARIO``: the trapping windows of a scenario's loading path.

    Writes ``<out>/window.json`` (windows, every evaluation, failed points) and
    ``<out>/window.png``; returns the dictionary written. ``out`` defaults to
    ``outputs/<stem>_window/``: new, empty or a dynslip result; ``force`` allows writing
    into another folder (never a file). Raises :class:`InputError` for bad input (before
    anything is created) and :class:`ComputationError` when every run failed. ``data``:
    the scenario as data (:func:`dynslip.window`), instead of reading the file
    ``scenario``, which then only names it.
    """
    from rich.console import Console

    from dynslip.schema import base as scen
    from dynslip.data.files import check_out, write_json, write_result_marker
    from dynslip.app.members import default_member_fn, resolve

    console = console or Console()
    member_fn = member_fn or default_member_fn
    path = Path(scenario)
    data = scen.load_data(path, list(overrides)) if data is None else copy.deepcopy(data)
    start = data.get("start_from") if isinstance(data, dict) else None
    if isinstance(start, str) and not Path(start).is_absolute() and not Path(start).exists():
        # members run without the file's folder: a start_from relative to it is made absolute
        data["start_from"] = str((path.parent / start).resolve())
    resolved = resolve(data, str(path), validate_fn)
    field_name, tied = friction_field(resolved, field)
    d = WindowDefaults()
    lo = d.lo if lo is None else float(lo)
    hi = d.hi if hi is None else float(hi)
    coarse = d.coarse if coarse is None else int(coarse)
    tol = d.tol if tol is None else float(tol)
    # Check the range and the scenario at both ends before running anything.
    for mu in (lo, hi):
        if mu < 0:
            raise InputError(f"{path}: window range: {field_name} = {mu}: must be >= 0")
    check_range(lo, hi, coarse, tol, str(path))
    for mu in (lo, hi):
        resolve(
            member_at(data, resolved, field_name, tied, mu),
            f"{path} ({field_name}={mu})",
            validate_fn,
        )

    out = Path(out) if out is not None else Path("outputs") / f"{path.stem}_window"
    check_out(out, force=force, in_place=True)
    out.mkdir(parents=True, exist_ok=True)
    write_result_marker(out, "window")
    lines = []

    def progress(mu, v):
        word = {True: "trapped", False: "not trapped", None: "FAILED or unresolved"}[v]
        lines.append(f"{field_name} = {mu:.6g}: {word}")
        console.print(f"  {field_name} = {mu:.6g}: {word}")

    console.print(
        f"window search over {field_name} in [{lo}, {hi}], {coarse} coarse points, tol {tol}"
    )
    res = scenario_window(
        data,
        resolved,
        member_fn,
        field_name=field_name,
        tied=tied,
        lo=lo,
        hi=hi,
        coarse=coarse,
        tol=tol,
        work_dir=out,
        console=None,
        progress=progress,
    )
    from dynslip.analysis.convergence import critical_edge

    result = {
        "scenario": str(path),
        "overrides": list(overrides),
        "field": field_name,
        "tied": tied,
        **res.to_dict(),
    }
    # the path's critical mu: the lowest friction at which it ends trapped (the lowest window's
    # lower edge; None when nothing traps). Upper edges are reported as found: artefacts
    # unless they survive mesh refinement (run with --nodes).
    result["critical_mu"] = critical_edge(result["windows_detail"])
    if tied:
        base = float(get_path(resolved, field_name))
        result["critical_mu_tied"] = ({t: float(get_path(resolved, t)) / base * result["critical_mu"]["value"]
                                       for t in tied} if result["critical_mu"] and base else None)
    write_json(out / "window.json", result)
    if res.evaluations and all(v is None for v in res.evaluations.values()):
        raise ComputationError(
            f"{path}: every run of the window search failed (see {out / 'window.json'})"
        )
    from dynslip.plot.sweep import plot_window

    plot_window(result, out / "window.png")
    shown = ", ".join(f"[{w.lo.value:.4g}, {w.hi.value:.4g}]" for w in res.windows) or "none"
    console.print(
        f"trapping windows of {field_name}: {shown} (tol {tol}, resolution {res.resolution:.3g})"
    )
    if res.failed:
        console.print(f"[yellow]{len(res.failed)} failed runs: {res.failed}[/yellow]")
    return result


def parse_nodes(text: str) -> list[int]:
    """``--nodes 50,100,200`` as a list of mesh sizes (increasing, each 6..4000)."""
    try:
        ns = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--nodes = {text!r}: allowed: comma-separated mesh sizes, e.g. 50,100,200") from None
    if not ns or any(not 6 <= n <= 4000 for n in ns) or sorted(set(ns)) != ns:
        raise InputError(f"--nodes = {text!r}: allowed: increasing mesh sizes, each in 6..4000")
    return ns


def run_window_nodes(scenario, nodes: list[int], overrides=(), *, out: Path | None = None, console=None,
                     force: bool = False, **kw) -> dict:
    """``dynslip window SCENARIO --nodes 50,100,200``: the window search at each mesh size
    (``<out>/N<n>/``), then ``<out>/window.json`` with ``critical_mu`` per N (value, err),
    its Richardson extrapolation with the measured order
    (:func:`dynslip.analysis.convergence.richardson`) and ``<out>/critical_mu.png``."""
    from rich.console import Console

    from dynslip.analysis.convergence import richardson
    from dynslip.data.files import check_out, write_json, write_result_marker
    from dynslip.plot.sweep import plot_critical_mu

    console = console or Console()
    path = Path(scenario)
    out = Path(out) if out is not None else Path("outputs") / f"{path.stem}_window"
    check_out(out, force=force, in_place=True)
    per_n = {}
    for n in nodes:
        console.print(f"[bold]N = {n}[/bold]")
        per_n[n] = run_window(scenario, [*overrides, f"numerics.nodes={n}"], out=out / f"N{n}", console=console,
                              force=force, **kw)
    out.mkdir(parents=True, exist_ok=True)
    write_result_marker(out, "window")
    crit = {str(n): per_n[n]["critical_mu"] for n in nodes}
    found = [n for n in nodes if per_n[n]["critical_mu"] is not None]
    extrap = (richardson(found, [per_n[n]["critical_mu"]["value"] for n in found],
                         [per_n[n]["critical_mu"]["err"] for n in found])
              if found else {"extrapolable": False, "reason": "no window at any mesh size"})
    first = per_n[nodes[0]]
    result = {"scenario": str(path), "overrides": list(overrides), "field": first["field"], "tied": first["tied"],
              "nodes": list(nodes), "critical_mu": crit, "extrapolation": extrap,
              "windows": {str(n): per_n[n]["windows"] for n in nodes},
              "upper_edges": "reported as found; an upper edge is an artefact unless it survives refinement"}
    write_json(out / "window.json", result)
    plot_critical_mu(result, out / "critical_mu.png")
    console.print(f"critical {result['field']} per N: "
                  + ", ".join(f"{n}: {c['value']:.4g} +- {c['err']:.2g}" if c else f"{n}: none" for n, c in crit.items()))
    if extrap.get("extrapolable"):
        console.print(f"extrapolated: {extrap['value']:.4g} +- {extrap['err']:.2g} (order {extrap['order']:.2f})")
    else:
        console.print(f"not extrapolable: {extrap.get('reason')}")
    return result
