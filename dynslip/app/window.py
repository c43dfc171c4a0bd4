r"""``dynslip window SCENARIO``: the trapping windows of a scenario's loading path, from
running the scenario at each $\mu$ of the search (:func:`dynslip.analysis.windows.find_windows`
has the algorithm; :func:`dynslip.schema.sweep.friction_field` the field searched).

For a scenario (``run_window``), $\mu$ is the ideal law's ``physics.friction.mu``, or
``mu_s`` with ``mu_k / mu_s`` (and every field named in ``tie``) held at its ratio to
``mu_s``.
"""

from __future__ import annotations

import copy
import itertools
import math
import tempfile
from collections.abc import Callable
from pathlib import Path

from dynslip.analysis.convergence import critical_edge, richardson
from dynslip.analysis.windows import WindowResult, check_search, find_windows
from dynslip.data.evaluations import EvaluationLog, search_key
from dynslip.data.files import write_json
from dynslip.data.folders import check_out, write_result_marker
from dynslip.data.lock import out_lock
from dynslip.errors import ComputationError, InputError, run_not_kept
from dynslip.plot.sweep import plot_critical_mu, plot_window
from dynslip.schema import base as scen
from dynslip.schema.paths import get_path
from dynslip.schema.sweep import WindowSpec, friction_field, member_at

# ---------------------------------------------------------------------------------------
# A scenario's window: the predicate from running the scenario at each mu.


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
    depths: dict[float, float] | None = None,
    errors: dict[float, str] | None = None,
) -> WindowResult:
    """Window search with ``trapped(mu)`` from running ``member_fn`` on the scenario at mu;
    ``depths`` (when given) receives each member's deepest chord (``mesh_check``); ``errors``
    (when given) gets the reason of each failed point before ``progress`` is called."""

    def trapped(mu: float) -> bool | None:
        try:
            return _trapped(mu)
        except ComputationError as err:
            # the member's run folder is discarded: its path is not part of the reason
            err = run_not_kept(err)
            if errors is not None:
                errors[float(mu)] = str(err)
            raise err

    def _trapped(mu: float) -> bool | None:
        member = member_at(data, resolved, field_name, tied, mu)
        with tempfile.TemporaryDirectory(dir=work_dir) as tmp:
            summary = member_fn(member, Path(tmp) / "run", console)
        t = summary.get("trapped")
        check = summary.get("mesh_check") or {}
        if depths is not None and check.get("max_chord_depth") is not None:
            depths[float(mu)] = float(check["max_chord_depth"])
        if (
            check.get("resolved") is False
        ):  # no answer: recorded with the reason among the failed points
            raise ComputationError(
                f"contact not resolved by the mesh: a chord {check['max_chord_depth']:.3g} R "
                f"inside the ball at t = {check['time_s']:.4g} s (limit {check['limit']:g})"
            )
        if t is None or (isinstance(t, float) and math.isnan(t)):
            if errors is not None:  # no verdict: its reason beside the failed runs'
                why = summary.get("trapped_unknown_reasons") or ["no verdict"]
                errors[float(mu)] = f"trapped unknown: {why[0]}"
            return None
        return bool(t)

    return find_windows(trapped, lo, hi, coarse=coarse, tol=tol, known=known, progress=progress)


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

    # at call time: the tests replace it in its home module
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
    d = WindowSpec.model_fields  # the defaults of a sweep's window search
    lo = d["lo"].default if lo is None else float(lo)
    hi = d["hi"].default if hi is None else float(hi)
    coarse = d["coarse"].default if coarse is None else int(coarse)
    tol = d["tol"].default if tol is None else float(tol)
    # Check the range and the scenario at both ends before running anything.
    for mu in (lo, hi):
        if mu < 0:
            raise InputError(f"{path}: window range: {field_name} = {mu}: must be >= 0")
    check_search(lo, hi, coarse, tol, str(path))
    for mu in (lo, hi):
        resolve(
            member_at(data, resolved, field_name, tied, mu),
            f"{path} ({field_name}={mu})",
            validate_fn,
        )

    out = Path(out) if out is not None else Path("outputs") / f"{path.stem}_window"
    check_out(out, force=force, in_place=True)

    with out_lock(out):  # one search per folder at a time
        return _search(out, path, overrides, data, resolved, member_fn, field_name, tied, lo, hi, coarse,  # noqa: E501
                       tol, console, EvaluationLog(out, search_key(resolved, field_name, tied)))


