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

Longer than 400 lines: one driver for both solver families, with the run's state machine
(:class:`MemberRun`: stage set-up, segments, recording and stop rules) that
:mod:`dynslip.physics.batch` steps in lockstep. The field, the solvers, the frames and the
failures live in :mod:`dynslip.physics.field`, :mod:`.solvers` (with :mod:`.loadstep` and
:mod:`.newton`), :mod:`.frames` and :mod:`.failures`; their names are also this module's, as
before.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.chords import deepest_chord_in
from dynslip.physics.bodies.held import held_entries, n_free, n_memory, stage_moved
from dynslip.physics.failures import (
    ContactUnresolved,
    NonFinite,
    RunFailure,
    SolverFailure,
    StepLimit,
)
from dynslip.physics.field import (
    N_ACC,
    N_ACC_MOVED,
    Layout,
    StageArgs,
    _f,
    vector_field,
)
from dynslip.physics.frames import frame_record, initial_state, state_from
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.newton import zero_rate
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel, deepest_chord
from dynslip.physics.solvers import SOLVERS, Settings, TimeStepping, _counts_newton, solver_for

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


@dataclasses.dataclass
class Result:
    frames: list  # dicts of numpy arrays (see frame_record) plus "time", "stage"
    stage_end: list  # per stage: dict(name, t_start, t_end, condition_met)
    stats: dict
    failed: str | None = None
    e0: float = 0.0
    failure: RunFailure | None = None  # the failure with its quantities (failed is its message)


def _stage_args(
    stage,
    t0,
    zb0,
    f_start,
    fc_start,
    friction,
    eps,
    drag,
    ball_drag,
    weight,
    support_z=0.0,
    support_k=1e3,
    body_z0=None,
):
    dur = stage.max_duration
    moved = {}
    if body_z0 is not None:
        v = np.zeros(len(body_z0)) if not stage.body_vz else np.asarray(stage.body_vz, float)
        moved = {"body_z0": _f(body_z0), "body_v": _f(v)}
    f0 = f_start if stage.ball_force_start is None else stage.ball_force_start
    fc0 = fc_start if stage.clamp_force_start is None else stage.clamp_force_start
    return StageArgs(
        t0=_f(t0),
        clamp_mode=jnp.asarray(stage.clamp_mode, jnp.int32),
        vzc=_f(stage.clamp_vz),
        vrhoc=_f(stage.clamp_vrho),
        fc0=_f(fc0),
        fc1=_f(stage.clamp_force_end),
        ball_mode=jnp.asarray(stage.ball_mode, jnp.int32),
        vzb=_f(stage.ball_vz),
        f0=_f(f0),
        f1=_f(stage.ball_force_end),
        ramp=_f(dur),
        friction=friction,
        eps=_f(eps),
        drag=_f(drag),
        ball_drag=_f(ball_drag),
        weight=_f(weight),
        support=_f(1.0 if stage.support else 0.0),
        support_z=_f(support_z),
        support_k=_f(support_k),
        **moved,
    )


def _to_numpy(rec):
    return {k: np.asarray(v) for k, v in rec.items()}


def static_key(settings: Settings, layout: Layout, model, args) -> tuple:
    """Everything a compiled segment step is specialised on: the solver object (its static
    settings; the tolerances are arrays), the mesh size and the non-array parts of the model
    and stage loads."""
    return (
        repr(solver_for(settings)),
        layout.n,
        repr(eqx.filter((model, args), eqx.is_array, inverse=True)),
    )


@dataclasses.dataclass
class Segment:
    """One save segment a member asks for (the inputs of :func:`segment_step` but the model,
    layout, tolerances and contact threshold)."""

    y: jax.Array
    t0: float
    t1: float
    dt0: float
    args: StageArgs
    rate: tuple  # the predictor's rate (load stepping), zero at a stage's start


