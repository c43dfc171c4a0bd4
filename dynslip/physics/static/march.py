r"""The paper's soft-threshold march to rest (paper Section 3.3):
$\dot\theta_i = S(F_{m,i}, \mu F_{N,i})$, $S(f, c) = \mathrm{sign}(f)\max(|f| - c, 0)$.

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$ (the paper's contact-region model, Section 3;
the package docstring of :mod:`dynslip.physics.static` states the whole model).

Three integrators of the same march: :func:`march_explicit` (a jitted forward-Euler
``lax.while_loop``), :func:`march_implicit` (backward Euler with growing steps, each solved
by semi-smooth Newton) and :func:`march_diffrax` (diffrax with a steady-state event);
:func:`march` dispatches by name.
"""

from __future__ import annotations

from typing import NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics.friction import soft_threshold  # eps = 0: the paper's march rule S(f, c)
from dynslip.physics.materials import AbstractMaterial, tensions
from dynslip.physics.static.grid import fields


def velocity(material: AbstractMaterial, theta, h, mu):
    r"""March velocity $S(F_m, \mu\max(F_N, 0))$ at interior nodes, 0 at both ends.

    Where $F_N < 0$ the Coulomb bound is meaningless (the sheet would lift off); the
    threshold is then 0 and such nodes are reported by :func:`check_equilibrium`."""
    f = fields(material, theta, h)
    v = soft_threshold(f.fm, mu * jnp.maximum(f.fn, 0.0))
    return v.at[0].set(0.0).at[-1].set(0.0)


def stable_dt(material: AbstractMaterial, theta, h, safety: float = 0.4):
    r"""Forward-Euler step below $h^2/(2D)$ with
    $D = (\partial T_\theta/\partial\lambda_\theta)/\lambda_\theta$, the march's
    diffusivity, taken at its largest over the shape (times ``safety``)."""
    f = fields(material, theta, h)
    eps = 1e-6
    tp_, _ = tensions(material, f.lt + eps, f.lp)
    tm_, _ = tensions(material, f.lt - eps, f.lp)
    d = jnp.abs((tp_ - tm_) / (2 * eps)) / f.lt
    dmax = jnp.max(d)
    # A step a little below the bound also covers shapes met later in the march
    # (the diffusivity changes little near rest).
    return safety * h**2 / (2.0 * dmax)


class MarchResult(NamedTuple):
    theta: jax.Array  # end shape (N,)
    vmax: jax.Array  # largest |velocity| at the end
    steps: jax.Array  # steps taken
    converged: jax.Array  # vmax <= vtol


_CHUNK = 16  # explicit steps between two rest checks


@eqx.filter_jit
def march_explicit(material, theta0, h, mu, dt, vtol, max_steps):
    r"""The paper's march $\theta^{n+1} = \theta^n + dt\,S(F_m, \mu F_N)$ to rest (forward Euler in
    a ``lax.while_loop``, the rest test $\max|\dot\theta| \le$ ``vtol`` every 16 steps); stops at
    rest or after ``max_steps``. Stable for ``dt`` below :func:`stable_dt`."""

    def cond(c):
        _, n, vmax = c
        return (vmax > vtol) & (n < max_steps)

    def step(_, theta):
        return theta + dt * velocity(material, theta, h, mu)

    def body(c):
        theta, n, _ = c
        theta = jax.lax.fori_loop(0, _CHUNK, step, theta)
        vmax = jnp.max(jnp.abs(velocity(material, theta, h, mu)))
        return theta, n + _CHUNK, vmax

    v0 = jnp.max(jnp.abs(velocity(material, theta0, h, mu)))
    theta, n, vmax = jax.lax.while_loop(cond, body, (theta0, jnp.asarray(0), v0))
    return MarchResult(theta, vmax, n, vmax <= vtol)


