"""Static/kinetic friction by slip-distance weakening (issue 4).

A one-node ramp against closed forms, then the whole sheet (N = 40, the shortened
push-down path of test_forming): mu_s = mu_k reproduces ideal Coulomb, the energy
balance closes with the weakening law's dissipation, the end state is rate independent;
mesh convergence at fixed d_c and the trend in d_c are slow checks.
"""

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.driver.simulate import simulate
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.solver.methods import Settings
from test_forming import MAT, MODEL, PRE, Z0, push_protocol, residual

MU_S, MU_K, D_C = 0.99, 0.82, 0.02


# ----------------------------------------------------------------------------- one node


@eqx.filter_jit
def _node_segment(fr, y0, t0, t1, x_drive0, v_drive, stiff, normal, eta):
    """A node on a rigid plane, pulled by a spring whose end moves at v_drive:
    eta x' = S(K (X(t) - x), mu(delta) N), delta' = |x'|."""

    def vf(t, y, args):
        x, delta = y
        f = stiff * (x_drive0 + v_drive * (t - t0) - x)
        s = fr.slip_force(f, normal, delta)
        return jnp.stack([s / eta, fr.internal_rate(s / eta, normal, delta)])

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(vf),
        diffrax.Kvaerno5(),
        t0,
        t1,
        1e-3,
        y0,
        stepsize_controller=diffrax.PIDController(rtol=1e-8, atol=1e-10),
        max_steps=20000,
    )
    y1 = sol.ys[-1]
    f1 = stiff * (x_drive0 + v_drive * (t1 - t0) - y1[0])
    s1 = fr.slip_force(f1, normal, y1[1])
    return y1, f1, s1


def _ramp(fr, legs, seg=0.05, stiff=10.0, normal=1.0, eta=0.1, heal_rate=0.0):
    """Drive along ``legs`` = [(duration, velocity), ...]; the law's reset at every segment end
    (as the driver does), healing where the slip rate is at most ``heal_rate``. Returns arrays
    t, x, delta, force, slip."""
    y = jnp.zeros(2)
    t, xd = 0.0, 0.0
    out = [(0.0, 0.0, 0.0, 0.0, 0.0)]
    for dur, v in legs:
        for _ in range(int(round(dur / seg))):
            y, f, s = _node_segment(
                fr,
                y,
                jnp.asarray(t),
                jnp.asarray(t + seg),
                jnp.asarray(xd),
                jnp.asarray(v),
                stiff,
                normal,
                eta,
            )
            y = y.at[1].set(fr.reset(y[1], s / eta, normal, heal_rate))
            t, xd = t + seg, xd + v * seg
            out.append((t, float(y[0]), float(y[1]), float(f), float(s)))
    return [np.array(c) for c in zip(*out, strict=True)]


def test_one_node_ramp_sticks_at_mu_s_slides_at_mu_k_and_resticks():
    """Spring-driven node (K = 10, V = 0.01, N = 1, eta = 0.1; K > (mu_s - mu_k) N / d_c, so
    weakening is stable): stuck until K V t = mu_s N; slides at mu_k N + eta V once past d_c;
    unloading re-sticks it (slip distance reset); reloading needs mu_s N again."""
    fr = SlipWeakening(mu_s=MU_S, mu_k=MU_K, d_c=D_C, eps=1e-4)
    v, eta = 0.01, 0.1
    t, x, delta, force, slip = _ramp(fr, [(20.0, v), (2.0, -v), (18.0, v)])
    first = t <= 20.0 + 1e-9
    # stick: exactly no motion while the force is below the static threshold (minus smoothing)
    t_onset = MU_S / (10.0 * v)  # K V t = mu_s N
    stuck = t < t_onset * (1 - 1e-3)
    assert np.all(x[stuck] == 0.0)
    assert np.all(x[(t > t_onset * 1.01) & first] > 0.0)
    # onset and peak: the closed form mu_s N, within 1%
    peak1 = force[first].max()
    # measured (pytest -s tests/test_weakening.py): peak 0.9899992 (8e-7), sliding force
    # exact to round-off, second peak 0.9904589 (4.6e-4: the reload overshoots by one segment)
    assert abs(peak1 - MU_S) / MU_S < 1e-5, peak1
    # sliding past d_c: F = mu_k N + eta V (the drag of the overdamped law), within 1%
    late = (t > 17.0) & (t <= 20.0 + 1e-9)
    assert np.all(delta[late] > D_C)
    slide_err = np.max(np.abs(force[late] / (MU_K + eta * v) - 1))
    assert slide_err < 1e-8, force[late]
    # unloading: sticks (force criterion), the slip distance is reset, the node stays put
    back = (t > 20.2) & (t <= 22.0 + 1e-9)
    assert np.all(slip[back] == 0.0) and np.all(delta[back] == 0.0)
    assert np.ptp(x[back]) == 0.0
    # reloading: the static threshold again (a law without reset would slide at mu_k)
    second = t > 22.0
    peak2 = force[second].max()
    assert abs(peak2 - MU_S) / MU_S < 5e-3, peak2
    print(
        f"one-node ramp: peaks {peak1:.7f}, {peak2:.7f} (mu_s N = {MU_S}); sliding force "
        f"{force[late].mean():.7f} (mu_k N + eta V = {MU_K + eta * v:.5f}), max rel error {slide_err:.2e}"  # noqa: E501
    )


