"""The paper's static contact-region model: grid formulas, equilibria, the fully mobilised
family, the march and the mu search (physics.md Section 2)."""

import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.analysis.paper import PAPER_MU
from dynslip.errors import ComputationError
from dynslip.physics import static as S
from dynslip.physics.materials import Gent, Hookean, NeoHookean

RMAX, TMAX, N = 0.9, 1.8, 100
SEL = 0.25  # the selection rule: switch radius rbar_s = 0.25 R (docs/static-model.md)
MATS = {"hookean": Hookean(), "neo_hookean": NeoHookean(), "gent": Gent(jm=50.0)}
PAPER = PAPER_MU  # the paper's mu, from its one place


@pytest.fixture(scope="session")
def members():
    """The selected fully mobilised member of each model, sampled on the paper's grid."""
    r = S.grid(N, RMAX)
    out = {}
    for name, mat in MATS.items():
        m = S.solve_member(mat, SEL, TMAX, RMAX, (2.2, 1.0, 0.25), by="switch_radius")
        assert m.converged, name
        th, _ = S.sample_member(mat, m, RMAX, r)
        out[name] = (m, th)
    return out


def test_grid_formulas_on_a_uniform_stretch():
    """theta = asin(l rbar)-free check: theta = c rbar gives lambda_theta = c exactly and
    lambda_phi = sin(c rbar)/rbar, with F_m = 0 at the pole."""
    r = S.grid(30, RMAX)
    th = 1.7 * r
    f = S.fields(NeoHookean(), jnp.asarray(th), r[1])
    np.testing.assert_allclose(f.lt, 1.7, rtol=1e-12)
    np.testing.assert_allclose(f.lp[1:], np.sin(th[1:]) / r[1:], rtol=1e-14)
    assert f.lp[0] == pytest.approx(1.7)
    assert f.fm[0] == 0.0


def test_f_m_matches_the_exact_derivative():
    """F_m on the grid converges to the exact F_m of a smooth shape: second order on a fixed
    inner interval, first order next to the pole (the O(h^2) error of T_theta - T_phi is divided
    by cot's 1/theta ~ 1/h) and at the last two nodes (the one-sided stretch's error differs
    from its neighbours', and F_m differentiates it)."""
    mat = NeoHookean()

    def exact(rr):
        th = 1.6 * rr + 0.3 * rr**3
        lt = 1.6 + 0.9 * rr**2
        dlt = 1.8 * rr
        lp = np.sin(th) / rr
        dlp = (lt * np.cos(th) - lp) / rr
        tt, tp = (np.asarray(x) for x in S.tensions(mat, jnp.asarray(lt), jnp.asarray(lp)))
        e = 1e-6
        ttp = np.asarray(S.tensions(mat, jnp.asarray(lt + e), jnp.asarray(lp))[0])
        ttm = np.asarray(S.tensions(mat, jnp.asarray(lt - e), jnp.asarray(lp))[0])
        tqp = np.asarray(S.tensions(mat, jnp.asarray(lt), jnp.asarray(lp + e))[0])
        tqm = np.asarray(S.tensions(mat, jnp.asarray(lt), jnp.asarray(lp - e))[0])
        dtt = (ttp - ttm) / (2 * e) * dlt + (tqp - tqm) / (2 * e) * dlp
        return dtt / lt + (tt - tp) / np.tan(th)

    errs, ends, hs = [], [], []
    for n in (21, 41, 81):
        r = S.grid(n, 0.6)
        th = 1.6 * r + 0.3 * r**3
        f = S.fields(mat, jnp.asarray(th), r[1])
        err = np.abs(np.asarray(f.fm)[1:] - exact(r[1:]))
        inner = (r[1:] >= 0.15) & (r[1:] <= 0.45)
        errs.append(np.max(err[inner]))
        ends.append(max(np.max(err[-2:]), err[0]))
        hs.append(r[1])
    assert np.polyfit(np.log(hs), np.log(errs), 1)[0] > 1.8
    assert np.polyfit(np.log(hs), np.log(ends), 1)[0] > 0.9


@pytest.mark.slow
def test_f_v_identity_converges_at_second_order(members):
    """F_v (eq. Fz, F_f = -F_m) minus 2 pi T_theta(theta_max) sin^2 theta_max -> 0 at order >=
    1.5."""
    for name, (m, _) in members.items():
        res, hs = [], []
        for n in (51, 101, 201, 401):
            r = S.grid(n, RMAX)
            th = jnp.asarray(S.sample_member(MATS[name], m, RMAX, r)[0])
            res.append(
                abs(
                    float(
                        S.vertical_force(MATS[name], th, r[1])
                        - S.vertical_force_identity(MATS[name], th, r[1])
                    )
                )
            )
            hs.append(r[1])
        order = np.polyfit(np.log(hs), np.log(res), 1)[0]
        assert order > 1.5, (name, order, res)