@eqx.filter_jit
def march_diffrax(material, theta0, h, mu, dt, t_end, vtol, rtol, solver: str = "euler",
                  max_steps: int = 400_000):
    r"""The same march as an ODE $\dot\theta = S(F_m, \mu F_N)$ integrated by diffrax until the
    steady-state event $\max|\dot\theta| \le$ ``vtol`` (or ``t_end``, or ``max_steps``).

    ``solver="euler"``: forward Euler at the constant step ``dt`` (the paper's scheme; agrees
    with :func:`march_explicit`). ``solver="tsit5"``: adaptive Tsit5 with PID control at
    ``rtol``; its rest state depends on the path and the tolerance (the soft threshold has
    kinks), see docs/static-model.md."""
    term = diffrax.ODETerm(lambda t, y, args: velocity(material, y, h, mu))

    def steady(t, y, args, **kw):
        return jnp.max(jnp.abs(velocity(material, y, h, mu))) <= vtol

    method: diffrax.AbstractSolver
    controller: diffrax.AbstractStepSizeController
    dt0: float | None
    if solver == "euler":
        method, controller, dt0 = diffrax.Euler(), diffrax.ConstantStepSize(), dt
    elif solver == "tsit5":
        method, controller, dt0 = (
            diffrax.Tsit5(),
            diffrax.PIDController(rtol=rtol, atol=rtol * 1e-2),
            None,
        )
    else:
        raise ValueError(f"unknown diffrax solver {solver!r}")
    sol = diffrax.diffeqsolve(
        term, method, t0=0.0, t1=t_end, dt0=dt0, y0=theta0,
        stepsize_controller=controller,
        event=diffrax.Event(steady),
        max_steps=max_steps,
        throw=False,
    )
    theta = sol.ys[-1]
    vmax = jnp.max(jnp.abs(velocity(material, theta, h, mu)))
    return MarchResult(theta, vmax, sol.stats["num_steps"], vmax <= vtol)


_BAND = 2  # the march velocity at node i depends on theta at nodes i-2 .. i+2


def velocity_jacobian(material, theta, h, mu):
    r"""$\partial\dot\theta/\partial\theta$ of :func:`velocity` (N, N), dense, from five
    Jacobian-vector products: the velocity at node $i$ depends on $\theta_{i-2..i+2}$ only
    (centred differences of centred differences), so seeds $e_j$ summed over $j \equiv c$
    (mod 5) do not overlap. JAX's derivative of the soft threshold (1 where a node slips, 0
    where it sticks) makes this a generalised Jacobian: Newton on it is semi-smooth Newton."""
    n = theta.shape[0]
    width = 2 * _BAND + 1
    idx = jnp.arange(n)
    seeds = (idx[None, :] % width == jnp.arange(width)[:, None]).astype(theta.dtype)  # (5, N)
    fn = lambda th: velocity(material, th, h, mu)  # noqa: E731
    cols = jax.vmap(lambda s: jax.jvp(fn, (theta,), (s,))[1])(seeds)  # (5, N): cols[c, i]
    # J[i, j] = cols[j % 5, i] for |i - j| <= 2, else 0
    jj = idx[None, :]
    ii = idx[:, None]
    band = jnp.abs(ii - jj) <= _BAND
    return jnp.where(band, cols[jj % width, ii], 0.0)


