r"""The well-posed form of the paper's model: the fully mobilised family (physics.md
Section 2).

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$ (the paper's contact-region model, Section 3;
the package docstring of :mod:`dynslip.physics.static` states the whole model).

$F_m = +\mu F_N$ from the pole to the switch point, $F_m = -\mu F_N$ beyond: an ODE in
$\bar r$ solved by shooting with unknowns (pole stretch, $\mu$, switch radius) and end
conditions $\theta(\bar r_{max}) = \theta_{max}$, $T_\theta(\bar r_{max}) = 0$, and the
switch angle $\theta(\bar r_s) = \theta_s$ that parameterises the family
(:func:`solve_member`, :func:`solve_family`, :func:`sample_member`).
"""

from __future__ import annotations

from typing import NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx


def _tt_scalar(material, lt, lp):
    return jax.grad(material.energy, 0)(lt, lp) / lp


def _tp_scalar(material, lt, lp):
    return jax.grad(material.energy, 1)(lt, lp) / lt


def _ode_rhs(r, y, args):
    r"""$y = (\theta, \lambda_\theta)$; $F_m = s\mu F_N$ solved for $\theta''$:
    $\theta'' = [\lambda_\theta(s\mu F_N - (T_\theta - T_\phi)\cot\theta)
       - \partial_{\lambda_\phi}T_\theta\,(\lambda_\theta\cos\theta - \lambda_\phi)/\bar r]
       / \partial_{\lambda_\theta}T_\theta$."""
    material, mu, s = args
    th, lt = y
    lp = jnp.sin(th) / r
    tt = _tt_scalar(material, lt, lp)
    tp = _tp_scalar(material, lt, lp)
    dtt_dlt, dtt_dlp = jax.grad(_tt_scalar, argnums=(1, 2))(material, lt, lp)
    dlp_dr = (lt * jnp.cos(th) - lp) / r
    rhs = lt * (s * mu * (tt + tp) - (tt - tp) / jnp.tan(th)) - dtt_dlp * dlp_dr
    return jnp.stack([lt, rhs / dtt_dlt])


_R0 = 1e-5  # start of the integration near the pole (theta = lambda0 r there)


def _solve_segment(material, mu, s, r0, r1, y0, rtol, saveat):
    return diffrax.diffeqsolve(
        diffrax.ODETerm(_ode_rhs),
        diffrax.Tsit5(),
        t0=r0,
        t1=r1,
        dt0=None,
        y0=y0,
        args=(material, mu, s),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol),
        saveat=saveat,
        adjoint=diffrax.ForwardMode(),
        max_steps=20_000,
        throw=False,
    )


def _shoot(material, p, theta_s, rbar_max, rtol, by_radius=0.0):
    """Residuals of the fully mobilised BVP for unknowns p = (lambda0, mu, rbar_s): the
    switch condition (theta(rbar_s) - theta_s, or rbar_s - theta_s when ``by_radius`` is 1,
    ``theta_s`` then holding the switch radius), theta(rbar_max), T_theta(rbar_max)."""
    lam0, mu, rs = p
    y0 = jnp.stack([lam0 * _R0, lam0])
    a = _solve_segment(material, mu, 1.0, _R0, rs, y0, rtol, diffrax.SaveAt(t1=True))
    ys = a.ys[-1]
    b = _solve_segment(material, mu, -1.0, rs, rbar_max, ys, rtol, diffrax.SaveAt(t1=True))
    ye = b.ys[-1]
    lp_e = jnp.sin(ye[0]) / rbar_max
    switch = (1.0 - by_radius) * (ys[0] - theta_s) + by_radius * (rs - theta_s)
    return jnp.stack([switch, ye[0], _tt_scalar(material, ye[1], lp_e)]), ys[0]


class FamilyMember(NamedTuple):
    """A member of the fully mobilised family."""

    lam0: float  # stretch at the pole
    mu: float  # friction coefficient
    rbar_s: float  # switch radius (F_m changes sign), units R
    theta_s: float  # switch angle, rad
    residual: float  # largest residual of the end conditions
    converged: bool