@pytest.mark.parametrize("heal_rate", [1e-4, 1e-3])
def test_settling_node_heals_and_needs_mu_s_again(heal_rate):
    """Drive the node past d_c (sliding at mu_k), then stop the drive: the node settles onto
    its kinetic limit with a slip rate that decays but never reaches S = 0 exactly (the
    smoothed law's blend gives an algebraic tail). With the bare force criterion
    (heal_rate = 0) its slip distance is never reset and reloading slides at once at mu_k;
    with healing (slip rate at most heal_rate) it resets, stays put, and reloading needs
    mu_s N again."""
    fr = SlipWeakening(mu_s=MU_S, mu_k=MU_K, d_c=D_C, eps=1e-4)
    v = 0.01
    legs = [(20.0, v), (1.0, 0.0), (4.0, v)]
    out = {}
    for h in (0.0, heal_rate):
        t, x, delta, force, slip = _ramp(fr, legs, heal_rate=h)
        settle = (t > 20.5) & (t <= 21.0 + 1e-9)
        reload = t > 21.0
        out[h] = dict(
            delta_end=delta[settle][-1],
            slip_end=slip[settle][-1],
            peak=force[reload].max(),
            moved=np.ptp(x[settle]),
            x_reload=x[reload],
        )
    bare, healed = out[0.0], out[heal_rate]
    # the bare criterion: still weakened (slip distance > d_c), still creeping (S > 0)
    assert bare["delta_end"] > D_C and bare["slip_end"] > 0.0
    assert abs(bare["peak"] - (MU_K + 0.1 * v)) / MU_K < 2e-2, bare["peak"]
    # healed: slip distance 0 and exactly stuck after it healed
    assert healed["delta_end"] == 0.0 and healed["slip_end"] == 0.0
    assert abs(healed["peak"] - MU_S) / MU_S < 1e-2, healed["peak"]
    print(
        f"settling node: bare criterion delta = {bare['delta_end']:.4g} R, reload peak {bare['peak']:.4f}; "  # noqa: E501
        f"healed at {heal_rate:g} R/s: reload peak {healed['peak']:.4f} (mu_s N = {MU_S})"
    )


