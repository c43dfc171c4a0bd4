r"""The diffrax driver of the whole-sheet forming model.

State vector (flat, float64; :class:`Layout` names the slices so that later issues can
append, e.g. a per-node slip distance):

- ``rho[1:N-1]`` and ``z[0:N-1]`` of the free nodes (the pole's $\rho_0 = 0$; node
  $N-1$ is moved by the clamp);
- ``zb``, the ball centre height;
- four accumulators integrated from their constitutive rates (physics.md Section 4,
  "Energy balance"): work of the clamp $\dot W_c = C\cdot\dot x_c$ with
  $C = \partial E/\partial x_c$ the clamp's force on the sheet; work of the hold and of
  gravity on the ball $\dot W_b = (F_h + F_g)\dot z_b$; drag dissipation
  $\sum_i \eta A_i|u_i|^2 + \eta_b\dot z_b^2$; friction dissipation
  $\sum_i (F_{t,i} - S_i)S_i/(\eta A_i) \ge 0$.

Ball: held ($\dot z_b$ prescribed, the hold supplies $F_h = \eta_b\dot z_b - C_z - F_g$)
or force-controlled ($F_h$ ramped, $\eta_b\dot z_b = F_h + C_z + F_g$): global balance
with the sheet's drag taken relative to the ball (:mod:`dynslip.physics.sheet`).

Energy balance: $W_c + W_b = \Delta(E_{el} + E_{pen}) + D_{drag} + D_{fric}$, with the
initial (pre-stretch) energy counted in $E(0)$.

Integration: load stepping (:mod:`dynslip.physics.newton`, the schema default) or a
stiff diffrax solver (Kvaerno5, the reference) with a PID controller, one stage at a time
(a restart at every stage boundary: the protocol's kinks), each stage run in save segments;
condition stops (clamp force below a threshold, rest) are
checked between segments, so their resolution is the save interval. The vector field
and the segment solve are jitted once per mesh size and shared by every run
(:func:`segment_solver`).

One driver for both solver families (:func:`drive`); the run's state machine
(:class:`MemberRun`: stage set-up, segments, recording and stop rules), which
:mod:`dynslip.physics.batch` steps in lockstep, lives in :mod:`dynslip.physics.member`. The
field, the solvers, the frames and the failures live in :mod:`dynslip.physics.field`,
:mod:`.solvers` (with :mod:`.loadstep` and :mod:`.newton`), :mod:`.frames` and
:mod:`.failures`; their names are also this module's, as before.
"""

from __future__ import annotations

import time as _time

import equinox as eqx
import jax
import numpy as np

from dynslip.physics.beside import Beside
from dynslip.physics.failures import (
    ContactUnresolved,
    NonFinite,
    RunFailure,
    SolverFailure,
    StepLimit,
)
from dynslip.physics.field import N_ACC, Layout, StageArgs, _f, vector_field
from dynslip.physics.frames import frame_record, initial_state
from dynslip.physics.member import MemberRun, Result, Segment, static_key
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel
from dynslip.physics.solvers import SOLVERS, Settings, TimeStepping, solver_for

__all__ = [
    "Layout",
    "StageArgs",
    "Settings",
    "SolverFailure",
    "RunFailure",
    "StepLimit",
    "NonFinite",
    "ContactUnresolved",
    "Result",
    "SOLVERS",
    "TimeStepping",
    "solver_for",
    "segment_solver",
    "segment_step",
    "compile_step",
    "COMPILER_OPTIONS",
    "LARGE_COMPILER_OPTIONS",
    "FAST_COMPILE_NODES",
    "simulate",
    "drive",
    "stack",
    "MemberRun",
    "Segment",
    "static_key",
    "initial_state",
    "vector_field",
    "frame_record",
    "N_ACC",
]


_SOLVE_CACHE: dict = {}
_COMPILED: dict = {}  # ahead-of-time compiled segment steps, keyed by everything static


def segment_solver(settings: Settings):
    """Jitted ``solve(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate=None) ->
    SegmentOutput`` of the solver object of ``settings`` (:func:`solver_for`); shared by every
    caller (compiled once per mesh size and material class)."""
    solver = solver_for(settings)
    if solver not in _SOLVE_CACHE:
        _SOLVE_CACHE[solver] = eqx.filter_jit(solver.segment)
    return _SOLVE_CACHE[solver]




