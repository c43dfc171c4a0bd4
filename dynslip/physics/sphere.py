r"""The paper's contact-region model of a membrane on a rigid sphere (paper Section 3).

Nondimensional: lengths by the ball radius $R$, tensions by $G h_0$, areal force
densities by $G h_0/R$, forces by $G h_0 R$. A material point at undeformed radius
$\bar r$ sits at polar angle $\theta(\bar r)$ on the unit sphere; the sheet is in
contact from the pole $\bar r = 0$ to $\bar r_{max}$, where $\theta = \theta_{max}$.

Grid formulas (paper Section 3.3, physics.md Section 2), on ``N`` equally spaced nodes
$\bar r_i = i h$, $h = \bar r_{max}/(N-1)$:

- $\lambda_\theta = d\theta/d\bar r$ (paper eq. (eq_lambda_th)): centred differences, an
  odd ghost node at the pole ($\theta_{-1} = -\theta_1$) and the second-order one-sided
  difference $(3\theta_{N-1} - 4\theta_{N-2} + \theta_{N-3})/2h$ at the outer end;
- $\lambda_\phi = \sin\theta/\bar r$ (eq. (eq_lambda_phi)), $\lambda_\phi = \lambda_\theta$ at the pole;
- $T_\theta, T_\phi$ from :func:`dynslip.physics.materials.tensions` (eqs. (1)-(2), typo fixed);
- $F_m = dT_\theta/d\theta + (T_\theta - T_\phi)\cot\theta$ with
  $dT_\theta/d\theta = (dT_\theta/d\bar r)/\lambda_\theta$ (same differences; $T_\theta$ even at
  the pole, so $F_m = 0$ there);
- $F_N = T_\theta + T_\phi$; Coulomb $|F_f| \le \mu F_N$ (eq. (FOB)), at rest $F_f = -F_m$;
- $F_v = 2\pi\int_0^{\theta_{max}} (F_N\cos\theta - F_f\sin\theta)\sin\theta\,d\theta$ (eq. (eq_Fz)),
  trapezoidal in $\bar r$ with $d\theta = \lambda_\theta d\bar r$. At any equilibrium
  $F_v = 2\pi T_\theta(\theta_{max})\sin^2\theta_{max}$ (physics.md Section 2).

Solvers:

- the paper's soft-threshold march $\dot\theta_i = S(F_{m,i}, \mu F_{N,i})$,
  $S(f, c) = \mathrm{sign}(f)\max(|f| - c, 0)$, to rest: :func:`march_explicit` (a jitted
  forward-Euler ``lax.while_loop``), :func:`march_implicit` (backward Euler with growing
  steps, each solved by semi-smooth Newton) and :func:`march_diffrax` (diffrax with a
  steady-state event);
- the search on $\mu$ for $F_v = 0$: :func:`search_mu` (bracket and bisection);
- the well-posed form, the fully mobilised family (:func:`solve_member`): $F_m = +\mu F_N$
  from the pole to the switch point, $F_m = -\mu F_N$ beyond, an ODE in $\bar r$ solved by
  shooting with unknowns (pole stretch, $\mu$, switch radius) and end conditions
  $\theta(\bar r_{max}) = \theta_{max}$, $T_\theta(\bar r_{max}) = 0$, and the switch angle
  $\theta(\bar r_s) = \theta_s$ that parameterises the family.
"""

from __future__ import annotations

from typing import NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from dynslip.errors import ComputationError
from dynslip.physics.friction import soft_threshold  # eps = 0: the paper's march rule S(f, c)
from dynslip.physics.materials import AbstractMaterial, MaterialRangeError, tensions

__all__ = [
    "GridFields",
    "grid",
    "initial_shape",
    "fields",
    "vertical_force",
    "vertical_force_identity",
    "velocity",
    "stable_dt",
    "MarchResult",
    "march_explicit",
    "march_implicit",
    "velocity_jacobian",
    "march_diffrax",
    "march",
    "SearchResult",
    "search_mu",
    "Member",
    "solve_member",
    "solve_family",
    "sample_member",
    "check_equilibrium",
    "check_static_range",
    "saturation_fraction",
    "sign_change_index",
    "inflection_index",
]


# --------------------------------------------------------------------------- grid formulas


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
_vertical_force_jit = eqx.filter_jit(vertical_force)