class MemberRun:
    """One member's run through its protocol, on the host: the state between save segments.

    The driver (:func:`drive`: one member, or many in lockstep) asks :meth:`segment` for the
    next save segment, solves it (:func:`segment_step`, alone or vmapped with the others),
    hands the output to :meth:`advance`, and records the frame computed with it with
    :meth:`record`, which checks the stage's stop rule and sets up the next stage. The keyword
    arguments are those of :func:`simulate`. Split by concern: stage set-up
    (:meth:`_begin_stage`), one segment (:meth:`segment`, :meth:`advance`), recording and
    the stop check (:meth:`record`, :meth:`_end_stage`).
    """

    def __init__(
        self,
        model: SheetModel,
        protocol: Protocol,
        *,
        friction: AbstractFriction,
        eps: float,
        drag: float,
        ball_drag: float,
        pre_stretch: float,
        z_sheet: float,
        weight: float = 0.0,
        settings: Settings = Settings(),
        on_frame: Callable[[dict], None] | None = None,
        start: dict | None = None,
        support_stiffness: float = 1e3,
    ):
        self.model, self.protocol, self.settings, self.on_frame = (
            model,
            protocol,
            settings,
            on_frame,
        )
        self.loads = dict(
            friction=friction,
            eps=eps,
            drag=drag,
            ball_drag=ball_drag,
            weight=weight,
            support_z=protocol.ball_z0,
            support_k=support_stiffness,
        )
        # bodies moved by the stages: their heights (R, per held entry; their reference
        # placement is 0) are carried from stage to stage, and their work is accumulated
        self.body_z = np.zeros(len(model.bodies)) if stage_moved(model.bodies) else None
        # bodies free along the axis: their heights are state unknowns (load stepping only)
        nf = n_free(model.bodies)
        n_acc = N_ACC_MOVED if self.body_z is not None or nf else N_ACC
        # the slip distances of the held bodies whose friction law has memory (none: 0, the
        # state unchanged)
        self.layout = Layout(model.mesh.n, friction.n_internal(), n_acc, nf,
                             n_memory(model.bodies))
        self.solver = solver_for(settings)
        if nf and not _counts_newton(self.solver):
            raise ValueError(
                "a held body free along the axis needs load stepping (solver load_step): its "
                "height is a border unknown of Newton's system"
            )
        if start is None:
            self.y = initial_state(model, self.layout, pre_stretch, z_sheet, protocol.ball_z0)
        else:
            self.y = state_from(self.layout, start)
        self.rtol, self.atol = _f(settings.rtol), _f(settings.atol)
        self.t = 0.0
        self.frames: list = []
        self.stage_end: list = []
        self.stats = {
            "steps": 0,
            "accepted": 0,
            "rejected": 0,
            "compile_s": 0.0,
            "run_s": 0.0,
            "segments": 0,
            "method": settings.solver
            if isinstance(settings.solver, str)
            else type(settings.solver).__name__,
            "newton_iterations": 0 if _counts_newton(self.solver) else None,
        }
        self.dt_guess = 1e-3 * settings.save_interval
        self.reaction = 0.0
        self.clamp_reaction = (0.0, 0.0)
        self.t_wall0 = _time.perf_counter()
        self.failed: str | None = None
        self.failure: RunFailure | None = None
        self.e0: float | None = None
        self.si = -1
        self.done = False
        self._begin_stage(0)
        self.key = static_key(settings, self.layout, model, self.args)

    # -- stage set-up
    def _begin_stage(self, si: int) -> None:
        """Loads, save times and the stop rule's state of stage ``si`` (the run is done past
        the last)."""
        if si >= len(self.protocol.stages):
            self._finish()
            return
        self.si = si
        stage = self.protocol.stages[si]
        zb_now = float(self.y[2 * self.layout.n - 1])
        self.args = _stage_args(
            stage, self.t, zb_now, self.reaction, self.clamp_reaction, **self.loads,
            body_z0=self.body_z,
        )
        self.t_start = self.t
        n_seg = max(1, math.ceil(stage.max_duration / self.settings.save_interval - 1e-9))
        self.seg_ts = np.linspace(self.t, self.t + stage.max_duration, n_seg + 1)
        self.seg = 1
        self.rate = zero_rate(self.layout.n)
        self.met = stage.stop.met_at_duration
        self.stop_state = stage.stop.init()

    # -- one segment
    def segment(self) -> Segment:
        """The next save segment; before the first frame, and for a finished run (masked by
        the batch), a zero-length one."""
        if self.done or not self.frames:
            return Segment(self.y, self.t, self.t, self.dt_guess, self.args, self.rate)
        t1 = float(self.seg_ts[self.seg])
        return Segment(
            self.y, self.t, t1, min(self.dt_guess, 0.5 * (t1 - self.t)), self.args, self.rate
        )

    def advance(self, seg: Segment, out, run_s: float) -> bool:
        """Take a segment's solve output (:class:`dynslip.physics.newton.SegmentOutput`); False
        (and the run done, with ``failed`` set) where the solver did not reach the segment's end."""
        y1, ok, nst, nacc, nrej = out.y, out.ok, out.steps, out.accepted, out.rejected
        if _counts_newton(self.solver):
            self.stats["newton_iterations"] += int(out.newton_iterations)
        ok = bool(ok)
        self.stats["run_s"] += run_s
        nst, nacc, nrej = int(nst), int(nacc), int(nrej)
        self.stats["steps"] += nst
        self.stats["accepted"] += nacc
        self.stats["rejected"] += nrej
        self.stats["segments"] += 1
        if not ok:
            s = self.settings
            if nst >= s.max_steps:
                self._fail(StepLimit(self.stage.name, self.t, seg.t1, s.max_steps))
            else:
                self._fail(
                    NonFinite(
                        self.stage.name,
                        self.t,
                        f"the solver did not reach t = {seg.t1:.6g} s: "
                        "non-finite state (NaN/inf: a stretch outside the material's range, or "
                        "divergence)",
                    )
                )
            return False
        self.dt_guess = (seg.t1 - self.t) / max(nacc, 1)
        self.y, self.t, self.rate = y1, seg.t1, out.rate
        self.seg += 1
        return True

    @property
    def stage(self):
        return self.protocol.stages[self.si]

    # -- recording and the stop check
    def record(self, rec: dict) -> None:
        """Keep the frame of the current state (``frame_record``'s values), then check the
        stop rule: the stage ends when the rule is met or its last segment is done."""
        rec = _to_numpy(rec)
        rec["time"] = float(self.t)
        rec["stage"] = self.si
        self.frames.append(rec)
        if self.on_frame is not None:
            self.on_frame(rec)
        if len(self.frames) == 1:
            self.e0 = float(rec["energy_elastic"] + rec["energy_penalty"])
            return  # the initial frame
        if not np.all(np.isfinite(rec["energy_elastic"])):
            self._fail(
                NonFinite(
                    self.stage.name,
                    self.t,
                    "elastic energy not finite (a stretch outside the material's range)",
                )
            )
            return
        unresolved = self._unresolved(rec)
        if unresolved is not None:
            self._fail(unresolved)
            return
        met, self.stop_state = self.stage.stop.check(rec, self.t, self.stop_state)
        if met:
            self.met = True
        if met or self.seg >= len(self.seg_ts):
            self._end_stage()

    def _fail(self, failure: RunFailure) -> None:
        self.failure, self.failed = failure, str(failure)
        self._end_stage()

    def _unresolved(self, rec: dict) -> ContactUnresolved | None:
        """Why the frame ``rec`` is past what the mesh resolves, or None
        (``Settings.max_chord_depth``): an element chord deeper than the limit inside the ball
        or the pole through it (:func:`~dynslip.physics.sheet.deepest_chord`), else a chord
        deeper than the limit inside a held body, each placed at its height in the frame
        (``rec["body_z"]``; :func:`~dynslip.physics.bodies.chords.deepest_chord_in`). The pole's
        crossing is the ball's only: a held body is off the axis or pressed by the pole from one
        side (docs/bodies.md, "The mesh check against every body"). One limit for every body,
        in R. No shipped scenario reaches it against a held body at its default mesh, nor the
        main job at N = 30 (the same page), so the rule stops a run on any body; a chord straight
        across a body thinner than twice the limit reads its half thickness and passes (the
        tube's 3 mm wall: 0.075 R at N = 30). The depth relative to the profile's local radius,
        which catches that, is reported in ``summary.json`` and the end table, not enforced here
        (docs/bodies.md, "The relative test")."""
        limit = self.settings.max_chord_depth
        if limit is None:
            return None
        first = self.frames[0]
        rbar = np.asarray(self.model.mesh.rbar)

        def unresolved(depth, k, crossed, body=None):
            return ContactUnresolved(
                self.stage.name, self.t, float(depth), float(limit),
                (float(rbar[k]), float(rbar[k + 1])), bool(crossed), body=body,
            )

        depth, k, crossed = deepest_chord(
            rec["rho"], rec["z"], rec["ball_z"], np.sign(first["z"][0] - first["ball_z"]),
            self.model.ball,
        )
        if crossed or depth > limit:
            return unresolved(depth, k, crossed)
        names = self.settings.body_names
        for j, e in enumerate(held_entries(self.model.bodies)):
            depth, k = deepest_chord_in(e.body, rec["rho"], rec["z"], rec["body_z"][j])
            if depth > limit:
                return unresolved(depth, k, False, names[j] if j < len(names) else f"held body {j}")
        return None

    def _end_stage(self) -> None:
        last = self.frames[-1]
        if self.body_z is not None:
            self.body_z = self.body_z + np.asarray(self.args.body_v) * (self.t - self.t_start)
        self.reaction = float(last["ball_reaction"])
        self.clamp_reaction = (float(last["clamp_force_rho"]), float(last["clamp_force"]))
        self.stage_end.append(
            {
                "name": self.stage.name,
                "t_start": self.t_start,
                "t_end": self.t,
                "condition_met": bool(self.met),
                "clamp_z": float(last["clamp_z"]),
            }
        )
        if self.failed:
            self._finish()
        else:
            self._begin_stage(self.si + 1)

    def _finish(self) -> None:
        self.done = True
        self.stats["wall_s"] = _time.perf_counter() - self.t_wall0
        self.stats["time_per_step_ms"] = 1e3 * self.stats["run_s"] / max(self.stats["steps"], 1)

    def result(self) -> Result:
        return Result(
            frames=self.frames,
            stage_end=self.stage_end,
            stats=self.stats,
            failed=self.failed,
            e0=self.e0 or 0.0,
            failure=self.failure,
        )


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
            return out, frame_record(model, layout, t1, out.y, args, contact_threshold)

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


def drive(runs: list[MemberRun]) -> list[Result]:
    """The host loop of one run (``len(runs) == 1``: :func:`segment_step` as compiled) or of
    B members in lockstep (the step vmapped over them, one call per save segment for all:
    :mod:`dynslip.physics.batch`). Each tick asks every member for its next segment, solves
    them together, and hands each active member its output and frame
    (:meth:`MemberRun.advance`, :meth:`MemberRun.record`); the first tick is a zero-length
    segment per member, whose frame is the initial one. Raises ``ValueError`` when the
    members need different compiled steps (:func:`static_key`)."""
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
            lambda inputs=inputs: step.lower(*inputs).compile(),
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
    ``support_stiffness`` (:class:`MemberRun`).

    Raises nothing on solver failure: the result's ``failed`` holds the message and
    ``frames`` what was computed before it (the runner turns it into exit 3). Many members
    of the same shape run in lockstep with :func:`dynslip.physics.batch.simulate_batch`.
    """
    return drive([MemberRun(model, protocol, **kwargs)])[0]
