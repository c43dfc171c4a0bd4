r"""The diffrax driver of the whole-sheet forming model.

State vector (flat, float64; :class:`Layout` names the slices, and holds those after the
accumulators: the friction laws' per-node state and the free held bodies' heights):

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

Integration: load stepping (:mod:`dynslip.physics.solver.newton`, the schema default) or a
stiff diffrax solver (Kvaerno5, the reference) with a PID controller, one stage at a time
(a restart at every stage boundary: the protocol's kinks), each stage run in save segments;
condition stops (clamp force below a threshold, rest) are
checked between segments, so their resolution is the save interval. The vector field
and the segment step are jitted once per solver and shared by every run
(:func:`segment_step`), and compiled once per static key (:func:`_compiled`).

One driver for both solver families (:func:`drive`); the run's state machine
(:class:`~dynslip.physics.driver.member.MemberRun`: stage set-up, segments, recording and stop
rules), which :mod:`dynslip.physics.driver.batch` steps in lockstep, lives in
:mod:`dynslip.physics.driver.member`. The field, the solvers, the frames and the failures live
in :mod:`dynslip.physics.field`, :mod:`dynslip.physics.solver` (:mod:`~.solver.methods`,
:mod:`~.solver.loadstep`, :mod:`~.solver.newton`), :mod:`dynslip.physics.frames` and
:mod:`.failures`.
"""

from __future__ import annotations

import functools
import time as _time
from collections import OrderedDict
from typing import NamedTuple

import equinox as eqx
import jax
import numpy as np

from dynslip.physics.driver.member import MemberRun, Result
from dynslip.physics.frames import frame_record
from dynslip.physics.layout import f64
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel
from dynslip.physics.solver.newton import SegmentOutput

__all__ = [
    "COMPILER_OPTIONS",
    "FAST_COMPILE_NODES",
    "LARGE_COMPILER_OPTIONS",
    "StepOutput",
    "compile_step",
    "drive",
    "segment_step",
    "simulate",
    "stack",
]

#: How many compiled segment steps (and jitted step functions) a process keeps: a run needs one,
#: a lockstep batch of a sweep two per distinct static key (its full batches and the last,
#: smaller one). An evicted one is compiled again (or read from the persistent compilation
#: cache) when it is asked for again: the same program, the same numbers.
CACHE_SIZE = 8


#: XLA's compile options for the segment step of a mesh of at most :data:`FAST_COMPILE_NODES`
#: nodes: with the CPU backend's fusion emitters off the step compiles about 35% faster (the
#: main job's 8.8 -> 7.0 s of XLA, the let-go path's 6.5-7.2 -> 3.8-4.5 s) and runs up to about
#: 15% slower at 400 and 800 nodes (the same at 50-200, within the noise), so a small mesh's
#: run, which its compile dominates, takes them and a large one keeps XLA's defaults
#: (docs/speed.md). By the mesh alone, so a run and a batch of the same mesh compile alike and
#: their iterates agree. A jaxlib that does not know an option compiles with its defaults.
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
FAST_COMPILE_NODES = 200
#: ... and for a larger mesh: XLA's own default, asked for because the package turns the fusion
#: emitters off for every other program (:mod:`dynslip._jaxconfig`)
LARGE_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": True}


def compile_step(lowered, nodes: int):
    """``lowered.compile()``, with :data:`COMPILER_OPTIONS` for a mesh of ``nodes`` <=
    :data:`FAST_COMPILE_NODES`, else :data:`LARGE_COMPILER_OPTIONS` (without them where this
    jaxlib refuses one)."""
    options = COMPILER_OPTIONS if nodes <= FAST_COMPILE_NODES else LARGE_COMPILER_OPTIONS
    try:
        return lowered.compile(compiler_options=options)
    except jax.errors.JaxRuntimeError as err:
        if "No such compile option" not in str(err):
            raise
        return lowered.compile()


#: The ahead-of-time compiled segment steps, least recently used first, keyed by
#: :func:`~dynslip.physics.driver.member.static_key` (and, for a batch, its size): at most
#: :data:`CACHE_SIZE`.
_COMPILED: OrderedDict = OrderedDict()


def _compiled(key, compile_fn, stats_list):
    """The ahead-of-time compiled step of ``key`` (compiled now where it is not kept, its time
    added to each stats' compile_s; the least recently used one dropped past
    :data:`CACHE_SIZE`)."""
    if key in _COMPILED:
        _COMPILED.move_to_end(key)
        return _COMPILED[key]
    c0 = _time.perf_counter()
    compiled = compile_fn()
    for st in stats_list:
        st["compile_s"] += _time.perf_counter() - c0
    _COMPILED[key] = compiled
    if len(_COMPILED) > CACHE_SIZE:
        _COMPILED.popitem(last=False)
    return compiled


