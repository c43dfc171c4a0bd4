"""Sensitivities of a forming run's recorded scalars to its physical parameters, through the
whole loading path (docs/sensitivities.md): :func:`sensitivities`.

The derivative is forward mode through every save segment, stage hand-off and stop time
(:mod:`dynslip.physics.driver.tangent`). Where it is not the derivative of the run (the
contact set, the stick/slip branch or the increment count changes within a step of the
parameter) the result says so, with the reason: the run is also made at ``p - h`` and
``p + h`` for every parameter, and each is compared with the base run, and the central
difference with the tangent.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.errors import InputError
from dynslip.physics.driver.member import MemberRun
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.driver.tangent import TangentRun, Variant, drive_tangent, observables
from dynslip.schema.base import validate_data
from dynslip.schema.paths import get_path, set_path

__all__ = ["Sensitivities", "sensitivities"]

#: the relative step of the neighbouring runs (``h = step * |p|``, or ``step`` where p = 0)
STEP = 1e-4
#: the tangent and the central difference agree where they differ by at most this fraction
#: of the larger, or by at most :data:`NOISE` of the value's scale over the step
CD_RTOL = 2e-2
#: the relative rounding noise of a run's scalars (a compiled step's rounding, amplified by
#: hundreds of Newton-solved increments: ~1e-9 measured, docs/sensitivities.md)
NOISE = 1e-8


@dataclass
class Sensitivities:
    """What :func:`sensitivities` returns.

    ``params``: the dotted paths; ``values``: each recorded scalar of the end frame
    (:func:`~dynslip.physics.driver.tangent.observables`); ``jacobian``: its derivative in
    each parameter, per unit of the parameter as the scenario states it, (n_params,);
    ``defined``: False where a tangent is not the run's derivative, ``reasons`` why (one line
    each); ``step``: the ``h`` of each parameter; ``central``: the central differences
    (n_params,) of the neighbouring runs (empty without the check); ``events``: per condition
    stage that met its rule, its event's ``time``, ``dt`` (the stop time's derivative, s per
    unit; NaN where the stage stopped at rest, where its stop time moves nothing), ``values`` and
    ``jacobian`` at the frame it stopped on; ``stats``: timings; ``notes``: what was not
    compared, and why (not reasons against the derivative).
    """

    params: list[str]
    values: dict[str, float]
    jacobian: dict[str, np.ndarray]
    defined: bool
    reasons: list[str]
    step: dict[str, float] = field(default_factory=dict)
    central: dict[str, np.ndarray] = field(default_factory=dict)
    events: dict[str, dict] = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def matrix(self, names=None) -> tuple[list[str], np.ndarray]:
        """``(names, J)``: the Jacobian as an (n_obs, n_params) array, rows in ``names``
        (default: every value that is finite)."""
        if names is None:
            names = [k for k, v in self.values.items() if np.isfinite(v)]
        return list(names), np.stack([self.jacobian[k] for k in names])


def _number(data: dict, path: str) -> float:
    try:
        value = get_path(data, path)
    except KeyError:
        raise InputError(f"params: field '{path}' does not exist in the scenario") from None
    if isinstance(value, bool) or not isinstance(value, float):
        raise InputError(f"params: field '{path}' is {value!r}: a parameter to differentiate "
                         "must be a real number (not a count, a name or a switch)")
    return float(value)


def _world(data: dict, path: str, value: float, source: str):
    d = json.loads(json.dumps(data))
    set_path(d, path, value, source)
    return validate_data(d, source).world()


def _member(w) -> MemberRun:
    """The host state of a world's run before its first segment (its start state, loads)."""
    return MemberRun(w.model, w.protocol, **w.simulate_kwargs())


def _tangent(plus, minus, width: float, path: str):
    """The difference quotient of two worlds' model (inexact array leaves) and start state;
    :class:`InputError` where the parameter moves a part of the model that is not an array
    (a body's size, the mesh's size: not traced)."""
    (pd, ps), (md, ms) = (eqx.partition(w.model, eqx.is_inexact_array) for w in (plus, minus))
    same_tree = str(jax.tree_util.tree_structure(pd)) == str(jax.tree_util.tree_structure(md))
    if repr(ps) != repr(ms) or not same_tree:
        raise InputError(f"params: field '{path}' changes a part of the model that is not a "
                         "traced value (a body's size or the mesh's node count); allowed: the "
                         "physical parameters of the material, the friction law, the penalty "
                         "and the stages")
    dm = jax.tree_util.tree_map(lambda a, b: (jnp.asarray(a) - jnp.asarray(b)) / width, pd, md)
    dy = (jnp.asarray(_member(plus).y) - jnp.asarray(_member(minus).y)) / width
    return dm, dy


def _scalars(frame) -> dict[str, float]:
    """The differentiated scalars of a host frame (its time and stage left out)."""
    return {k: float(np.asarray(v)) for k, v in observables(frame).items()
            if k not in ("time", "stage")}


def _compare(base, other, label: str) -> list[str]:
    """Why the run ``other`` (at a neighbouring value) is on another branch than ``base``."""
    if other.failed:
        return [f"{label}: the run failed ({other.failed})"]
    out = []
    fb, fo = base.frames[-1], other.frames[-1]
    if len(base.frames) != len(other.frames):
        out.append(f"{label}: {len(other.frames)} frames against {len(base.frames)} (a stop "
                   "moved across a save time)")
    sb, so = np.asarray(fb["state"]), np.asarray(fo["state"])
    cb, co = sb != 0, so != 0
    if not np.array_equal(cb, co):
        out.append(f"{label}: the end frame's contact set changes (nodes "
                   f"{np.flatnonzero(cb != co).tolist()})")
    elif not np.array_equal(sb, so):
        out.append(f"{label}: the end frame's stick/slip branch changes (nodes "
                   f"{np.flatnonzero(sb != so).tolist()})")
    if base.stats["steps"] != other.stats["steps"]:
        out.append(f"{label}: {other.stats['steps']} increments against {base.stats['steps']}")
    return out