def _search(out, path, overrides, data, resolved, member_fn, field_name, tied, lo, hi, coarse, tol, console,  # noqa: E501
            log) -> dict:
    """The window search of :func:`run_window` in ``out``, resuming from the evaluations ``log``
    kept by an earlier, stopped attempt of the same search (each evaluation is kept as it ends)."""

    out.mkdir(parents=True, exist_ok=True)
    write_result_marker(out, "window")
    known, known_errors, known_depths = log.load()
    if known:
        console.print(f"resuming: {len(known)} evaluations kept by an earlier attempt ({log.path})")
    lines = []
    depths: dict[float, float] = dict(known_depths)  # the kept members' mesh checks
    errors: dict[float, str] = {}

    def progress(mu, v):
        log.record(mu, v, errors.get(float(mu)), depths.get(float(mu)))
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
        depths=depths,
        known=known,
        errors=errors,
    )
    # the reasons of failed points kept by an earlier attempt, and of runs without a verdict
    for mu, err in (*known_errors.items(), *errors.items()):
        res.errors.setdefault(mu, err)

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
        result["critical_mu_tied"] = (
            {t: float(get_path(resolved, t)) / base * result["critical_mu"]["value"] for t in tied}
            if result["critical_mu"] and base
            else None
        )
    nodes, limit = _mesh_of(resolved)
    result["resolution_check"] = resolution_check(result, depths, nodes, limit, str(path))
    write_json(out / "window.json", result)
    if res.evaluations and all(v is None for v in res.evaluations.values()):
        raise ComputationError(
            f"{path}: every run of the window search failed (see {out / 'window.json'})"
        )

    plot_window(result, out / "window.png")
    shown = ", ".join(f"[{w.lo.value:.4g}, {w.hi.value:.4g}]" for w in res.windows) or "none"
    console.print(
        f"trapping windows of {field_name}: {shown} (tol {tol}, resolution {res.resolution:.3g})"
    )
    if res.failed:
        console.print(f"[yellow]{len(res.failed)} failed runs: {res.failed}[/yellow]")
    console.print(f"[bold]{result['resolution_check']['says']}[/bold]", highlight=False)
    return result


def _mesh_of(resolved: dict) -> tuple[int | None, float]:
    """The scenario's mesh size and chord-depth limit (``numerics.nodes``,
    ``numerics.max_chord_depth``)."""
    try:
        nodes = int(get_path(resolved, "numerics.nodes"))
    except (InputError, KeyError, TypeError, ValueError):
        nodes = None
    try:
        limit = float(get_path(resolved, "numerics.max_chord_depth"))
    except (InputError, KeyError, TypeError, ValueError):
        limit = 0.1  # the schema's default
    return nodes, limit


def resolution_check(result: dict, depths: dict[float, float], nodes: int | None, limit: float,
                     scenario: str) -> dict:
    """Whether a one-mesh window search can be read as physics, in words, for window.json.

    Its members are resolved when none failed on the mesh check and none came within half the
    limit (``numerics.max_chord_depth``; the depth of a chord falls as the square of the
    element's angle, so a refinement by 1.4 is what halves it: such a member's answer may
    change with the mesh). A search at one mesh size does not know whether its windows
    survive a refinement: it says so, and names the command that checks it."""
    failed_mesh = [m for m, why in result.get("failed", [])
                   if "not resolved by the mesh" in str(why)]
    marginal = sorted(m for m, d in depths.items() if 0.5 * limit < d <= limit)
    n_windows = len(result.get("windows", []))
    words = []
    if failed_mesh:
        at = ", ".join(f"{m:.4g}" for m in failed_mesh)
        words.append(f"{len(failed_mesh)} members did not resolve the contact "
                     f"(no answer at mu = {at})")
    if marginal:
        words.append(f"{len(marginal)} of {len(depths)} members reach a chord depth over half the "
                     f"limit ({0.5 * limit:g} R): a finer mesh may change their answers")
    resolved = not failed_mesh and not marginal
    if n_windows > 1:
        words.append(f"{n_windows} separate windows: a fragmented answer is typical of a mesh "
                     "too coarse for the contact; only windows that persist under refinement "
                     "are physics")
    n = f"N = {nodes}" if nodes else "one mesh size"
    finer = f"{nodes},{2 * nodes},{4 * nodes}" if nodes else "N,2N,4N"
    cmd = (f"dynslip window {scenario} --nodes {finer}" if scenario.endswith((".yaml", ".yml"))
           else f"the same search at numerics.nodes = {finer}")
    head = ("members resolved" if resolved else "MEMBERS NOT RESOLVED") + f" at {n}"
    says = (f"{head}; windows not checked against refinement (check: {cmd})"
            + ("; " + "; ".join(words) if words else ""))
    return {"members_resolved": resolved, "nodes": nodes,
            "max_chord_depth": dict(sorted(depths.items())), "marginal": marginal,
            "failed_on_mesh": failed_mesh, "refinement_checked": False, "says": says}


