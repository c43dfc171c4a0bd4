"""How the members of a sweep run (:mod:`dynslip.app.sweep` expands and assembles them).

Runners (``mode``):

- ``sequential``: one member after another in this process.
- ``batched``: members grouped by shape (same structure, integers and strings of the
  resolved scenario; only floats differ, so members differing in the mesh, the material
  model or the friction law fall in different groups). A group of forming members runs
  through :func:`dynslip.physics.driver.batch.simulate_batch` (:func:`run_forming_batch`):
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
import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

from dynslip.analysis.summary import summarize
from dynslip.app.forming import finish, to_dataset
from dynslip.app.members import Member
from dynslip.app.outputs import Outputs
from dynslip.app.window import scenario_window
from dynslip.data import files as io
from dynslip.data.files import jsonable
from dynslip.data.trajectory import TRAJECTORY_FILE
from dynslip.errors import PARTIAL_KEPT, ComputationError, InputError
from dynslip.physics.driver.batch import batch_key, simulate_batch
from dynslip.schema.paths import get_path
from dynslip.schema.sweep import friction_field

MODES = ("sequential", "batched", "dask")
#: seconds to wait for a dask scheduler given by address
CONNECT_TIMEOUT_S = 10.0


# ---------------------------------------------------------------------------------------
# Running one member (module level: it travels to dask workers)


def _jsonable_summary(summary: dict) -> dict:

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


def connect_client(scheduler: str | None, timeout: float | None = None):
    """A dask client: to ``scheduler`` (waiting ``timeout`` s for it, default
    :data:`CONNECT_TIMEOUT_S`), or to a new LocalCluster on loopback."""
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
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    try:
        return Client(scheduler, timeout=timeout), None
    except Exception as err:  # noqa: BLE001 - OSError, TimeoutError, ValueError for a bad address
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise InputError(
            f"--scheduler {scheduler!r}: cannot reach a dask scheduler within "
            f"{timeout:g} s "
            f"({reason[:120]}); give an address like tcp://HOST:8786"
        ) from None


def run_members(
    pending: list[Member],
    *,
    mode: str,
    client,
    member_fn: Callable,
    simulator: bool,
    window: dict | None,
    run_dir: Callable[[Member], str | None],
    done: Callable[[Member, dict], None],
) -> str:
    """Run ``pending`` members, calling ``done(member, record)`` as each finishes.
    ``simulator``: ``member_fn`` is the simulator's own runner (only then may forming members
    run in lockstep).

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
        if not simulator or window is not None:
            for group in groups.values():
                for m in group:
                    done(m, execute_member(member_fn, m.data, m.resolved, window, run_dir(m)))
            why = "a window search" if window is not None else "a runner other than the simulator"
            return (
                f"grouped sequential: {why} runs member after member, so each of the "
                f"{len(groups)} shape groups ran member after member"
            )
        return _run_batched(groups, member_fn, run_dir, done)
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
# The batched runner: forming members in lockstep (dynslip.physics.driver.batch.simulate_batch)

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
        return cast("int | None", BATCH_SIZE)  # "auto" is its one text
    import jax

    return 1 if jax.default_backend() == "cpu" else None


def _batchable(m: Member) -> bool:
    """A forming member that runs alone from the flat sheet (a ``start_from`` member first
    runs or reads another scenario: it runs as in ``sequential``)."""
    return m.resolved.get("kind") == "forming" and not m.resolved.get("start_from")


def _forming_outputs(world, result, out: Path | None) -> dict:
    """What :func:`dynslip.app.forming.finish` makes of a lockstep member's result: the
    summary (raises :class:`ComputationError` for a failed run), with its files in ``out``
    when given (``keep_runs``; the figures too)."""

    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    if result.failed:
        where = out / TRAJECTORY_FILE if out is not None else "<not kept: keep_runs is off>"
        if result.frames and out is not None:
            ds = to_dataset(world, result.frames, result.e0, False)
            io.write_netcdf(ds, out / TRAJECTORY_FILE)
            io.write_json(out / "summary.json", summarize(world, ds, result))
        raise ComputationError(f"{result.failed}{PARTIAL_KEPT}{where}")
    return finish(world, result, Outputs(out))


def run_forming_batch(
    datas: list[dict], run_dirs: list[str | None], batch_size: int | None = None
) -> list[dict]:
    """Forming members (scenario data) of one shape run in lockstep: one member record each,
    as :func:`execute_member` writes it (module level: it travels to worker processes).
    Members whose compiled solves differ (a float setting of the increment control, say)
    form separate batches, each of at most ``batch_size`` members (None: all)."""
    # at call time: the tests replace it in its home module
    from dynslip.schema.base import validate_data

    t0 = time.perf_counter()
    recs: list[dict | None] = [None] * len(datas)
    batches: dict[tuple, list] = {}
    for i, data in enumerate(datas):
        try:
            world = validate_data(data, "<member>").world()
            core = (world.model, world.protocol, world.simulate_kwargs())
            batches.setdefault(batch_key(*core), []).append((i, world, core))
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
        for (i, world, _), result in zip(batch, results, strict=True):
            rec: dict[str, Any] = {"status": "ok", "error": "", "summary": {}}
            out = Path(run_dirs[i]) / "run" if run_dirs[i] else None
            try:
                rec["summary"] = _jsonable_summary(_forming_outputs(world, result, out))
            except ComputationError as err:
                rec.update(status="failed", error=f"ComputationError: {err}")
            except Exception as err:  # noqa: BLE001
                rec.update(status="error", error=f"{type(err).__name__}: {err}")
            rec["wall_s"] = (time.perf_counter() - b0) / len(batch)  # the batch's time, shared
            recs[i] = rec
    # every member has its record: its batch's, or its validation's failure
    done = cast("list[dict]", recs)
    for member_rec in done:
        member_rec.setdefault("wall_s", (time.perf_counter() - t0) / len(datas))
    return done


def _run_batched(groups: dict[str, list[Member]], member_fn, run_dir, done) -> str:
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
                done(m, execute_member(member_fn, m.data, m.resolved, None, run_dir(m)))
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
