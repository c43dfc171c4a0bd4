"""Runner of ``kind: forming`` scenarios: core objects, progress bar, trajectory.nc, summary,
figures.

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

import jax.numpy as jnp
import numpy as np

from dynslip.app.endtable import print_end_table
from dynslip.app.outputs import Outputs
from dynslip.data import files as io
from dynslip.data import trajectory
from dynslip.errors import PARTIAL_KEPT, ComputationError

__all__ = ["run_forming", "resolve_start", "build_core", "finish", "to_dataset", "FLUSH_FRAMES"]

FLUSH_FRAMES = 25


def build_core(sc):
    """(model, protocol, simulate kwargs) of a validated scenario: the core knows no pydantic."""
    from dynslip.physics.bodies.held import Held
    from dynslip.physics.protocols import ball_drag_coefficient
    from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
    from dynslip.physics.solvers import Settings
    from dynslip.schema.forming import build_protocol

    p, nu = sc.physics, sc.numerics
    r = p.ball_radius_mm
    m = p.material
    material = m.core()
    r_edge = p.rim_radius_mm / r / p.pre_stretch
    mesh = make_mesh(nu.nodes, r_edge, nu.mesh_grading, nu.edge_grading)
    # pressures in kPa per unit of G h0 / R (a pressure-dependent law's scale)
    kpa = 1e3 * p.force_scale_N / r**2
    moved = set(p.moved_names())
    # a free body: its applied force in G h0 R, its drag as the ball's (eta_b of its multiple)
    free = {
        b.name: dict(free=True, force=jnp.asarray((b.force_N or 0.0) / p.force_scale_N),
                     drag=jnp.asarray(ball_drag_coefficient(nu.drag_time_s,
                                                            1.0 if b.drag is None else b.drag)))
        for b in p.bodies if b.motion == "free"
    }
    bodies = tuple(
        Held(body, law.build(r, nu.friction_smoothing, kpa),
             moves_with_ball=with_ball, stage=name in moved, **free.get(name, {}))
        for name, body, with_ball, law in p.held_specs()
    )
    g_h0 = p.force_scale_N / r  # N/mm
    model = SheetModel(
        mesh,
        material,
        Penalty(jnp.asarray(nu.penalty_stiffness), jnp.asarray(nu.penalty_width)),
        ball=p.ball_body(),
        bodies=bodies,
        band_grip=jnp.asarray(p.band_grip_N_per_mm / g_h0),
    )
    protocol = build_protocol(sc)
    weight = -(p.ball_mass_g * 1e-3 * 9.81) / p.force_scale_N if p.gravity else 0.0
    settings = Settings(
        solver=nu.solver,
        rtol=nu.rtol,
        atol=nu.atol,
        pcoeff=nu.pid_pcoeff,
        icoeff=nu.pid_icoeff,
        max_steps=nu.max_steps,
        save_interval=nu.save_interval_s,
        linear_solver=nu.linear_solver,
        contact_threshold=nu.contact_threshold,
        heal_rate=nu.heal_rate_mm_s / r,
        max_increment=nu.max_increment,
        max_increment_free=nu.max_increment_free,
        newton_max_iter=nu.newton_max_iter,
        newton_backtrack=nu.newton_backtrack,
        newton_weight=nu.newton_weight,
        max_chord_depth=nu.max_chord_depth,
        body_names=tuple(name for name, *_ in p.named_bodies()),
    )
    kwargs = dict(
        friction=p.friction.build(r, nu.friction_smoothing, kpa),
        eps=nu.friction_smoothing,
        drag=nu.drag_time_s,
        ball_drag=ball_drag_coefficient(nu.drag_time_s, nu.ball_drag),
        pre_stretch=p.pre_stretch,
        z_sheet=p.sheet_start_mm / r,
        weight=weight,
        settings=settings,
        support_stiffness=nu.support_stiffness,
    )
    return model, protocol, kwargs


def to_dataset(sc, frames, rbar, e0, complete: bool, stage_names, extra_attrs=None):
    """The trajectory contract from the driver's frames
    (:func:`dynslip.data.trajectory.frames_to_dataset`), handed the scenario's values as plain
    data."""
    p = sc.physics
    f = p.friction
    mu_s, mu_k, d_c_mm = f.static_kinetic()
    return trajectory.frames_to_dataset(
        frames,
        rbar,
        e0,
        complete,
        stage_names,
        scenario_json=sc.to_json(),
        scales={
            "R_m": p.ball_radius_mm * 1e-3,
            "G_Pa": p.youngs_modulus_MPa * 1e6 / 3.0,
            "h0_m": p.thickness_um * 1e-6,
            "force_scale_N": p.force_scale_N,
        },
        contact_threshold=sc.numerics.contact_threshold,
        friction={
            "mu": f.nominal_mu,
            "friction_law": f.law,
            "mu_s": mu_s,
            "mu_k": mu_k,
            "d_c": d_c_mm / p.ball_radius_mm,
        },
        friction_smoothing=sc.numerics.friction_smoothing,
        extra_attrs=extra_attrs,
        body_names=[name for name, *_ in p.named_bodies()] or None,
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


def resolve_start(sc, console=None):
    """Resolve and check ``sc.start_from`` (running its scenario first when needed) before any
    output is written; bad input raises :class:`dynslip.errors.InputError`. Returns (start
    state, provenance), or None without ``start_from``; kept on the scenario for the run."""
    from dynslip.app.sizes import check_forming

    check_forming(sc)  # a run that would not fit in memory is refused before it starts
    if sc.start_from and sc._start is None:
        from dynslip.app.release import load_start

        sc._start = load_start(sc, console, run=run_forming)
    return sc._start


def run_forming(sc, out, console=None) -> dict:
    """Run a forming scenario into ``out`` (a folder, or :class:`dynslip.app.outputs.Outputs`:
    in memory without a folder); return the summary (raises ComputationError on failure)."""
    from rich.console import Console

    from dynslip.errors import MaterialRangeError  # noqa: F401  (documented error type)
    from dynslip.physics.simulate import simulate

    console = console or Console(stderr=True)
    outs = Outputs.of(out)
    if outs.writes:
        outs.folder.mkdir(parents=True, exist_ok=True)
    model, protocol, kw = build_core(sc)
    start, start_info = resolve_start(sc, console) or (None, None)
    names = protocol.names
    rbar = np.asarray(model.mesh.rbar)
    total = sum(s.max_duration for s in protocol.stages)
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
        ds = to_dataset(sc, frames, rbar, e0, complete, names, start_info)
        outs.netcdf(ds, "trajectory.nc")
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
            result = simulate(model, protocol, on_frame=on_frame, start=start, **kw)
    except BaseException:  # interrupted (SIGINT, SIGTERM) or any error: keep what was computed
        try:
            flush(frames_seen)
        except Exception:  # noqa: BLE001 - the original error is the one to report
            pass
        raise
    if result.failed:
        ds = flush(result.frames)
        if ds is not None:
            from dynslip.analysis.summary import summarize

            outs.json(summarize(sc, ds, result))
        raise ComputationError(
            f"{result.failed}{PARTIAL_KEPT}{outs.where('trajectory.nc')}"
        )
    summary = finish(sc, model, result, outs, names, start_info)
    print_end_table(console, summary)
    return summary


def finish(sc, model, result, outs: Outputs, names, start_info=None) -> dict:
    """What a forming run makes of the driver's finished result (a single run's or a member's
    of a lockstep batch): the trajectory checked against its contract, the summary (with the
    release metrics of a ``start_from`` run), the figures where ``outs`` writes; returns the
    summary."""
    from dynslip.analysis.summary import summarize
    from dynslip.plot.forming import make_figures

    rbar = np.asarray(model.mesh.rbar)
    ds = to_dataset(sc, result.frames, rbar, result.e0, True, names, start_info)
    io.check_units(ds)
    outs.netcdf(ds, "trajectory.nc")
    summary = summarize(sc, ds, result)
    if start_info is not None:
        from dynslip.analysis.release import release_metrics
        from dynslip.plot.release import plot_release

        summary["start"] = start_info
        summary["release"] = release_metrics(ds, model)
        ramp = summary["release"].get("force_ramp")
        # the sweep's variable (N): the ramped force at tear-out where measured so, else the peak
        summary["release_force"] = (ramp["release_force_N"] if ramp is not None
                                    else summary["release"]["peak_force_N"])
        if outs.writes:
            plot_release(ds, summary["release"], outs.folder)
    outs.json(summary)
    if outs.writes:
        make_figures(ds, outs.folder, summary.get("outcome"), _drawn_ball(model.ball))
        if model.bodies:
            _world_figure(sc, ds, model, outs, summary.get("outcome"))
    return summary


def _drawn_ball(ball):
    """The ball's body for the figures: None for the unit sphere (drawn as a circle)."""
    from dynslip.physics.bodies import Sphere

    return None if isinstance(ball, Sphere) and ball.is_unit else ball


