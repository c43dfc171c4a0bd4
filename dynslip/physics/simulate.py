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
:mod:`dynslip.physics.batch` steps in lockstep, and the failures it reports; the field and
the solvers themselves live in :mod:`dynslip.physics.field`, :mod:`.loadstep` and
:mod:`.newton`.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.field import (
    N_ACC,
    Layout,
    StageArgs,
    _f,
    evaluate,
    heal,
    sheet_structure,
    vector_field,
)
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.linalg import BorderedBlockTridiagonal
from dynslip.physics.loadstep import FullStateLoadStep
from dynslip.physics.newton import MotionNewton, SegmentOutput, zero_rate
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel, deepest_chord
from dynslip.physics.upstream import VeryChord

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


@dataclasses.dataclass(frozen=True)
class Settings:
    """Numerics of the driver (nondimensional except times in s)."""

    solver: str = "kvaerno5"
    rtol: float = 1e-5
    atol: float = 1e-7
    pcoeff: float = 0.3
    icoeff: float = 0.3
    max_steps: int = 20000  # per segment
    save_interval: float = 1.0  # s
    contact_threshold: float = 1e-2  # G h0 / R
    heal_rate: float = (
        0.0  # R/s: a node heals (slip distance reset) where its slip rate is at most this
    )
    linear_solver: str = "structured"  # "structured" (block tridiagonal + border) or "dense" (LU)
    # solver "load_step" (dynslip.physics.loadstep): Newton iteration limit per increment, and the
    # increment bound in drag times, driven stages / stages with the ball or clamp under a force
    newton_max_iter: int = 20
    newton_backtrack: int = (
        4  # halvings of a Newton correction that would raise the residual (0: plain Newton)
    )
    max_increment: float = 20.0
    max_increment_free: float = 5.0
    # a run stops as failed when an element chord dips deeper than this into the ball, or the
    # pole passes through it (the mesh no longer resolves the contact); None: never checked
    max_chord_depth: float | None = None


class TimeStepping(eqx.Module):
    """A stiff diffrax solver (``method``: :class:`diffrax.Kvaerno5`, the reference, or another
    implicit one) with a PID controller over a save segment; at the segment's end the friction
    law's reset (healing, :func:`dynslip.physics.field.heal`, ``heal_rate``): a reset inside
    the steps would be a discontinuity in an adaptive error-controlled step."""

    method: type = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    linear_solver: str = eqx.field(static=True, default="structured")
    pcoeff: float = eqx.field(static=True, default=0.3)
    icoeff: float = eqx.field(static=True, default=0.3)
    heal_rate: float = eqx.field(static=True, default=0.0)

    def _diffrax_solver(self, layout: Layout):
        # VeryChord with the termination fix of diffrax PR #754 (dynslip.physics.upstream), on
        # both paths: the dense path otherwise builds diffrax's own VeryChord.
        chord = diffrax.with_stepsize_controller_tols(VeryChord)
        if self.linear_solver == "dense":
            return self.method(root_finder=chord())
        lin = BorderedBlockTridiagonal(sheet_structure(layout))
        return self.method(root_finder=chord(linear_solver=lin))

    def segment(self, model, layout, y0, t0, t1, dt0, args, rtol, atol, rate=None) -> SegmentOutput:
        term = diffrax.ODETerm(vector_field(model, layout))
        ctrl = diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=self.pcoeff, icoeff=self.icoeff)
        sol = diffrax.diffeqsolve(
            term,
            self._diffrax_solver(layout),
            t0,
            t1,
            dt0,
            y0,
            args=args,
            stepsize_controller=ctrl,
            max_steps=self.max_steps,
            throw=False,
            saveat=diffrax.SaveAt(t1=True),
        )
        y1 = sol.ys[-1]
        ok = (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(y1))
        # a zero-length segment (a run's first frame, a finished batch member) is not healed
        y1 = jnp.where(t1 > t0, heal(model, layout, y1, args, self.heal_rate), y1)
        st = sol.stats
        return SegmentOutput(
            y=y1,
            ok=ok,
            steps=st["num_steps"],
            accepted=st["num_accepted_steps"],
            rejected=st["num_rejected_steps"],
            newton_iterations=jnp.zeros((), jnp.int32),
            rate=zero_rate(layout.n),
        )


