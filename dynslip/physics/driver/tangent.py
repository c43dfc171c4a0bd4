r"""Forward-mode sensitivities of a run through its whole protocol (docs/sensitivities.md).

A run's frames are a function of the model's and the loads' traced parameters (every
physical parameter is an array leaf, :func:`dynslip.physics.layout.traced`), of the start
state and of the stage loads. :class:`TangentRun` is :class:`~.member.MemberRun` with K
tangent directions carried beside the state:

- **Through each save segment**: the segment step (the solver's ``segment`` and the frame of
  its end state, as :func:`~.simulate.segment_step`) under ``jax.jvp``, ``vmap``-ed over the K
  tangents (:func:`tangent_step`): one program per solver and K, its primal loop run once and
  the K tangents alongside (the adaptive increments' control flow follows the primal). The
  tangents of the segment's inputs: the model's (the parameters), the start state's (carried),
  the stage loads' and the segment's start and end times.
- **Stage hand-offs**: a stage's loads are the difference quotient of
  :func:`~.member.stage_args` between the two neighbouring worlds of each direction (the unit
  conversions of the schema, linear, are exact so), plus the carried tangents of the values
  the previous stage hands on (the ball's reaction and the clamp's force at the ramp's start,
  read on the host in the forward run) and of the stage's start time.
- **Stop times**: a stage that ends at its duration ends at $t_0 + D$, both differentiated
  (its save times $t_0 + D i/n$ with them). A condition stop ends at the save time after
  the rule's event $g(t^*, p) = 0$ (``g`` by rule: :data:`EVENTS`; a rule registered from
  outside has none, and the result says so). The event is located between the two saved
  frames on either side by linear interpolation of ``g``, and the tangent is that of the
  located time, the implicit $dt^*/dp = -(\partial g/\partial p)/(\partial g/\partial t)$
  with $\partial g/\partial p$ interpolated at $t^*$ and $\partial g/\partial t$ the secant's;
  the save grid's offset from the event is held fixed. The state, the frame and the next
  stage's start time then take the event time's tangent, with the state's rate from one more
  tangent of the stop's segment, along its end time alone. A stage that stops at rest (the
  state's rate zero to rounding) needs no stop-time tangent: nothing moves with it.

What a tangent cannot see (the contact set, the stick/slip branch or the increment count
changing within a step of the parameter) is for the caller to test
(:func:`dynslip.app.sensitivities.sensitivities` runs the neighbouring worlds).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.driver.member import MemberRun, stage_args
from dynslip.physics.driver.simulate import CACHE_SIZE, StepOutput, compile_step
from dynslip.physics.frames import frame_record
from dynslip.physics.layout import f64

#: a stop frame whose state's rate is at most this (per unit of the state's scale and per s)
#: is at rest: its stop time's tangent is not needed
RESTING = 1e-12

__all__ = ["EVENTS", "TangentResult", "TangentRun", "Variant", "observables", "tangent_step"]


def observables(frame: dict) -> dict:
    """The scalars of a frame that are differentiated: every 0-d float value of
    :func:`~dynslip.physics.frames.frame_record` (whatever keys it returns), and the largest
    meridional and hoop stretches over the nodes."""
    out = {k: v for k, v in frame.items()
           if jnp.ndim(v) == 0 and jnp.issubdtype(jnp.result_type(v), jnp.floating)}
    out["lambda_theta_max"] = jnp.max(frame["lambda_theta"])
    out["lambda_phi_max"] = jnp.max(frame["lambda_phi"])
    return out


def _split(tree):
    return eqx.partition(tree, eqx.is_inexact_array)


class SegmentInputs(eqx.Module):
    """The differentiated inputs of one segment (the inexact arrays of the model and of the
    stage loads, the start state, the start and end times), or their tangents."""

    model: Any
    y0: Any
    t0: Any
    t1: Any
    args: Any


class SegmentCall(eqx.Module):
    """The inputs of one segment that are not differentiated: the first increment's size,
    the tolerances, the predictor's rate and the contact threshold."""

    dt0: Any
    rtol: Any
    atol: Any
    rate: Any
    thr: Any


