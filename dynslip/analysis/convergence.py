r"""Mesh convergence of a path's critical friction coefficient (pure numbers, no files).

The critical $\mu_c$ of a loading path is the lowest friction at which it ends trapped
(the paper's "minimum friction coefficient"): the lower edge of the lowest trapping
window. Searched at mesh sizes $N_1 < N_2 < N_3$ with a constant refinement ratio
$r = N_2/N_1 = N_3/N_2$, Richardson extrapolation with the *measured* order

$$p = \frac{\ln|(\mu_2-\mu_1)/(\mu_3-\mu_2)|}{\ln r},\qquad
  \mu_\infty = \mu_3 + \frac{\mu_3-\mu_2}{r^p-1},$$

is applied only when the three values are monotone (otherwise the order is not measurable and
the result is flagged ``extrapolable: false``); its uncertainty is $|\mu_\infty - \mu_3|$ plus
the search's own half-bracket at $N_3$. "Converged" means each of the two refinements moves
$\mu_c$ by at most ``tol`` (0.02).
"""

from __future__ import annotations

import math

__all__ = ["critical_edge", "richardson"]


def critical_edge(windows_detail: list[dict]) -> dict | None:
    """The lowest window's lower edge ``{"value", "err", "open", "unresolved"}`` from a window
    search's ``windows_detail``, or None when no window was found."""
    if not windows_detail:
        return None
    low = min(windows_detail, key=lambda w: w["lo"]["value"])
    return dict(low["lo"])


def richardson(
    ns: list[int], values: list[float], errs: list[float] | None = None, tol: float = 0.02
) -> dict:
    """Richardson extrapolation of ``values`` at mesh sizes ``ns`` (module docstring).

    Example::

        >>> r = richardson([50, 100, 200], [1.3 - 4 / 50, 1.3 - 4 / 100, 1.3 - 4 / 200])
        >>> round(r["order"], 6), round(r["value"], 6)
        (1.0, 1.3)
    """
    errs = list(errs) if errs is not None else [0.0] * len(values)
    out: dict = {"nodes": list(ns), "values": list(values), "tol": tol}
    if len(values) >= 2:
        steps = [abs(b - a) for a, b in zip(values[:-1], values[1:], strict=True)]
        out["changes"] = steps
        out["converged"] = len(steps) >= 2 and all(s <= tol for s in steps[-2:])
    if len(values) != 3:
        return {**out, "extrapolable": False, "reason": "needs exactly three mesh sizes"}
    n1, n2, n3 = ns
    v1, v2, v3 = values
    r1, r2 = n2 / n1, n3 / n2
    if abs(r1 - r2) > 1e-9 * r1 or r1 <= 1:
        return {
            **out,
            "extrapolable": False,
            "reason": f"refinement ratios differ ({r1:g}, {r2:g})",
        }
    d1, d2 = v2 - v1, v3 - v2
    if d1 == 0 or d2 == 0 or (d1 > 0) != (d2 > 0) or abs(d2) >= abs(d1):
        return {**out, "extrapolable": False,
                "reason": "values not monotone with shrinking changes: the order is not measurable"}
    p = math.log(abs(d1 / d2)) / math.log(r1)
    v_inf = v3 + d2 / (r1**p - 1.0)
    return {
        **out,
        "extrapolable": True,
        "order": p,
        "value": v_inf,
        "err": abs(v_inf - v3) + errs[-1],
    }