def test_slip_force_against_its_closed_form():
    """The weakening law's slip force against its closed form written out here (friction.py's
    module docstring): mu(delta) = mu_k + (mu_s - mu_k) max(0, 1 - delta/d_c), c = mu N,
    e = eps c / (c + eps); S = 0 for |f| <= c - e, (|f| - c + e)^2 / (4 e) on the blend,
    |f| - c beyond, with the sign of f; mu_s = mu_k is Coulomb at that mu."""
    eps = 1e-2
    f = np.linspace(-2.0, 2.0, 401)
    normal = np.full(f.size, 1.3)
    for mu_s, mu_k in ((MU_S, MU_K), (0.9, 0.9)):
        sw = SlipWeakening(mu_s=mu_s, mu_k=mu_k, d_c=D_C, eps=eps)
        for delta in (0.0, 0.5 * D_C, 3 * D_C):
            mu = mu_k + (mu_s - mu_k) * max(0.0, 1.0 - delta / D_C)
            c = mu * 1.3
            e = eps * c / (c + eps)
            a = np.abs(f)
            mag = np.where(a <= c - e, 0.0, np.where(a < c + e, (a - c + e) ** 2 / (4 * e), a - c))
            got = np.asarray(
                sw.slip_force(jnp.asarray(f), jnp.asarray(normal), jnp.full(f.size, delta))
            )
            np.testing.assert_allclose(got, np.sign(f) * mag, rtol=1e-13, atol=1e-15)
            assert np.count_nonzero(got == 0.0) > 0 and np.count_nonzero(got) > 0
    co = Coulomb(mu=jnp.asarray(0.9), eps=jnp.asarray(eps))
    sw = SlipWeakening(mu_s=0.9, mu_k=0.9, d_c=D_C, eps=eps)
    np.testing.assert_allclose(
        np.asarray(sw.slip_force(jnp.asarray(f), jnp.asarray(normal), jnp.full(f.size, 0.5))),
        np.asarray(co.slip_force(jnp.asarray(f), jnp.asarray(normal))),
        rtol=1e-13,
        atol=1e-15,
    )


# ----------------------------------------------------------------------------- the whole sheet


def _sheet_run(friction, factor=1.0, model=MODEL, save=1.0, rtol=1e-5):
    return simulate(
        model,
        push_protocol(factor=factor),
        friction=friction,
        eps=1e-3,
        drag=0.1,
        ball_drag=0.1 * 4 * math.pi,
        pre_stretch=PRE,
        z_sheet=Z0,
        settings=Settings(rtol=rtol, atol=rtol * 1e-2, save_interval=save),
    )


def _sw(mu_s=MU_S, mu_k=MU_K, d_c=D_C):
    return SlipWeakening(
        mu_s=jnp.asarray(mu_s), mu_k=jnp.asarray(mu_k), d_c=jnp.asarray(d_c), eps=jnp.asarray(1e-3)
    )


@pytest.fixture(scope="module")
def sw_base():
    res = _sheet_run(_sw())
    assert res.failed is None, res.failed
    return res


def _contact_dtheta(a, b):
    ta, tb = np.asarray(a["theta"]), np.asarray(b["theta"])
    both = np.isfinite(ta) & np.isfinite(tb)
    assert both.sum() >= 3
    return float(np.max(np.abs(ta[both] - tb[both])))


@pytest.mark.slow
def test_equal_coefficients_reproduce_ideal_coulomb():
    """mu_s = mu_k = 0.8 through the driver (slip-distance state, resets) against the ideal
    law at mu = 0.8: the same end state within solver tolerance."""
    a = _sheet_run(_sw(0.8, 0.8))
    b = _sheet_run(Coulomb(mu=jnp.asarray(0.8), eps=jnp.asarray(1e-3)))
    assert a.failed is None and b.failed is None
    fa, fb = a.frames[-1], b.frames[-1]
    d = max(np.max(np.abs(fa["rho"] - fb["rho"])), np.max(np.abs(fa["z"] - fb["z"])))
    print(f"mu_s = mu_k vs coulomb: max |dx| = {d:.2e} R")
    assert d < 1e-6


def test_weakening_energy_balance_and_memory(sw_base):
    """Energy balance with the weakening law's dissipation (its own accumulated state): measured
    residual / work 6.2e-8 (``pytest -s tests/test_weakening.py``, Kvaerno5, N = 40), asserted
    below 5e-6 (80x); the law really weakened (nodes past d_c at mu_k) and the pole stuck at
    mu_s; the nodes past d_c slide at their kinetic limit, mu_mobilised = mu_k within 5e-3
    (measured 5e-4), and no node mobilises
    more than 1.06 its current mu."""
    r, work = residual(sw_base)
    f = sw_base.frames[-1]
    print(f"weakening energy residual / work = {r:.2e} (work {work:.3f})")
    assert r <= 5e-6
    assert f["dissipation_friction"] > 1e-3 * work
    contact = np.asarray(f["state"]) > 0
    mu = np.asarray(f["mu_current"])[contact]
    assert np.isclose(mu.min(), MU_K) and np.isclose(mu.max(), MU_S)
    sd = np.asarray(f["slip_distance"])
    assert np.all(sd[~contact] == 0.0) and sd.max() > D_C
    # the static formulas on the end state: mobilised friction below the node's current mu
    mob = np.asarray(f["mu_mobilised"])[contact]
    weak = sd[contact] > 1.5 * D_C
    weak[-1] = False  # the lift-off node carries the penalty's edge
    print(f"mu_mobilised / mu_k on the nodes past d_c: {np.round(mob[weak] / MU_K, 4).tolist()}")
    assert weak.sum() >= 3
    assert np.max(np.abs(mob[weak] / MU_K - 1)) < 5e-3
    assert np.all(mob[:-1] <= mu[:-1] * 1.06)