@functools.lru_cache(maxsize=CACHE_SIZE)
def tangent_step(solver):
    """Jitted ``step(layout, primal, call, tangents) -> (StepOutput, dy1 (K, ny), dobs
    {name: (K,)})``: the segment step (``primal``: a :class:`SegmentInputs` with the whole model
    and stage loads; ``call``: :class:`SegmentCall`) and its jvp in the K directions of
    ``tangents`` (a :class:`SegmentInputs` of the inexact leaves with a leading axis K). The
    predictor's rate, the first increment's size and the tolerances are not differentiated:
    they move the Newton iterates, not the converged state."""

    def step(layout, primal: SegmentInputs, call: SegmentCall, tangents):
        m_dyn, m_st = _split(primal.model)
        a_dyn, a_st = _split(primal.args)

        def f(p: SegmentInputs):
            m, a = eqx.combine(p.model, m_st), eqx.combine(p.args, a_st)
            out = solver.segment(m, layout, p.y0, p.t0, p.t1, call.dt0, a, call.rtol, call.atol,
                                 call.rate)
            frame = frame_record(m, layout, p.t1, out.y, a, call.thr, forces=out.forces,
                                 vb=out.ball_velocity)
            return (out.y, observables(frame)), StepOutput(out, frame)

        at = SegmentInputs(m_dyn, primal.y0, primal.t0, primal.t1, a_dyn)

        def one(tan):
            return jax.jvp(f, (at,), (tan,), has_aux=True)

        (_, dout, aux) = jax.vmap(one, out_axes=(None, 0, None))(tangents)
        return aux, dout[0], dout[1]

    return eqx.filter_jit(step)


@dataclasses.dataclass(frozen=True)
class Variant:
    """One tangent direction's neighbouring worlds: the protocol and loads at ``p - h`` and
    ``p + h`` (their difference quotient over ``width`` = 2h is the direction's tangent of
    the stage loads and durations)."""

    minus: tuple  # (protocol, loads)
    plus: tuple
    width: float


def _quotient(plus, minus, width):
    """(plus - minus) / width over the inexact array leaves (the other leaves None)."""
    p, _ = _split(plus)
    m, _ = _split(minus)
    return jax.tree_util.tree_map(lambda a, b: (jnp.asarray(a) - jnp.asarray(b)) / width, p, m)


def _stack(trees):
    return jax.tree_util.tree_map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *trees)


def _moving(f):
    return jnp.maximum(f["slip_max"], jnp.abs(f["ball_velocity"]))


#: The event function ``g(frame)`` of each condition stop rule (``kind``), zero at the event:
#: the rule is met where it changes sign. A rule not here is not differentiated.
EVENTS: dict[str, Callable[[Any, dict], Any]] = {
    "clamp_force_below": lambda rule, f: jnp.abs(f["clamp_force_static"]) - rule.force,
    "ball_reaction_below": lambda rule, f: f["ball_reaction_static"] - rule.force,
    "theta_max_below": lambda rule, f: f["theta_max"] - rule.angle,
    "ball_speed_above": lambda rule, f: rule.rate - jnp.abs(f["ball_velocity"]),
    # rest begins where the motion falls below the rate; the stop is a hold later
    "rest": lambda rule, f: _moving(f) - rule.rate,
}


@dataclasses.dataclass
class TangentResult:
    """A tangent run: its ``frames`` (as :class:`~.member.Result`'s), per frame the tangents
    of :func:`observables` (``dframes``: {name: (K,)}), the condition stops' ``events``
    (stage name -> its event ``time``, ``dt`` (K,) the event time's tangent, and the
    ``frame`` index it moved), why a tangent is not the derivative (``reasons``), and the
    run's ``stats``, ``failed``, ``stage_end``."""

    frames: list
    dframes: list
    events: dict
    reasons: list
    stats: dict
    stage_end: list
    failed: str | None
    steps_per_stage: list


