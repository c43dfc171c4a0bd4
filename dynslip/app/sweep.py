"""Studies over scenario fields: members, runners and resume (the sweep file is
:mod:`dynslip.schema.sweep`, the dataset :mod:`dynslip.data.sweep`).

A sweep file is a small YAML file of its own (validated strictly, like a scenario)::

    base: method2.yaml                 # the scenario every member starts from (relative to this
    file)
    overrides: {numerics.nodes: 30}    # applied to every member
    grid:                              # a dimension per field, named by dotted path ...
      physics.protocol.depth: [4, 5, 6]
      physics.friction.mu: {start: 0.4, stop: 1.2, num: 5}
    # list: [{physics.friction.mu: 0.8}, {physics.friction.mu: 1.0, numerics.nodes: 40}]  # ... or
    a list
    window: {lo: 0.2, hi: 2.5, coarse: 12, tol: 0.02}   # optional: each member's trapping window
    out: outputs/my_study                               # default outputs/<sweep file stem>/

The grid (or list) key ``base`` sweeps over scenario files (e.g. method 1 vs method 2).

Every member's scenario is resolved and validated before anything runs: a field that
does not exist, an empty range or a value of the wrong type stops the sweep with one
line naming it. Each finished member is written at once, atomically, to
``<out>/members/<fingerprint>.json`` (the fingerprint hashes the resolved scenario and
the window settings), so an interrupted sweep resumes where it stopped: members whose
file exists are not run again. The members are then assembled into ``<out>/sweep.nc``
(a dimension per swept field for a grid, a ``member`` dimension for a list) and plotted.

A failed member (:class:`~dynslip.errors.ComputationError`, or any other exception of
its run) is kept as NaN with ``status`` and ``error``: never as "not trapped".

How members run (``mode``: sequential, batched, dask): :mod:`dynslip.app.sweep_runners`.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import math
import shutil
import time
from collections.abc import Callable
from pathlib import Path

from dynslip.app.members import Member, default_member_fn, resolve
from dynslip.app.sweep_runners import MODES, connect_client, run_members
from dynslip.data.files import provenance, write_json, write_netcdf
from dynslip.data.folders import RESULT_MARKER, check_out, kept_on_error, write_result_marker
from dynslip.data.lock import out_lock
from dynslip.data.sweep import assemble
from dynslip.errors import ComputationError, InputError
from dynslip.plot.sweep import plot_sweep
from dynslip.schema.base import load_data
from dynslip.schema.paths import get_path, set_path
from dynslip.schema.sweep import BASE_KEY, SweepSpec, friction_field, load_spec, unit_of_field

#: The default runner: the fastest in ``benchmarks/sweep.py`` on the 2-core machine.
DEFAULT_MODE = "sequential"


# ---------------------------------------------------------------------------------------
# The sweep file


def validate_sweep(path, validate_fn: Callable | None = None) -> list[Member]:
    """``dynslip validate SWEEP.yaml``: the sweep file and every member's scenario validated
    (nothing runs); returns the members. Raises :class:`InputError` (one line)."""
    return expand(load_spec(path), Path(path), validate_fn)


# ---------------------------------------------------------------------------------------
# Members


def _fingerprint(resolved: dict, window: dict | None) -> str:
    text = json.dumps({"scenario": resolved, "window": window}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def expand(spec: SweepSpec, sweep_path: Path, validate_fn: Callable | None = None) -> list[Member]:
    """Every member of the sweep, resolved and validated (nothing runs)."""

    root = Path(sweep_path).parent
    if spec.grid is not None:
        grid = spec.grid_values()
        keys = list(grid)
        combos = [
            (idx, {k: grid[k][i] for k, i in zip(keys, idx, strict=True)})
            for idx in itertools.product(*(range(len(grid[k])) for k in keys))
        ]
    else:
        assert spec.list_ is not None  # the sweep's check: a grid or a list, one of them
        combos = [((i,), dict(entry)) for i, entry in enumerate(spec.list_)]
    window = spec.window.model_dump() if spec.window else None
    bases: dict[str, dict] = {}
    members = []
    for idx, assign in combos:
        src = f"{sweep_path} member [{', '.join(f'{k}={v}' for k, v in assign.items())}]"
        base_name = str(assign.get(BASE_KEY, spec.base))
        base = (root / base_name).resolve()
        if base_name not in bases:
            if not base.is_file():
                raise InputError(
                    f"{sweep_path}: field 'base' = {json.dumps(base_name)}: scenario file not found"
                )
            # members start from the resolved base (defaults filled in): stages can be named
            bases[base_name] = resolve(load_data(base), str(base), validate_fn)
        data = copy.deepcopy(bases[base_name])
        for k, v in spec.overrides.items():
            set_path(data, k, v, f"{sweep_path}: overrides")
        for k, v in assign.items():
            if k != BASE_KEY:
                set_path(data, k, v, src)
        resolved = resolve(data, src, validate_fn)
        for k in list(spec.overrides) + [k for k in assign if k != BASE_KEY]:
            try:
                get_path(resolved, k)
            except KeyError:
                raise InputError(f"{src}: field '{k}' does not exist in the scenario") from None
        if window is not None:

            field_name, _ = friction_field(resolved, window["field"])
            if field_name in assign:
                raise InputError(
                    f"{src}: field '{field_name}' is both swept and searched by the window"
                )
        members.append(Member(idx, assign, base, data, resolved, _fingerprint(resolved, window)))
    return members


# ---------------------------------------------------------------------------------------
# The dataset


def _base_value(m: Member, k: str):
    if k == BASE_KEY:
        return str(m.base.name)
    try:
        return get_path(m.resolved, k)
    except KeyError:
        return math.nan


# ---------------------------------------------------------------------------------------
# The entry point


def run_sweep(
    sweep,
    *,
    out: Path | None = None,
    mode: str | None = None,
    scheduler: str | None = None,
    connect_timeout: float | None = None,
    console=None,
    member_fn: Callable | None = None,
    validate_fn: Callable | None = None,
    plot: bool = True,
    force: bool = False,
) -> dict:
    """``dynslip sweep SWEEP.yaml``: run every member not yet done, then assemble and plot.

    Writes ``<out>/members/*.json`` (one per member, as each finishes), ``<out>/sweep.nc``,
    ``<out>/sweep.png`` and ``<out>/summary.json``; returns the summary. Raises
    :class:`InputError` for a bad sweep file, member or scheduler (before anything runs;
    ``connect_timeout``: seconds to wait for ``scheduler``, default
    :data:`~dynslip.app.sweep_runners.CONNECT_TIMEOUT_S`),
    :class:`ComputationError` when every member failed. ``member_fn(data, out_dir,
    console) -> summary`` replaces the real simulator (tests, benchmarks). ``out`` must be
    new, empty or a dynslip result (a sweep resumes in it); ``force`` allows writing into
    another folder (never a file); checked before anything is created.
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


    console = console or Console()
    sweep = Path(sweep)
    spec = load_spec(sweep)
    if scheduler is not None:
        if mode not in (None, "dask"):
            raise InputError(f"--scheduler {scheduler!r} needs --mode dask (got --mode {mode})")
        mode = "dask"
    mode = mode or spec.mode or DEFAULT_MODE
    if mode not in MODES:
        raise InputError(f"--mode {mode!r}: allowed: {', '.join(MODES)}")
    member_fn = member_fn or default_member_fn
    members = expand(spec, sweep, validate_fn)
    window = spec.window.model_dump() if spec.window else None
    out = (
        Path(out)
        if out is not None
        else Path(spec.out)
        if spec.out
        else Path("outputs") / sweep.stem
    )
    check_out(out, force=force, in_place=True)  # before anything is created
    mdir = out / "members"

    records: dict[str, dict] = {}
    for m in members:
        f = mdir / f"{m.key}.json"
        if f.is_file():
            with contextlib.suppress(ValueError, OSError):
                rec = json.loads(f.read_text())
                if rec.get("fingerprint") == m.fingerprint:
                    records[m.fingerprint] = rec
    pending = list({m.fingerprint: m for m in members if m.fingerprint not in records}.values())
    n_unique = len({m.fingerprint for m in members})

    def run_dir(m: Member) -> str | None:
        if not spec.keep_runs:
            return None
        d = out / "runs" / m.key
        if d.exists():  # this member's own folder from an earlier, unfinished attempt
            shutil.rmtree(d)
        d.mkdir(parents=True)
        write_result_marker(d, "sweep member")
        return str(d)

    with contextlib.ExitStack() as stack:
        client = None
        if mode == "dask" and pending:  # before anything is printed: unreachable is bad input
            client, cluster = connect_client(scheduler, connect_timeout)
            stack.callback(client.close)
            if cluster is not None:
                stack.callback(cluster.close)
        # the folder is made only now that the input (and the scheduler) has been checked

        stack.enter_context(out_lock(out))  # one sweep per folder at a time
        mdir.mkdir(parents=True, exist_ok=True)
        if not (out / RESULT_MARKER).is_file():
            write_result_marker(out, "sweep")
        stack.enter_context(kept_on_error(out))  # an interrupted sweep resumes from out/members/
        console.print(
            f"sweep {sweep}: {len(members)} members ({n_unique - len(pending)} already done, "
            f"{len(pending)} to run), mode {mode}"
        )
        t0 = time.perf_counter()
        bar = stack.enter_context(
            Progress(
                TextColumn("members"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                console=console,
                transient=False,
            )
        )
        task = bar.add_task("members", total=n_unique, completed=n_unique - len(pending))

        def done(m: Member, rec: dict) -> None:
            rec = {
                "fingerprint": m.fingerprint,
                "assign": m.assign,
                "base": str(m.base),
                "scenario": m.resolved,
                **rec,
            }
            write_json(mdir / f"{m.key}.json", rec)
            records[m.fingerprint] = json.loads((mdir / f"{m.key}.json").read_text())
            bar.advance(task)
            if rec["status"] != "ok":
                bar.console.print(
                    f"[yellow]member {m.label}: {rec['status']}: {rec['error'][:200]}[/yellow]"
                )

        note = run_members(
            pending,
            mode=mode,
            client=client,
            member_fn=member_fn,
            simulator=member_fn is default_member_fn,
            window=window,
            run_dir=run_dir,
            done=done,
        )
    wall = time.perf_counter() - t0

    base_json = json.dumps(members[0].resolved)
    attrs = provenance(base_json, "sweep")
    attrs["sweep"] = spec.model_dump_json(by_alias=True)
    attrs["sweep_file"] = str(sweep)
    attrs["swept_fields"] = json.dumps(
        list(spec.grid_values())
        if spec.grid is not None
        else list(dict.fromkeys(k for m in members for k in m.assign))
    )
    ds = assemble(spec, members, records, attrs, base_value=_base_value,
                  unit_of=lambda k: "1" if k == BASE_KEY else unit_of_field(k, members))
    write_netcdf(ds, out / "sweep.nc")
    statuses = [records[m.fingerprint]["status"] for m in members]
    summary = {
        "sweep": str(sweep),
        "out": str(out),
        "mode": mode,
        "batched": note,
        "n_members": len(members),
        "n_run": len(pending),
        "n_ok": statuses.count("ok"),
        "n_failed": len(statuses) - statuses.count("ok"),
        "wall_s": wall,
        "members_per_minute": 60.0 * len(pending) / wall if pending and wall > 0 else None,
    }
    write_json(out / "summary.json", summary)
    if plot:

        plot_sweep(ds, out / "sweep.png")
    console.print(
        f"sweep done: {summary['n_ok']} ok, {summary['n_failed']} failed; {out / 'sweep.nc'}"
    )
    if summary["n_ok"] == 0:
        raise ComputationError(
            f"{sweep}: every member failed (errors in {out / 'sweep.nc'}, variable 'error')"
        )
    return summary
