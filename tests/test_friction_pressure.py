"""Friction falling with the contact pressure (Schallamach), bounded at low pressure
(:class:`dynslip.physics.friction.PressureDependent`, law ``pressure``).

- at exponent 0 it is ideal Coulomb exactly (thresholds, slip forces, derivatives);
- a node driven tangentially at constant speed under a ramped normal load slides with the
  force mu(p) N of the power law, and the exponent fitted to the sliding forces is the law's;
- below the cap's pressure mu is mu_max exactly, the threshold's derivative is continuous
  and bounded (what the return map's Newton differentiates), finite at N = 0;
- the law reproduces the capstan strip test it is referred to;
- bad input is one line and exit 2.
"""

from __future__ import annotations

import math
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.cli import main
from dynslip.physics.friction import CAP_BLEND, Coulomb, PressureDependent
from helpers import one_line

ROOT = Path(__file__).resolve().parents[1]
P_REF = 0.212  # the schema's 1.06 kPa over G h0 / R = 5 kPa
AREA = 0.01  # a node's reference area (R^2), of the order of the N = 100 mesh's
MU_REF, MU_MAX = 0.99, 2.18


def law(a, mu_max=MU_MAX, eps=0.0):
    return PressureDependent(mu_ref=MU_REF, p_ref=P_REF, a=a, mu_max=mu_max, eps=eps)


def test_exponent_zero_is_coulomb_exactly():
    """a = 0: threshold, slip force (ideal and smoothed), stuck flag and the threshold's
    derivative are those of Coulomb(mu_ref), bit for bit, at every load and area."""
    fn = jnp.array([-1.0, 0.0, 1e-300, 1e-12, 1e-6, 2e-3, 0.3, 40.0])
    ft = jnp.array([0.5, -0.2, 1e-300, 3e-12, -1e-6, 2e-3, -0.1, 41.0])
    area = jnp.array([0.01, 0.003, 1.0, 1e-4, 0.02, 0.01, 0.5, 0.01])
    coulomb = Coulomb(mu=jnp.asarray(MU_REF), eps=jnp.asarray(0.0))
    p0 = law(0.0)
    assert np.array_equal(p0.threshold(fn, area=area), coulomb.threshold(fn))
    for eps in (0.0, 1e-3):
        assert np.array_equal(p0.slip_force(ft, fn, eps=eps, area=area),
                              coulomb.slip_force(ft, fn, eps=eps))
        assert np.array_equal(p0.stuck(ft, fn, eps=eps, area=area), coulomb.stuck(ft, fn, eps=eps))
    dp = jax.vmap(jax.grad(lambda n, a: p0.threshold(n, area=a)))(fn, area)
    dc = jax.vmap(jax.grad(lambda n: coulomb.threshold(n)))(fn)
    assert np.array_equal(dp, dc)


# --------------------------------------------------------------------------- one-node ramp

K_SPRING = 100.0  # the driving spring (G h0 per R)
V_DRIVE = 1e-3  # the spring's far end (R/s)
ETA_A = 1e-6  # the node's drag eta A
T_RAMP, STEPS = 100.0, 4000
P0, DECADES = 0.01 * P_REF, 4.0  # the pressure ramps from 0.01 p_ref to 100 p_ref


@jax.jit
def ramp(friction):
    """A node of reference area AREA on a rigid surface, pulled by a spring whose far end moves
    at V_DRIVE, under a normal load N(t) = AREA p0 10^(DECADES t/T), overdamped:
    eta A x' = S(F, mu(N/A) N), F = k (v t - x). Backward Euler with the law's exact return map
    (ideal threshold): S = S(F_trial, c)/(1 + k dt/(eta A)). Returns (pressure, sliding force F,
    slip rate) at each step's end."""
    h = T_RAMP / STEPS
    beta = K_SPRING * h / ETA_A

    def step(x0, t1):
        p = P0 * 10.0 ** (DECADES * t1 / T_RAMP)
        n = p * AREA
        f_trial = K_SPRING * (V_DRIVE * t1 - x0)
        s = friction.slip_force(f_trial, n, area=AREA) / (1.0 + beta)
        x1 = x0 + h * s / ETA_A
        return x1, (p, K_SPRING * (V_DRIVE * t1 - x1), s / ETA_A)

    _, out = jax.lax.scan(step, jnp.asarray(0.0), h * jnp.arange(1, STEPS + 1))
    return out