def refinement_check(per_n: dict, field_name: str) -> dict:
    """Whether the windows of searches at increasing mesh sizes stay the same: the number of
    windows, and each edge within the sum of its two searches' tolerances. Windows that change
    are mesh artefacts until a finer pair agrees."""
    nodes = sorted(per_n)
    changes = []
    for a, b in itertools.pairwise(nodes):
        wa, wb = per_n[a]["windows"], per_n[b]["windows"]
        tol = per_n[a]["tol"] + per_n[b]["tol"]
        if len(wa) != len(wb):
            changes.append(f"N = {a} -> {b}: {len(wa)} -> {len(wb)} windows")
            continue
        moved = max((abs(x - y) for u, v in zip(wa, wb, strict=True)
                     for x, y in zip(u, v, strict=True)), default=0.0)
        if moved > tol:
            changes.append(f"N = {a} -> {b}: an edge moves by {moved:.3g} (> {tol:.3g})")
    unresolved = [n for n in nodes
                  if not per_n[n].get("resolution_check", {}).get("members_resolved", True)]
    if changes:
        says = (f"windows of {field_name} CHANGE WITH REFINEMENT ({'; '.join(changes)}): read "
                "only the finest, and only what persists")
    else:
        says = f"windows of {field_name} agree across N = " + ", ".join(map(str, nodes))
    if unresolved:
        says += "; members not resolved at N = " + ", ".join(map(str, unresolved))
    return {"windows_change": bool(changes), "changes": changes, "unresolved_at": unresolved,
            "says": says}


def no_answer(window_json: Path, error: str) -> dict:
    """A mesh size without an answer: the distinct reasons of its failed runs (from the
    ``failed`` list of its ``window.json``, written before the search gave up), each with the
    number of runs that gave it, and one line ``says``."""
    import json

    failed: list = []
    try:
        failed = json.loads(window_json.read_text()).get("failed", [])
    except (OSError, ValueError):
        pass
    counts: dict[str, int] = {}
    for _, why in failed:
        counts[str(why)] = counts.get(str(why), 0) + 1
    reasons = [{"reason": r, "runs": c} for r, c in sorted(counts.items(), key=lambda x: -x[1])]
    head = reasons[0]["reason"] if reasons else error
    more = f" (and {len(reasons) - 1} more reasons)" if len(reasons) > 1 else ""
    return {"answered": False, "error": error, "runs_failed": len(failed), "reasons": reasons,
            "says": f"every run of its search failed or had no verdict: {head}{more}"}