def _world_figure(sc, ds, model, outs: Outputs, outcome) -> None:
    """``world.png``: the meridian with the ball and every held body (the tube's wall, the
    bottle), at the widest contact of the run and at its end."""
    import textwrap

    from dynslip.data.files import save_figure
    from dynslip.physics.bodies.held import held_entries
    from dynslip.plot.world import plot_world

    entries = held_entries(model.bodies)
    moves = [e.moves_with_ball or e.stage or e.free for e in entries]
    held = [e.body for e, m in zip(entries, moves, strict=True) if not m]
    # every moving body at its saved displacement (the ball's height for the bottle)
    moved = [(e.body, ds["body_z"].values[:, k]) for k, (e, m) in
             enumerate(zip(entries, moves, strict=True)) if m]
    theta = ds["theta_max"].values
    widest = int(np.nanargmax(theta)) if np.isfinite(theta).any() else 0
    last = ds.sizes["time"] - 1
    # the deepest push (the sheet's edge lowest, or the ball highest relative to it: the
    # tube's bottom), the widest contact and the end: the pocket's making
    depth = ds["ball_z"].values - ds["z"].values[:, -1]
    deep = int(np.argmax(depth))
    # halfway back from the deepest push: the lip and the neck under the ball while it refills
    after = np.arange(depth.size) >= deep
    half = int(np.argmin(np.where(after, np.abs(depth - 0.5 * (depth[deep] + depth[last])),
                                  np.inf)))
    frames: dict = {}
    for label, i in (("deepest push", deep), ("halfway back", half),
                     ("widest contact", widest), ("end", last)):
        if i not in frames.values():
            frames[label] = i
    end = "\n".join(textwrap.wrap(f"end: {outcome}", 55))
    zb = float(ds["ball_z"].values[last])
    fig = plot_world(ds, frames, held=held, moved=moved, limits=None,
                     ball=_drawn_ball(model.ball), zoom=((0.0, 2.8), (zb - 2.2, zb + 1.4)),
                     title=f"{sc.name} (N = {ds.sizes['rbar']})\n{end}")
    save_figure(fig, outs.folder / "world.png", dpi=120)