def _power_law(a, p):
    return MU_REF * (p / P_REF) ** (-a)


@pytest.mark.parametrize("a", [1.0 / 3.0, 0.5])
def test_one_node_ramp_slides_at_the_power_law_and_recovers_its_exponent(a):
    """Sliding (slip rate near the drive's) over four decades of pressure: the spring's force
    is mu(p) N within 1e-3 where the power law holds (mu <= mu_max e^-w), mu_max N where it
    is capped, and the exponent fitted to ln(F/N) against ln p is a within 1e-4. (Tolerance:
    the drag's share eta A v / (mu N) is below 1e-4 here; the rest is the spring's lag behind
    the rising threshold over one step.)"""
    p, f, u = (np.asarray(x) for x in ramp(law(a)))
    n = p * AREA
    sliding = u > 0.5 * V_DRIVE
    late = np.arange(p.size) > 50  # past the initial loading of the spring
    assert np.all(sliding[late]), "the node must slide throughout the ramp"
    mu_meas = f / n
    power = late & (_power_law(a, p) <= MU_MAX * math.exp(-CAP_BLEND))
    capped = late & (_power_law(a, p) >= MU_MAX * math.exp(CAP_BLEND))
    assert power.sum() > 1000 and capped.sum() > 100
    np.testing.assert_allclose(mu_meas[power], _power_law(a, p[power]), rtol=1e-3)
    np.testing.assert_allclose(mu_meas[capped], MU_MAX, rtol=1e-3)
    slope, _ = np.polyfit(np.log(p[power]), np.log(mu_meas[power]), 1)
    print(f"a = {a:.4f}: fitted exponent {-slope:.6f}")
    assert -slope == pytest.approx(a, abs=1e-4)


def test_one_node_ramp_at_exponent_zero_slides_at_constant_mu():
    """The same ramp with a = 0: the sliding force is mu_ref N at every pressure (Coulomb)."""
    p, f, u = (np.asarray(x) for x in ramp(law(0.0)))
    late = np.arange(p.size) > 50
    assert np.all(u[late] > 0.5 * V_DRIVE)
    np.testing.assert_allclose(f[late] / (p[late] * AREA), MU_REF, rtol=1e-3)


# --------------------------------------------------------------------------- the bound


def test_the_bound_at_low_pressure_and_a_threshold_newton_can_differentiate():
    """mu <= mu_max at every pressure and = mu_max exactly below the cap's pressure
    p_ref (mu_ref / (mu_max e^w))^(1/a); the threshold c(N) = mu(N/A) N is C^1: its autodiff
    derivative matches central differences to 1e-6 (across the rounding band too), its jumps
    between grid neighbours halve with the grid step, it lies in [(1 - a) mu, mu_max], and is
    finite at N = 0 (mu_max: no blow-up)."""
    a = 1.0 / 3.0
    fr = law(a)
    p = jnp.logspace(-12, 3, 4001) * P_REF
    mu = np.asarray(fr.mu(p))
    assert np.all(mu <= MU_MAX + 1e-15) and np.all(mu > 0)
    p_cap = P_REF * (MU_REF / (MU_MAX * math.exp(CAP_BLEND))) ** (1 / a)
    assert np.all(mu[np.asarray(p) <= p_cap] == MU_MAX)
    assert float(fr.mu(jnp.asarray(0.0))) == MU_MAX
    pw = np.asarray(p) >= P_REF * (MU_REF / (MU_MAX * math.exp(-CAP_BLEND))) ** (1 / a)
    np.testing.assert_allclose(mu[pw], _power_law(a, np.asarray(p)[pw]), rtol=1e-13)

    def c(n):
        return fr.threshold(n, area=AREA)

    n = p * AREA
    dc = np.asarray(jax.vmap(jax.grad(c))(n))
    h = 1e-6 * np.asarray(n)
    fd = (np.asarray(jax.vmap(c)(n + h)) - np.asarray(jax.vmap(c)(n - h))) / (2 * h)
    np.testing.assert_allclose(dc, fd, rtol=1e-6)
    # continuity of the derivative across the rounding band: its largest jump between grid
    # neighbours halves with the grid step (a hard min would keep a jump of a mu_max = 0.73)
    jumps = []
    for m in (1001, 2001, 4001):
        nb = jnp.logspace(-2, 0, m) * P_REF * AREA
        jumps.append(float(np.max(np.abs(np.diff(np.asarray(jax.vmap(jax.grad(c))(nb)))))))
    assert jumps[0] < 0.05 and jumps[1] < 0.55 * jumps[0] and jumps[2] < 0.55 * jumps[1], jumps
    assert np.all(dc <= MU_MAX + 1e-12) and np.all(dc >= (1 - a) * mu - 1e-12)
    d0 = float(jax.grad(c)(jnp.asarray(0.0)))
    assert np.isfinite(d0) and 0 < d0 <= MU_MAX
    # reverse-mode derivatives of the slip force stay finite everywhere (the solver's vjps)
    g = jax.vmap(jax.grad(lambda f, n: fr.slip_force(f, n, eps=1e-6, area=AREA), argnums=(0, 1)))(
        jnp.full_like(n, 0.5), jnp.concatenate([jnp.zeros(1), n[1:]]))
    assert all(np.all(np.isfinite(np.asarray(x))) for x in g)