class TangentRun(MemberRun):
    """:class:`~.member.MemberRun` with K tangent directions (the module docstring).

    ``dmodel``: the tangent of the model's inexact array leaves (a leading axis K);
    ``dy0``: of the start state (K, ny); ``variants``: per direction its
    :class:`Variant`; the other arguments are :class:`~.member.MemberRun`'s.
    """

    def __init__(self, model, protocol, *, dmodel, dy0, variants: Sequence[Variant], **kwargs):
        self.variants = list(variants)
        self.k = len(self.variants)
        self.dmodel = dmodel
        self.dy = jnp.asarray(dy0)
        self.tau = np.zeros(self.k)  # the tangent of the current stage's start time
        self.dreaction = np.zeros(self.k)
        self.dclamp = np.zeros((self.k, 2))
        self.dframes: list = []
        self.events: dict = {}
        self.reasons: list = []
        self.steps_per_stage: list = []
        self.stage_log: list = []  # (Segment, frame index) of the current stage's segments
        self._pending: tuple | None = None
        super().__init__(model, protocol, **kwargs)

    # -- stage set-up: the loads' tangents
    def _begin_stage(self, si: int) -> None:
        super()._begin_stage(si)
        if self.done:
            return
        self.steps_per_stage.append(0)
        self.stage_log = []
        zb = float(self.y[2 * self.layout.n - 1])
        douts, ddur = [], np.zeros(self.k)
        for j, v in enumerate(self.variants):
            side = []
            for prot, loads in (v.plus, v.minus):
                stage = prot.stages[si]
                side.append((stage, stage_args(stage, self.t, zb, self.reaction,
                                               self.clamp_reaction, **loads,
                                               body_z0=self.body_z)))
            (sp, ap), (sm, am) = side
            d = _quotient(ap, am, v.width)
            own = self.stage
            d = eqx.tree_at(lambda a: a.t0, d, f64(self.tau[j]))
            if own.ball_force_start is None:
                d = eqx.tree_at(lambda a: a.f0, d, d.f0 + self.dreaction[j])
            if own.clamp_force_start is None:
                d = eqx.tree_at(lambda a: a.fc0, d, d.fc0 + f64(self.dclamp[j]))
            ddur[j] = (sp.max_duration - sm.max_duration) / v.width
            n = [max(1, math.ceil(s.max_duration / self.settings.save_interval - 1e-9))
                 for s in (sp, sm)]
            if n[0] != n[1] or n[0] != len(self.seg_ts) - 1:
                self.reasons.append(
                    f"direction {j}: stage {own.name!r} has {n[1]} and {n[0]} save segments at "
                    f"the two neighbouring values (its duration moves across a save time)")
            douts.append(d)
        self.dargs = _stack(douts)
        self.ddur = ddur

    def _grid_tangent(self, i: int) -> np.ndarray:
        """The tangent of the stage's save time ``seg_ts[i]`` (t0 + D i / n)."""
        return self.tau + self.ddur * (i / (len(self.seg_ts) - 1))

    def tangents_of(self, seg) -> Any:
        """The K tangents of a segment's inputs (:class:`SegmentInputs`)."""
        if not self.frames or self.done:
            t0 = t1 = self._grid_tangent(self.seg - 1 if self.frames else 0)
        else:
            t0, t1 = self._grid_tangent(self.seg - 1), self._grid_tangent(self.seg)
        return SegmentInputs(self.dmodel, self.dy, f64(t0), f64(t1), self.dargs)

    def take(self, seg, dy1, dobs) -> None:
        """Hold the segment's tangents until :meth:`advance` accepts it (and :meth:`record`
        its frame)."""
        self._pending = (seg, dy1, {k: np.asarray(v) for k, v in dobs.items()})

    def advance(self, seg, out, run_s: float) -> bool:
        ok = super().advance(seg, out, run_s)
        if ok and self._pending is not None:
            self.dy = self._pending[1]
            self.steps_per_stage[-1] += int(out.steps)
        return ok

    def record(self, rec: dict) -> None:
        assert self._pending is not None, "record before a segment"
        seg, _, dobs = self._pending
        self.dframes.append(dobs)
        if self.frames:  # not the initial frame: a segment of this stage
            self.stage_log.append((seg, self.dy, len(self.frames)))
        super().record(rec)

    # -- the stage's end: the stop time's tangent
    def _end_stage(self) -> None:
        if not self.failed:
            self._stop_tangent()
        last = self.dframes[-1]
        self.dreaction = np.asarray(last["ball_reaction"], float)
        self.dclamp = np.stack([last["clamp_force_rho"], last["clamp_force"]], axis=-1)
        super()._end_stage()

    def _stop_tangent(self) -> None:
        """Set the tangents of the stage's end (state, frame, time) to the event time's, where
        a condition rule met; else the end time is the grid's, t0 + D."""
        end = self._grid_tangent(self.seg - 1)
        rule = self.stage.stop
        if not (self.met and not rule.met_at_duration):
            self.tau = end
            return
        if rule.kind not in EVENTS:
            self.reasons.append(f"stage {self.stage.name!r}: the stop rule {rule.kind!r} has no "
                                "event function: its stop time is not differentiated")
            self.tau = end
            return
        # the stop frame's rates: where the state does not move (at rest, to rounding), the
        # stop time's tangent moves nothing (the later stages run on t - t0)
        seg_s, _, i_s = self.stage_log[-1]
        ydot, xdot = self._time_rates(seg_s)
        y_scale = max(1.0, float(np.max(np.abs(np.asarray(self.y)))))
        if not float(np.max(np.abs(ydot))) > RESTING * y_scale:
            self.events[self.stage.name] = {"time": float(self.frames[i_s]["time"]),
                                            "dt": np.full(self.k, np.nan), "frame": i_s,
                                            "at_rest": True}
            self.tau = end
            return
        # the event's frame: the rule's (rest: where rest began), of this stage's segments
        at = len(self.stage_log) - 1
        if rule.kind == "rest" and self.stop_state is not None:
            times = [self.frames[i]["time"] for _, _, i in self.stage_log]
            at = int(np.argmin(np.abs(np.asarray(times) - self.stop_state)))
        seg_e, _, i_e = self.stage_log[at]
        dt_star = self._event_time(rule, i_e, int(self.seg_ts.searchsorted(seg_e.t1 - 1e-12)))
        if dt_star is None:
            self.reasons.append(f"stage {self.stage.name!r}: the stop rule's event function "
                                "does not change between the frames on either side of its "
                                "event: its stop time has no derivative")
            self.tau = end
            return
        # the stop frame (the last) moved from its grid tangent to the event's
        shift = dt_star - end
        self.dy = self.dy + shift[:, None] * ydot[None, :]
        self.dframes[-1] = {k: v + shift * xdot[k] for k, v in self.dframes[-1].items()}
        self.events[self.stage.name] = {"time": float(self.frames[i_s]["time"]),
                                        "event_frame": i_e,
                                        "dt": dt_star, "frame": i_s, "at_rest": False}
        self.tau = dt_star

    def _time_rates(self, seg):
        """(dy/dt (ny,), {name: dX/dt}) at a segment's end, its start held: one more tangent of
        the segment, along its end time alone (in the first of the K slots)."""
        e = np.zeros(self.k)
        e[0] = 1.0
        zero = jax.tree_util.tree_map(jnp.zeros_like, SegmentInputs(self.dmodel, self.dy, f64(e),
                                                                   f64(e), self.dargs))
        tan = eqx.tree_at(lambda s: s.t1, zero, f64(e))
        _, dy1, dobs = self.solve(seg, tan)
        return np.asarray(dy1[0]), {k: float(np.asarray(v)[0]) for k, v in dobs.items()}

    def _event_time(self, rule, i: int, n: int):
        """The tangent (K,) of the event time located between frame ``i`` (save time ``n`` of
        the stage's grid) and the frame before it by linear interpolation of the rule's event
        function g: t* = t_a + (t_b - t_a) s, s = g_a / (g_a - g_b), differentiated (the
        implicit dt*/dp = -(dg/dp)/(dg/dt) with dg/dp interpolated at t* and dg/dt the
        secant's); None where g_a = g_b."""
        g = functools.partial(EVENTS[rule.kind], rule)

        def at(j):
            obs = observables(self.frames[j])
            vals = {k: jnp.asarray(float(np.asarray(obs[k]))) for k in self.dframes[j]}
            tans = {k: jnp.asarray(v) for k, v in self.dframes[j].items()}
            value = float(g(vals))
            tan = np.asarray(jax.vmap(lambda t: jax.jvp(g, (vals,), (t,))[1])(tans))
            return value, tan

        (ga, dga), (gb, dgb) = at(i - 1), at(i)
        if not (np.isfinite(ga) and np.isfinite(gb)) or ga == gb:
            return None
        ta, tb = float(self.frames[i - 1]["time"]), float(self.frames[i]["time"])
        dta, dtb = self._grid_tangent(n - 1), self._grid_tangent(n)
        frac = ga / (ga - gb)
        dfrac = (dga - frac * (dga - dgb)) / (ga - gb)
        return dta + (dtb - dta) * frac + (tb - ta) * dfrac

    def solve(self, seg, tangents):
        """The compiled tangent step of ``seg`` with ``tangents``."""
        return _call(self, seg, tangents)

    def tangent_result(self) -> TangentResult:
        base = self.result()
        return TangentResult(frames=base.frames, dframes=self.dframes, events=self.events,
                             reasons=self.reasons, stats=base.stats, stage_end=base.stage_end,
                             failed=base.failed, steps_per_stage=self.steps_per_stage)