def sensitivities(scn, params: list[str], *, step: float = STEP, check: bool = True,
                  cd_rtol: float = CD_RTOL, noise: float = NOISE) -> Sensitivities:
    """The derivatives of the end frame's recorded scalars in ``params`` (dotted paths of
    the scenario ``scn``, as ``--set`` names them), forward mode through the whole path, in
    every direction at once (docs/sensitivities.md).

    ``check``: also run the path at ``p -+ h`` (``h = step |p|``, ``step`` where p = 0) for
    each parameter and report, as not defined, a change of the end frame's contact set or
    stick/slip branch, of the increment or frame count, or a central difference that
    disagrees with the tangent by more than ``cd_rtol`` of the larger (and more than
    ``noise`` of the value's scale over 2h). Without it, ``defined`` reflects only what the
    tangent run itself saw (a stop rule without an event function, a segment count that
    moves). Raises :class:`InputError` for an unknown path, a value that is not a number, a
    parameter that is not a traced value, or a step that leaves the field's bounds.
    """
    if getattr(scn, "kind", None) != "forming":
        raise InputError(f"sensitivities: a forming scenario is needed, got kind "
                         f"{getattr(scn, 'kind', None)!r}")
    if getattr(scn, "start_from", None):
        raise InputError("start_from: sensitivities start from the flat sheet (a saved state "
                         "has no tangent); remove start_from")
    params = list(params)
    if not params or len(set(params)) != len(params):
        raise InputError(f"params: {params!r}: give one or more distinct dotted paths")
    source = f"{scn.name or '<scenario>'}: sensitivities"
    data = json.loads(scn.to_json())
    base = validate_data(json.loads(json.dumps(data)), source).world()
    values = {p: _number(data, p) for p in params}
    hs = {p: step * abs(v) if v != 0 else step for p, v in values.items()}
    worlds = {p: (_world(data, p, values[p] - hs[p], source),
                  _world(data, p, values[p] + hs[p], source)) for p in params}
    tans = [_tangent(worlds[p][1], worlds[p][0], 2 * hs[p], p) for p in params]
    dmodel = jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *[t[0] for t in tans])
    dy0 = jnp.stack([t[1] for t in tans])
    variants = []
    for p in params:
        m, pl = (_member(w) for w in worlds[p])
        variants.append(Variant(minus=(worlds[p][0].protocol, m.loads),
                                plus=(worlds[p][1].protocol, pl.loads), width=2 * hs[p]))
    t0 = time.perf_counter()
    run = TangentRun(base.model, base.protocol, dmodel=dmodel, dy0=dy0, variants=variants,
                     **base.simulate_kwargs())
    res = drive_tangent(run)
    tangent_s = time.perf_counter() - t0
    reasons = list(res.reasons)
    if res.failed:
        reasons.append(f"the run failed: {res.failed}")
    end = _scalars(res.frames[-1])
    jac = {k: np.asarray(res.dframes[-1][k], float) for k in end}
    out = Sensitivities(params=params, values=end, jacobian=jac, defined=False, reasons=reasons,
                        step=hs, stats={"tangent_s": tangent_s,
                                        "compile_s": res.stats["compile_s"],
                                        "steps": res.stats["steps"]})
    for stage, ev in res.events.items():
        i = ev["frame"]
        out.events[stage] = {"time": ev["time"], "dt": np.asarray(ev["dt"], float),
                             "values": _scalars(res.frames[i]),
                             "jacobian": {k: np.asarray(v, float)
                                          for k, v in res.dframes[i].items()}}
    moved = [name for name, ev in res.events.items() if not ev["at_rest"]]
    if check:
        _check(out, res, worlds, params, hs, cd_rtol if not moved else None, noise)
    if check and moved:
        out.notes.append(
            f"central differences not compared with the tangents: the stop of {moved} moves "
            "with its event in the tangent (dt*/dp), while a run stops at the save time after "
            "the event, a step function of the parameter")
    out.defined = not out.reasons
    return out


def _check(out: Sensitivities, res, worlds, params, hs, cd_rtol, noise) -> None:
    """The neighbouring runs: branch changes, and the central differences against the
    tangents (into ``out``; ``cd_rtol`` None: the differences kept, not compared)."""
    t0 = time.perf_counter()
    cds = {k: np.full(len(params), np.nan) for k in out.values}
    for j, p in enumerate(params):
        ends = []
        for sign, w in zip("-+", worlds[p], strict=True):
            r = simulate(w.model, w.protocol, **w.simulate_kwargs())
            out.reasons += _compare(res, r, f"{p} {sign} {hs[p]:.3g}")
            ends.append(_scalars(r.frames[-1]))
        for k in out.values:
            cds[k][j] = (ends[1][k] - ends[0][k]) / (2 * hs[p])
    out.central = cds
    if cd_rtol is None:
        out.stats["check_s"] = time.perf_counter() - t0
        return
    for k, v in out.values.items():
        for j, p in enumerate(params):
            a, b = out.jacobian[k][j], cds[k][j]
            if not (np.isfinite(v) and np.isfinite(a) and np.isfinite(b)):
                continue
            diff = abs(a - b)
            if diff > cd_rtol * max(abs(a), abs(b)) and diff > noise * max(abs(v), 1.0) / hs[p]:
                out.reasons.append(f"d{k}/d{p}: the tangent {a:.6g} and the central difference "
                                   f"{b:.6g} disagree (step {hs[p]:.3g})")
    out.stats["check_s"] = time.perf_counter() - t0
