r"""One member's run through its protocol, on the host (:class:`MemberRun`): stage set-up,
save segments, recording and the stop rules, between the compiled segment steps that the driver
(:func:`dynslip.physics.driver.simulate.drive`) runs for one member or many in lockstep; the run's
result (:class:`Result`) and the stage loads (:func:`stage_args`).
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.bodies.held import held_entries, n_free, n_memory, stage_moved
from dynslip.physics.conditions import BALLS, CLAMPS
from dynslip.physics.driver.failures import NonFinite, RunFailure, StepLimit
from dynslip.physics.driver.meshcheck import ball_unresolved, held_unresolved
from dynslip.physics.field import StageArgs
from dynslip.physics.frames import initial_state, state_from
from dynslip.physics.friction import AbstractFriction
from dynslip.physics.layout import N_ACC, N_ACC_MOVED, Layout, f64
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel
from dynslip.physics.solver.methods import Settings
from dynslip.physics.solver.newton import zero_rate

__all__ = ["MemberRun", "Result", "Segment", "stage_args", "static_key"]

@dataclasses.dataclass
class Result:
    frames: list  # dicts of numpy arrays (see frame_record) plus "time", "stage"
    stage_end: list  # per stage: dict(name, t_start, t_end, condition_met)
    stats: dict
    failed: str | None = None
    e0: float = 0.0
    failure: RunFailure | None = None  # the failure with its quantities (failed is its message)


def stage_args(
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
    if stage.clamp_mode not in CLAMPS or stage.ball_mode not in BALLS:
        # a traced mode outside the registries would select another mode's law silently
        raise ValueError(
            f"stage {stage.name!r}: clamp mode {stage.clamp_mode} (known: {sorted(CLAMPS)}), "
            f"ball mode {stage.ball_mode} (known: {sorted(BALLS)})"
        )
    dur = stage.max_duration
    moved = {}
    if body_z0 is not None:
        v = np.zeros(len(body_z0)) if not stage.body_vz else np.asarray(stage.body_vz, float)
        moved = {"body_z0": f64(body_z0), "body_v": f64(v)}
    f0 = f_start if stage.ball_force_start is None else stage.ball_force_start
    fc0 = fc_start if stage.clamp_force_start is None else stage.clamp_force_start
    return StageArgs(
        t0=f64(t0),
        clamp_mode=jnp.asarray(stage.clamp_mode, jnp.int32),
        vzc=f64(stage.clamp_vz),
        vrhoc=f64(stage.clamp_vrho),
        fc0=f64(fc0),
        fc1=f64(stage.clamp_force_end),
        ball_mode=jnp.asarray(stage.ball_mode, jnp.int32),
        vzb=f64(stage.ball_vz),
        f0=f64(f0),
        f1=f64(stage.ball_force_end),
        ramp=f64(dur),
        friction=friction,
        eps=f64(eps),
        drag=f64(drag),
        ball_drag=f64(ball_drag),
        weight=f64(weight),
        support=f64(1.0 if stage.support else 0.0),
        support_z=f64(support_z),
        support_k=f64(support_k),
        **moved,
    )


def _to_numpy(rec):
    return {k: np.asarray(v) for k, v in rec.items()}


def static_key(settings: Settings, layout: Layout, model, args) -> tuple:
    """Everything a compiled segment step is specialised on, as a hashable value: the solver
    object (an equinox module, hashed and compared by its fields; the tolerances are arrays),
    the layout (static ints) and, of the model and stage loads, what ``eqx.filter_jit`` keys
    on: the pytree's structure (with the equinox modules' static fields), each non-array leaf
    with its type (so 1 and 1.0 differ) and each array's shape and dtype."""
    leaves, treedef = jax.tree_util.tree_flatten((model, args))
    return (
        settings.solver,
        layout,
        treedef,
        tuple((x.shape, np.dtype(x.dtype)) if eqx.is_array(x) else (type(x), x) for x in leaves),
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
        carried = any(e.moves_with_ball for e in held_entries(model.bodies))
        n_acc = N_ACC_MOVED if self.body_z is not None or nf or carried else N_ACC
        # the slip distances of the held bodies whose friction law has memory (none: 0, the
        # state unchanged)
        self.layout = Layout(model.mesh.n, friction.n_internal(), n_acc, nf,
                             n_memory(model.bodies))
        self.solver = settings.solver
        if nf and not self.solver.counts_newton:
            raise ValueError(
                "a held body free along the axis needs load stepping (solver load_step): its "
                "height is a border unknown of Newton's system"
            )
        if start is None:
            self.y = initial_state(model, self.layout, pre_stretch, z_sheet, protocol.ball_z0)
        else:
            self.y = state_from(self.layout, start)
        self.rtol, self.atol = f64(settings.rtol), f64(settings.atol)
        self.t = 0.0
        self.frames: list = []
        self.stage_end: list = []
        self.stats: dict[str, Any] = {
            "steps": 0,
            "accepted": 0,
            "rejected": 0,
            "compile_s": 0.0,
            "run_s": 0.0,
            "segments": 0,
            "method": self.solver.name,
            "newton_iterations": 0 if self.solver.counts_newton else None,
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
        self.args = stage_args(
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
        """Take a segment's solve output (:class:`dynslip.physics.solver.newton.SegmentOutput`);
        False
        (and the run done, with ``failed`` set) where the solver did not reach the segment's
        end."""
        y1, ok, nst, nacc, nrej = out.y, out.ok, out.steps, out.accepted, out.rejected
        if self.solver.counts_newton:
            self.stats["newton_iterations"] += int(out.newton_iterations)
        ok = bool(ok)
        self.stats["run_s"] += run_s
        nst, nacc, nrej = int(nst), int(nacc), int(nrej)
        self.stats["steps"] += nst
        self.stats["accepted"] += nacc
        self.stats["rejected"] += nrej
        self.stats["segments"] += 1
        if not ok:
            limit = self.solver.max_steps
            if nst >= limit:
                self._fail(StepLimit(self.stage.name, self.t, seg.t1, limit))
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
        """Keep the frame of the current state (``frame_record``'s values), check the mesh
        (:meth:`_mesh_check`), then the stop rule: the stage ends when it is met or its last
        segment is done. A failed check fails the run at this frame (the frame is kept)."""
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
            self._fail(NonFinite(self.stage.name, self.t, "elastic energy not finite (a "
                                 "stretch outside the material's range)"))
            return
        why = self._mesh_check(rec)
        if why is not None:
            self._fail(why)
            return
        met, self.stop_state = self.stage.stop.check(rec, self.t, self.stop_state)
        if met:
            self.met = True
        if met or self.seg >= len(self.seg_ts):
            self._end_stage()

    def _fail(self, failure: RunFailure) -> None:
        self.failure, self.failed = failure, str(failure)
        self._end_stage()

    def _mesh_check(self, rec: dict) -> RunFailure | None:
        """Why the frame ``rec`` is past what the mesh resolves (a
        :class:`~dynslip.physics.driver.failures.ContactUnresolved`), or None; never checked where
        ``Settings.max_chord_depth`` is None. Against the ball: a chord deeper than that limit
        inside the ball, or the pole through it
        (:func:`~dynslip.physics.driver.meshcheck.ball_unresolved`). Against a held body: a chord
        deeper than the limit inside it, at its height in the frame
        (:func:`~dynslip.physics.driver.meshcheck.held_unresolved`). The pole's crossing is the
        ball's
        only: a held body is off the axis or pressed by the pole from one side
        (docs/bodies.md, "The mesh check against every body"). One limit for every body, in R.
        No shipped scenario reaches it against a held body at its default mesh, nor the main
        job at N = 30 (the same page), so the rule stops a run on any body; a chord straight
        across a body thinner than twice the limit reads its half thickness and passes (the
        tube's 3 mm wall: 0.075 R at N = 30). The depth relative to the profile's local radius,
        which catches that, is reported in ``summary.json`` and the end table, not enforced here
        (docs/bodies.md, "The relative test")."""
        limit = self.settings.max_chord_depth
        if limit is None:
            return None
        why = ball_unresolved(self.model, rec, self.frames[0], limit, self.stage.name, self.t)
        if why is None and held_entries(self.model.bodies):
            why = held_unresolved(self.model, self.settings.body_names, rec, limit,
                                  self.stage.name, self.t)
        return why

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
