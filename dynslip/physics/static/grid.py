r"""The grid formulas of the paper's contact-region model (paper Section 3.3, physics.md
Section 2): stretches, tensions and forces from a shape $\theta(\bar r_i)$ on the grid.

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$ (the package docstring of
:mod:`dynslip.physics.static` states the whole model).

On ``N`` equally spaced nodes $\bar r_i = i h$, $h = \bar r_{max}/(N-1)$:

- $\lambda_\theta = d\theta/d\bar r$ (paper eq. (eq_lambda_th)): centred differences, an
  odd ghost node at the pole ($\theta_{-1} = -\theta_1$) and the second-order one-sided
  difference $(3\theta_{N-1} - 4\theta_{N-2} + \theta_{N-3})/2h$ at the outer end;
- $\lambda_\phi = \sin\theta/\bar r$ (eq. (eq_lambda_phi)), $\lambda_\phi = \lambda_\theta$
  at the pole;
- $T_\theta, T_\phi$ from :func:`dynslip.physics.materials.tensions` (eqs. (1)-(2), typo
  fixed);
- $F_m = dT_\theta/d\theta + (T_\theta - T_\phi)\cot\theta$ with
  $dT_\theta/d\theta = (dT_\theta/d\bar r)/\lambda_\theta$ (same differences; $T_\theta$ even at
  the pole, so $F_m = 0$ there);
- $F_N = T_\theta + T_\phi$; Coulomb $|F_f| \le \mu F_N$ (eq. (FOB)), at rest $F_f = -F_m$;
- $F_v = 2\pi\int_0^{\theta_{max}} (F_N\cos\theta - F_f\sin\theta)\sin\theta\,d\theta$
  (eq. (eq_Fz)), trapezoidal in $\bar r$ with $d\theta = \lambda_\theta d\bar r$. At any
  equilibrium $F_v = 2\pi T_\theta(\theta_{max})\sin^2\theta_{max}$ (physics.md Section 2).
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.materials import AbstractMaterial, tensions


def grid(n: int, rbar_max: float) -> np.ndarray:
    """Undeformed radii $\\bar r_i = i\\,\\bar r_{max}/(N-1)$, $i = 0..N-1$ (units of R)."""
    return np.linspace(0.0, rbar_max, n)


def initial_shape(kind: str, rbar, theta_max: float, slope: float = 2.0):
    """A smooth initial shape: ``"linear"``, theta = slope * rbar rescaled to hit theta_max
    at the edge (slope is then theta_max / rbar_max), or ``"power"``, the paper-free smooth
    choice theta = slope*rbar with the end node set to theta_max."""
    rbar = np.asarray(rbar, float)
    if kind == "linear":
        return theta_max * rbar / rbar[-1]
    if kind == "slope":
        th = slope * rbar
        th[-1] = theta_max
        return th
    raise ValueError(f"unknown initial shape {kind!r}")


class GridFields(NamedTuple):
    """Fields of a shape on the grid (all arrays of shape (N,))."""

    lt: jax.Array  # meridional stretch
    lp: jax.Array  # hoop stretch
    tt: jax.Array  # T_theta, units G h0
    tp: jax.Array  # T_phi, units G h0
    fm: jax.Array  # meridional elastic force density F_m, units G h0 / R
    fn: jax.Array  # normal force density F_N, units G h0 / R


def _ddr(f, h, parity: int):
    """d/drbar on the grid: centred inside, ghost f(-h) = parity*f(h) at the pole,
    second-order one-sided at the outer end. Shape (N,) -> (N,)."""
    ghost = parity * f[1:2]
    ext = jnp.concatenate([ghost, f])  # ext[k] = f_{k-1}
    centred = (ext[2:] - ext[:-2]) / (2.0 * h)  # nodes 0..N-2
    end = (3.0 * f[-1] - 4.0 * f[-2] + f[-3]) / (2.0 * h)
    return jnp.concatenate([centred, end[None]])


def fields(material: AbstractMaterial, theta, h) -> GridFields:
    r"""Stretches, tensions and force densities of the shape ``theta`` (N,) on the grid.

    ``h`` is the grid spacing $\bar r_{max}/(N-1)$ (a scalar; may be traced)."""
    theta = jnp.asarray(theta)
    n = theta.shape[0]
    rbar = h * jnp.arange(n, dtype=theta.dtype)
    lt = _ddr(theta, h, -1)
    r_safe = jnp.where(rbar > 0, rbar, 1.0)
    lp = jnp.where(rbar > 0, jnp.sin(theta) / r_safe, lt[0])
    tt, tp = tensions(material, lt, lp)
    dtt = _ddr(tt, h, +1) / lt
    th_safe = jnp.where(rbar > 0, theta, 1.0)
    hoop = jnp.where(rbar > 0, (tt - tp) / jnp.tan(th_safe), 0.0)
    fm = dtt + hoop
    return GridFields(lt, lp, tt, tp, fm, tt + tp)


def _trapz(y, h):
    return h * (jnp.sum(y) - 0.5 * (y[0] + y[-1]))


def vertical_force(material: AbstractMaterial, theta, h):
    r"""$F_v$ of paper eq. (eq_Fz) with $F_f = -F_m$ (units $G h_0 R$):
    $2\pi\int_0^{\bar r_{max}} (F_N\cos\theta + F_m\sin\theta)\sin\theta\,\lambda_\theta\,d\bar r$,
    trapezoidal rule."""
    f = fields(material, theta, h)
    integrand = (f.fn * jnp.cos(theta) + f.fm * jnp.sin(theta)) * jnp.sin(theta) * f.lt
    return 2.0 * jnp.pi * _trapz(integrand, h)


# F_v compiled once per material and grid size (eagerly it costs more than a march near rest)
vertical_force_jit = eqx.filter_jit(vertical_force)


def vertical_force_identity(material: AbstractMaterial, theta, h):
    r"""The boundary form $2\pi T_\theta(\theta_{max})\sin^2\theta_{max}$ (units $G h_0 R$)."""
    f = fields(material, theta, h)
    return 2.0 * jnp.pi * f.tt[-1] * jnp.sin(theta[-1]) ** 2