def _from_settings(cls, settings: Settings, **given):
    """``cls`` (a solver object) with each of its fields that :class:`Settings` has by the same
    name taken from ``settings``, and the ``given`` ones."""
    take = {f.name for f in dataclasses.fields(cls)} - set(given)
    return cls(**{k: getattr(settings, k) for k in take if hasattr(settings, k)}, **given)


def _motion_newton(s: Settings) -> MotionNewton:
    linear = "thomas" if s.linear_solver == "thomas" else "cyclic"
    return _from_settings(
        MotionNewton, s, max_iter=s.newton_max_iter, backtrack=s.newton_backtrack, linear=linear
    )


def _time_stepping(method: type) -> Callable[[Settings], TimeStepping]:
    return lambda s: _from_settings(TimeStepping, s, method=method)


#: The segment solvers by the schema's ``numerics.solver`` name: each builds its solver object
#: from the :class:`Settings`. Every object has ``segment(model, layout, y0, t0, t1, dt0, args,
#: rtol, atol, rate) -> SegmentOutput``.
SOLVERS: dict[str, Callable[[Settings], eqx.Module]] = {
    "load_step": _motion_newton,
    "load_step_full": lambda s: _from_settings(FullStateLoadStep, s),
    "kvaerno5": _time_stepping(diffrax.Kvaerno5),
    "kvaerno4": _time_stepping(diffrax.Kvaerno4),
    "kvaerno3": _time_stepping(diffrax.Kvaerno3),
    "implicit_euler": _time_stepping(diffrax.ImplicitEuler),
}


def solver_for(settings: Settings):
    """The segment solver object of ``settings.solver``: the object itself, or the one
    :data:`SOLVERS` builds for its name (``load_step``, the default,
    :class:`dynslip.physics.newton.MotionNewton`; ``load_step_full``, the full-state Newton
    baseline :class:`dynslip.physics.loadstep.FullStateLoadStep`; a diffrax solver,
    :class:`TimeStepping`)."""
    if not isinstance(settings.solver, str):
        return settings.solver
    try:
        make = SOLVERS[settings.solver]
    except KeyError:
        raise ValueError(
            f"Settings.solver = {settings.solver!r}: allowed: {', '.join(SOLVERS)} or a solver "
            "object"
        ) from None
    return make(settings)


def _counts_newton(solver) -> bool:
    """Whether the solver's ``newton_iterations`` count anything (load stepping)."""
    return not isinstance(solver, TimeStepping)


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


@eqx.filter_jit
def frame_record(model: SheetModel, layout: Layout, t, y, args: StageArgs, contact_threshold):
    """Everything saved per frame: per-node fields and per-time scalars (jnp)."""
    dy, aux = evaluate(model, layout, t, y, args)
    rho, z, zb = aux["rho"], aux["z"], aux["zb"]
    d = model.diagnostics(
        rho, z, zb, args.friction, args.eps, args.drag, contact_threshold, layout.internal(y)
    )
    acc = layout.unpack(y)[3]
    contact = d["contact"]
    idx = jnp.arange(layout.n)
    any_c = jnp.any(contact)
    last = jnp.max(jnp.where(contact, idx, -1))
    theta_all = jnp.arctan2(rho, z - zb)
    theta_max = jnp.where(any_c, jnp.max(jnp.where(contact, theta_all, -jnp.inf)), jnp.nan)
    rbar_max = jnp.where(any_c, model.mesh.rbar[jnp.maximum(last, 0)], jnp.nan)
    slip_max = jnp.max(jnp.abs(d["slip_velocity"]))
    return {
        "rho": rho,
        "z": z,
        **{k: v for k, v in d.items() if k != "contact"},
        "clamp_z": aux["zc"],
        "clamp_rho": aux["rhoc"],
        "clamp_force": aux["clamp_force"],
        "clamp_force_rho": aux["clamp_force_rho"],
        "ball_z": zb,
        "ball_reaction": aux["ball_reaction"],
        "ball_velocity": aux["ball_v"],
        "theta_max": theta_max,
        "rbar_max": rbar_max,
        "work_clamp": acc[0],
        "work_ball": acc[1],
        "dissipation_drag": acc[2],
        "dissipation_friction": acc[3],
        "energy_elastic": model.elastic_energy(rho, z),
        "energy_penalty": model.penalty_energy(rho, z, zb),
        "slip_max": slip_max,
        "n_contact": jnp.sum(contact),
    }