#: XLA's compile options for the segment step of a mesh of at most :data:`FAST_COMPILE_NODES`
#: nodes: with the CPU backend's fusion emitters off the step compiles about 35% faster (the
#: main job's 8.8 -> 7.0 s of XLA, the let-go path's 6.5-7.2 -> 3.8-4.5 s) and runs up to about
#: 15% slower at 400 and 800 nodes (the same at 50-200, within the noise), so a small mesh's
#: run, which its compile dominates, takes them and a large one keeps XLA's defaults
#: (docs/speed.md, "fifth session"). By the mesh alone, so a run and a batch of the same mesh
#: compile alike and their iterates agree. A jaxlib that does not know an option compiles with
#: its defaults.
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
FAST_COMPILE_NODES = 200
#: ... and for a larger mesh: XLA's own default, asked for because the package turns the fusion
#: emitters off for every other program (:mod:`dynslip._jaxconfig`)
LARGE_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": True}


def compile_step(lowered, nodes: int, beside=()):
    """``lowered.compile()``, with :data:`COMPILER_OPTIONS` for a mesh of ``nodes`` <=
    :data:`FAST_COMPILE_NODES`, else :data:`LARGE_COMPILER_OPTIONS` (without them where this
    jaxlib refuses one). ``beside``: callables run in a thread meanwhile (:class:`_Beside`)."""
    with _Beside(beside):
        options = COMPILER_OPTIONS if nodes <= FAST_COMPILE_NODES else LARGE_COMPILER_OPTIONS
        try:
            return lowered.compile(compiler_options=options)
        except jax.errors.JaxRuntimeError as err:
            if "No such compile option" not in str(err):
                raise
            return lowered.compile()


class _Beside:
    """Run ``work`` (callables) in the process's worker thread (:class:`~.beside.Beside`) while
    the block runs, and wait for it at the block's end: what a run will do anyway after the
    step's compile (import the output libraries, compile the mesh check:
    :meth:`MemberRun.prepare`), done while XLA compiles the step, which releases the GIL and
    keeps about 1.5 of this machine's 2 cores busy (docs/speed.md, "sixth session": the main
    job cold about 1 s shorter). Only a warm-up: an error in ``work``
    is dropped, and the call it warmed raises it where it belongs."""

    def __init__(self, work):
        self.work = tuple(work)
        self.pending = None

    def _run(self):
        for w in self.work:
            try:
                w()
            except Exception:  # noqa: BLE001, S110 - a warm-up; the real call reports it
                pass

    def __enter__(self):
        if self.work:
            self.pending = Beside(self._run)
        return self

    def __exit__(self, *exc):
        if self.pending is not None:
            self.pending.result()
        return False


def _compiled(key, compile_fn, stats_list):
    """The ahead-of-time compiled step of ``key`` (compiled now, its time added to each stats'
    compile_s)."""
    if key not in _COMPILED:
        c0 = _time.perf_counter()
        _COMPILED[key] = compile_fn()
        for st in stats_list:
            st["compile_s"] += _time.perf_counter() - c0
    return _COMPILED[key]


_STEPS: dict = {}


def segment_step(solver, batched: bool = False):
    """Jitted ``step(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate, contact_threshold)
    -> (SegmentOutput, frame)``: one save segment of ``solver`` and the frame of its end state
    (:func:`frame_record` at ``t1``), in one program, so a segment costs one call and one
    transfer. ``batched``: vmapped over a leading member axis of every input but the layout
    (a model's float constants, such as Gent's J_m, broadcast)."""
    key = (solver, batched)
    if key not in _STEPS:

        def step(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate, contact_threshold):
            out = solver.segment(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate)
            return out, frame_record(model, layout, t1, out.y, args, contact_threshold,
                                     forces=out.forces, vb=out.ball_velocity)

        if batched:
            a = eqx.if_array(0)
            step = eqx.filter_vmap(step, in_axes=(a, None, a, a, a, a, a, a, a, a, a))
        _STEPS[key] = eqx.filter_jit(step)
    return _STEPS[key]


def stack(trees):
    """One pytree with the array leaves of ``trees`` stacked along a new first axis; the
    non-array parts must be equal (they are the compiled function's constants)."""
    dyn, static = zip(*(eqx.partition(t, eqx.is_array) for t in trees), strict=True)
    if any(repr(s) != repr(static[0]) for s in static[1:]):
        raise ValueError(
            "simulate_batch: members differ in a non-array part (an int, a string, a class): "
            f"{static[0]!r} vs {next(s for s in static[1:] if repr(s) != repr(static[0]))!r}"
        )
    stacked = jax.tree_util.tree_map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *dyn)
    return eqx.combine(stacked, static[0])