@eqx.filter_jit
def _solve_member_jit(material, value, by_radius, theta_max, rbar_max, guess, rtol, atol):
    def fn(p, args):
        res, _ = _shoot(material, p, value, rbar_max, rtol, by_radius)
        return res - jnp.stack([0.0, theta_max, 0.0])

    sol = optx.root_find(fn, optx.Newton(rtol=atol, atol=atol), guess, max_steps=60, throw=False)
    res, theta_s = _shoot(material, sol.value, value, rbar_max, rtol, by_radius)
    res = res - jnp.stack([0.0, theta_max, 0.0])
    return sol.value, jnp.max(jnp.abs(res)), theta_s


def solve_member(material, value, theta_max, rbar_max, guess=(2.0, 1.0, 0.25), *,
                 by: str = "switch_angle", rtol=1e-10, atol=1e-9) -> FamilyMember:
    r"""The fully mobilised member whose switch point is ``value``: shooting from the pole
    ($\theta = \lambda_0\bar r$, $\lambda_\theta = \lambda_0$ at $\bar r = 10^{-5}$) with Newton on
    $(\lambda_0, \mu, \bar r_s)$ so that $\theta(\bar r_{max}) = \theta_{max}$,
    $T_\theta(\bar r_{max}) = 0$ and either $\theta(\bar r_s) = $ ``value`` (``by="switch_angle"``,
    rad) or $\bar r_s = $ ``value`` (``by="switch_radius"``, units of R).

    In the ODE the largest meridional stretch sits exactly at the switch point
    ($\lambda_\theta' $ changes sign there), so the switch angle is also where the largest
    stretch sits."""
    if by not in ("switch_angle", "switch_radius"):
        raise ValueError(f"unknown switch parameter {by!r}")
    by_radius = 1.0 if by == "switch_radius" else 0.0
    p, res, theta_s = _solve_member_jit(material, jnp.asarray(value, float), jnp.asarray(by_radius),
                               jnp.asarray(theta_max, float), jnp.asarray(rbar_max, float),
                               jnp.asarray(guess, float), rtol, atol)
    p = np.asarray(p)
    res = float(res)
    ok = bool(np.isfinite(res) and res < 1e-6 and p[0] > 0 and 0 < p[2] < rbar_max and p[1] > 0)
    theta_s = float(theta_s) if ok else float("nan")
    return FamilyMember(float(p[0]), float(p[1]), float(p[2]), theta_s, res, ok)


def solve_family(material, values, theta_max, rbar_max, guess=(2.0, 1.0, 0.25), **kw):
    """Members along ``values`` of the switch parameter, each started from its neighbour
    (continuation). Members that do not converge are returned with ``converged=False``."""
    out = []
    g = guess
    for v in values:
        m = solve_member(material, v, theta_max, rbar_max, g, **kw)
        out.append(m)
        if m.converged:
            g = (m.lam0, m.mu, m.rbar_s)
    return out


@eqx.filter_jit
def _sample_jit(material, lam0, mu, rs, rbar_max, rgrid, rtol):
    y0 = jnp.stack([lam0 * _R0, lam0])
    # Grid points before the switch come from the first segment, the rest from the second.
    ra = jnp.clip(rgrid, _R0, rs)
    a = _solve_segment(material, mu, 1.0, _R0, rs, y0, rtol, diffrax.SaveAt(ts=ra))
    rb = jnp.clip(rgrid, rs, rbar_max)
    b = _solve_segment(material, mu, -1.0, rs, rbar_max, a.ys[-1], rtol, diffrax.SaveAt(ts=rb))
    th = jnp.where(rgrid <= rs, a.ys[:, 0], b.ys[:, 0])
    th = jnp.where(rgrid < _R0, lam0 * rgrid, th)
    lt = jnp.where(rgrid <= rs, a.ys[:, 1], b.ys[:, 1])
    lt = jnp.where(rgrid < _R0, lam0, lt)
    return th, lt


def sample_member(material, member: FamilyMember, rbar_max, rbar, rtol=1e-10):
    """theta and lambda_theta of a member at the radii ``rbar`` (from the ODE, not the grid)."""
    rbar = np.asarray(rbar, float)
    # Pad to a fixed length (a power of two, at least 1024) so that every grid size up to it
    # shares one compiled function.
    size = max(1024, 1 << int(np.ceil(np.log2(max(len(rbar), 1)))))
    padded = np.concatenate([rbar, np.full(size - len(rbar), rbar_max)])
    th, lt = _sample_jit(material, member.lam0, member.mu, member.rbar_s, rbar_max,
                         jnp.asarray(padded), rtol)
    return np.asarray(th)[: len(rbar)], np.asarray(lt)[: len(rbar)]
