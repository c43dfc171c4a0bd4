"""Studies over scenario fields: members, runners and resume (the sweep file is
:mod:`dynslip.schema.sweep`, the dataset :mod:`dynslip.data.sweep`).

Longer than 400 lines: the three runners (sequential, batched in lockstep, dask) are still
here beside the entry point; they are to move to a module of their own (issue 24).

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

Runners (``mode``):

- ``sequential``: one member after another in this process.
- ``batched``: members grouped by shape (same structure, integers and strings of the
  resolved scenario; only floats differ, so members differing in the mesh, the material
  model or the friction law fall in different groups). A group of forming members runs
  through :func:`dynslip.physics.batch.simulate_batch` (:func:`run_forming_batch`):
  members in lockstep, one ``jax.vmap``-ed call of the load-stepping segment solve per save
  segment for the whole batch, each member with its own stage, time and stop rule. A group
  of at least 4 is split over :data:`BATCH_WORKERS` (2) spawned worker processes, one half
  each. Members with ``start_from``, a window search or a stand-in runner run member after
  member ("grouped sequential"). The summary's ``batched`` entry says what ran.
  Under ``vmap`` each member's ``while_loop`` of load increments runs the batch's largest
  count of increments in every segment (4 members of the let-go path at 40 nodes: 1255
  lockstep increments against 689-800 of their own), and on the CPU a vmapped increment
  costs about as much per member as one alone, so lockstep alone does not pay on the CPU;
  the two processes do (docs/sweeps.md, "Throughput"). :data:`BATCH_SIZE` = 1, the default
  on the CPU, runs the members of each worker one after another (the fastest on 2 CPU
  cores); on an accelerator the default is a worker's whole share in one batch. Outputs of a
  member's run (trajectory, figures) are written only with ``keep_runs``: the summary is
  computed from the trajectory in memory, as the simulator's runner computes it.
- ``dask``: members submitted to a ``dask.distributed`` scheduler (``scheduler``
  address, or a LocalCluster on loopback when none is given); results come back and
  are written as they finish.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dynslip.app.members import default_member_fn, resolve
from dynslip.data.sweep import assemble
from dynslip.errors import ComputationError, InputError
from dynslip.schema.paths import get_path, set_path
from dynslip.schema.sweep import BASE_KEY, SweepSpec, _unit_of_field, load_spec

MODES = ("sequential", "batched", "dask")
#: The default runner: the fastest in ``benchmarks/sweep.py`` on the 2-core machine.
DEFAULT_MODE = "sequential"
CONNECT_TIMEOUT_S = 10.0


# ---------------------------------------------------------------------------------------
# The sweep file


def validate_sweep(path, validate_fn: Callable | None = None) -> list[Member]:
    """``dynslip validate SWEEP.yaml``: the sweep file and every member's scenario validated
    (nothing runs); returns the members. Raises :class:`InputError` (one line)."""
    return expand(load_spec(path), Path(path), validate_fn)


# ---------------------------------------------------------------------------------------
# Members


@dataclass
class Member:
    index: tuple[int, ...]  # grid multi-index, or (list position,)
    assign: dict[str, Any]  # swept field -> value (``base`` included when swept)
    base: Path
    data: dict  # scenario data before validation (base file + overrides + assignments)
    resolved: dict  # validated, every default filled in
    fingerprint: str

    @property
    def key(self) -> str:
        return self.fingerprint[:16]

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.assign.items())


def _fingerprint(resolved: dict, window: dict | None) -> str:
    text = json.dumps({"scenario": resolved, "window": window}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def expand(spec: SweepSpec, sweep_path: Path, validate_fn: Callable | None = None) -> list[Member]:
    """Every member of the sweep, resolved and validated (nothing runs)."""
    from dynslip.schema.base import load_data

    root = Path(sweep_path).parent
    if spec.grid is not None:
        grid = spec.grid_values()
        keys = list(grid)
        combos = [
            (idx, {k: grid[k][i] for k, i in zip(keys, idx, strict=True)})
            for idx in itertools.product(*(range(len(grid[k])) for k in keys))
        ]
    else:
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
            from dynslip.schema.sweep import friction_field

            field_name, _ = friction_field(resolved, window["field"])
            if field_name in assign:
                raise InputError(
                    f"{src}: field '{field_name}' is both swept and searched by the window"
                )
        members.append(Member(idx, assign, base, data, resolved, _fingerprint(resolved, window)))
    return members


# ---------------------------------------------------------------------------------------
# Running one member (module level: it travels to dask workers)


def _jsonable_summary(summary: dict) -> dict:
    from dynslip.data.files import jsonable

    return json.loads(json.dumps(jsonable(summary), default=str))


def execute_member(
    member_fn: Callable,
    data: dict,
    resolved: dict,
    window: dict | None,
    run_dir: str | None,
) -> dict:
    """Run one member (and its window search): the record written to its member file.

    Never raises for a failed run: ``status`` is ``ok``, ``failed``
    (:class:`ComputationError`) or ``error`` (any other exception), with ``error`` its
    message.
    """
    t0 = time.perf_counter()
    rec: dict[str, Any] = {"status": "ok", "error": "", "summary": {}}
    with contextlib.ExitStack() as stack:
        work = (
            Path(run_dir) if run_dir else Path(stack.enter_context(tempfile.TemporaryDirectory()))
        )
        try:
            rec["summary"] = _jsonable_summary(member_fn(data, work / "run", None))
            if (
                rec["summary"].get("status", "ok") != "ok"
            ):  # a runner that reports instead of raising
                rec.update(status="failed", error=str(rec["summary"].get("message", "failed")))
        except ComputationError as err:
            rec.update(status="failed", error=f"ComputationError: {err}")
        except Exception as err:  # noqa: BLE001 - a member's failure is data, not a crash of the sweep
            rec.update(status="error", error=f"{type(err).__name__}: {err}")
        if window is not None:
            from dynslip.app.window import scenario_window
            from dynslip.schema.sweep import friction_field

            field_name, tied = friction_field(resolved, window["field"])
            mu0 = float(get_path(resolved, field_name))
            t = rec["summary"].get("trapped") if rec["status"] == "ok" else None
            res = scenario_window(
                data,
                resolved,
                member_fn,
                field_name=field_name,
                tied=tied,
                lo=window["lo"],
                hi=window["hi"],
                coarse=window["coarse"],
                tol=window["tol"],
                known={mu0: None if t is None else bool(t)},
                work_dir=work,
            )
            rec["window"] = {"field": field_name, "tied": tied, **res.to_dict()}
    rec["wall_s"] = time.perf_counter() - t0
    return rec


def _shape_key(resolved: Any) -> Any:
    """The resolved scenario with every float blanked: members with equal keys share shapes."""
    if isinstance(resolved, dict):
        return {k: _shape_key(v) for k, v in resolved.items()}
    if isinstance(resolved, list):
        return [_shape_key(v) for v in resolved]
    return None if isinstance(resolved, float) else resolved


# ---------------------------------------------------------------------------------------
# Runners


def _connect(scheduler: str | None):
    """A dask client: to ``scheduler``, or to a new LocalCluster on loopback."""
    from distributed import Client, LocalCluster

    if scheduler is None:
        cluster = LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        )
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT_S), None
    except Exception as err:  # noqa: BLE001 - OSError, TimeoutError, ValueError for a bad address
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise InputError(
            f"--scheduler {scheduler!r}: cannot reach a dask scheduler within "
            f"{CONNECT_TIMEOUT_S:g} s "
            f"({reason[:120]}); give an address like tcp://HOST:8786"
        ) from None


def _run_members(
    pending: list[Member],
    *,
    mode: str,
    client,
    member_fn: Callable,
    window: dict | None,
    run_dir: Callable[[Member], str | None],
    done: Callable[[Member, dict], None],
) -> str:
    """Run ``pending`` members, calling ``done(member, record)`` as each finishes.

    Returns a note on how the batched mode ran (empty for the other modes).
    """
    if mode == "sequential":
        for m in pending:
            done(m, execute_member(member_fn, m.data, m.resolved, window, run_dir(m)))
        return ""
    if mode == "batched":
        groups: dict[str, list[Member]] = {}
        for m in pending:
            groups.setdefault(json.dumps(_shape_key(m.resolved), sort_keys=True), []).append(m)
        if member_fn is not default_member_fn or window is not None:
            for group in groups.values():
                for m in group:
                    done(m, execute_member(member_fn, m.data, m.resolved, window, run_dir(m)))
            why = "a window search" if window is not None else "a runner other than the simulator"
            return (
                f"grouped sequential: {why} runs member after member, so each of the "
                f"{len(groups)} shape groups ran member after member"
            )
        return _run_batched(groups, run_dir, done)
    if mode == "dask":
        from distributed import as_completed

        futures = {
            client.submit(
                execute_member,
                member_fn,
                m.data,
                m.resolved,
                window,
                run_dir(m),
                key=f"dynslip-member-{m.fingerprint}",
                pure=False,
            ): m
            for m in pending
        }
        lost = []
        for fut in as_completed(futures):
            m = futures[fut]
            try:
                rec = fut.result()
            except Exception as err:  # noqa: BLE001 - a lost worker: not written, rerun on resume
                lost.append(f"{m.label}: {type(err).__name__}: {err}")
                continue
            done(m, rec)
        if lost:
            raise ComputationError(
                f"{len(lost)} members could not be run on the cluster (first: {lost[0]}); "
                "run the sweep again to resume"
            )
        return ""
    raise InputError(f"mode = {mode!r}: allowed: {', '.join(MODES)}")


# ---------------------------------------------------------------------------------------
# The batched runner: forming members in lockstep (dynslip.physics.batch.simulate_batch)

#: worker processes of the batched runner (each runs part of every group; "spawn": JAX and fork
#: do not mix). 1 runs every batch in this process. docs/sweeps.md has the measurement.
BATCH_WORKERS = min(2, os.cpu_count() or 1)
#: the fewest members a worker process is given (below it, a batch runs in this process)
MIN_MEMBERS_PER_WORKER = 2
#: the most members of one lockstep batch (None: a worker's whole share; 1: one after another;
#: "auto": 1 on the CPU, where lockstep costs more than it saves, None on an accelerator).
#: docs/sweeps.md has the measurement (64 members at 100 nodes: 3 min 51 s with 1 per batch;
#: still running after 11 min with a worker's whole share of 32 in one batch).
BATCH_SIZE: int | None | str = "auto"


def _batch_size() -> int | None:
    if BATCH_SIZE != "auto":
        return BATCH_SIZE
    import jax

    return 1 if jax.default_backend() == "cpu" else None


def _batchable(m: Member) -> bool:
    """A forming member that runs alone from the flat sheet (a ``start_from`` member first
    runs or reads another scenario: it runs as in ``sequential``)."""
    return m.resolved.get("kind") == "forming" and not m.resolved.get("start_from")


def _forming_outputs(sc, model, result, out: Path | None) -> dict:
    """What :func:`dynslip.app.forming.finish` makes of a lockstep member's result: the
    summary (raises :class:`ComputationError` for a failed run), with its files in ``out``
    when given (``keep_runs``; the figures too)."""
    from dynslip.analysis.summary import summarize
    from dynslip.app.forming import finish, to_dataset
    from dynslip.app.outputs import Outputs
    from dynslip.data import files as io

    names = [s.name for s in sc.physics.stages]
    rbar = np.asarray(model.mesh.rbar)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    if result.failed:
        where = out / "trajectory.nc" if out is not None else "<not kept: keep_runs is off>"
        if result.frames and out is not None:
            ds = to_dataset(sc, result.frames, rbar, result.e0, False, names)
            io.write_netcdf(ds, out / "trajectory.nc")
            io.write_json(out / "summary.json", summarize(sc, ds, result))
        raise ComputationError(f"{result.failed}; partial trajectory kept in {where}")
    return finish(sc, model, result, Outputs(out), names)


def run_forming_batch(
    datas: list[dict], run_dirs: list[str | None], batch_size: int | None = None
) -> list[dict]:
    """Forming members (scenario data) of one shape run in lockstep: one member record each,
    as :func:`execute_member` writes it (module level: it travels to worker processes).
    Members whose compiled solves differ (a float setting of the increment control, say)
    form separate batches, each of at most ``batch_size`` members (None: all)."""
    from dynslip.app.forming import build_core
    from dynslip.physics.batch import batch_key, simulate_batch
    from dynslip.schema.base import validate_data

    t0 = time.perf_counter()
    recs: list[dict | None] = [None] * len(datas)
    batches: dict[str, list] = {}
    for i, data in enumerate(datas):
        try:
            sc = validate_data(data, "<member>")
            core = build_core(sc)
            batches.setdefault(batch_key(*core), []).append((i, sc, core))
        except ComputationError as err:
            recs[i] = {"status": "failed", "error": f"ComputationError: {err}", "summary": {}}
        except Exception as err:  # noqa: BLE001 - a member's failure is data
            recs[i] = {"status": "error", "error": f"{type(err).__name__}: {err}", "summary": {}}
    size = batch_size or len(datas)
    chunks = [b[k : k + size] for b in batches.values() for k in range(0, len(b), size)]
    for batch in chunks:
        b0 = time.perf_counter()
        try:
            results = simulate_batch([c[0] for _, _, c in batch], [c[1] for _, _, c in batch],
                                     [c[2] for _, _, c in batch])
        except Exception as err:  # noqa: BLE001 - the whole batch failed (e.g. out of memory)
            for i, _, _ in batch:
                recs[i] = {
                    "status": "error",
                    "error": f"{type(err).__name__}: {err}",
                    "summary": {},
                }
            continue
        for (i, sc, core), result in zip(batch, results, strict=True):
            rec: dict[str, Any] = {"status": "ok", "error": "", "summary": {}}
            out = Path(run_dirs[i]) / "run" if run_dirs[i] else None
            try:
                rec["summary"] = _jsonable_summary(_forming_outputs(sc, core[0], result, out))
            except ComputationError as err:
                rec.update(status="failed", error=f"ComputationError: {err}")
            except Exception as err:  # noqa: BLE001
                rec.update(status="error", error=f"{type(err).__name__}: {err}")
            rec["wall_s"] = (time.perf_counter() - b0) / len(batch)  # the batch's time, shared
            recs[i] = rec
    for rec in recs:
        rec.setdefault("wall_s", (time.perf_counter() - t0) / len(datas))
    return recs


def _run_batched(groups: dict[str, list[Member]], run_dir, done) -> str:
    """``mode: batched``: each shape group of forming members through
    :func:`run_forming_batch`, split over :data:`BATCH_WORKERS` spawned processes when the
    group is large enough; other members run as in ``sequential``."""
    notes = []
    other = 0
    sizes = []
    batch_size = _batch_size()
    for group in groups.values():
        forming = [m for m in group if _batchable(m)]
        for m in group:
            if not _batchable(m):
                other += 1
                done(m, execute_member(default_member_fn, m.data, m.resolved, None, run_dir(m)))
        if not forming:
            continue
        n_work = max(1, min(BATCH_WORKERS, len(forming) // MIN_MEMBERS_PER_WORKER))
        parts = [forming[k::n_work] for k in range(n_work)]
        sizes.append("+".join(str(len(p)) for p in parts))
        dirs = {m.fingerprint: run_dir(m) for m in forming}
        if n_work == 1:
            recs = run_forming_batch(
                [m.data for m in forming], [dirs[m.fingerprint] for m in forming], batch_size
            )
            for m, rec in zip(forming, recs, strict=True):
                done(m, rec)
            continue
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(
            max_workers=n_work, mp_context=multiprocessing.get_context("spawn")
        ) as pool:
            futures = {
                pool.submit(
                    run_forming_batch,
                    [m.data for m in part],
                    [dirs[m.fingerprint] for m in part],
                    batch_size,
                ): part
                for part in parts
            }
            for fut in as_completed(futures):
                part = futures[fut]
                try:
                    recs = fut.result()
                except Exception as err:  # noqa: BLE001 - a lost worker: its members are errors
                    recs = [
                        {"status": "error", "error": f"{type(err).__name__}: {err}", "summary": {}}
                    ] * len(part)
                for m, rec in zip(part, recs, strict=True):
                    done(m, rec)
    if sizes:
        notes.append(
            f"lockstep batches (simulate_batch, one vmapped segment solve per save segment) of "
            f"{', '.join(sizes)} forming members in {len(sizes)} shape groups"
            + (f", at most {batch_size} per batch" if batch_size else "")
            + (f" on up to {BATCH_WORKERS} worker processes" if BATCH_WORKERS > 1 else "")
        )
    if other:
        notes.append(f"{other} members (not forming, or with start_from) ran member after member")
    return "batched: " + "; ".join(notes) if notes else "batched: nothing to run"


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
    console=None,
    member_fn: Callable | None = None,
    validate_fn: Callable | None = None,
    plot: bool = True,
    force: bool = False,
) -> dict:
    """``dynslip sweep SWEEP.yaml``: run every member not yet done, then assemble and plot.

    Writes ``<out>/members/*.json`` (one per member, as each finishes), ``<out>/sweep.nc``,
    ``<out>/sweep.png`` and ``<out>/summary.json``; returns the summary. Raises
    :class:`InputError` for a bad sweep file, member or scheduler (before anything runs),
    :class:`ComputationError` when every member failed. ``member_fn(data, out_dir,
    console) -> summary`` replaces the real simulator (tests, benchmarks). ``out`` must be
    new, empty or a dynslip result (a sweep resumes in it); ``force`` allows writing into
    another folder (never a file); checked before anything is created.
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from dynslip.data.files import provenance, write_json, write_netcdf
    from dynslip.data.folders import RESULT_MARKER, check_out, kept_on_error, write_result_marker

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
            client, cluster = _connect(scheduler)
            stack.callback(client.close)
            if cluster is not None:
                stack.callback(cluster.close)
        # the folder is made only now that the input (and the scheduler) has been checked
        from dynslip.data.lock import out_lock

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

        note = _run_members(
            pending,
            mode=mode,
            client=client,
            member_fn=member_fn,
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
                  unit_of=lambda k: "1" if k == BASE_KEY else _unit_of_field(k, members))
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
        from dynslip.plot.sweep import plot_sweep

        plot_sweep(ds, out / "sweep.png")
    console.print(
        f"sweep done: {summary['n_ok']} ok, {summary['n_failed']} failed; {out / 'sweep.nc'}"
    )
    if summary["n_ok"] == 0:
        raise ComputationError(
            f"{sweep}: every member failed (errors in {out / 'sweep.nc'}, variable 'error')"
        )
    return summary