def vertical_force_identity(material: AbstractMaterial, theta, h):
    r"""The boundary form $2\pi T_\theta(\theta_{max})\sin^2\theta_{max}$ (units $G h_0 R$)."""
    f = fields(material, theta, h)
    return 2.0 * jnp.pi * f.tt[-1] * jnp.sin(theta[-1]) ** 2


# --------------------------------------------------------------------------- the march


def velocity(material: AbstractMaterial, theta, h, mu):
    r"""March velocity $S(F_m, \mu\max(F_N, 0))$ at interior nodes, 0 at both ends.

    Where $F_N < 0$ the Coulomb bound is meaningless (the sheet would lift off); the
    threshold is then 0 and such nodes are reported by :func:`check_equilibrium`."""
    f = fields(material, theta, h)
    v = soft_threshold(f.fm, mu * jnp.maximum(f.fn, 0.0))
    return v.at[0].set(0.0).at[-1].set(0.0)


def stable_dt(material: AbstractMaterial, theta, h, safety: float = 0.4):
    r"""Forward-Euler step below $h^2/(2D)$ with $D = (\partial T_\theta/\partial\lambda_\theta)/\lambda_\theta$,
    the march's diffusivity, taken at its largest over the shape (times ``safety``)."""
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

    if solver == "euler":
        method, controller, dt0 = diffrax.Euler(), diffrax.ConstantStepSize(), dt
    elif solver == "tsit5":
        method, controller, dt0 = diffrax.Tsit5(), diffrax.PIDController(rtol=rtol, atol=rtol * 1e-2), None
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
    $\theta^{n+1} = \theta^n + \Delta t_n\,S(F_m(\theta^{n+1}), \mu F_N(\theta^{n+1}))$, each solved by
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

        th, k, r = jax.lax.while_loop(cond, body, (theta_n, jnp.asarray(0), jnp.asarray(1e300, theta_n.dtype)))
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
    theta, _, _, n_acc, vmax, _ = jax.lax.while_loop(cond, body, (theta0, jnp.asarray(dt0, theta0.dtype), z, z, v0, z))
    return MarchResult(theta, vmax, n_acc, vmax <= vtol)


def march(material, theta0, h, mu, *, method: str = "explicit", vtol=1e-6, max_steps=400_000,
          dt=None, rtol=1e-6, solver="euler", implicit_dt_factor=100.0, implicit_growth=4.0) -> MarchResult:
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
        return march_implicit(material, theta0, h, mu, dt * implicit_dt_factor, vtol, jnp.asarray(max_steps),
                              growth=implicit_growth)
    if method == "diffrax":
        t_end = dt * max_steps
        return march_diffrax(material, theta0, h, mu, dt, t_end, vtol, rtol, solver, int(max_steps))
    raise ValueError(f"unknown march method {method!r}")


# --------------------------------------------------------------------------- the mu search


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
        fv = float(_vertical_force_jit(material, res.theta, jnp.asarray(h, float)))
        cache[mu] = (fv, res)
        return fv

    f_lo, f_hi = fv_of(mu_lo), fv_of(mu_hi)
    if not (f_lo > fv_tol and f_hi <= fv_tol):
        err = ComputationError(
            f"no friction coefficient in [{mu_lo:g}, {mu_hi:g}] makes F_v vanish: "
            f"F_v({mu_lo:g}) = {f_lo:.4g}, F_v({mu_hi:g}) = {f_hi:.4g} (units G*h0*R); "
            "F_v must be > 0 at the lower end and <= 0 at the upper end"
        )
        err.partial = {"mu": (mu_lo, mu_hi), "fv": (f_lo, f_hi),
                       "theta": (np.asarray(cache[mu_lo][1].theta), np.asarray(cache[mu_hi][1].theta)),
                       "march": (cache[mu_lo][1], cache[mu_hi][1])}
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


# --------------------------------------------------------------------------- fully mobilised family


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


class Member(NamedTuple):
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
                 by: str = "switch_angle", rtol=1e-10, atol=1e-9) -> Member:
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
    return Member(float(p[0]), float(p[1]), float(p[2]), theta_s, res, ok)


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


