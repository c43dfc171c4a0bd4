"""Evidence for the headline results through the whole sheet (issue 27): stick/slip read off the
sheet's motion, a release tear-out against the equilibrium of the free span, a real window
search against the critical mu that equilibrium predicts, and the headline that the tube path
does not trap at the measured friction.

Every reference is a closed form, an equilibrium identity computed here from the saved
positions (not from the driver's diagnostics), or labelled a regression with the command and
commit that produced it. docs/evidence.md lists, per test, the broken variants it catches.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

from conftest import SCENARIOS
from dynslip.app.kinds import run as run_scenario
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.friction import SlipWeakening
from dynslip.physics.solver.methods import Settings
from dynslip.schema.base import load
from numerics import named_solver
from test_forming import MODEL, PRE, Z0, push_protocol

# ----------------------------------------------------------------- stick/slip through the sheet

MU_S, MU_K, D_C = 0.99, 0.82, 0.02
ETA = 0.1  # the drag per reference area of the run below (G h0 R / (R/s) per R^2)


def _penalty_normal_force(model, pen_depth):
    """N_i = A_i phi'(d_i), the penalty law of physics/sheet.py's module docstring written out
    here: 0 for d <= 0, k d^2 / (2 w) for 0 < d < w, k (d - w/2) beyond."""
    k, w = float(model.penalty.k), float(model.penalty.w)
    d = pen_depth
    quad = k * np.clip(d, 0.0, w) ** 2 / (2 * w)
    p = np.where(d <= 0, 0.0, np.where(d < w, quad, k * (d - w / 2)))
    return np.asarray(model.mesh.area) * p


def _contact_forces(model, rho, z, zb):
    """From positions alone (frames on the leading axis): the tangential elastic force F_t on
    each node (jax.grad of the elastic energy, on the ball's tangent toward the equator), the
    normal force N (the penalty law above), the polar angle and the distance from the ball's
    centre."""
    grad = jax.vmap(jax.grad(model.elastic_energy, argnums=(0, 1)))
    rho, z = np.atleast_2d(rho), np.atleast_2d(z)
    g_rho, g_z = (np.asarray(a) for a in grad(jnp.asarray(rho), jnp.asarray(z)))
    dz = z - np.reshape(zb, (-1, 1))
    r = np.hypot(rho, dz)
    th = np.arctan2(rho, dz)
    ft = -(g_rho * np.cos(th) - g_z * np.sin(th))  # t = (cos theta, -sin theta)
    return ft, _penalty_normal_force(model, 1.0 - r), th, r


@pytest.fixture(scope="module")
def weakening_push():
    """The held push-down of test_forming (N = 40, Gent, the rim pushed from 1.02 R to -1.5 R
    at 0.2 R/s: the sheet loads the ball ever more as it wraps), with slip-distance weakening
    mu_s = 0.99, mu_k = 0.82, d_c = 0.02 R, by load stepping (the default solver: every node's
    rate from physics/solver/increment.py node_rate), frames every 0.1 s."""
    fr = SlipWeakening(
        mu_s=jnp.asarray(MU_S), mu_k=jnp.asarray(MU_K), d_c=jnp.asarray(D_C), eps=jnp.asarray(1e-3)
    )
    res = simulate(
        MODEL,
        push_protocol(),
        friction=fr,
        eps=1e-3,
        drag=ETA,
        ball_drag=ETA * 4 * math.pi,
        pre_stretch=PRE,
        z_sheet=Z0,
        settings=Settings(solver=named_solver(), save_interval=0.1),
    )
    assert res.failed is None, res.failed
    return res


def _stick_slip_record(res):
    """Per node and frame, from the saved positions only: the tangential elastic force F_t
    (jax.grad of the elastic energy, projected on the ball's tangent), the normal force N (the
    penalty law written out above, from the penetration), the tangential displacement relative
    to the ball since the last frame, and the slip distance accumulated from those
    displacements since the node last stood still (reset out of contact). The friction law and
    the driver's diagnostics are not used."""
    fs = res.frames
    rho = np.array([np.asarray(f["rho"]) for f in fs])
    z = np.array([np.asarray(f["z"]) for f in fs])
    zb = np.array([float(f["ball_z"]) for f in fs])
    t = np.array([float(f["time"]) for f in fs])
    ft, normal, th, r = _contact_forces(MODEL, rho, z, zb)
    area = np.asarray(MODEL.mesh.area)
    contact = normal > 1e-2 * area  # pressure above the contact threshold (G h0 / R)
    stuck_ratio, onsets, kinetic, weakening = [], [], [], []
    for j in range(1, rho.shape[1] - 1):  # the pole carries no tangential force; the rim is held
        delta, was_stuck = 0.0, False
        for i in range(1, t.size):
            ds = abs(th[i, j] - th[i - 1, j]) * r[i, j]
            if normal[i, j] <= 0 and normal[i - 1, j] <= 0:
                delta, was_stuck = 0.0, False
                continue
            # compared only inside the contact, and never at its outermost node (the penalty's edge)
            if not (contact[i, j] and contact[i - 1, j] and contact[i, j + 1]):
                delta += ds
                was_stuck = False
                continue
            ratio = abs(ft[i, j]) / normal[i, j]
            if ds < 1e-12:  # the node stood still on the ball over the frame (to round-off)
                stuck_ratio.append(ratio)
                delta, was_stuck = 0.0, True
                continue
            # the friction force is F_t less the drag eta A v_t (the overdamped law)
            fric = ratio - ETA * area[j] * ds / (t[i] - t[i - 1]) / normal[i, j]
            if was_stuck:
                onsets.append((j, fric))
            delta += ds
            was_stuck = False
            mu = MU_K + (MU_S - MU_K) * max(0.0, 1.0 - delta / D_C)
            (kinetic if delta > 1.5 * D_C else weakening).append((j, fric - mu))
    return np.array(stuck_ratio), onsets, np.array(kinetic), np.array(weakening)


def test_stick_slip_through_the_sheet_onset_at_mu_s_sliding_at_mu_k(weakening_push):
    """Stick/slip read off the sheet's motion under a slowly growing load. A node stands still
    on the ball (its tangential displacement relative to the ball below 1e-12 R, round-off:
    motion along the normal leaves its polar angle unchanged) only while |F_t| <= mu_s N; it
    starts to move when |F_t| reaches mu_s N (onset, less the force-space smoothing); once its
    slip distance, measured from its own displacements, is past d_c it slides at
    |F_t| - eta A v_t = mu_k N; in between at mu(delta) = mu_k + (mu_s - mu_k)(1 - delta/d_c).
    F_t, N and the slip are computed here from the saved positions, not from the driver's
    friction diagnostics.

    Measured (``pytest -s tests/test_evidence_sheet.py -k stick_slip``, b988ecf): 3 nodes
    stuck before their onset; largest stuck ratio 0.9786; onset friction / N 0.98877-0.98904
    (mu_s - 1.2e-3: the smoothing band); on 605 node-frames past 1.5 d_c, |friction / mu_k N
    - 1| at most 5.1e-4 (median 1e-5); on 598 weakening node-frames, |friction / N -
    mu(delta)| at most 0.012 (7% of mu_s - mu_k: the increment's first-order lag, mu taken at
    the increment's start, physics/solver/increment.py slip_update)."""
    stuck, onsets, kinetic, weakening = _stick_slip_record(weakening_push)
    onset_nodes = sorted({j for j, _ in onsets})
    first_onset = {j: f for j, f in reversed(onsets)}  # each node's first onset
    print(
        f"stick/slip: {stuck.size} stuck node-frames, largest |F_t|/N {stuck.max():.5f}; onset "
        f"at nodes {onset_nodes}: {[round(float(first_onset[j]), 5) for j in onset_nodes]}; "
        f"{len(kinetic)} kinetic node-frames, max |fric/mu_k N - 1| "
        f"{np.max(np.abs(kinetic[:, 1])) / MU_K:.2e}; {len(weakening)} weakening node-frames, "
        f"max |fric/N - mu(delta)| {np.max(np.abs(weakening[:, 1])):.3e}"
    )
    assert stuck.size >= 20 and len(onset_nodes) >= 3
    # stick: inside the static cone (the smoothing only lowers the threshold)
    assert stuck.max() <= MU_S + 1e-9
    # onset at mu_s N: within 5e-3 (measured 1.2e-3 below it: the smoothing band)
    assert all(abs(f - MU_S) < 5e-3 for f in first_onset.values()), first_onset
    # sliding past d_c at mu_k N: 5e-3 relative (measured 5.1e-4), on several nodes
    assert len({int(j) for j in kinetic[:, 0]}) >= 5
    assert np.max(np.abs(kinetic[:, 1])) / MU_K < 5e-3
    # weakening: mu(delta) of the measured slip distance, within 0.03 (measured 0.012: first order
    # in the increment, so not 10x; the kinetic and static ends are 0.17 apart)
    assert len(weakening) >= 20
    assert np.max(np.abs(weakening[:, 1])) < 0.03


# ------------------------------------------------------------------------------- the headline


def test_pinned_rim_tube_path_does_not_trap_at_the_measured_friction(tmp_path):
    """THE PINNED-RIM STAND-IN (a regression, labelled): the experiment's path with the rim a pin
    holding the sheet's edge, the tube pushed down
    past the ball on its bottle neck and raised (scenarios/method2_pinned.yaml as shipped, Gent
    J_m = 50), at the measured friction mu_s = 0.99, mu_k = 0.82, does not trap the ball: the
    sheet wraps past the equator in the push-down, and the raise, until the tube's pull net of
    the sheet's drag vanishes, peels it back to a cap at the pole. At
    N = 30 the mesh check resolves every frame with margin (deepest chord below half the
    0.1 R limit), so "not trapped" is an answer, not a mesh artefact.

    Regression values (``dynslip run scenarios/method2_pinned.yaml --set numerics.nodes=30``,
    b988ecf, load stepping, 11 s): trapped false, deepest chord 0.0354 R, theta_max 1.925 at
    the end of the hold, no node in contact from the end of the raise on; at N = 20 and 40 the
    same
    verdict (chords 0.074, 0.023 R). If the model ever traps on this path at the measured
    friction, or loses its resolution, this test fails and the README's answer table must change."""
    sc = load(SCENARIOS / "method2_pinned.yaml", ["numerics.nodes=30"])
    fr = sc.physics.friction
    assert (fr.law, fr.mu_s, fr.mu_k) == ("slip_weakening", 0.99, 0.82)  # as measured
    s = run_scenario(sc, tmp_path, None)
    with xr.open_dataset(tmp_path / "trajectory.nc") as ds:
        stage = ds["stage"].values
        names = [st["name"] for st in s["stages"]]
        hold_end = ds.isel(time=int(np.flatnonzero(stage == names.index("hold"))[-1]))
        after_raise = np.flatnonzero(stage >= names.index("raise"))
        raise_end = int(np.flatnonzero(stage == names.index("raise"))[-1])
        theta_hold = float(hold_end["theta_max"])
        theta_raise_end = float(ds["theta_max"].values[raise_end])
        contact_after = (ds["state"].values[raise_end:] > 0).sum(axis=1)
    mc = s["mesh_check"]
    print(
        f"headline (method2_pinned.yaml, N = 30): trapped {s['trapped']}; deepest chord "
        f"{mc['max_chord_depth']:.4f} R; theta_max after the hold {theta_hold:.3f}; contact "
        f"nodes from the end of the raise {contact_after.max()}"
    )
    assert s["status"] == "ok"
    assert mc["resolved"] and mc["max_chord_depth"] <= 0.5 * mc["limit"]  # resolved, not marginal
    assert s["trapped"] is False
    assert theta_hold > math.pi / 2  # the push-down wrapped the sheet past the equator
    # the raise peeled the contact back to a cap about the pole (3 nodes or fewer)
    assert after_raise.size and theta_raise_end < 0.3 and contact_after.max() <= 3


@pytest.mark.slow
def test_headline_the_experiment_in_its_world_traps_at_the_measured_friction(tmp_path):
    """THE HEADLINE (a regression, labelled): the main job, scenarios/method2.yaml as shipped
    (N = 150), the experiment's path in the lab frame (the tube pushed 220 mm down over the
    ball on its bottle, its rim above the table, then raised until the support stops carrying
    the ball; Gent J_m = 97.2), at the measured friction mu_s = 0.99, mu_k = 0.82, traps the
    ball in the paper's pocket:
    - trapped, with an answer (no reason for unknown: every body resolved, the energy balance
      closed to 2% of the work, every stage's condition met);
    - the contact ends past the equator near the paper's 1.8 rad, the lip's material near its
      rbar 0.9;
    - the ball lifted off its support (no reaction at the end), the bottle at rest;
    - the push laid the tent on the bottle, and the tube's rim stayed above the table;
    - the largest stretch on the path is reported past latex's 6, and flagged.

    Regression values (``dynslip run scenarios/method2.yaml``): theta_max 2.064, rbar_max
    0.888, largest stretch 7.11 (I1-uniaxial 7.76), energy residual 0.43% of the work. If the
    model ever stops trapping here, this test fails and the README's answer must change."""
    sc = load(SCENARIOS / "method2.yaml")
    p = sc.physics
    assert (p.friction.law, p.friction.mu_s, p.friction.mu_k) == ("slip_weakening", 0.99, 0.82)
    assert p.frame == "lab" and p.tube is not None and p.bottle is not None
    s = run_scenario(sc, tmp_path, None)
    with xr.open_dataset(tmp_path / "trajectory.nc") as ds:
        ds = ds.load()
    names = [name for name, *_ in p.named_bodies()]
    rim = p.tube_rim_z + ds["body_z"].values[:, names.index("tube wall")]
    print(f"headline (method2.yaml): trapped {s['trapped']}; theta_max {s['theta_max']:.3f}, "
          f"rbar_max {s['rbar_max']:.3f}; lowest rim {rim.min() * p.ball_radius_mm:.1f} mm "
          f"(table {p.table_z_mm():.1f} mm); largest stretch "
          f"{s['largest_stretch']['path_max']:.2f}; energy "
          f"{s['energy_balance']['relative_residual']:.2e}")
    assert s["status"] == "ok" and s["trapped_unknown_reasons"] == []
    assert s["trapped"] is True and s["end_at_rest"]
    assert 1.8 < s["theta_max"] < 2.3 and 0.8 < s["rbar_max"] < 1.0
    assert abs(s["ball_reaction_end"]) < sc.numerics.trap_reaction_tol and s["ball_z_end"] >= 0
    assert np.all(ds["body_z"].values[:, names.index("bottle")] == 0.0)  # the bottle at rest
    assert next(b for b in s["bodies"] if b["name"] == "bottle")["touched"]
    assert rim.min() * p.ball_radius_mm > p.table_z_mm()
    assert s["largest_stretch"]["past_damage"] and s["largest_stretch"]["path_max"] > 6.0
    assert s["energy_balance"]["relative_residual"] < 0.02


# --------------------------------------------------------- a formed pocket (N = 20), shared


@pytest.fixture(scope="module")
def let_go_pocket(tmp_path_factory):
    """The shipped let-go path (scenarios/method2_let_go.yaml: Gent, mu_s 1.5, mu_k 1.25,
    healed at rest) at N = 20: a trapped pocket, written as a trajectory.nc (8 s)."""
    out = tmp_path_factory.mktemp("let_go_pocket")
    s = run_scenario(load(SCENARIOS / "method2_let_go.yaml", ["numerics.nodes=20"]), out, None)
    assert s["status"] == "ok" and s["trapped"] is True, s["outcome"]
    return out / "trajectory.nc"


def _from_pocket(path, pocket, stages=None):
    """A scenario that starts from ``pocket`` at N = 20 (start_from by --set; ``stages``
    replaces the file's)."""
    values = {"physics.stages": stages} if stages is not None else None
    return load(SCENARIOS / path, [f"start_from={pocket}", "numerics.nodes=20"], values=values)


# ---------------------------------------------------------------- the release: a tear-out

#: the pull of release_pull.yaml after a preload that takes up the let-go pocket's slack skirt
#: (as release_pull_tube.yaml does: without it the ball runs on the slack sheet at once and the
#: speed rule reads a tear-out at 0.02 N, docs/evidence.md); the stop speed 3 mm/s lets the run
#: go on until the ball has left the pocket; the release force is read at 0.1 mm/s, the shipped
#: release_pull.yaml's rule
TEAR_OUT_STAGES = [
    {"name": "preload", "ball": "pull", "ball_force_N": -0.6, "duration_s": 30.0},
    {"name": "settle", "ball": "pull", "ball_force_N": -0.6, "until":
     {"rule": "rest", "rate_mm_s": 0.01, "hold_s": 5.0}, "duration_s": 200.0},
    {"name": "pull", "ball": "pull", "ball_force_N": -6.0, "until":
     {"rule": "ball_speed_above", "speed_mm_s": 3.0}, "duration_s": 270.0},
]  # fmt: skip
RELEASE_SPEED_MM_S = 0.1


@pytest.mark.slow
def test_release_tear_out_against_the_free_span_equilibrium(let_go_pocket, tmp_path):
    """A tear-out from the formed let-go pocket (N = 20, the edge held where the pocket left
    it): a force on the ball ramped toward the opening at 0.02 N/s until the ball runs out.
    Equilibrium of the free sheet (physics.md Section 4): while the ball is quasi-static, the
    applied force less the drags equals the axial force 2 pi rho T_theta sin(psi) carried by
    the free span, the same on every free element. So the tear-out force (the applied force
    at the last frame below 0.1 mm/s) is bounded by the largest axial force the free span at
    the opening carried: F_tear = max P + (drag) + (one ramp step), and past it the ball leaves
    the pocket (theta_max < pi/2). P is computed here from the saved positions.

    Measured (``pytest -s -m slow tests/test_evidence_sheet.py -k tear_out``, b988ecf): on the
    quasi-static frames of the pull, applied - ball drag = P within 7.6e-3 (3e-3 until the
    last frames before the runaway: the load rate's first-order lag), spread of P along the
    span at most 1.3e-2 of P; max P 0.4023 G h0 R (0.805 N), tear-out 0.820 N at t = 54 s (ball
    drag 1.1% of it); the ball out of the pocket 8 s later (theta_max 0.128).
    Regression (labelled, same command and commit): tear-out force 0.82 N at N = 20 (the paper
    measured 2.3 N on the tube's pocket; the let-go pocket is not that pocket)."""
    import json

    from dynslip.analysis.release import sheet_force
    from dynslip.app.forming import build_core

    sc = _from_pocket("release_pull.yaml", let_go_pocket, TEAR_OUT_STAGES)
    model = build_core(sc)[0]
    s = run_scenario(sc, tmp_path, None)
    assert s["status"] == "ok", s["outcome"]
    with xr.open_dataset(tmp_path / "trajectory.nc") as ds:
        ds = ds.load()
    fs = float(ds.attrs["force_scale_N"])
    r_mm = float(ds.attrs["R_m"]) * 1e3
    t = ds["time"].values
    pull = ds["stage"].values == 2
    speed = np.abs(np.gradient(ds["ball_z"].values, t)) * r_mm
    applied = -ds["ball_reaction"].values  # the pull, toward the opening (down), as positive
    # less the ball's drag (the sheet's drag acts between sheet and ball, so it is inside P)
    drag = applied + sheet_force(ds)
    p_free, spread = np.full(t.size, np.nan), np.full(t.size, np.nan)
    for i in np.flatnonzero(pull):
        f = ds.isel(time=i)
        free = f["state"].values == 0
        el = free[:-1] & free[1:]
        if el.sum() >= 3:
            p = np.asarray(
                model.free_span_axial_force(
                    jnp.asarray(f["rho"].values), jnp.asarray(f["z"].values)
                )
            )[el]
            p_free[i], spread[i] = np.mean(p), np.ptp(p) / abs(np.mean(p))
    slow = pull & (speed < RELEASE_SPEED_MM_S)
    i_rel = int(np.flatnonzero(slow)[-1])
    f_tear = applied[i_rel] * fs
    balance = np.abs(applied[slow] - drag[slow] - p_free[slow]) / applied[slow]
    p_max = float(np.nanmax(p_free[slow]))
    end = ds.isel(time=-1)
    summary_release = json.loads((tmp_path / "summary.json").read_text())["release"]["force_ramp"]
    print(
        f"tear-out (N = 20): F_tear {f_tear:.4f} N at t = {t[i_rel]:.0f} s; max free-span force "
        f"{p_max:.5f} G h0 R = {p_max * fs:.4f} N; balance residual max {balance.max():.2e}; "
        f"spread max {np.nanmax(spread[slow]):.2e}; ball drag {drag[i_rel] / applied[i_rel]:.4f}; "
        f"end theta_max {float(end['theta_max']):.3f} at t = {t[-1]:.0f} s"
    )
    # the ball left the pocket: the pull stopped by its speed rule, the contact above the equator
    assert s["stages"][-1]["condition_met"] and t[-1] < t[pull][0] + 270.0
    assert float(end["theta_max"]) < math.pi / 2 or not np.isfinite(float(end["theta_max"]))
    # quasi-static: the free span carries the applied force less the drags, the same everywhere
    assert slow.sum() >= 8
    assert balance.max() < 3e-2  # measured 7.6e-3: first order in the load rate, not round-off
    assert np.nanmax(spread[slow]) < 0.05  # measured 1.3e-2
    # the tear-out force against the free span's largest force: within the drags and one frame's
    # ramp (0.02 N)
    share = drag[i_rel] / applied[i_rel]
    assert share < 0.05  # the regularisation's part, measured 0.011
    assert p_max * fs <= f_tear <= p_max * fs / (1 - share) + 0.02 + 1e-9
    # the shipped analysis reads the same force at the same rule
    assert summary_release["torn_out"] is True
    # REGRESSION (labelled; command and commit in the docstring): 0.820 N at N = 20, within two
    # frames of the ramp (0.02 N each)
    assert abs(f_tear - 0.82) <= 0.04


# ------------------------------------------------------------ a critical mu against equilibrium


@pytest.mark.slow
def test_window_search_finds_the_critical_mu_that_the_pocket_equilibrium_predicts(
    let_go_pocket, tmp_path
):
    """A real window search (dynslip.app.window.run_window, the code behind ``dynslip window``)
    on the shipped margin path (scenarios/margin_let_go.yaml: from the formed let-go pocket,
    healed, mu_s lowered with mu_k / mu_s held at 1.25 / 1.5, hold until at rest), N = 20.

    Known answer, from the equilibrium of the start state: a node of the healed pocket stays
    stuck while |F_t| <= mu_s N. So every mu_s above mu* = the largest |F_t| / N over the
    interior contact nodes (F_t, N from the saved positions; the outermost contact node, at
    the penalty's edge, excluded) leaves the pocket where it is: trapped. Below mu* an interior
    node slips, weakens to mu_k < its load, and the pocket unravels (the weakening's
    cascade). So the critical mu is mu*, up to the smoothing band (1e-3 G h0/R over the
    pressure) and the bisection's tolerance.

    Measured (``pytest -s -m slow tests/test_evidence_sheet.py -k critical``, b988ecf): mu* =
    1.3390 (node 3; the plateau 1.248-1.251 of the nodes that slid last in the forming, at its
    mu_k 1.25; the outermost node 1.444); the search (lo 1.0, hi 1.5, 3 coarse points, tol
    0.01; 8 runs, 45 s) finds one window [1.3398, 1.5], critical mu 1.3398 +- 0.0039: 8e-4 from
    mu*. (At N = 50 docs/forming.md reports that the pocket holds down to mu_s = 1.252, the
    plateau's level; that mesh's mu* is not computed here.)"""
    from dynslip.app.forming import build_core
    from dynslip.app.window import run_window

    sc = _from_pocket("margin_let_go.yaml", let_go_pocket)
    model = build_core(sc)[0]
    with xr.open_dataset(let_go_pocket) as ds:
        end = ds.isel(time=-1).load()
    assert np.all(end["slip_distance"].values == 0.0)  # healed: every node at mu_s
    ft, normal, _, _ = _contact_forces(
        model, end["rho"].values, end["z"].values, float(end["ball_z"])
    )
    ft, normal = ft[0], normal[0]
    contact = np.flatnonzero(normal > 1e-2 * np.asarray(model.mesh.area))
    interior = contact[(contact > 0) & (contact < contact.max())]
    ratio = np.abs(ft[interior]) / normal[interior]
    mu_star = float(ratio.max())
    res = run_window(
        SCENARIOS / "margin_let_go.yaml",
        [f"start_from={let_go_pocket}", "numerics.nodes=20"],
        lo=1.0,
        hi=1.5,
        coarse=3,
        tol=0.01,
        out=tmp_path / "window",
    )
    crit = res["critical_mu"]
    print(
        f"margin path, N = 20: mu* = {mu_star:.4f} (interior |F_t|/N {np.round(ratio, 4)}); "
        f"windows {res['windows']}; critical mu {crit}; evaluations {res['evaluations']}"
    )
    assert res["resolution_check"]["members_resolved"]
    assert len(res["windows"]) == 1 and not res["failed"]
    assert not crit["open"] and not crit["unresolved"] and not crit["failed_side"]
    # the critical mu is the equilibrium's mu*: within the bracket and 5e-3 (measured 8e-4)
    assert abs(crit["value"] - mu_star) <= crit["err"] + 5e-3
    # and the trapped side holds above it: every evaluation above mu* traps, below it does not
    for mu, trapped in res["evaluations"]:
        if abs(mu - mu_star) > 5e-3:
            assert trapped is (mu > mu_star), (mu, trapped)