_COMPILED_TANGENT: dict = {}


def _call(run: TangentRun, seg, tangents):
    step = tangent_step(run.solver)
    inputs = (run.layout,
              SegmentInputs(run.model, seg.y, f64(seg.t0), f64(seg.t1), seg.args),
              SegmentCall(f64(seg.dt0), run.rtol, run.atol, seg.rate,
                          f64(run.settings.contact_threshold)),
              tangents)
    key = (run.key, run.k)
    compiled = _COMPILED_TANGENT.get(key)
    if compiled is None:
        import time

        t0 = time.perf_counter()
        compiled = compile_step(step.lower(*inputs), run.layout.n)
        run.stats["compile_s"] += time.perf_counter() - t0
        _COMPILED_TANGENT[key] = compiled
        while len(_COMPILED_TANGENT) > CACHE_SIZE:
            _COMPILED_TANGENT.pop(next(iter(_COMPILED_TANGENT)))
    return jax.device_get(compiled(*inputs))


def drive_tangent(run: TangentRun) -> TangentResult:
    """The host loop of one tangent run (as :func:`~.simulate.drive` for one member)."""
    import time

    while not run.done:
        seg = run.segment()
        r0 = time.perf_counter()
        got, dy1, dobs = run.solve(seg, run.tangents_of(seg))
        run_s = time.perf_counter() - r0
        run.take(seg, jnp.asarray(dy1), dobs)
        if not run.frames:
            run.record(got.frame)
            continue
        if run.advance(seg, got.segment, run_s):
            run.record(got.frame)
    return run.tangent_result()