@eqx.filter_jit
def march_implicit(material, theta0, h, mu, dt0, vtol, max_steps, growth=4.0, dt_max=1e6,
                   newton_tol=1e-12, max_newton=30):
    r"""The paper's march to rest with backward-Euler steps,
    $\theta^{n+1} = \theta^n + \Delta t_n\,S(F_m(\theta^{n+1}), \mu F_N(\theta^{n+1}))$, each
    solved by
    semi-smooth Newton on $G = \theta - \theta^n - \Delta t\,\dot\theta(\theta)$
    (:func:`velocity_jacobian`, dense LU) from $\theta^n$ until the Newton update is at most
    ``newton_tol`` (rad) at every node.

    The steps grow by ``growth`` from ``dt0`` up to ``dt_max``; a step whose Newton solve does
    not converge in ``max_newton`` iterations is rejected and retried at a quarter of the
    step. Stops at rest, $\max|\dot\theta| \le$ ``vtol`` (the same test as
    :func:`march_explicit`), or after ``max_steps`` attempted steps. ``steps`` counts the
    accepted steps. The end state is the rest state reached along the (first-order
    accurate) path; with the large steps it tracks the overdamped flow only coarsely, see
    docs/static-model.md for the measured difference to the explicit march."""
    n = theta0.shape[0]
    eye = jnp.eye(n, dtype=theta0.dtype)

    def newton(theta_n, dt):
        def g(th):
            return th - theta_n - dt * velocity(material, th, h, mu)

        def cond(c):
            _, k, r = c
            return (r > newton_tol) & (k < max_newton) & jnp.isfinite(r)

        def body(c):
            th, k, _ = c
            jac = eye - dt * velocity_jacobian(material, th, h, mu)
            d = jnp.linalg.solve(jac, g(th))
            return th - d, k + 1, jnp.max(jnp.abs(d))

        th, k, r = jax.lax.while_loop(
            cond, body, (theta_n, jnp.asarray(0), jnp.asarray(1e300, theta_n.dtype))
        )
        return th, k, (r <= newton_tol) & jnp.all(jnp.isfinite(th))

    def cond(c):
        _, _, n_att, _, vmax, _ = c
        return (vmax > vtol) & (n_att < max_steps)

    def body(c):
        theta, dt, n_att, n_acc, vmax, n_newton = c
        th1, k, ok = newton(theta, dt)
        theta = jnp.where(ok, th1, theta)
        vmax = jnp.where(ok, jnp.max(jnp.abs(velocity(material, theta, h, mu))), vmax)
        dt = jnp.where(ok, jnp.minimum(dt * growth, dt_max), dt / 4.0)
        return theta, dt, n_att + 1, n_acc + ok.astype(n_acc.dtype), vmax, n_newton + k

    v0 = jnp.max(jnp.abs(velocity(material, theta0, h, mu)))
    z = jnp.asarray(0)
    theta, _, _, n_acc, vmax, _ = jax.lax.while_loop(
        cond, body, (theta0, jnp.asarray(dt0, theta0.dtype), z, z, v0, z)
    )
    return MarchResult(theta, vmax, n_acc, vmax <= vtol)


def march(
    material,
    theta0,
    h,
    mu,
    *,
    method: str = "explicit",
    vtol=1e-6,
    max_steps=400_000,
    dt=None,
    rtol=1e-6,
    solver="euler",
    implicit_dt_factor=100.0,
    implicit_growth=4.0,
) -> MarchResult:
    """Run the march with ``method`` ``"explicit"`` (jitted loop), ``"implicit"`` (backward
    Euler, :func:`march_implicit`: first step ``implicit_dt_factor * dt``, each next one
    ``implicit_growth`` times longer) or ``"diffrax"`` (with ``solver`` ``"euler"`` or
    ``"tsit5"``); ``dt`` defaults to :func:`stable_dt`."""
    theta0 = jnp.asarray(theta0, float)
    if dt is None:
        dt = stable_dt(material, theta0, h)
    h, mu, dt, vtol = (jnp.asarray(x, float) for x in (h, mu, dt, vtol))
    if method == "explicit":
        return march_explicit(material, theta0, h, mu, dt, vtol, jnp.asarray(max_steps))
    if method == "implicit":
        return march_implicit(
            material,
            theta0,
            h,
            mu,
            dt * implicit_dt_factor,
            vtol,
            jnp.asarray(max_steps),
            growth=implicit_growth,
        )
    if method == "diffrax":
        t_end = dt * max_steps
        return march_diffrax(material, theta0, h, mu, dt, t_end, vtol, rtol, solver, int(max_steps))
    raise ValueError(f"unknown march method {method!r}")