def sample_member(material, member: Member, rbar_max, rbar, rtol=1e-10):
    """theta and lambda_theta of a member at the radii ``rbar`` (from the ODE, not the grid)."""
    rbar = np.asarray(rbar, float)
    # Pad to a fixed length (a power of two, at least 1024) so that every grid size up to it
    # shares one compiled function.
    size = max(1024, 1 << int(np.ceil(np.log2(max(len(rbar), 1)))))
    padded = np.concatenate([rbar, np.full(size - len(rbar), rbar_max)])
    th, lt = _sample_jit(material, member.lam0, member.mu, member.rbar_s, rbar_max,
                         jnp.asarray(padded), rtol)
    return np.asarray(th)[: len(rbar)], np.asarray(lt)[: len(rbar)]


# --------------------------------------------------------------------------- checks


def check_static_range(material: AbstractMaterial, lt, lp, where: str = "") -> None:
    """Raise :class:`MaterialRangeError` where the (unrelaxed) energy is not finite or a
    stretch is not positive (Gent beyond its locking stretch). The paper's model is
    unrelaxed and taut on the ball, so the relaxed Hookean limit of stretch 3 does not apply."""
    lt = np.asarray(lt, float)
    lp = np.asarray(lp, float)
    w = np.asarray(material.energy(jnp.asarray(lt), jnp.asarray(lp)))
    bad = ~((lt > 0) & (lp > 0) & np.isfinite(w) & np.isfinite(lt) & np.isfinite(lp))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MaterialRangeError(
            f"{material.name}: stretches (lambda_theta={lt[i]:.4g}, lambda_phi={lp[i]:.4g}) "
            f"at node {i} outside the material's range{(' ' + where) if where else ''}"
            + (f"; the Gent model locks at I1 = J_m + 3 = {material.jm + 3:g}" if hasattr(material, "jm") else "")
        )


def saturation_fraction(fm, fn, mu, rel=0.02):
    """Fraction of interior nodes where $|F_m| = \\mu F_N$ within ``rel`` (relative)."""
    fm = np.asarray(fm)[1:-1]
    fn = np.asarray(fn)[1:-1]
    return float(np.mean(np.abs(np.abs(fm) - mu * fn) <= rel * mu * np.abs(fn)))


def sign_change_index(fm):
    """Index of the first interior node after which F_m turns from positive to negative."""
    fm = np.asarray(fm)[1:-1]
    idx = np.flatnonzero((fm[:-1] > 0) & (fm[1:] <= 0))
    return int(idx[0]) + 1 if idx.size else -1


def inflection_index(theta):
    """Index of the first node where the second difference of theta turns from + to -."""
    th = np.asarray(theta)
    d2 = th[2:] - 2 * th[1:-1] + th[:-2]
    idx = np.flatnonzero((d2[:-1] > 0) & (d2[1:] <= 0))
    return int(idx[0]) + 1 if idx.size else -1


def check_equilibrium(material, theta, h, mu, *, vtol, force_tol=1e-8, edge_tol=None) -> dict:
    r"""Check a returned state as an equilibrium, with the grid formulas:
    $|F_m| \le \mu F_N + $ tol at every interior node, $\max|\dot\theta| \le$ ``vtol``,
    $F_N > 0$ at interior nodes, and (if ``edge_tol``) $|T_\theta(\bar r_{max})| \le$ ``edge_tol``.
    Returns a dict of the measured quantities with ``ok``."""
    f = fields(material, jnp.asarray(theta), h)
    fm, fn = np.asarray(f.fm)[1:-1], np.asarray(f.fn)[1:-1]
    excess = float(np.max(np.abs(fm) - mu * fn))
    vmax = float(jnp.max(jnp.abs(velocity(material, jnp.asarray(theta), h, mu))))
    fv = float(vertical_force(material, jnp.asarray(theta), h))
    fv_id = float(vertical_force_identity(material, jnp.asarray(theta), h))
    out = {
        "coulomb_excess": excess,
        "vmax": vmax,
        "min_F_N": float(fn.min()),
        "T_theta_edge": float(f.tt[-1]),
        "F_v": fv,
        "F_v_identity": fv_id,
        "F_v_residual": fv - fv_id,
    }
    ok = excess <= force_tol + vmax and vmax <= vtol and out["min_F_N"] > 0
    if edge_tol is not None:
        ok = ok and abs(out["T_theta_edge"]) <= edge_tol
    out["ok"] = bool(ok)
    return out