def initial_state(model: SheetModel, layout: Layout, pre_stretch: float, z_sheet: float, zb: float):
    """Flat sheet at height ``z_sheet``, uniformly pre-stretched radially (rho = lambda rbar)."""
    rho = pre_stretch * model.mesh.rbar
    z = jnp.full(layout.n, _f(z_sheet))
    return layout.pack(rho, z, _f(zb), jnp.zeros(N_ACC))


def state_from(layout: Layout, start: dict):
    """State vector from a saved end state: ``rho``, ``z`` (n,), ``zb``, and optionally
    ``slip_distance`` (n,); the accumulators start at zero."""
    internal = None
    if layout.n_int:
        internal = jnp.asarray(start.get("slip_distance", np.zeros(layout.n)), dtype=jnp.float64)
        internal = jnp.where(jnp.isfinite(internal), internal, 0.0)
    return layout.pack(
        _f(start["rho"]), _f(start["z"]), _f(start["zb"]), jnp.zeros(N_ACC), internal
    )


@eqx.filter_jit
def reset_internal(model: SheetModel, layout: Layout, y, args: StageArgs, heal_rate=0.0):
    """The friction law's restart at a save-segment end (time-stepped solvers):
    :func:`dynslip.physics.field.heal`. Load stepping applies the same reset after every
    increment."""
    return heal(model, layout, y, args, heal_rate)


class SolverFailure(RuntimeError):
    """The solver did not reach the end of a segment (step limit, NaN, material range)."""


class RunFailure(SolverFailure):
    """Why a run stopped as failed, in physics terms, with the quantities (``Result.failure``;
    ``Result.failed`` is its message). The schema layer maps each kind to the settings a user
    can change (numerics.max_steps, numerics.nodes, ...): no setting names here."""

    def __init__(self, stage: str, t: float, what: str):
        self.stage, self.t, self.what = stage, t, what
        super().__init__(f"stage '{stage}' at t = {t:.6g} s: {what}")


class StepLimit(RunFailure):
    """A save segment from ``t`` to ``t1`` needed more than ``max_steps`` steps."""

    def __init__(self, stage: str, t: float, t1: float, max_steps: int):
        self.t1, self.max_steps = t1, max_steps
        super().__init__(
            stage,
            t,
            f"the solver did not reach t = {t1:.6g} s: step limit reached "
            f"({max_steps} steps per save segment)",
        )


class NonFinite(RunFailure):
    """A state or energy went non-finite (a stretch outside the material's range, or divergence)."""


class ContactUnresolved(RunFailure):
    """The mesh no longer resolves the contact: an element chord ``depth`` (R) inside the ball,
    beyond ``limit`` (R), on the element of material radii ``element`` (R), or the pole passed
    through the ball (``pole_crossed``, depth 1)."""

    def __init__(
        self, stage: str, t: float, depth: float, limit: float, element: tuple, pole_crossed: bool
    ):
        self.depth, self.limit, self.element, self.pole_crossed = (
            depth,
            limit,
            element,
            pole_crossed,
        )
        why = (
            "the pole passed through the ball"
            if pole_crossed
            else f"the chord of the element on rbar [{element[0]:.4g}, {element[1]:.4g}] R "
            f"lies {depth:.3g} R "
            f"inside the ball (limit {limit:g} R)"
        )
        super().__init__(
            stage,
            t,
            f"contact not resolved by the mesh: {why}; a finer mesh near the contact, or "
            "a larger chord-depth limit, is needed",
        )


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
):
    dur = stage.max_duration
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
        self.layout = Layout(model.mesh.n, friction.n_internal())
        self.solver = solver_for(settings)
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
            stage, self.t, zb_now, self.reaction, self.clamp_reaction, **self.loads
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
        (``Settings.max_chord_depth``)."""
        limit = self.settings.max_chord_depth
        if limit is None:
            return None
        first = self.frames[0]
        depth, k, crossed = deepest_chord(
            rec["rho"], rec["z"], rec["ball_z"], np.sign(first["z"][0] - first["ball_z"]),
            self.model.ball,
        )
        if crossed or depth > limit:
            rbar = np.asarray(self.model.mesh.rbar)
            return ContactUnresolved(
                self.stage.name,
                self.t,
                float(depth),
                float(limit),
                (float(rbar[k]), float(rbar[k + 1])),
                bool(crossed),
            )
        return None

    def _end_stage(self) -> None:
        last = self.frames[-1]
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
