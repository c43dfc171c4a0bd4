"""Guards on three reported figures, each read back from the saved frames by its definition or
by a balance the code does not use to make it (issue 44, item 4):

- when a stage counts as at rest (``until: rest``): the stage ends at the first saved frame
  where the largest slip speed has stayed below the stated rate for the stated hold;
- the release test's force (``summary.json`` ``release.peak_force_N``): the force the hold
  supplies against the sheet equals, by the sheet's global axial balance, minus the clamp's
  axial force, a separate reaction of the run;
- the energy balance with a held body moved by the stages (the tube's wall in the lab frame):
  recomputed from the saved accumulators, it closes; the moved body's work is a large share of
  it, and that work equals the wall's force, from the sheet's axial balance (minus the clamp's
  and the hold's forces), times the wall's saved velocity, integrated over the frames.

Each guard fails when its figure is a few percent off (the defects planted for the note: the
rest rate x1.05, the release force x0.97 (the peak's or the force ramp's), the moved body's
work dropped from its accumulator or from the residual the summary reports). All of them are in
the quick suite, so that the quick loop catches those defects: small meshes (N <= 32), the
runs at N = 20 sharing one compiled step. Measured with ``pytest tests/test_guards.py
--durations=0`` and an empty compilation cache, the two cores busy with other work: each
test's runs 7-13 s in the module, 15-21 s alone.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

from dynslip import api
from helpers import capstan_tube, load_data, run_kept

R_MM = 20.0  # the ball's radius (the schema's default): lengths in the core are in R

# a pocket pushed over the held ball (test_release's path, quicker), frames every 0.1 s; the
# settle stage lets the sheet creep toward rest (the smoothed Coulomb law's tail)
POCKET = {
    "name": "guards",
    "kind": "forming",
    "physics": {
        "friction": {"law": "coulomb", "mu": 0.8},
        "stages": [
            {"name": "push_down", "clamp_to_z_mm": -30.0, "clamp_speed_mm_s": 4.0},
            {"name": "settle", "duration_s": 10.0},
        ],
    },
    "numerics": {"nodes": 20, "save_interval_s": 0.1},
}
HOLD_S = 0.5  # the rest rule's hold: 5 frames


def _moving(ds):
    """The rest rule's reading of each saved frame (R/s): the largest slip speed over the nodes
    (the ball is held at rest on this path, so its speed is 0)."""
    return np.max(np.abs(ds["slip_velocity"].values), axis=1)


def _rest_end(t, moving, rate, hold):
    """The time a stage with ``until: rest`` ends, by the rule's definition, from its frames: the
    first frame where ``moving`` has stayed below ``rate`` for ``hold`` seconds (None: never)."""
    since = None
    for ti, mi in zip(t, moving, strict=True):
        if not mi < rate:
            since = None
            continue
        since = ti if since is None else since
        if ti - since >= hold - 1e-9:
            return float(ti)
    return None


@pytest.fixture(scope="module")
def pocket(tmp_path_factory):
    """The pocket path, its settle stage a fixed 10 s; written to a folder (the release starts
    from it)."""
    tmp = tmp_path_factory.mktemp("pocket")
    res = api.run(load_data(tmp, POCKET, "pocket"), out=tmp / "run")
    assert res.summary["status"] == "ok"
    return res.trajectory, tmp / "run" / "trajectory.nc"


@pytest.fixture(scope="module")
def rate_and_frame(pocket):
    """A rest rate placed between two saved frames of the settle stage's tail: frame k's reading
    is 2% above it (inside a 5% band) and frame k+1's below it, where the reading is near 1e-6
    R/s and falls by more than 6% per frame. A rule read a few percent off ends the stage a frame
    early or late."""
    ds, _ = pocket
    settle = ds["stage"].values == 1
    t, m = ds["time"].values[settle], _moving(ds)[settle]
    ks = [k for k in range(1, t.size - 30) if m[k] < 2e-6 and m[k] / m[k + 1] > 1.06]
    assert ks, m
    k = ks[0]
    rate = float(m[k] / 1.02)
    assert m[k + 1] < rate <= m[k] < 1.05 * rate
    return rate, float(t[k]), float(t[k + 1])


def test_a_rest_stage_ends_where_the_rest_rule_says_from_the_saved_frames(
    pocket, rate_and_frame, tmp_path
):
    """The settle stage run again with ``until: rest`` at the rate above (mm/s in the file) and a
    0.5 s hold: it ends at the frame where the largest saved slip speed has stayed below the
    rate for the hold, read here from its own frames: the frame after k, plus the hold. Its
    frames up to there are the fixed-duration run's (the rule only reads them). A rate read 5%
    high would end it a frame (0.1 s) early, a hold 5% long a frame late."""
    ref, _ = pocket
    rate, t_k, t_k1 = rate_and_frame
    data = copy.deepcopy(POCKET)
    data["physics"]["stages"][1].update(
        until={"rule": "rest", "rate_mm_s": rate * R_MM, "hold_s": HOLD_S}, duration_s=10.0
    )
    res = api.run(load_data(tmp_path, data, "rest"))
    ds = res.trajectory
    settle = ds["stage"].values == 1
    t, m = ds["time"].values[settle], _moving(ds)[settle]
    n = ds.sizes["time"]
    np.testing.assert_allclose(ds["rho"].values, ref["rho"].values[:n], rtol=0, atol=1e-12)
    expected = _rest_end(t, m, rate, HOLD_S)
    print(f"rest rate {rate:.4e} R/s; frame k {t_k:.2f} s reads {m[t == t_k][0] / rate:.4f} x rate;"
          f" the rule's end from the frames {expected} s, the stage's end {t[-1]:.2f} s")
    assert expected is not None, f"the stage ended at {t[-1]:.2f} s, before the rule holds"
    assert t[-1] == pytest.approx(expected, abs=1e-9), (t[-1], expected)
    assert expected == pytest.approx(t_k1 + HOLD_S, abs=1e-9)
    stage = res.summary["stages"][1]
    assert stage["condition_met"] is True
    assert res.summary["trapped"] is not None


# ---------------------------------------------------------------------------- the release force


@pytest.fixture(scope="module")
def release(pocket, tmp_path_factory):
    """From the pocket's end state (the clamp held where it left the edge), the held ball pulled
    toward its pole at 0.2 mm/s for 10 s: the release test of scenarios/release.yaml."""
    _, start = pocket
    tmp = tmp_path_factory.mktemp("release")
    data = {
        "name": "release guard",
        "kind": "forming",
        "start_from": str(start),
        "physics": copy.deepcopy(POCKET["physics"]),
        "numerics": {"nodes": 20, "save_interval_s": 0.5},
    }
    data["physics"]["stages"] = [
        {"name": "pull", "ball": "hold", "ball_velocity_mm_s": 0.2, "duration_s": 10.0}
    ]
    res = api.run(load_data(tmp, data, "release"))
    assert res.summary["status"] == "ok"
    return res


def test_the_release_force_is_the_clamps_reaction_by_the_sheets_axial_balance(release):
    """The release force (``release.peak_force_N``, and ``release_force``) is the hold's force on
    the sheet at the peak, over the frames before the opening reaches R (this pocket's contact
    edge stays below the equator, so that is the first frame). By the sheet's axial balance the
    hold's force on the sheet is, at every frame, minus the clamp's axial force, a reaction the
    run saves separately: exactly where nothing moves (the elastic energy does not change when
    the whole sheet is shifted along the axis), otherwise less the sheet's drag (ball speed 0.01
    R/s, drag time 0.1 s). Measured: 0 at the peak, the start state (N = 20); bound 1%, a third
    of a 3% error."""
    s, ds = release.summary, release.trajectory
    rel = s["release"]
    fs = float(ds.attrs["force_scale_N"])
    th = ds["theta_max"].values
    below = np.flatnonzero(~(th >= math.pi / 2))
    upto = np.arange(max(int(below[0]) if below.size else th.size, 1))
    clamp_n = -ds["clamp_force"].values * fs  # the sheet's pull on the ball, from the clamp
    i = int(upto[np.argmax(np.abs(clamp_n[upto]))])
    mismatch = abs(rel["peak_force_N"] / clamp_n[i] - 1)
    print(f"release peak force {rel['peak_force_N']:.5f} N, minus the clamp's axial force there "
          f"{clamp_n[i]:.5f} N: relative difference {mismatch:.2e}")
    assert abs(clamp_n[i]) > 1.0  # the pocket loads the sheet (N)
    assert mismatch < 1e-2
    assert s["release_force"] == rel["peak_force_N"]
    disp = (ds["ball_z"].values[i] - ds["ball_z"].values[0]) * R_MM
    assert rel["peak_displacement_mm"] == pytest.approx(disp, abs=1e-9)


BALL_DRAG = 1000.0  # the ball's drag, times the sheet's over 4 pi R^2: the sheet's share ~1e-3
SPEED_MM_S = 0.1  # the tear-out threshold


@pytest.fixture(scope="module")
def ramp(tmp_path_factory):
    """The release by a force ramp (scenarios/release_pull.yaml) on a trivial path: from a flat
    sheet above the ball (no contact: the start written by a 1 s hold), the force on the ball
    ramped down to -14 N over 20 s until its speed exceeds 0.1 mm/s. The ball is overdamped and
    the sheet stays put, so its speed is F(t) / eta and it tears out where F = eta v: a closed
    form, eta = drag time x 4 pi x ball_drag (G h0 R s / R)."""
    tmp = tmp_path_factory.mktemp("ramp")
    numerics = {"nodes": 20, "save_interval_s": 0.1, "ball_drag": BALL_DRAG}
    flat = {"name": "flat", "kind": "forming",
            "physics": {"friction": {"law": "coulomb", "mu": 0.8},
                        "stages": [{"name": "wait", "duration_s": 1.0}]},
            "numerics": numerics}
    # no work done: the energy balance has no scale, and the run has no answer
    start = run_kept(load_data(tmp, flat, "flat"), out=tmp / "flat").out
    data = copy.deepcopy(flat)
    data["start_from"] = str(start / "trajectory.nc")
    data["physics"]["stages"] = [
        {"name": "pull", "ball": "pull", "ball_force_N": -14.0, "duration_s": 20.0,
         "until": {"rule": "ball_speed_above", "speed_mm_s": SPEED_MM_S}}
    ]
    return run_kept(load_data(tmp, data, "ramp"))  # the ball runs away: the verdict has no answer


def test_the_release_force_of_a_force_ramp_against_its_closed_form(ramp):
    """``release_force`` (the applied force at the last saved frame below the threshold speed)
    against eta v_threshold: the ramp's step per frame (0.07 N, 0.6%) below it, the sheet's drag
    (its area over the ball's drag, 1.4e-3) above. Measured +2.7e-3 (N = 20). Bound 1%: a 3% error
    fails."""
    s, ds = ramp.summary, ramp.trajectory
    fs = float(ds.attrs["force_scale_N"])
    nu = json.loads(ds.attrs["scenario"])["numerics"]
    eta = float(nu["drag_time_s"]) * 4 * math.pi * BALL_DRAG  # G h0 R per R/s
    closed = eta * SPEED_MM_S / R_MM * fs  # N
    ramp_n = s["release"]["force_ramp"]
    err = abs(s["release_force"]) / closed - 1
    print(f"release force {s['release_force']:.4f} N against eta v = {closed:.4f} N ({err:+.2e}); "
          f"drag share {ramp_n['drag_share']:.4f}")
    assert ramp_n["torn_out"] is True
    assert s["release_force"] == ramp_n["release_force_N"] < 0  # toward the opening
    assert abs(err) < 1e-2


# --------------------------------------------------- the energy balance with a moving held body

# the capstan's path (tests/test_independent_mu.py): in the lab frame the tube (its wall a held
# body moved by the stages, and the band) is pushed down over the held ball, which draws the
# sheet over the rim (Coulomb 0.3 on the tube) until the band slides; frames every 0.5 s
TUBE = capstan_tube("tube guard", tube_mu=0.3, save_interval_s=0.5)


@pytest.fixture(scope="module")
def tube_run(tmp_path_factory):
    """The run, also where its verdict has no answer (a residual above the bound): what it
    computed is what the balance below is read from."""
    res = run_kept(load_data(tmp_path_factory.mktemp("tube"), TUBE, "tube"))
    assert res.summary["status"] == "ok"
    return res


def test_energy_balance_with_a_moving_held_body(tube_run):
    """W_clamp + W_ball + W_bodies - (change of elastic and penalty energy) - friction and drag
    dissipation, from the saved accumulators: below 1% of the work (measured 1.2e-3, load
    stepping's first-order dissipation), and the summary reports that residual. The moved wall's
    work is most of the work (about 0.7 of it): without it the residual would be that large.
    The wall's work read independently: its axial force on the sheet is, by the sheet's axial
    balance, minus the clamp's and the hold's (the ball at rest in the lab, the sheet's drag
    acting between sheet and ball), and its power that force times its saved velocity;
    integrated over the frames it matches the accumulator to 1% (measured 1.8e-3 at 0.5 s
    frames)."""
    s, ds = tube_run.summary, tube_run.trajectory
    k = list(ds["body"].values).index("tube wall")
    w_bodies = ds["work_bodies"].values
    work = ds["work_clamp"].values + ds["work_ball"].values + w_bodies
    stored = ds["energy_elastic"].values + ds["energy_penalty"].values
    diss = ds["dissipation_friction"].values + ds["dissipation_drag"].values
    resid = work - (stored - stored[0]) - diss
    scale = float(np.max(np.abs(ds["work_clamp"].values) + np.abs(ds["work_ball"].values)
                         + np.abs(w_bodies)))
    rel = float(np.max(np.abs(resid))) / scale
    share = float(np.max(np.abs(w_bodies))) / scale
    without = float(np.max(np.abs(resid - w_bodies))) / scale
    # the wall's work from the axial balance and its saved motion
    t = ds["time"].values
    f_wall = -(ds["clamp_force"].values + ds["ball_reaction"].values)
    v_wall = np.gradient(ds["body_z"].values[:, k], t)
    power = f_wall * v_wall
    w_indep = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    w_err = abs(w_indep[-1] / w_bodies[-1] - 1)
    print(f"energy residual {rel:.2e} of the work; the moved wall's share {share:.3f}; without it "
          f"{without:.3f}; the wall's work {w_bodies[-1]:.5f} against {w_indep[-1]:.5f} from the "
          f"axial balance ({w_err:.2e})")
    assert np.all(ds["ball_z"].values == 0.0) and np.ptp(ds["body_z"].values[:, k]) > 1.0
    assert rel < 1e-2
    assert s["energy_balance"]["relative_residual"] == pytest.approx(rel, rel=1e-6)
    assert share > 0.3 and without > 0.3
    assert w_err < 1e-2
