r"""``dynslip fit SCENARIO --data OBS.yaml --params a.b,c.d``: the scenario fields that make
its run reproduce the observations, and how well the observations determine them.

1. **Coarse scan** (derivative-free): ``scan`` values of each parameter over its start
   $\times(1 \pm$ ``span``$)$, within its schema's bounds. Each point is a run. The start of
   the least-squares fit is the best point that meets the observations' facts (``trapped``,
   ``past_equator``): the branch the observations were made on.
2. **Levenberg-Marquardt** (:func:`_levenberg_marquardt`; a step at most about 20% of each
   value, :data:`U_SCALE`) on the weighted residuals
   (:mod:`dynslip.analysis.fit`). The residual is a host callback (a run), and its derivative
   comes from a Jacobian provider. The default provider, :func:`central_differences`, uses
   central differences of forward runs with step ``rel_step`` (1e-2) of each parameter. A run
   that fails or leaves the branch returns a large residual, so the step is refused. Bounds are
   kept by fitting a transform of each parameter (:func:`to_params`). optimistix's
   Levenberg-Marquardt was tried first and left for this loop. Its Gauss-Newton linearises at
   every trial point, which costs a whole Jacobian (2k runs) for each refused step. Its first
   step on method 1 was not held to the trust region either: mu_s went from 1.95 to 0.33
   with the radius at about 20%.
3. **At the optimum:** the residual per observation, the Jacobian's singular values and the
   Gauss-Newton confidence region (:func:`dynslip.analysis.fit.confidence`). The run is
   written to ``<out>/optimum/`` with its usual files. ``fit.json`` holds everything and
   ``fit.png`` shows the observations against the fit.

Every run is kept in ``<out>/fit_evaluations.json`` as it ends, written atomically under a
key of what decides it (the resolved scenario, the observations, the parameters, the
settings). A stopped fit given the same command replays its path from them instead of running
them again: the scan and the solver are deterministic.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynslip.analysis.fit import confidence, facts_met, predictions, residuals
from dynslip.data.evaluations import search_key
from dynslip.data.files import write_json
from dynslip.data.folders import check_out, write_result_marker
from dynslip.data.lock import out_lock
from dynslip.errors import ComputationError, InputError
from dynslip.physics.observables import theta_key
from dynslip.schema import base as scen
from dynslip.schema.observations import fit_parameters, load_observations
from dynslip.schema.paths import get_path, set_path

__all__ = ["run_fit", "FitOptions", "CentralDifferences", "central_differences", "to_params",
           "tied_fields", "ForwardSensitivities", "JACOBIANS",
           "EVALUATIONS_FILE", "FAILED_RESIDUAL", "U_SCALE"]

EVALUATIONS_FILE = "fit_evaluations.json"
#: the residual of each observation at a run that failed or left the observations' branch
FAILED_RESIDUAL = 1e3
#: the Jacobian providers by name (``--jacobian``)
JACOBIANS = ("differences", "forward")
#: the fitted variables' scale: a unit step of u changes each value by about this fraction
U_SCALE = 0.2


class CentralDifferences:
    """The default Jacobian provider: ``provider(p, model, lo, hi) -> dm/dp`` (observations x
    parameters) by central differences of the model ``model(p)`` (one run each) with the step
    ``rel_step * |p_j|`` (``rel_step`` where p_j = 0). A step that would cross a bound is taken
    one-sided.

    A jump within the step (the contact set or the branch changing between the neighbours)
    shows as one-sided differences that disagree: where the forward and backward slopes
    differ by more than half the larger, the entry is the smaller one-sided slope (the side
    without the jump), and :attr:`flags` lists it ``(observation, parameter)`` (the last
    call's). The derivative is not defined there, and the fit reports it."""

    def __init__(self, rel_step: float = 1e-2):
        self.rel_step = rel_step
        self.flags: list[tuple[int, int]] = []
        self.describe = (f"central differences of forward runs, step {rel_step:g} of each "
                         "value (one-sided where a jump lies within the step)")

    def __call__(self, p, model, lo, hi):
        m0 = model(p)
        cols, flags = [], []
        for j in range(len(p)):
            h = self.rel_step * (abs(p[j]) if p[j] != 0 else 1.0)
            up, dn = p.copy(), p.copy()
            up[j] = min(p[j] + h, hi[j])
            dn[j] = max(p[j] - h, lo[j])
            fwd = (model(up) - m0) / (up[j] - p[j]) if up[j] > p[j] else None
            bwd = (m0 - model(dn)) / (p[j] - dn[j]) if dn[j] < p[j] else None
            if fwd is None or bwd is None:
                cols.append(fwd if bwd is None else bwd)
                continue
            jump = np.abs(fwd - bwd) > 0.5 * np.maximum(np.abs(fwd), np.abs(bwd)) + 1e-12
            central = 0.5 * (fwd + bwd)  # the central difference on the same step
            cols.append(np.where(jump, np.where(np.abs(fwd) < np.abs(bwd), fwd, bwd), central))
            flags += [(int(i), j) for i in np.flatnonzero(jump)]
        self.flags = flags
        return np.stack(cols, axis=1)


def central_differences(rel_step: float = 1e-2) -> CentralDifferences:
    """The default Jacobian provider (:class:`CentralDifferences`) with step ``rel_step``."""
    return CentralDifferences(rel_step)


class ForwardSensitivities:
    """A Jacobian provider from forward-mode sensitivities through the whole loading path
    (:func:`dynslip.app.sensitivities.sensitivities`): one tangent run at ``p`` gives the
    derivatives of every end-frame scalar. The located edge (``theta_edge``, ``rbar_edge``) and
    theta at the fixed radii (:func:`dynslip.physics.observables.theta_key`) are end-frame
    scalars. The release force (an event of the path) and the path's largest stretch (a
    maximum over the path) are not: their rows come from :class:`CentralDifferences`, run
    only when such a row is present and is not a bound that holds (whose row is zero). A tied
    field's derivative is added along its ratio. Where the sensitivities report a derivative
    that is not defined (``defined`` False: a contact set, stick/slip branch or increment
    count changing within the step), every entry is listed in :attr:`flags` and the reasons
    are kept in :attr:`reasons`."""

    def __init__(self, path, overrides, names, tied, rows, check: bool = True,
                 rel_step: float = 1e-2):
        self.path, self.overrides, self.names, self.tied = Path(path), list(overrides), names, tied
        self.rows, self.check = rows, check
        self.fallback = CentralDifferences(rel_step)
        self.flags: list[tuple[int, int]] = []
        self.reasons: list[str] = []
        self.describe = ("forward-mode sensitivities through the loading path "
                         f"(check of the neighbouring runs: {check}); central differences "
                         f"(step {rel_step:g}) for the release force and the path's stretch")

    @staticmethod
    def frame_key(key: str) -> str | None:
        if key in ("theta_edge", "rbar_edge"):
            return key
        if key.startswith("theta_at_rbar:"):
            return theta_key(float(key.split(":", 1)[1]))
        return None

    def __call__(self, p, model, lo, hi):
        from dynslip.app.sensitivities import sensitivities

        values = dict(zip(self.names, map(float, p), strict=True))
        for n, ties in self.tied.items():
            values.update({t: values[n] * ratio for t, ratio in ties})
        sc = scen.load(self.path, [*self.overrides, *(f"{k}={v!r}" for k, v in values.items())])
        params = list(values)
        sens = sensitivities(sc, params, check=self.check)
        jac = np.full((len(self.rows), len(self.names)), np.nan)
        for i, r in enumerate(self.rows):
            key = self.frame_key(r["key"])
            if key is None or key not in sens.jacobian:
                continue
            g = np.asarray(sens.jacobian[key], float)
            for j, n in enumerate(self.names):
                jac[i, j] = g[params.index(n)] + sum(
                    ratio * g[params.index(t)] for t, ratio in self.tied.get(n, []))
        missing = np.isnan(jac).any(axis=1)
        m0 = model(p)
        for i, r in enumerate(self.rows):  # a bound that holds has no gradient: no runs for it
            if missing[i] and r["kind"] == "bound" and m0[i] <= r["value"]:
                jac[i], missing[i] = 0.0, False
        if missing.any():
            jac[missing] = self.fallback(p, model, lo, hi)[missing]
        self.reasons = [] if sens.defined else list(sens.reasons)
        self.flags = ([(i, j) for i in range(len(self.rows)) for j in range(len(self.names))]
                      if self.reasons else [])
        self.flags += [f for f in self.fallback.flags if missing[f[0]]] if missing.any() else []
        return jac


def to_params(u, start, lo, hi):
    r"""The parameters of the fitted variables ``u`` (0 at ``start``): $lo + (hi - lo)\sigma(u
    + \operatorname{logit}((start - lo)/(hi - lo)))$ between two bounds, $lo + (start - lo)e^u$
    above a lower one, $hi - (hi - start)e^{u}$ below an upper one, $start(1 + u)$ without any.
    Returns ``(p, dp/du)``."""
    u = np.asarray(u, float)
    p, d = np.empty_like(u), np.empty_like(u)
    for j in range(u.size):
        a, b, s = lo[j], hi[j], start[j]
        if math.isfinite(a) and math.isfinite(b):
            x = u[j] + math.log((s - a) / (b - s))
            sig = 1.0 / (1.0 + math.exp(-x))
            p[j], d[j] = a + (b - a) * sig, (b - a) * sig * (1 - sig)
        elif math.isfinite(a):
            p[j] = a + (s - a) * math.exp(u[j])
            d[j] = p[j] - a
        elif math.isfinite(b):
            p[j] = b - (b - s) * math.exp(u[j])
            d[j] = p[j] - b
        else:
            scale = abs(s) if s else 1.0
            p[j], d[j] = s + scale * u[j], scale
    return p, d


def _in_memory_run(data: dict) -> dict:
    """A forming run of the scenario ``data`` in memory (nothing written): its summary, also
    where its verdict is unknown (the fit reads the end state and reports the reasons)."""
    from rich.console import Console

    from dynslip.app import kinds
    from dynslip.app.outputs import Outputs

    console = Console(quiet=True)
    sc = scen.validate_data(data, "<fit>")
    return kinds.run(sc, Outputs(None), console, kinds.preflight(sc, console))


def tied_fields(resolved: dict, names: list[str]) -> dict[str, list[tuple[str, float]]]:
    """The fields that follow a fitted one at a fixed ratio: a static coefficient's kinetic
    sibling (``...mu_s`` -> ``...mu_k``, as a window search ties it) unless fitted too."""
    out: dict[str, list[tuple[str, float]]] = {}
    for n in names:
        if n.endswith(".mu_s"):
            sib = n[: -len("mu_s")] + "mu_k"
            try:
                base, k = float(get_path(resolved, n)), float(get_path(resolved, sib))
            except (KeyError, TypeError, ValueError, InputError):
                continue
            if sib not in names and base:
                out[n] = [(sib, k / base)]
    return out


def _check_producible(resolved: dict, rows: list[dict], source: str) -> None:
    """Refuse an observation the scenario cannot produce (one line, exit 2)."""
    if resolved.get("kind") != "forming":
        raise InputError(f"{source}: kind = {resolved.get('kind')!r}: allowed: a forming "
                         "scenario (the observations are of a formed pocket)")
    stages = resolved.get("physics", {}).get("stages", [])
    ramp = any(st.get("ball") == "pull" and (st.get("until") or {}).get("rule")
               == "ball_speed_above" for st in stages)
    if any(r["key"] == "release_force" for r in rows) and not ramp:
        raise InputError(
            f"{source}: the observation release_force_N cannot be produced by this scenario: it "
            "has no stage pulling the ball until it runs away (ball: pull, until: "
            "ball_speed_above); allowed: such a scenario, or observations without "
            "release_force_N")


class _Evaluations:
    """The runs of one fit, cached by parameter values and kept in ``<out>/`` as each ends."""

    def __init__(self, out: Path, key: str, run: Callable, data: dict, paths: list[str],
                 rows: list[dict], facts: dict, console):
        self.path = out / EVALUATIONS_FILE
        self.key, self.run, self.data, self.paths = key, run, data, paths
        self.rows, self.facts, self.console = rows, facts, console
        self.cache: dict[tuple, dict] = {}
        self.tied: dict[str, list[tuple[str, float]]] = {}
        self.order: list[dict] = []
        self.kept = 0
        try:
            saved = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            saved = None
        if isinstance(saved, dict) and saved.get("key") == key:
            for rec in saved.get("evaluations", []):
                self.cache[self._k(rec["params"])] = rec
            self.kept = len(self.cache)

    @staticmethod
    def _k(p) -> tuple:
        return tuple(float(f"{x:.12g}") for x in p)

    def __call__(self, p, why: str = "") -> dict:
        k = self._k(p)
        if k in self.cache:
            rec = self.cache[k]
        else:
            data = copy.deepcopy(self.data)
            for path, v in zip(self.paths, k, strict=True):
                set_path(data, path, float(v))
                for tied, ratio in self.tied.get(path, []):
                    set_path(data, tied, float(v) * ratio)
            try:
                s = self.run(data)
                pred = predictions(s, self.rows)
                ok, miss = facts_met(s, self.facts)
                rec = {"params": list(k), "status": s.get("status", "ok"),
                       "error": s.get("message", ""), "predictions": _list(pred),
                       "facts_met": ok, "facts_missed": miss, "trapped": s.get("trapped"),
                       "unknown_reasons": s.get("trapped_unknown_reasons", [])}
            except (ComputationError, InputError) as err:  # a point the schema refuses too
                rec = {"params": list(k), "status": "failed", "error": str(err),
                       "predictions": [None] * len(self.rows), "facts_met": False,
                       "facts_missed": ["the run failed"], "trapped": None,
                       "unknown_reasons": []}
            self.cache[k] = rec
            self.order.append(rec)
            write_json(self.path, {"key": self.key, "evaluations": list(self.cache.values())})
            r = self.residual(rec)
            shown = ", ".join(f"{n.rsplit('.', 1)[-1]}={v:.6g}" for n, v in zip(self.paths, k,
                                                                               strict=True))
            self.console.print(f"  run {len(self.cache)} ({why}): {shown}: "
                               + (f"|r| = {np.linalg.norm(r):.4g}" if rec["facts_met"]
                                  else f"[yellow]{'; '.join(rec['facts_missed'])}[/yellow]"),
                               highlight=False)
        return rec

    def residual(self, rec: dict) -> np.ndarray:
        pred = np.array([np.nan if v is None else v for v in rec["predictions"]], float)
        if rec["status"] != "ok" or not rec["facts_met"] or not np.all(np.isfinite(pred)):
            return np.full(len(self.rows), FAILED_RESIDUAL)
        return residuals(pred, self.rows)

    def model(self, p, why: str) -> np.ndarray:
        """The predictions at ``p``; a run without them raises ComputationError (a Jacobian
        needs every neighbour)."""
        rec = self(p, why)
        pred = np.array([np.nan if v is None else v for v in rec["predictions"]], float)
        if rec["status"] != "ok" or not np.all(np.isfinite(pred)):
            raise ComputationError(f"the run at {rec['params']} gives no "
                                   f"value for every observation ({rec['error'] or 'no contact'})")
        return pred


def _list(a) -> list:
    return [float(x) if np.isfinite(x) else None for x in a]


@dataclass(frozen=True)
class FitOptions:
    """The settings of a fit (``dynslip fit``'s options): ``scan`` values of each parameter
    over its start x (1 +- ``span``); at most ``max_steps`` Levenberg-Marquardt steps;
    ``rel_step`` the default Jacobian provider's step; ``run_optimum``: write the run at the
    optimum to ``<out>/optimum/`` (False for a ``run_fn`` that is not the scenario's run);
    ``run_fn(data) -> summary`` runs one scenario (None: a forming run in memory);
    ``jacobian``: the Jacobian provider, ``"differences"`` (:class:`CentralDifferences` with
    ``rel_step``), ``"forward"`` (:class:`ForwardSensitivities`), or a callable
    ``(p, model, lo, hi) -> dm/dp``."""

    scan: int = 3
    span: float = 0.3
    max_steps: int = 15
    rel_step: float = 1e-2
    run_optimum: bool = True
    run_fn: Callable | None = None
    jacobian: Callable | str = "differences"

    def check(self) -> None:
        if not (isinstance(self.scan, int) and 1 <= self.scan <= 9):
            raise InputError(f"--scan = {self.scan!r}: allowed: an integer 1..9 (1: no scan)")
        if not (0 < self.span < 1):
            raise InputError(f"--span = {self.span!r}: allowed: 0 < span < 1")
        if not (isinstance(self.max_steps, int) and 1 <= self.max_steps <= 200):
            raise InputError(f"--max-steps = {self.max_steps!r}: allowed: an integer 1..200")
        if isinstance(self.jacobian, str) and self.jacobian not in JACOBIANS:
            raise InputError(f"--jacobian = {self.jacobian!r}: allowed: "
                             f"{', '.join(JACOBIANS)}")


@dataclass
class _Problem:
    """What one fit works on (built by :func:`run_fit`)."""

    out: Path
    path: Path
    data_file: str
    overrides: list
    rows: list
    pars: list
    ev: _Evaluations
    provider: Callable
    options: FitOptions

    @property
    def names(self) -> list[str]:
        return [p.path for p in self.pars]

    @property
    def lo(self) -> np.ndarray:
        return np.array([p.lo for p in self.pars])

    @property
    def hi(self) -> np.ndarray:
        return np.array([p.hi for p in self.pars])

    @property
    def start(self) -> np.ndarray:
        return np.array([p.start for p in self.pars])


def run_fit(scenario, data_file, params: list[str], overrides=(), *, options=None, out=None,
            force: bool = False, console=None) -> dict:
    """``dynslip fit``: the module docstring, with ``options`` (:class:`FitOptions`). Returns
    the dictionary of ``fit.json``. Bad input raises :class:`InputError` before anything is
    written; a scan with no point on the observations' branch, or a fit whose optimum has no
    Jacobian, raises :class:`ComputationError` (fit.json written)."""
    from rich.console import Console

    console = console or Console()
    options = options or FitOptions()
    options.check()
    path = Path(scenario)
    sc = scen.load(path, list(overrides))
    obs = load_observations(data_file)
    rows = obs.rows()
    pars = fit_parameters(sc, list(params))
    resolved = json.loads(sc.to_json())
    _check_producible(resolved, rows, str(data_file))
    out = Path(out) if out is not None else Path("outputs") / f"{path.stem}_fit"
    check_out(out, force=force, in_place=True)
    names = [p.path for p in pars]
    data = scen.load_data(path, list(overrides))
    tied = tied_fields(resolved, names)
    provider: Callable
    if options.jacobian == "forward":
        provider = ForwardSensitivities(path, overrides, names, tied, rows,
                                        rel_step=options.rel_step)
    elif options.jacobian == "differences":
        provider = central_differences(options.rel_step)
    else:
        assert callable(options.jacobian)
        provider = options.jacobian
    facts = {"trapped": obs.trapped, "past_equator": obs.past_equator}
    key = search_key(resolved, rows, names, tied, options.scan, options.span, options.rel_step,
                     options.max_steps, getattr(provider, "describe", repr(provider)))
    with out_lock(out):
        out.mkdir(parents=True, exist_ok=True)
        write_result_marker(out, "fit")
        ev = _Evaluations(out, key, options.run_fn or _in_memory_run, data, names, rows, facts,
                          console)
        ev.tied = tied
        if ev.kept:
            console.print(f"resuming: {ev.kept} runs kept by an earlier attempt ({ev.path})")
        return _fit(_Problem(out, path, str(data_file), list(overrides), rows, pars, ev,
                             provider, options), console)


def _fit(pb: _Problem, console) -> dict:
    out, path, data_file, overrides, rows, pars, ev, provider = (
        pb.out, pb.path, pb.data_file, pb.overrides, pb.rows, pb.pars, pb.ev, pb.provider)
    names, lo, hi, start = pb.names, pb.lo, pb.hi, pb.start
    scan, span, max_steps = pb.options.scan, pb.options.span, pb.options.max_steps
    console.print(f"fit of {', '.join(names)} to {len(rows)} observations ({data_file})")
    # 1. the coarse scan
    axes = [np.clip(np.linspace(s * (1 - span), s * (1 + span), scan) if scan > 1
                    else np.array([s]), a, b) for s, a, b in zip(start, lo, hi, strict=True)]
    scanned = []
    for point in itertools.product(*axes):
        rec = ev(np.array(point), "scan")
        scanned.append((float(np.sum(ev.residual(rec) ** 2)), rec))
    on_branch = [(c, r) for c, r in scanned
                 if r["facts_met"] and c < len(rows) * FAILED_RESIDUAL**2]
    result = {"scenario": str(path), "overrides": list(overrides), "observations": str(data_file),
              "parameters": [p.model_dump() for p in pars],
              "tied": {n: [{"field": t, "ratio": r} for t, r in v] for n, v in ev.tied.items()},
              "jacobian_provider": getattr(provider, "describe", repr(provider)),
              "scan": [{"params": r["params"], "cost": c, "facts_met": r["facts_met"],
                        "facts_missed": r["facts_missed"]} for c, r in scanned]}
    if not on_branch:
        result["says"] = ("no point of the scan meets the observations' facts and gives every "
                          "observation: no branch to fit")
        write_json(out / "fit.json", result)
        raise ComputationError(f"{path}: {result['says']} (see {out / 'fit.json'})")
    cost0, best = min(on_branch, key=lambda x: x[0])
    p0 = np.array(best["params"])
    console.print(f"scan: {len(on_branch)} of {len(scanned)} points on the branch; start at "
                  + ", ".join(f"{v:.6g}" for v in p0) + f" (cost {cost0:.4g})")
    # 2. Levenberg-Marquardt from the scan's best point
    p_opt, lm = _levenberg_marquardt(ev, provider, p0, lo, hi, len(rows), max_steps)
    # 3. the confidence region at the optimum
    rec = ev(p_opt, "optimum")
    try:
        jac = provider(p_opt, lambda q: ev.model(q, "jacobian"), lo, hi)
    except ComputationError as err:
        result["says"] = f"no Jacobian at the optimum: {err}"
        write_json(out / "fit.json", result)
        raise ComputationError(f"{path}: {result['says']} (see {out / 'fit.json'})") from None
    flags = [{"observation": rows[i]["name"], "parameter": names[j]}
             for i, j in getattr(provider, "flags", [])]
    pred = np.array(rec["predictions"], float)
    res = residuals(pred, rows)
    region = confidence(jac, rows, pred, p_opt, names)
    result.update({
        "start": dict(zip(names, map(float, p0), strict=True)),
        "best": dict(zip(names, map(float, p_opt), strict=True)),
        "solver": lm,
        "cost": float(np.sum(res**2)),
        "residuals": [{**{k: r[k] for k in ("name", "kind", "value", "uncertainty", "unit",
                                             "source")},
                       "model": float(m), "residual": float(x)}
                      for r, m, x in zip(rows, pred, res, strict=True)],
        "residuals_means": ("residual = (model - value) / uncertainty; for a bound, (model - "
                            "max) / uncertainty past it, else 0"),
        "jacobian": [[float(x) for x in row] for row in jac],
        "jacobian_means": "d model / d parameter at the optimum (observations x parameters, in "
                          "their units)",
        "derivative_not_defined": flags,
        "derivative_reasons": list(getattr(provider, "reasons", [])),
        "derivative_not_defined_means": ("entries of the Jacobian at the optimum where a jump "
                                         "lies within the difference step (the one-sided "
                                         "differences disagree): the derivative is not defined "
                                         "there; the entry is the side without the jump"),
        **region,
        "optimum_trapped": rec["trapped"],
        "optimum_unknown_reasons": rec["unknown_reasons"],
        "runs": len(ev.cache),
    })
    if pb.options.run_optimum:
        result["optimum_run"] = _optimum_run(out, path, overrides, names, p_opt, ev.tied,
                                             console)
    result["says"] = _words(result)
    write_json(out / "fit.json", result)
    from dynslip.plot.fit import plot_fit

    plot_fit(result, out / "fit.png")
    console.print(f"[bold]{result['says']}[/bold]", highlight=False)
    return result


def _levenberg_marquardt(ev, provider, p0, lo, hi, m, max_steps):
    r"""Levenberg-Marquardt on the variables of :func:`to_params` (scaled by :data:`U_SCALE`):
    ``(p at the end, what the solver says)``.

    The step solves $(J^TJ + \lambda\,\mathrm{diag}(J^TJ) + \lambda\epsilon I)\,d = -J^Tr$
    (Marquardt's scaling), cut to the trust radius ($\|d\|_\infty \le 1$: about U_SCALE of
    each value). The gain ratio $\rho$ of actual over predicted reduction accepts the step
    ($\rho > 10^{-3}$) and updates $\lambda$ (Nielsen: $\lambda \max(1/3, 1 - (2\rho -
    1)^3)$ on success, doubling factors on failure). The Jacobian is taken only at accepted
    points: each costs 2k runs, a refused step one. Stops when the step or the cost's
    relative change falls below 1e-6, or after ``max_steps`` steps."""

    def at(u):
        p, dp = to_params(U_SCALE * u, p0, lo, hi)
        return p, U_SCALE * dp

    def jac_u(p, dp, rec):
        jac = provider(p, lambda q: ev.model(q, "jacobian"), lo, hi)
        s = np.array([r["uncertainty"] for r in ev.rows], float)
        pred = np.array(rec["predictions"], float)
        bound = np.array([r["kind"] == "bound" for r in ev.rows])
        vals = np.array([r["value"] for r in ev.rows], float)
        live = ~bound | (pred > vals)  # a bound that holds has no gradient
        return (jac / s[:, None]) * live[:, None] * dp[None, :]

    k = p0.size
    u = np.zeros(k)
    p, dp = at(u)
    rec = ev(p, "fit")
    r = ev.residual(rec)
    jac = jac_u(p, dp, rec)
    lam, nu = 1e-3, 2.0
    cost = float(r @ r)
    steps, refused, why = 0, 0, f"max_steps ({max_steps}) reached"
    while steps < max_steps:
        steps += 1
        a, g = jac.T @ jac, jac.T @ r
        diag = np.diag(a)
        d = np.linalg.lstsq(a + lam * np.diag(diag) + lam * 1e-9 * max(diag.max(), 1.0)
                            * np.eye(k), -g, rcond=None)[0]
        big = np.max(np.abs(d))
        if big > 1.0:
            d = d / big
        predicted = cost - float(np.sum((r + jac @ d) ** 2))
        p_new, dp_new = at(u + d)
        rec_new = ev(p_new, "fit")
        r_new = ev.residual(rec_new)
        cost_new = float(r_new @ r_new)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        if rho > 1e-3:
            u, p, dp, rec, r = u + d, p_new, dp_new, rec_new, r_new
            small_change = abs(cost - cost_new) <= 1e-6 * max(cost, 1e-300)
            cost = cost_new
            lam *= max(1 / 3, 1 - (2 * rho - 1) ** 3)
            nu = 2.0
            if np.max(np.abs(d)) < 1e-6 or small_change or cost < 1e-20:
                why = "converged"
                break
            try:
                jac = jac_u(p, dp, rec)
            except ComputationError as err:
                why = f"no Jacobian at the last accepted point: {err}"
                break
        else:
            refused += 1
            lam *= nu
            nu *= 2
            if np.max(np.abs(d)) < 1e-6:
                why = "converged (the refused step fell below 1e-6)"
                break
            if lam > 1e12:
                why = "converged (no step reduces the cost further)"
                break
    return p, {"name": "Levenberg-Marquardt (dynslip.app.fit)", "steps": steps,
               "refused_steps": refused, "max_steps": max_steps, "result": why,
               "trust_region": f"each step at most {U_SCALE:g} of each value (in the scaled "
                               "variables); Marquardt's damping, Nielsen's update",
               "cost": cost}


def _optimum_run(out: Path, path: Path, overrides, names, p, tied, console) -> dict:
    """The run at the optimum written to ``<out>/optimum/`` (its usual files)."""
    from dynslip.app import kinds

    values = dict(zip(names, map(float, p), strict=True))
    for n, ties in tied.items():
        values.update({t: values[n] * ratio for t, ratio in ties})
    sets = [f"{n}={v!r}" for n, v in values.items()]
    overrides = [o for o in overrides if o.split("=", 1)[0].strip() not in values]
    folder = out / "optimum"
    try:
        sc = scen.load(path, [*overrides, *sets])
        kinds.run_into(sc, folder, console, force=True)
        return {"folder": str(folder), "command": _command(path, [*overrides, *sets], folder)}
    except ComputationError as err:
        kept = getattr(err, "dynslip_kept", None)
        return {"folder": str(kept) if kept else None, "error": str(err),
                "command": _command(path, [*overrides, *sets], folder)}


def _command(path, sets, folder) -> str:
    return (f"dynslip run {path} " + " ".join(f"--set {s}" for s in sets) + f" --out {folder}")


def _words(r: dict) -> str:
    best = ", ".join(
        f"{n} = {v:.5g}" + (f" +- {r['intervals'][n]['sd']:.2g}" if r["intervals"][n] else
                            " (unidentifiable)")
        for n, v in r["best"].items())
    worst = max(r["residuals"], key=lambda x: abs(x["residual"]))
    weak = f"; {len(r['unidentifiable'])} unidentifiable directions" if r["unidentifiable"] else ""
    return (f"best: {best}; cost {r['cost']:.3g}, largest residual {worst['residual']:+.2g} "
            f"({worst['name']}){weak}; solver {r['solver']['result']} in "
            f"{r['solver']['steps']} steps, {r['runs']} runs")
