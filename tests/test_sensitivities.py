"""Sensitivities through the whole loading path (issue 55, item 3;
:func:`dynslip.api.sensitivities`, docs/sensitivities.md), on the let-go path of
scenarios/method2_let_go.yaml at 20 nodes (push, hold, the rim's force ramped off, the ball's
hold ramped off, rest): the tangents against central differences where the path is smooth, a
step across a known jump reported, several directions at once against one at a time, and a
condition stop's time against its closed form.

The tangent programs compile for 30-60 s each (one per number of directions), shared by the
module's tests.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dynslip
from dynslip.api import load
from dynslip.errors import InputError
from dynslip.physics.driver.simulate import simulate

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "method2_let_go.yaml"
BASE = {"numerics.nodes": 20}
PARAMS = ["physics.material.jm", "physics.friction.mu_s"]
#: the end state's scalars: the contact edge's angle, the pocket's energies, its largest
#: stretches, the clamp's end position
STATE = ("theta_max", "energy_elastic", "energy_penalty", "lambda_theta_max", "lambda_phi_max",
         "clamp_z", "clamp_rho")
#: integrals along the path (the accumulators): the clamp's work, drag and friction dissipation
PATH = ("work_clamp", "dissipation_drag", "dissipation_friction")
SMOOTH = STATE + PATH


@pytest.fixture(scope="module")
def both():
    return dynslip.sensitivities(load(SCENARIO, set=BASE), PARAMS)


@pytest.fixture(scope="module")
def one():
    return dynslip.sensitivities(load(SCENARIO, set=BASE), PARAMS[:1], check=False)


def test_smooth_stretch_tangents_agree_with_central_differences(both):
    """At J_m = 50, mu_s = 1.5 nothing jumps within h = 1e-4 |p|: defined, and each tangent
    is the central difference of the neighbouring runs, at the precision each achieves
    (measured at 20 nodes): the end state's scalars to at most 4.7e-7 of the larger (rtol
    1e-6 here), the path integrals to at most 8.6e-4 (2e-3 here; the drag's dissipation in
    J_m the worst): they sum every increment, and a Newton iteration count or a node's
    healing that moves within the step moves them by a little more than the difference's
    own error."""
    assert both.defined, both.reasons
    assert both.reasons == [] and both.notes == []
    assert both.step == pytest.approx({PARAMS[0]: 5e-3, PARAMS[1]: 1.5e-4})
    for names, rtol in ((STATE, 1e-6), (PATH, 2e-3)):
        for name in names:
            jvp, cd = both.jacobian[name], both.central[name]
            assert np.all(np.abs(jvp) > 0), name
            np.testing.assert_allclose(jvp, cd, rtol=rtol, err_msg=name)
    names, jac = both.matrix(SMOOTH)
    assert jac.shape == (len(SMOOTH), 2) and names == list(SMOOTH)


def test_piecewise_constant_values_have_zero_tangents(both):
    """rbar_max is a node's material radius and n_contact a count: their tangents are 0, and
    so are the central differences on a stretch where the contact set stays."""
    for name in ("rbar_max", "n_contact"):
        if name in both.jacobian:
            assert np.all(both.jacobian[name] == 0.0)
            assert np.all(both.central[name] == 0.0)


def test_several_directions_at_once_equal_one_at_a_time(both, one):
    assert one.params == PARAMS[:1]
    for name in SMOOTH:
        np.testing.assert_allclose(one.jacobian[name][0], both.jacobian[name][0], rtol=1e-9,
                                   atol=1e-14, err_msg=name)
        assert one.values[name] == pytest.approx(both.values[name], rel=1e-12)


def test_a_step_across_the_pocket_losing_contact_is_reported(one):
    """Between J_m = 38 and 39 (20 nodes) the sheet comes off the ball at the let-go on one
    side and stays on it on the other; a step of 2% of 38.5 crosses it: not defined, with
    the contact set named, never a one-sided number presented as the derivative."""
    w = {jm: load(SCENARIO, set={**BASE, PARAMS[0]: jm}).world() for jm in (38.0, 39.0)}
    ends = {jm: simulate(x.model, x.protocol, **x.simulate_kwargs()).frames[-1]
            for jm, x in w.items()}
    assert np.isnan(ends[38.0]["theta_max"]) and np.isfinite(ends[39.0]["theta_max"])
    got = dynslip.sensitivities(load(SCENARIO, set={**BASE, PARAMS[0]: 38.5}), PARAMS[:1],
                                step=0.02)
    assert not got.defined
    assert any("contact set changes" in r for r in got.reasons), got.reasons


def _event_time(frames, stage: int, force: float) -> float:
    """The time the hold's reaction crosses ``force`` in stage ``stage``, between the frames
    on either side, by linear interpolation."""
    got = [(f["time"], float(f["ball_reaction_static"])) for f in frames if f["stage"] == stage]
    before = [f for f in frames if f["stage"] < stage][-1]
    got = [(before["time"], float(before["ball_reaction_static"]))] + got
    k = next(i for i, (_, g) in enumerate(got) if g < force)
    (t0, g0), (t1, g1) = got[k - 1], got[k]
    return t0 + (t1 - t0) * (g0 - force) / (g0 - g1)


def test_a_condition_stops_time_is_differentiated_at_its_event(one):
    """The let-go stage ended by ball_reaction_below 50 N (the rim's force ramped off from the
    hold's, the hold's reaction falls with it, from 102 N through 50 N between two saves):
    the stop time's tangent, dt*/dJ_m = -(dg/dJ_m)/(dg/dt) at the event located between the
    saved frames by linear interpolation of g, against the central difference of the event
    time located so in the neighbouring runs (measured agreement 1e-7)."""
    until = {"physics.stages.let_go.until": {"rule": "ball_reaction_below", "force_N": 50.0}}
    scn = load(SCENARIO, set={**BASE, **until})
    got = dynslip.sensitivities(scn, PARAMS[:1])
    ev = got.events["let_go"]
    assert np.isfinite(ev["dt"][0]) and ev["dt"][0] != 0.0
    assert ev["values"]["ball_reaction_static"] < 25.0  # 50 N in G h0 R = 2 N
    h = got.step[PARAMS[0]]
    force = scn.world().protocol.stages[2].stop.force
    t_star = {}
    for s in (-1, 1):
        x = load(SCENARIO, set={**BASE, **until, PARAMS[0]: 50.0 + s * h}).world()
        r = simulate(x.model, x.protocol, **x.simulate_kwargs())
        t_star[s] = _event_time(r.frames, 2, force)
    assert ev["dt"][0] == pytest.approx((t_star[1] - t_star[-1]) / (2 * h), rel=1e-5)
    # the neighbouring runs stop at save times: the end frame's central differences are not
    # compared with the tangents (which move the stop with its event), and that is said
    assert any("not compared" in n for n in got.notes)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        (["physics.material.nope"], "does not exist"),
        (["physics.material.model"], "real number"),
        (["numerics.nodes"], "real number"),
        ([], "one or more"),
    ],
)
def test_bad_parameters_are_refused_in_one_line(params, match):
    with pytest.raises(InputError, match=match):
        dynslip.sensitivities(load(SCENARIO, set=BASE), params)