class StepOutput(NamedTuple):
    """What the compiled segment step returns: the solver's ``segment`` output and the
    ``frame`` of its end state (:func:`frame_record`)."""

    segment: SegmentOutput
    frame: dict


@functools.lru_cache(maxsize=CACHE_SIZE)
def segment_step(solver, batched: bool = False):
    """Jitted ``step(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate, contact_threshold)
    -> StepOutput``: one save segment of ``solver`` and the frame of its end state
    (:func:`frame_record` at ``t1``), in one program, so a segment costs one call and one
    transfer. ``batched``: vmapped over a leading member axis of every input but the layout
    (a model's float constants, such as Gent's J_m, broadcast). Kept for the :data:`CACHE_SIZE`
    solvers last asked for (a solver object is hashed and compared by its fields)."""

    def step(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate, contact_threshold):
        out = solver.segment(model, layout, y0, t0, t1, dt0, args, rtol, atol, rate)
        return StepOutput(out, frame_record(model, layout, t1, out.y, args, contact_threshold,
                                            forces=out.forces, vb=out.ball_velocity))

    if batched:
        a = eqx.if_array(0)
        step = eqx.filter_vmap(step, in_axes=(a, None, a, a, a, a, a, a, a, a, a))
    return eqx.filter_jit(step)


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


def drive(runs: list[MemberRun]) -> list[Result]:
    """The host loop of one run (``len(runs) == 1``: :func:`segment_step` as compiled) or of
    B members in lockstep (the step vmapped over them, one call per save segment for all:
    :mod:`dynslip.physics.driver.batch`). Each tick asks every member for its next segment, solves
    them together, and hands each active member its output and frame
    (:meth:`MemberRun.advance`, :meth:`MemberRun.record`); the first tick is a zero-length
    segment per member, whose frame is the initial one. Raises ``ValueError`` when the
    members need different compiled steps (:func:`~dynslip.physics.driver.member.static_key`)."""
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
            f64(first.settings.contact_threshold),
        )
    while not all(r.done for r in runs):
        segs = [r.segment() for r in runs]
        seg: tuple
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
            seg, rate = (s.y, f64(s.t0), f64(s.t1), f64(s.dt0), s.args), s.rate
        inputs = (model, layout, *seg, *tol, rate, thr)
        active = [b for b, r in enumerate(runs) if not r.done]
        compiled = _compiled(
            key,
            lambda inputs=inputs: compile_step(step.lower(*inputs), layout.n),
            [runs[b].stats for b in active],
        )
        r0 = _time.perf_counter()
        got = jax.device_get(compiled(*inputs))
        # the tick's time, shared by its active members
        run_s = (_time.perf_counter() - r0) / len(active)
        # the tick's cost: the batch's largest increment count
        lockstep = int(np.max(got.segment.steps))
        for b in active:
            r = runs[b]
            own = got if not batched else jax.tree_util.tree_map(lambda o, b=b: o[b], got)
            if not r.frames:
                r.record(own.frame)
                continue
            if batched:
                r.stats["lockstep_steps"] = r.stats.get("lockstep_steps", 0) + lockstep
            if r.advance(segs[b], own.segment, run_s):
                r.record(own.frame)
    return [r.result() for r in runs]


def simulate(model: SheetModel, protocol: Protocol, **kwargs) -> Result:
    """Run ``protocol`` from a flat pre-stretched sheet (or from ``start``, a saved end
    state, see :func:`~dynslip.physics.frames.state_from`); return the saved frames.

    Keyword arguments: ``friction`` (an :class:`~dynslip.physics.friction.AbstractFriction`),
    ``eps``, ``drag``, ``ball_drag``, ``pre_stretch``, ``z_sheet``, and optionally ``weight``,
    ``settings`` (:class:`~dynslip.physics.solver.methods.Settings`), ``on_frame`` (called with
    every
    frame), ``start`` and ``support_stiffness`` (:class:`~dynslip.physics.driver.member.MemberRun`).

    Raises nothing on solver failure: the result's ``failed`` holds the message and
    ``frames`` what was computed before it (the runner turns it into exit 3). Many members
    of the same shape run in lockstep with :func:`dynslip.physics.driver.batch.simulate_batch`.
    """
    return drive([MemberRun(model, protocol, **kwargs)])[0]