def test_weakening_rate_independence(sw_base):
    """Halving every speed (holds scaled): max |delta theta| on the contact region below 1e-4
    (measured 2.7e-6 and 9.4e-7, ``pytest -s tests/test_weakening.py``; 37x), and the change
    falls at the next halving (measured ratio 2.86)."""
    half = _sheet_run(_sw(), factor=2.0)
    quarter = _sheet_run(_sw(), factor=4.0)
    th = float(quarter.frames[-1]["theta_max"])
    d1 = _contact_dtheta(sw_base.frames[-1], half.frames[-1])
    d2 = _contact_dtheta(half.frames[-1], quarter.frames[-1])
    print(
        f"weakening rate independence: |dtheta| 1x->2x {d1:.2e}, 2x->4x {d2:.2e}, ratio {d1 / max(d2, 1e-300):.2f},"  # noqa: E501
        f" theta_max {th:.4f}"
    )
    assert d1 < 1e-4 and d2 < 1e-4
    assert 1.4 < d1 / d2 < 4.0


@pytest.mark.slow
def test_weakening_mesh_convergence_at_fixed_dc_and_trend_in_dc():
    """At fixed d_c (15 sqrt(d_c R) = 2.1 R, mesh spacing 0.06..0.03 R on the reference disc)
    the end state converges under refinement; the trend as d_c shrinks is reported, not
    claimed to converge (its limit is ill posed)."""
    from dynslip.physics.sheet import Penalty, SheetModel, make_mesh

    def model(n):
        return SheetModel(
            make_mesh(n, 2.54 / PRE), MAT, Penalty(jnp.asarray(1e4), jnp.asarray(1e-3))
        )

    ends = {}
    for n in (20, 40, 80):
        res = MODEL if n == 40 else model(n)
        r = _sheet_run(_sw(), model=res)
        assert r.failed is None, r.failed
        ends[n] = r.frames[-1]

    # compare theta at common material radii (the 20-node radii are in all three meshes)
    def th_at(frame, n, rb):
        rbar = np.linspace(0, 2.54 / PRE, n)
        th = np.asarray(frame["theta"])
        ok = np.isfinite(th)
        return np.interp(rb, rbar[ok], th[ok])

    rb = np.linspace(0, 2.54 / PRE, 20)
    rb = rb[rb < 0.8 * min(float(ends[n]["rbar_max"]) for n in ends)]
    e1 = np.max(np.abs(th_at(ends[20], 20, rb) - th_at(ends[40], 40, rb)))
    e2 = np.max(np.abs(th_at(ends[40], 40, rb) - th_at(ends[80], 80, rb)))
    tm = {n: float(ends[n]["theta_max"]) for n in ends}
    print(
        f"weakening mesh convergence (d_c = {D_C} R): |dtheta| 20->40 {e1:.2e}, 40->80 {e2:.2e}, "
        f"order {math.log2(e1 / e2):.2f}; theta_max {tm}"
    )
    # measured (``pytest -s -m slow tests/test_weakening.py -k mesh``, abd10c6 + speed 0c23bc9):
    # 8.2e-4, 2.6e-4, order 1.62
    assert 1.2 <= math.log2(e1 / e2) <= 2.3
    trend = {}
    for dc in (0.04, 0.02, 0.01, 0.005):
        r = _sheet_run(_sw(d_c=dc))
        assert r.failed is None, r.failed
        f = r.frames[-1]
        trend[dc] = (float(f["theta_max"]), float(f["rbar_max"]), float(f["dissipation_friction"]))
    print("trend in d_c (theta_max, rbar_max, friction dissipation):", trend)