def drive(runs: list[MemberRun], beside=()) -> list[Result]:
    """The host loop of one run (``len(runs) == 1``: :func:`segment_step` as compiled) or of
    B members in lockstep (the step vmapped over them, one call per save segment for all:
    :mod:`dynslip.physics.batch`). Each tick asks every member for its next segment, solves
    them together, and hands each active member its output and frame
    (:meth:`MemberRun.advance`, :meth:`MemberRun.record`); the first tick is a zero-length
    segment per member, whose frame is the initial one. Raises ``ValueError`` when the
    members need different compiled steps (:func:`static_key`). ``beside``: the caller's
    work to run while the step compiles (:func:`compile_step`), after the members' own
    (:meth:`MemberRun.prepare`)."""
    first = runs[0]
    if any(r.key != first.key for r in runs[1:]):
        raise ValueError(
            "simulate_batch: the members need different compiled solves (solver settings, mesh "
            "size or a non-array part of the model); run them in separate batches"
        )
    batched = len(runs) > 1
    step = segment_step(first.solver, batched)
    layout = first.layout
    key = ("batch", len(runs), *first.key) if batched else first.key
    if batched:
        model = stack([r.model for r in runs])
        tol = (np.asarray([float(r.rtol) for r in runs]), np.asarray([float(r.atol) for r in runs]))
        thr = np.asarray([float(r.settings.contact_threshold) for r in runs])
    else:
        model, tol, thr = (
            first.model,
            (first.rtol, first.atol),
            _f(first.settings.contact_threshold),
        )
    while not all(r.done for r in runs):
        segs = [r.segment() for r in runs]
        if batched:
            seg = (
                np.stack([np.asarray(s.y) for s in segs]),
                np.asarray([s.t0 for s in segs]),
                np.asarray([s.t1 for s in segs]),
                np.asarray([s.dt0 for s in segs]),
                stack([s.args for s in segs]),
            )
            rate = jax.tree_util.tree_map(
                lambda *r: np.stack([np.asarray(x) for x in r]), *[s.rate for s in segs]
            )
        else:
            s = segs[0]
            seg, rate = (s.y, _f(s.t0), _f(s.t1), _f(s.dt0), s.args), s.rate
        inputs = (model, layout, *seg, *tol, rate, thr)
        active = [b for b, r in enumerate(runs) if not r.done]
        compiled = _compiled(
            key,
            lambda inputs=inputs: compile_step(
                step.lower(*inputs), layout.n, [r.prepare for r in runs] + list(beside)
            ),
            [runs[b].stats for b in active],
        )
        r0 = _time.perf_counter()
        out, frames = jax.device_get(compiled(*inputs))
        # the tick's time, shared by its active members
        run_s = (_time.perf_counter() - r0) / len(active)
        lockstep = int(np.max(out.steps))  # the tick's cost: the batch's largest increment count
        for b in active:
            r = runs[b]
            ob, fb = (
                (out, frames)
                if not batched
                else jax.tree_util.tree_map(lambda o, b=b: o[b], (out, frames))
            )
            if not r.frames:
                r.record(fb)
                continue
            if batched:
                r.stats["lockstep_steps"] = r.stats.get("lockstep_steps", 0) + lockstep
            if r.advance(segs[b], ob, run_s):
                r.record(fb)
    return [r.result() for r in runs]


def simulate(model: SheetModel, protocol: Protocol, **kwargs) -> Result:
    """Run ``protocol`` from a flat pre-stretched sheet (or from ``start``, a saved end
    state, see :func:`state_from`); return the saved frames.

    Keyword arguments: ``friction`` (an :class:`~dynslip.physics.friction.AbstractFriction`),
    ``eps``, ``drag``, ``ball_drag``, ``pre_stretch``, ``z_sheet``, and optionally ``weight``,
    ``settings`` (:class:`Settings`), ``on_frame`` (called with every frame), ``start`` and
    ``support_stiffness`` (:class:`MemberRun`); ``beside``: callables to run while the step
    compiles (:func:`drive`).

    Raises nothing on solver failure: the result's ``failed`` holds the message and
    ``frames`` what was computed before it (the runner turns it into exit 3). Many members
    of the same shape run in lockstep with :func:`dynslip.physics.batch.simulate_batch`.
    """
    beside = kwargs.pop("beside", ())
    return drive([MemberRun(model, protocol, **kwargs)], beside)[0]