def test_members_are_fully_mobilised_on_the_grid(members):
    """Evaluated with the grid formulas (not by construction): |F_m| = mu F_N within 2% at
    >= 90% of interior nodes; F_m's sign change, the largest lambda_theta and the inflection of
    theta coincide within two grid spacings; the edge is tension-free to O(h^2)."""
    h = RMAX / (N - 1)
    for name, (m, th) in members.items():
        f = S.fields(MATS[name], jnp.asarray(th), h)
        assert S.saturation_fraction(f.fm, f.fn, m.mu, 0.02) >= 0.9, name
        i_s, i_l, i_i = S.sign_change_index(f.fm), int(np.argmax(f.lt)), S.inflection_index(th)
        assert i_s > 0 and i_i > 0
        assert max(i_s, i_l, i_i) - min(i_s, i_l, i_i) <= 2, (name, i_s, i_l, i_i)
        assert abs(m.rbar_s / h - i_s) <= 2
        assert abs(float(f.tt[-1])) < 5e-3
        assert float(np.min(np.asarray(f.fn))) > 0


def test_mu_ordering_and_paper_values(members):
    """Hookean needs the most friction, neo-Hookean the least (paper); report the gap to
    1.47/0.99/1.1."""
    mu = {k: v[0].mu for k, v in members.items()}
    assert mu["hookean"] > mu["gent"] > mu["neo_hookean"]
    gaps = {k: mu[k] / PAPER[k] - 1 for k in mu}
    # Hookean and neo-Hookean within 5%; Gent is 6.2% high under the same rule (docs/static-
    # model.md)
    assert abs(gaps["hookean"]) < 0.05 and abs(gaps["neo_hookean"]) < 0.05
    assert 0.05 < gaps["gent"] < 0.08


def test_bvp_end_conditions(members):
    """The shooting's ODE solution meets theta(rbar_max) = theta_max, T_theta(rbar_max) = 0."""
    for name, (m, _) in members.items():
        th, lt = S.sample_member(MATS[name], m, RMAX, np.array([0.1, RMAX]))
        assert abs(th[-1] - TMAX) < 1e-8
        tt, _ = S.tensions(MATS[name], jnp.asarray(lt[-1:]), jnp.asarray([np.sin(TMAX) / RMAX]))
        assert abs(float(tt[0])) < 1e-8


@pytest.mark.parametrize("name", ["neo_hookean", pytest.param("hookean", marks=pytest.mark.slow),
                                  pytest.param("gent", marks=pytest.mark.slow)])
def test_march_from_member_stays_put_and_returns_its_mu(members, name):
    """The paper's march and search started from the member: same mu within 1%, the state
    moved by little, and the returned state is checked as an equilibrium."""
    m, th = members[name]
    h = RMAX / (N - 1)
    sr = S.search_mu(MATS[name], th, h, 0.5 * m.mu, 2.0 * m.mu, mu_tol=1e-3)
    assert abs(sr.mu / m.mu - 1) < 0.01
    assert np.max(np.abs(sr.theta - th)) < 5e-3
    chk = S.check_equilibrium(MATS[name], sr.theta, h, sr.mu, vtol=1e-6, edge_tol=5e-3)
    assert chk["ok"], chk
    assert chk["coulomb_excess"] <= 1e-6 + 1e-8
    assert abs(chk["F_v"]) < 2e-3


def test_explicit_and_diffrax_marches_agree(members):
    """Forward Euler in a jitted loop and diffrax Euler at the same step reach the same rest
    state."""
    m, th = members["neo_hookean"]
    h = RMAX / (N - 1)
    mu = 0.99 * m.mu
    a = S.march(MATS["neo_hookean"], th, h, mu, method="explicit", vtol=1e-5)
    b = S.march(MATS["neo_hookean"], th, h, mu, method="diffrax", solver="euler", vtol=1e-5)
    assert bool(a.converged) and bool(b.converged)
    assert np.max(np.abs(np.asarray(a.theta) - np.asarray(b.theta))) < 1e-6
    assert int(a.steps) > 1000  # it did move: the grid state is not saturated at 0.99 mu
    for res in (a, b):
        v = S.velocity(MATS["neo_hookean"], res.theta, h, mu)
        assert float(jnp.max(jnp.abs(v))) <= 1e-5


def test_no_root_is_a_computation_error_with_both_ends():
    """From theta = 2 rbar the edge is in tension at every mu: F_v > 0 at both bracket ends."""
    n = 30
    r = S.grid(n, RMAX)
    th = S.initial_shape("linear", r, TMAX)
    with pytest.raises(ComputationError, match=r"F_v\(1\) = .*F_v\(3\) = ") as exc:
        S.search_mu(NeoHookean(), th, r[1], 1.0, 3.0, max_steps=20_000)
    lo, hi = exc.value.partial["fv"]
    assert lo > 0 and hi > 0
    ident = float(
        S.vertical_force_identity(NeoHookean(), jnp.asarray(exc.value.partial["theta"][1]), r[1])
    )
    assert ident > 0  # T_theta(theta_max) > 0: the sheet pulls off


def test_stable_dt_bound():
    """A step twice the bound h^2/(2D) blows up; one below it stays bounded."""
    n = 30
    r = S.grid(n, RMAX)
    th = jnp.asarray(S.initial_shape("linear", r, TMAX))
    mat = NeoHookean()
    dt = float(S.stable_dt(mat, th, r[1], safety=1.0))
    ok = S.march(mat, th, r[1], 0.0, dt=0.9 * dt, vtol=1e-3, max_steps=4000)
    bad = S.march(mat, th, r[1], 0.0, dt=3.0 * dt, vtol=1e-3, max_steps=4000)
    assert np.all(np.isfinite(np.asarray(ok.theta)))
    assert not np.all(np.isfinite(np.asarray(bad.theta))) or float(bad.vmax) > 1e3 * float(ok.vmax)
