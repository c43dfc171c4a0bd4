r"""The paper's search on $\mu$ for $F_v = 0$ (paper Section 3.3): bracket and bisection on
$\mu$, each $F_v(\mu)$ the vertical force (eq. (eq_Fz)) on the end state of a march to rest.

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$ (the paper's contact-region model, Section 3;
the package docstring of :mod:`dynslip.physics.static` states the whole model).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from dynslip.errors import ComputationError
from dynslip.physics.static.grid import vertical_force_jit
from dynslip.physics.static.march import MarchResult, march, stable_dt


class SearchResult(NamedTuple):
    mu: float
    theta: np.ndarray
    fv: float  # F_v at the returned mu, units G h0 R
    bracket: tuple[float, float]
    fv_bracket: tuple[float, float]  # F_v at both ends of the initial bracket
    evaluations: int
    march: MarchResult


def search_mu(material, theta0, h, mu_lo, mu_hi, *, method="explicit", mu_tol=1e-4,
              fv_tol=1e-3, max_iter=60, **march_kw) -> SearchResult:
    r"""The paper's search: raise $\mu$ if $F_v > 0$, lower it if $F_v < 0$ (bisection on the
    bracket [mu_lo, mu_hi]); each $F_v(\mu)$ is eq. (eq_Fz) on the end state of the march
    from ``theta0``. $F_v(\mu)$ decreases with $\mu$; the search returns the smallest
    $\mu$ (to ``mu_tol``, relative) with $F_v \le$ ``fv_tol`` (units $G h_0 R$; the default
    1e-3 is the size of the discretisation error of $F_v$ at N = 100, measured by the
    identity residual, so that a state that is an equilibrium of the ODE counts as
    $F_v = 0$ on the grid).

    Raises :class:`ComputationError` (with ``.partial`` holding both ends) if $F_v$ does
    not change sign over the bracket."""
    theta0 = jnp.asarray(theta0, float)
    if march_kw.get("dt") is None:
        march_kw["dt"] = float(stable_dt(material, theta0, h))
    cache: dict[float, tuple[float, MarchResult]] = {}

    def fv_of(mu):
        res = march(material, theta0, h, mu, method=method, **march_kw)
        fv = float(vertical_force_jit(material, res.theta, jnp.asarray(h, float)))
        cache[mu] = (fv, res)
        return fv

    f_lo, f_hi = fv_of(mu_lo), fv_of(mu_hi)
    if not (f_lo > fv_tol and f_hi <= fv_tol):
        err = ComputationError(
            f"no friction coefficient in [{mu_lo:g}, {mu_hi:g}] makes F_v vanish: "
            f"F_v({mu_lo:g}) = {f_lo:.4g}, F_v({mu_hi:g}) = {f_hi:.4g} (units G*h0*R); "
            "F_v must be > 0 at the lower end and <= 0 at the upper end"
        )
        err.partial = {
            "mu": (mu_lo, mu_hi),
            "fv": (f_lo, f_hi),
            "theta": (np.asarray(cache[mu_lo][1].theta), np.asarray(cache[mu_hi][1].theta)),
            "march": (cache[mu_lo][1], cache[mu_hi][1]),
        }
        raise err
    a, b = mu_lo, mu_hi
    it = 0
    while b - a > mu_tol * max(1.0, b) and it < max_iter:
        m = 0.5 * (a + b)
        if fv_of(m) > fv_tol:
            a = m
        else:
            b = m
        it += 1
    fv, res = cache[b]
    return SearchResult(b, np.asarray(res.theta), fv, (a, b), (f_lo, f_hi), len(cache), res)