def parse_nodes(text: str) -> list[int]:
    """``--nodes 50,100,200`` as a list of mesh sizes (increasing, each 6..4000)."""
    try:
        ns = [int(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise InputError(
            f"--nodes = {text!r}: allowed: comma-separated mesh sizes, e.g. 50,100,200"
        ) from None
    if not ns or any(not 6 <= n <= 4000 for n in ns) or sorted(set(ns)) != ns:
        raise InputError(f"--nodes = {text!r}: allowed: increasing mesh sizes, each in 6..4000")
    return ns


def run_window_nodes(
    scenario,
    nodes: list[int],
    overrides=(),
    *,
    out: Path | None = None,
    console=None,
    force: bool = False,
    **kw,
) -> dict:
    """``dynslip window SCENARIO --nodes 50,100,200``: the window search at each mesh size
    (``<out>/N<n>/``), then ``<out>/window.json`` with ``critical_mu`` per N (value, err),
    its Richardson extrapolation with the measured order
    (:func:`dynslip.analysis.convergence.richardson`) and ``<out>/critical_mu.png``.

    A mesh size where no run of the search answers (every run failed or unresolved, as at a
    mesh too coarse for the tube's rim) is reported in ``unresolved`` with its reasons
    (:func:`no_answer`), its ``critical_mu`` None, and the study goes on with the others;
    :class:`ComputationError` only when no mesh size answers."""
    from rich.console import Console


    console = console or Console()
    path = Path(scenario)
    out = Path(out) if out is not None else Path("outputs") / f"{path.stem}_window"
    check_out(out, force=force, in_place=True)
    per_n, unresolved = {}, {}
    for n in nodes:
        console.print(f"[bold]N = {n}[/bold]")
        try:
            per_n[n] = run_window(
                scenario,
                [*overrides, f"numerics.nodes={n}"],
                out=out / f"N{n}",
                console=console,
                force=force,
                **kw,
            )
        except ComputationError as err:
            unresolved[n] = no_answer(out / f"N{n}" / "window.json", str(err))
            console.print(f"[yellow]N = {n}: no answer ({unresolved[n]['says']}); going on "
                          "with the other mesh sizes[/yellow]", highlight=False)
    out.mkdir(parents=True, exist_ok=True)
    write_result_marker(out, "window")
    if not per_n:
        first_why = next(iter(unresolved.values()))["says"]
        raise ComputationError(
            f"{path}: no mesh size of {', '.join(map(str, nodes))} answered (N = {nodes[0]}: "
            f"{first_why}; see {out / f'N{nodes[0]}' / 'window.json'})")
    answered = [n for n in nodes if n in per_n]
    crit = {str(n): per_n[n]["critical_mu"] if n in per_n else None for n in nodes}
    found = [n for n in answered if per_n[n]["critical_mu"] is not None]
    extrap = (richardson(found, [per_n[n]["critical_mu"]["value"] for n in found],
                         [per_n[n]["critical_mu"]["err"] for n in found])
              if found else {"extrapolable": False, "reason": "no window at any mesh size"})
    first = per_n[answered[0]]
    result = {
        "scenario": str(path),
        "overrides": list(overrides),
        "field": first["field"],
        "tied": first["tied"],
        "nodes": list(nodes),
        "answered_nodes": answered,
        "critical_mu": crit,
        "extrapolation": extrap,
        "windows": {str(n): per_n[n]["windows"] for n in answered},
        "unresolved": {str(n): u for n, u in unresolved.items()},
        "unresolved_means": ("mesh sizes where no run of the search answered (each failed or "
                             "had no verdict): their reasons, distinct, with how many runs "
                             "gave each; the study goes on with the other sizes, whose "
                             "extrapolation and refinement check leave these out"),
        "upper_edges": "reported as found; an upper edge is an artefact unless it survives "
            "refinement",
    }
    result["refinement_check"] = refinement_check(per_n, first["field"])
    if unresolved:
        result["refinement_check"]["says"] += (
            "; no answer at N = " + ", ".join(map(str, unresolved)) + " (unresolved)")
    write_json(out / "window.json", result)
    plot_critical_mu(result, out / "critical_mu.png")
    console.print(
        f"critical {result['field']} per N: "
        + ", ".join(
            f"{n}: {c['value']:.4g} +- {c['err']:.2g}" if c
            else f"{n}: {'unresolved' if n in result['unresolved'] else 'none'}"
            for n, c in crit.items()
        )
    )
    if extrap.get("extrapolable"):
        console.print(
            f"extrapolated: {extrap['value']:.4g} +- {extrap['err']:.2g} (order "
            f"{extrap['order']:.2f})"
        )
    else:
        console.print(f"not extrapolable: {extrap.get('reason')}")
    console.print(f"[bold]{result['refinement_check']['says']}[/bold]", highlight=False)
    return result
