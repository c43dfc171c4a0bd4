r"""The numbers of a fit (``dynslip fit``), from runs' summaries and a Jacobian: what the model
predicts for each observation, the weighted residuals, whether a run meets the observations'
facts, and the Gauss-Newton confidence region.

**Residuals.** For an observed value $y_i \pm \sigma_i$ and the model's $m_i(p)$,
$r_i = (m_i - y_i)/\sigma_i$. For a bound $m_i \le b_i$ (``kind: bound``),
$r_i = \max(0, m_i - b_i)/\sigma_i$: nothing while it holds.

**The confidence region.** With $J = \partial m/\partial p$ at the optimum and
$W = \operatorname{diag}(\sigma_i^{-2})$ (bounds that hold are inactive rows: they carry no
information), the Gauss-Newton covariance is $C = (J^T W J)^{-1}$, and the intervals are
$p_j \pm \sqrt{C_{jj}}$ (one standard deviation, linearised). The covariance is read through
the singular values $s_k$ of the weighted Jacobian in relative parameter units,
$\tilde J = W^{1/2} J \operatorname{diag}(p)$: a change of $p$ by the fraction $\delta$ along the
right singular vector $v_k$ moves the residuals by $s_k\delta$ standard deviations. A
direction with $s_k < 10^{-3} s_1$ (:data:`UNIDENTIFIABLE`), or with $s_k\delta < 1$ for every
$\delta$ up to 1 (a whole factor of 2 in the parameters not worth one standard deviation:
$s_k < 1$), is **unidentifiable**. It is reported with its parameter combination, and the
intervals of the parameters it involves are unbounded (None). The covariance is the
pseudo-inverse over the identifiable directions.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["UNIDENTIFIABLE", "predictions", "residuals", "facts_met", "confidence", "model_value"]

UNIDENTIFIABLE = 1e-3
"""Singular values below this fraction of the largest are unidentifiable directions."""


def model_value(summary: dict, key: str) -> float:
    """What the model gives for an observation's ``key``
    (:meth:`dynslip.schema.observations.Observations.rows`) in a run's ``summary``; NaN where
    the run has none (no contact, no release stage)."""
    smooth = summary.get("smooth") or {}
    if key in ("theta_edge", "rbar_edge"):
        v = smooth.get(key)
    elif key.startswith("theta_at_rbar:"):
        v = (smooth.get("theta_at_rbar") or {}).get(key.split(":", 1)[1])
    elif key == "release_force":
        v = summary.get("release_force")
        v = abs(v) if v is not None else None
    elif key == "path_max_stretch":
        v = (summary.get("largest_stretch") or {}).get("path_max")
    else:
        raise KeyError(key)
    return float(v) if v is not None else math.nan


def predictions(summary: dict, rows: list[dict]) -> np.ndarray:
    """The model's value for every observation row (NaN where the run has none)."""
    return np.array([model_value(summary, r["key"]) for r in rows], float)


def residuals(pred: np.ndarray, rows: list[dict]) -> np.ndarray:
    """The weighted residuals (module docstring) of the predictions ``pred``."""
    y = np.array([r["value"] for r in rows], float)
    s = np.array([r["uncertainty"] for r in rows], float)
    bound = np.array([r["kind"] == "bound" for r in rows])
    r = (pred - y) / s
    return np.where(bound, np.maximum(r, 0.0), r)


def facts_met(summary: dict, facts: dict) -> tuple[bool, list[str]]:
    """Whether a run meets the observations' qualitative facts (``trapped``,
    ``past_equator``; None: not asked), and what it misses, in words."""
    miss = []
    want = facts.get("trapped")
    if want is not None and summary.get("trapped") is not want:
        miss.append(f"trapped is {summary.get('trapped')}, observed {want}")
    want = facts.get("past_equator")
    past = (summary.get("trap_criterion") or {}).get("past")
    if want is not None and past is not want:
        miss.append(f"contact past the equator is {past}, observed {want}")
    return not miss, miss


def confidence(jac: np.ndarray, rows: list[dict], pred: np.ndarray, p: np.ndarray,
               names: list[str]) -> dict:
    """The Gauss-Newton confidence region at ``p`` (module docstring) from the Jacobian
    ``jac`` (observations x parameters, in the observations' and parameters' units) and the
    predictions ``pred`` there."""
    s = np.array([r["uncertainty"] for r in rows], float)
    active = np.array([r["kind"] != "bound" or pred[i] > r["value"] for i, r in enumerate(rows)])
    jw = (jac / s[:, None])[active]
    scale = np.where(p != 0, np.abs(p), 1.0)
    jt = jw * scale[None, :]
    k = len(p)
    if jt.shape[0] == 0:
        u = np.zeros((0, 0))
        sv = np.zeros(k)
        vt = np.eye(k)
    else:
        u, sv, vt = np.linalg.svd(jt, full_matrices=True)
        sv = np.concatenate([sv, np.zeros(k - sv.size)]) if sv.size < k else sv
    top = float(sv[0]) if sv.size and sv[0] > 0 else 0.0
    weak = [(float(sv[i]), vt[i]) for i in range(k)
            if not (top > 0 and sv[i] >= UNIDENTIFIABLE * top and sv[i] >= 1.0)]
    # covariance in relative units over the identifiable directions, then in physical units
    cov_rel = np.zeros((k, k))
    for i in range(k):
        if top > 0 and sv[i] >= UNIDENTIFIABLE * top and sv[i] >= 1.0:
            cov_rel += np.outer(vt[i], vt[i]) / sv[i] ** 2
    cov = cov_rel * np.outer(scale, scale)
    involved = np.zeros(k, bool)
    for _, v in weak:
        involved |= np.abs(v) > 0.1
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    intervals = {
        n: (None if involved[j] else {"value": float(p[j]), "sd": float(sd[j]),
                                      "lo": float(p[j] - sd[j]), "hi": float(p[j] + sd[j])})
        for j, n in enumerate(names)}
    return {
        "singular_values": [float(x) for x in sv],
        "right_singular_vectors": [{n: float(v[j]) for j, n in enumerate(names)} for v in vt],
        "covariance": [[float(x) for x in row] for row in cov],
        "intervals": intervals,
        "unidentifiable": [
            {"singular_value": sv_i,
             "direction": {n: float(v[j]) for j, n in enumerate(names) if abs(v[j]) > 1e-3},
             "says": _words(v, names, sv_i)}
            for sv_i, v in weak],
        "active_observations": [r["name"] for i, r in enumerate(rows) if active[i]],
        "means": ("singular values of the weighted Jacobian in relative parameter units "
                  "(residual standard deviations per fractional change along each right "
                  "singular vector); covariance (J^T W J)^-1 in the parameters' units over the "
                  "identifiable directions; intervals: value +- one standard deviation "
                  "(linearised), None for a parameter in an unidentifiable direction; "
                  f"unidentifiable: a singular value below {UNIDENTIFIABLE:g} of the largest, "
                  "or below 1 (doubling the parameters along it moves the observations by "
                  "less than one standard deviation)"),
    }


def _words(v: np.ndarray, names: list[str], sv: float) -> str:
    parts = [f"{'+' if v[j] > 0 else '-'}{abs(v[j]):.2g} d ln {n}" for j, n in enumerate(names)
             if abs(v[j]) > 1e-3]
    return (f"the observations do not determine {' '.join(parts)} (singular value {sv:.3g}: "
            "a fractional change along it moves them by that many standard deviations)")
