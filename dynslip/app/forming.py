"""Runner of ``kind: forming`` scenarios, in five steps: the world built once from the
scenario (:func:`prepare`: :class:`dynslip.schema.world.World`, with its memory checked and its
``start_from`` resolved), simulated under a progress bar, written (trajectory.nc), summarised
(summary.json, the end table) and drawn. After :func:`prepare` nothing reads the scenario.

The CLI hands :func:`run_forming` its staging folder and swaps it in on success. The trajectory
is rewritten (atomically, ``complete = 0``) every ``FLUSH_FRAMES`` frames, so a run killed
outright leaves a readable partial file, and a run whose final write fails (a full disk) keeps
the last one (tests/test_faults.py); an interrupted run (SIGINT, SIGTERM, any error) writes what
it has before it stops, and a failed run writes what it has and raises
:class:`dynslip.errors.ComputationError` (exit 3). By frames, not by wall time: the main job's
three partial writes cost about 0.6 s of its cold run, but a short run's earlier flush is what a
failed final write keeps (docs/speed.md).
"""

from __future__ import annotations

import numpy as np

from dynslip.analysis.release import release_metrics
from dynslip.analysis.summary import summarize
from dynslip.app.endtable import print_end_table
from dynslip.app.outputs import Outputs
from dynslip.app.release import load_start
from dynslip.app.sizes import check_forming
from dynslip.data import files as io
from dynslip.data import trajectory
from dynslip.errors import PARTIAL_KEPT, ComputationError
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.observables import OBS_RBAR, theta_key
from dynslip.plot.forming import make_figures
from dynslip.plot.release import plot_release
from dynslip.plot.world import drawn_ball, world_figure

__all__ = ["run_forming", "prepare", "build_core", "finish", "to_dataset", "FLUSH_FRAMES"]

FLUSH_FRAMES = 25


def build_core(sc):
    """(model, protocol, simulate kwargs) of a validated scenario's world
    (:meth:`~dynslip.schema.forming.FormingScenario.world`), for a caller that drives
    :func:`dynslip.physics.driver.simulate.simulate` itself."""
    world = sc.world()
    return world.model, world.protocol, world.simulate_kwargs()


def to_dataset(world, frames, e0, complete: bool):
    """The trajectory contract from the driver's frames
    (:func:`dynslip.data.trajectory.frames_to_dataset`), with the world's scales, friction,
    bodies and provenance (the start's too)."""
    f = world.friction
    return trajectory.frames_to_dataset(
        frames,
        np.asarray(world.model.mesh.rbar),
        e0,
        complete,
        world.stage_names,
        scenario_json=world.scenario_json,
        scales=world.scales.attrs,
        contact_threshold=world.limits.contact_threshold,
        friction={
            "mu": f["mu"],
            "friction_law": f["friction_law"],
            "mu_s": f["mu_s"],
            "mu_k": f["mu_k"],
            "d_c": f["d_c_mm"] / world.scales.R_mm,
        },
        friction_smoothing=world.limits.friction_smoothing,
        extra_attrs=world.start_info,
        body_names=world.body_names or None,
        rbar_at={theta_key(r): r for r in OBS_RBAR},
    )


def _progress(console, total):
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    prog = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("t = {task.fields[t]:.1f} s"),
        TimeElapsedColumn(),
        console=console,
        transient=False,
    )
    return prog, prog.add_task("compiling", total=total, t=0.0)


def prepare(sc, console=None):
    """The world of ``sc`` (:meth:`~dynslip.schema.forming.FormingScenario.world`), checked
    before any output is written: a run that would not fit in memory is refused, and
    ``start_from`` is resolved (its scenario run first when needed) into the world's start;
    bad input raises :class:`dynslip.errors.InputError`."""

    world = sc.world()
    check_forming(world)
    if world.start_from:
        world = world.with_start(load_start(sc, console, run=run_forming))
    return world


def run_forming(sc, out, console=None, world=None) -> dict:
    """Run a forming scenario into ``out`` (a folder, or :class:`dynslip.app.outputs.Outputs`:
    in memory without a folder); return the summary (raises ComputationError on failure).
    ``world``: the scenario's world as :func:`prepare` made it (made here when None)."""
    from rich.console import Console


    console = console or Console(stderr=True)
    outs = Outputs.of(out)
    if outs.writes:
        outs.folder.mkdir(parents=True, exist_ok=True)
    world = world if world is not None else prepare(sc, console)
    names = world.stage_names
    total = sum(s.max_duration for s in world.protocol.stages)
    frames_seen: list = []
    prog, task = _progress(console, total)
    state = {"e0": None}

    def flush(frames, complete=False):
        if not frames:
            return
        e0 = (
            state["e0"]
            if state["e0"] is not None
            else float(frames[0]["energy_elastic"] + frames[0]["energy_penalty"])
        )
        ds = to_dataset(world, frames, e0, complete)
        outs.netcdf(ds, trajectory.TRAJECTORY_FILE)
        return ds

    def on_frame(rec):
        frames_seen.append(rec)
        if len(frames_seen) == 1:
            state["e0"] = float(rec["energy_elastic"] + rec["energy_penalty"])
        prog.update(
            task,
            completed=min(rec["time"], total),
            t=rec["time"],
            description=f"{names[int(rec['stage'])]} ({int(rec['stage']) + 1}/{len(names)})",
        )
        if outs.writes and len(frames_seen) % FLUSH_FRAMES == 0:  # a readable partial file
            flush(list(frames_seen))

    try:
        with prog:
            result = simulate(world.model, world.protocol, on_frame=on_frame,
                              **world.simulate_kwargs())
    except BaseException:  # interrupted (SIGINT, SIGTERM) or any error: keep what was computed
        try:
            flush(frames_seen)
        except Exception:  # noqa: BLE001 - the original error is the one to report
            pass
        raise
    if result.failed:
        ds = flush(result.frames)
        if ds is not None:

            outs.json(summarize(world, ds, result))
        raise ComputationError(
            f"{result.failed}{PARTIAL_KEPT}{outs.where(trajectory.TRAJECTORY_FILE)}"
        )
    summary = finish(world, result, outs)
    print_end_table(console, summary)
    return summary


def finish(world, result, outs: Outputs) -> dict:
    """What a forming run makes of the driver's finished result (a single run's or a member's
    of a lockstep batch): the trajectory checked against its contract, the summary (with the
    release metrics of a ``start_from`` run), the figures where ``outs`` writes; returns the
    summary."""

    ds = to_dataset(world, result.frames, result.e0, True)
    io.check_units(ds)
    outs.netcdf(ds, trajectory.TRAJECTORY_FILE)
    summary = summarize(world, ds, result)
    if world.start_info is not None:

        summary["start"] = world.start_info
        summary["release"] = release_metrics(ds, world.model)
        ramp = summary["release"].get("force_ramp")
        # the sweep's variable (N): the ramped force at tear-out where measured so, else the peak
        summary["release_force"] = (ramp["release_force_N"] if ramp is not None
                                    else summary["release"]["peak_force_N"])
        if outs.writes:
            plot_release(ds, summary["release"], outs.folder)
    outs.json(summary)
    if outs.writes:
        make_figures(ds, outs.folder, summary.get("outcome"), drawn_ball(world.ball))
        if world.model.bodies:
            io.save_figure(world_figure(ds, world, summary.get("outcome")),
                           outs.folder / "world.png", dpi=120)
    return summary
