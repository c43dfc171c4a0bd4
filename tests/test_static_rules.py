"""The two selection rules of the fully mobilised family (rbar_s = 0.25 R, and the paper's
statement theta_s = pi/4: ``selection.rule: switch_angle``), and the implicit march of the
paper's algorithm against the explicit one (docs/static-model.md)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics import static as S
from dynslip.physics.materials import Gent, Hookean, NeoHookean
from dynslip.schema.static import Selection, StaticScenario

RMAX, TMAX, N = 0.9, 1.8, 100
GUESS = (2.2, 1.0, 0.25)
MATS = {"hookean": Hookean(), "neo_hookean": NeoHookean(), "gent": Gent(jm=50.0)}


def test_switch_angle_default_is_the_papers_pi_over_4():
    assert Selection(rule="switch_angle").value == pytest.approx(math.pi / 4)
    assert Selection().rule == "switch_radius" and Selection().value == 0.25
    sc = StaticScenario.model_validate({"physics": {"selection": {"rule": "switch_angle"}}})
    assert sc.physics.selection.value == pytest.approx(math.pi / 4)
    assert Selection(rule="switch_angle", value=0.8).value == 0.8


@pytest.mark.parametrize("name", ["neo_hookean", "gent"])
def test_rules_agree_where_they_coincide(name):
    """The member whose switch sits at theta = pi/4 has some switch radius r*; the radius rule
    at r* picks the same member (same mu, theta_s = pi/4). Conversely the angle rule at the
    switch angle of the rbar_s = 0.25 member picks that member (rbar_s = 0.25, same mu)."""
    mat = MATS[name]
    ma = S.solve_member(mat, math.pi / 4, TMAX, RMAX, GUESS, by="switch_angle")
    assert ma.converged and ma.theta_s == pytest.approx(math.pi / 4, abs=1e-9)
    mr = S.solve_member(mat, ma.rbar_s, TMAX, RMAX, GUESS, by="switch_radius")
    assert mr.converged
    assert mr.mu == pytest.approx(ma.mu, rel=1e-8)
    assert mr.theta_s == pytest.approx(math.pi / 4, abs=1e-8)
    assert mr.lam0 == pytest.approx(ma.lam0, rel=1e-8)

    m25 = S.solve_member(mat, 0.25, TMAX, RMAX, GUESS, by="switch_radius")
    mb = S.solve_member(mat, m25.theta_s, TMAX, RMAX, GUESS, by="switch_angle")
    assert mb.converged
    assert mb.rbar_s == pytest.approx(0.25, abs=1e-8)
    assert mb.mu == pytest.approx(m25.mu, rel=1e-8)


@pytest.mark.parametrize("name", ["hookean", "neo_hookean", "gent"])
def test_switch_angle_member_changes_sign_where_theta_crosses_pi_over_4(name):
    """On the paper's grid (N = 100, grid formulas), the last node with F_m > 0 is the last
    node with theta < pi/4: F_m changes sign between the two nodes that bracket theta = pi/4."""
    mat = MATS[name]
    ma = S.solve_member(mat, math.pi / 4, TMAX, RMAX, GUESS, by="switch_angle")
    assert ma.converged
    r = S.grid(N, RMAX)
    th, _ = S.sample_member(mat, ma, RMAX, r)
    f = S.fields(mat, jnp.asarray(th), r[1])
    i_s = S.sign_change_index(f.fm)
    j = int(np.flatnonzero(th < math.pi / 4)[-1])  # theta_j < pi/4 <= theta_{j+1}
    assert i_s == j, (i_s, j, th[j], th[j + 1])
    fm = np.asarray(f.fm)
    assert fm[j] > 0 and fm[j + 1] < 0
    # F_m = +mu F_N before the switch and -mu F_N after it, at the nodes outside the grid
    # formulas' five-node stencil around the kink
    fn = np.asarray(f.fn)
    np.testing.assert_allclose(fm[j - 5:j - 2] / fn[j - 5:j - 2], ma.mu, rtol=0.05)
    np.testing.assert_allclose(fm[j + 3:j + 6] / fn[j + 3:j + 6], -ma.mu, rtol=0.05)


def test_velocity_jacobian_matches_jacfwd():
    mat = NeoHookean()
    r = S.grid(40, RMAX)
    m = S.solve_member(mat, 0.25, TMAX, RMAX, GUESS, by="switch_radius")
    th, _ = S.sample_member(mat, m, RMAX, r)
    th = jnp.asarray(th)
    for mu in (0.5, 0.9):
        jc = S.velocity_jacobian(mat, th, r[1], mu)
        jf = jax.jacfwd(lambda t: S.velocity(mat, t, r[1], mu))(th)  # noqa: B023
        np.testing.assert_allclose(jc, jf, rtol=0, atol=1e-9 * float(jnp.max(jnp.abs(jf))))


def test_implicit_march_gives_the_explicit_mu_at_small_n():
    """The paper's search with the implicit march (backward Euler, semi-smooth Newton) returns
    the explicit march's mu within 1e-3, at N = 40 for neo-Hookean; both end states are rest
    states (max velocity <= 1e-6)."""
    mat = NeoHookean()
    n = 40
    r = S.grid(n, RMAX)
    h = float(r[1])
    fv_tol = 1e-3 * (99.0 / (n - 1)) ** 2
    m = S.solve_member(mat, 0.25, TMAX, RMAX, GUESS, by="switch_radius")
    th, _ = S.sample_member(mat, m, RMAX, r)
    se = S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="explicit")
    si = S.search_mu(mat, th, h, 0.1, 5.0, mu_tol=1e-4, fv_tol=fv_tol, method="implicit")
    assert abs(si.mu - se.mu) <= 1e-3
    assert bool(si.march.converged) and bool(se.march.converged)
    # below the member's mu the sheet slips: the two marches reach nearly the same rest state
    mu = 0.97 * m.mu
    e = S.march(mat, th, h, mu, method="explicit")
    i = S.march(mat, th, h, mu, method="implicit")
    assert bool(e.converged) and bool(i.converged)
    moved = float(jnp.max(jnp.abs(e.theta - th)))
    assert moved > 1e-4
    assert float(jnp.max(jnp.abs(i.theta - e.theta))) <= 0.01 * moved
    chk = S.check_equilibrium(mat, i.theta, h, mu, vtol=1e-6)
    assert chk["ok"], chk