def test_the_law_reproduces_the_capstan_strip_test_it_is_referred_to():
    """A strip over the ball (wrap pi, width 5 mm, R 20 mm) held by 2 g: integrating
    dT/dtheta = mu(T/(R w)) T with the schema's p_ref (1.06 kPa) and mu_ref = 0.99 gives the
    load at which it slips, and the belt formula read from it returns 0.99 (to the rounding
    of p_ref to 0.01 kPa); the schema's default is the derived capstan pressure."""
    from scipy.integrate import solve_ivp

    from dynslip.schema.friction import CAPSTAN_TEST, PressureSpec, capstan_reference_pressure_kPa

    spec = PressureSpec()
    assert spec.p_ref_kPa == pytest.approx(capstan_reference_pressure_kPa(spec.exponent), abs=5e-3)
    fr = spec.build(20.0, 0.0, pressure_scale_kPa=1.0)  # pressures in kPa
    r_m, w_m = CAPSTAN_TEST["ball_radius_mm"] * 1e-3, CAPSTAN_TEST["strip_width_mm"] * 1e-3
    t_hold = CAPSTAN_TEST["hold_mass_g"] * 1e-3 * 9.81
    mu = eqx.filter_jit(lambda p: fr.mu(p))
    sol = solve_ivp(lambda th, t: [float(mu(t[0] / (r_m * w_m) * 1e-3)) * t[0]],
                    (0.0, math.pi), [t_hold], rtol=1e-10, atol=1e-14)
    mu_read = math.log(sol.y[0, -1] / t_hold) / math.pi
    assert mu_read == pytest.approx(0.99, abs=2e-3)


def test_the_schema_makes_pressures_nondimensional_with_the_materials_scale():
    """p_ref in the core is p_ref_kPa / (G h0 / R): 1.06 / 5 for the paper's sheet and ball;
    the forming runner passes that scale (G h0 R / R^2)."""
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load

    sc = load(ROOT / "scenarios" / "method2_let_go_pressure.yaml")
    _, _, kw = build_core(sc)
    fr = kw["friction"]
    assert type(fr) is PressureDependent
    gh0_r_kPa = (2.0e6 / 3.0) * 150e-6 / 20e-3 * 1e-3
    assert float(fr.p_ref) == pytest.approx(1.06 / gh0_r_kPa, rel=1e-12)
    assert float(fr.a) == pytest.approx(1 / 3) and float(fr.mu_max) == 2.18
    with pytest.raises(ValueError, match="pressure scale"):
        sc.physics.friction.build(20.0, 0.0)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("field, value, says", [
    ("exponent", "1.0", "exponent"),
    ("exponent", "-0.1", "exponent"),
    ("p_ref_kPa", "0", "p_ref_kPa"),
    ("mu_max", "1.0", "mu_max"),
    ("mu_ref", "-1", "mu_ref"),
])
def test_bad_pressure_law_input_is_one_line_and_exit_2(field, value, says, capsys, tmp_path):
    """Each bad field gets exit 2 and one line naming it, and `dynslip run` writes nothing."""
    out = tmp_path / "run"
    scenario = ROOT / "scenarios" / "method2_let_go_pressure.yaml"
    rc = main(["run", str(scenario), "--out", str(out), "--set",
               f"physics.friction.{field}={value}"])
    line = one_line(capsys.readouterr().err)
    assert rc == 2 and says in line, line
    assert not out.exists()
