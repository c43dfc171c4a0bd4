r"""Members of a study run in lockstep: one ``jax.vmap``-ed segment solve per save segment.

Members that differ only in floats (friction coefficients, speeds, pre-stretch, stage
durations, tolerances...) have identical array shapes: every leaf of
:class:`dynslip.physics.field.StageArgs` and of the model's and friction law's parameters
is an array. :func:`simulate_batch` runs B such members together. Each member keeps its
own host state (:class:`dynslip.physics.simulate.MemberRun`: its stage, time, stop rule,
frames); the host loop advances every member by one save segment per tick with one call
of the segment solve vmapped over the stacked member states and stacked stage loads, so
members may be in different stages and at different times. A member that has finished
(its last stage done, or failed) asks for a zero-length segment: inside the vmapped
``while_loop`` its condition is false from the start and its state is carried unchanged.
Each member's frame is then recorded and its own stop rule checked on it
(:meth:`MemberRun.record`).

Cost. Under ``vmap`` a ``lax.while_loop`` runs while *any* member's condition holds, so
every tick costs the batch's largest number of load increments (and, inside each,
Newton iterations) in that segment, for all B members at once; members that are done
are masked, not skipped. What is gained is the per-call and per-operation overhead of
small (tens of nodes) problems, shared by B members. ``docs/sweeps.md`` has the
measurement.

Compiled once per (static key of the members, B): the key of
:func:`dynslip.physics.simulate.static_key` (solver settings other than the tolerances,
mesh size, the non-array parts of model and loads), which must be equal for every member.
"""

from __future__ import annotations

import time as _time
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.field import _f
from dynslip.physics.protocols import Protocol
from dynslip.physics.sheet import SheetModel
from dynslip.physics.simulate import (
    MemberRun,
    Result,
    _compiled,
    frame_record,
    reset_internal,
    segment_solver,
    simulate,
    static_key,
)

__all__ = ["simulate_batch", "batch_key", "stack"]

_VMAPPED: dict = {}


def _batched_solver(settings):
    """The segment solve of ``settings`` vmapped over everything but the layout."""
    key = id(segment_solver(settings))
    if key not in _VMAPPED:
        solve = segment_solver(settings)
        a = eqx.if_array(0)  # array leaves mapped; a model's float constants (Gent's J_m) broadcast
        _VMAPPED[key] = eqx.filter_jit(
            eqx.filter_vmap(solve, in_axes=(a, None, a, a, a, a, a, a, a, a))
        )
    return _VMAPPED[key]


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


def batch_key(model: SheetModel, protocol: Protocol, kwargs: dict) -> str:
    """Members with equal keys can run in one batch: the compiled solve's static key (solver
    settings but the tolerances, mesh size, non-array parts of model and first stage's loads)."""
    run = MemberRun(model, protocol, **{k: v for k, v in kwargs.items() if k != "on_frame"})
    return repr(static_key(run.settings, run.layout, model, run.args))


def simulate_batch(
    models: Sequence[SheetModel], protocols: Sequence[Protocol], kwargs: Sequence[dict]
) -> list[Result]:
    """Run B members in lockstep; ``kwargs[b]`` are member b's keyword arguments of
    :func:`dynslip.physics.simulate.simulate` (``friction``, ``eps``, ``drag``, ``settings``,
    ``start``, ``on_frame``, ...). Returns one :class:`Result` per member, the same content as
    ``simulate`` returns for it alone (to rounding: the batched linear algebra may order
    sums differently). Raises ``ValueError`` when the members cannot share one compiled
    solve (see :func:`batch_key`); B = 1 is :func:`simulate` itself.
    """
    if not (len(models) == len(protocols) == len(kwargs)) or not models:
        raise ValueError(
            "simulate_batch: give as many models, protocols and keyword sets, at least one"
        )
    if len(models) == 1:
        return [simulate(models[0], protocols[0], **kwargs[0])]
    runs = [MemberRun(m, p, **kw) for m, p, kw in zip(models, protocols, kwargs, strict=True)]
    layout = runs[0].layout
    keys = [static_key(r.settings, r.layout, r.model, r.args) for r in runs]
    if any(k != keys[0] for k in keys[1:]):
        raise ValueError(
            "simulate_batch: the members need different compiled solves (solver settings, mesh "
            "size or a non-array part of the model); run them in separate batches"
        )
    settings = runs[0].settings
    vsolve = _batched_solver(settings)
    models_b = stack(models)
    rtol = np.asarray([float(r.rtol) for r in runs])
    atol = np.asarray([float(r.atol) for r in runs])
    for r in runs:
        r.record(frame_record(r.model, layout, _f(r.t), r.y, r.args, r.settings.contact_threshold))
    n_b = len(runs)
    while not all(r.done for r in runs):
        segs = [r.segment() for r in runs]
        inputs = (
            models_b,
            layout,
            np.stack([np.asarray(s.y) for s in segs]),
            np.asarray([s.t0 for s in segs]),
            np.asarray([s.t1 for s in segs]),
            np.asarray([s.dt0 for s in segs]),
            stack([s.args for s in segs]),
            rtol,
            atol,
            jax.tree_util.tree_map(
                lambda *r: np.stack([np.asarray(x) for x in r]), *[s.rate for s in segs]
            ),
        )
        active = [b for b, r in enumerate(runs) if not r.done]
        compiled = _compiled(
            ("batch", n_b, *keys[0]),
            lambda inputs=inputs: vsolve.lower(*inputs).compile(),
            [runs[b].stats for b in active],
        )
        r0 = _time.perf_counter()
        out = jax.device_get(compiled(*inputs))
        run_s = (_time.perf_counter() - r0) / len(
            active
        )  # the tick's time, shared by its active members
        lockstep = int(
            np.max(out.steps)
        )  # the tick's cost: the largest increment count of the batch
        for b in active:
            r, seg = runs[b], segs[b]
            r.stats["lockstep_steps"] = r.stats.get("lockstep_steps", 0) + lockstep
            if not r.advance(seg, jax.tree_util.tree_map(lambda o, b=b: o[b], out), run_s):
                continue
            r.y = jnp.asarray(r.y)
            if r.heals_between_segments:
                r.y = reset_internal(r.model, layout, r.y, seg.args, _f(r.settings.heal_rate))
            r.record(
                frame_record(r.model, layout, _f(r.t), r.y, seg.args, r.settings.contact_threshold)
            )
    return [r.result() for r in runs]
