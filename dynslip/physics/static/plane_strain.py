r"""The 2D case of paper Section 5: a membrane on a rigid circular cylinder.

With no hoop direction the meridional balance is (paper eq. (eq_2D))

$$-\mu T \le \frac{dT}{d\theta} = -F_f \le \mu T,$$

so any admissible tension obeys Euler's capstan bounds (eq. (eq_2D_sol))
$T_0 e^{-\mu\theta} \le T(\theta) \le T_0 e^{\mu\theta}$, and the vertical force of the
cylinder on the membrane is a boundary term,

$$F_v = R\int_0^{\theta_{max}} (T\cos\theta - F_f\sin\theta)\,d\theta =
R\,T(\theta_{max})\sin\theta_{max} > 0$$

for $\theta_{max} \in (0, \pi)$: no elastically stabilised invagination in 2D.

Nondimensional: tensions by $T_0$ (the tension at the top, $\theta = 0$), forces per
unit length of cylinder by $T_0$ (lengths by $R$). Pure functions of arrays.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = [
    "capstan_ratio",
    "capstan_bounds",
    "tension_from_friction",
    "vertical_force",
    "vertical_force_closed",
    "random_admissible",
]


def capstan_ratio(mu, theta):
    r"""Euler's capstan relation $T_{load}/T_{hold} = e^{\mu\theta}$ (wrap angle $\theta$)."""
    return jnp.exp(mu * theta)


def capstan_bounds(mu, theta, t0=1.0):
    r"""Bounds $(T_0 e^{-\mu\theta}, T_0 e^{\mu\theta})$ of eq. (eq_2D_sol)."""
    return t0 * jnp.exp(-mu * theta), t0 * jnp.exp(mu * theta)


def _cumtrapz(y, x):
    inc = 0.5 * (y[1:] + y[:-1]) * jnp.diff(x)
    return jnp.concatenate([jnp.zeros(1, y.dtype), jnp.cumsum(inc)])


def tension_from_friction(m, theta, t0=1.0):
    r"""Tension for a mobilisation profile $m(\theta) = -F_f/(\mu T) \cdot \mu \in [-\mu, \mu]$:
    $dT/d\theta = m T$, i.e. $T = T_0\exp\int_0^\theta m$ (trapezoidal). Returns $(T, F_f)$
    with $F_f = -m T$."""
    t = t0 * jnp.exp(_cumtrapz(m, theta))
    return t, -m * t


def vertical_force(t, ff, theta):
    r"""$F_v/R = \int_0^{\theta_{max}} (T\cos\theta - F_f\sin\theta)\,d\theta$ (trapezoidal), units
    $T_0$."""
    y = t * jnp.cos(theta) - ff * jnp.sin(theta)
    return jnp.sum(0.5 * (y[1:] + y[:-1]) * jnp.diff(theta))


def vertical_force_closed(t_end, theta_max):
    r"""The boundary form $F_v/R = T(\theta_{max})\sin\theta_{max}$."""
    return t_end * jnp.sin(theta_max)


def random_admissible(key, mu, theta_max, n_profiles: int, n: int, n_modes: int = 6):
    r"""``n_profiles`` random admissible states on ``n`` nodes of $[0, \theta_{max}]$: mobilisation
    $m = \mu\tanh(\sum_k a_k \cos(k\pi\theta/\theta_{max}) + b_k\sin(\ldots))$ with random
    coefficients, so $|F_f| \le \mu T$ everywhere (stuck, slipping either way, or mixed).
    Returns ``theta`` (n,), ``T`` and ``F_f`` (n_profiles, n)."""
    theta = jnp.linspace(0.0, theta_max, n)
    ka, kb = jax.random.split(key)
    a = 3.0 * jax.random.normal(ka, (n_profiles, n_modes))
    b = 3.0 * jax.random.normal(kb, (n_profiles, n_modes))
    k = jnp.arange(n_modes)
    phase = jnp.pi * k[None, :] * theta[:, None] / theta_max  # (n, modes)
    s = a @ jnp.cos(phase).T + b @ jnp.sin(phase).T  # (profiles, n)
    m = mu * jnp.tanh(s)
    t, ff = jax.vmap(lambda mm: tension_from_friction(mm, theta))(m)
    return theta, t, ff
