"""Quasi-static load stepping (issue 10 section 2, :mod:`dynslip.physics.solver.loadstep`).

The local ImplicitEuler fix (diffrax PR #753) against the pinned class; load stepping
against Kvaerno5 on a short push-down path; the one-node friction ramp under load
stepping; the energy balance residual (implicit Euler's own numerical dissipation) and
the end state's error, with their order in the increment measured by a log-log fit.
Small mesh (N = 24), the push-down path of test_forming.
"""

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
import pytest

from dynslip.physics.driver.member import stage_args
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.frames import initial_state
from dynslip.physics.friction import Coulomb, SlipWeakening
from dynslip.physics.layout import Layout
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.solver.loadstep import (
    DampedNewton,
    FullStateLoadStep,
    LoadStepEuler,
    increments,
)
from dynslip.physics.solver.methods import Settings
from dynslip.physics.solver.upstream import ImplicitEuler
from numerics import named_solver
from test_forming import MAT, PRE, RIM, Z0, push_protocol

N = 24
MODEL = SheetModel(make_mesh(N, RIM / PRE), MAT, Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)))
TAU = 0.1  # drag time (s)
MU = 0.8


def _friction():
    return Coulomb(mu=jnp.asarray(MU), eps=jnp.asarray(1e-3))


def _run(name, rtol=1e-5, atol=1e-7, **numerics):
    return simulate(
        MODEL,
        push_protocol(),
        friction=_friction(),
        eps=1e-3,
        drag=TAU,
        ball_drag=TAU * 4 * math.pi,
        pre_stretch=PRE,
        z_sheet=Z0,
        settings=Settings(solver=named_solver(name, **numerics), save_interval=1.0, rtol=rtol,
                          atol=atol),
    )


# ----------------------------------------------------------------------------- diffrax PR #753


def _failing_step(cls):
    """One step of y' = -y^3 from y = 1 over dt = 1 with a single Newton iteration allowed:
    the root find fails (iteration limit)."""
    term = diffrax.ODETerm(lambda t, y, args: -(y**3))
    solver = cls(root_finder=optx.Newton(rtol=1e-10, atol=1e-12), root_find_max_steps=1)
    y0 = jnp.array([1.0])
    return solver.step(term, 0.0, 1.0, y0, None, solver.init(term, 0.0, 1.0, y0, None), False)


def test_failed_newton_solve_is_rejected():
    _, y_err, _, _, result = _failing_step(ImplicitEuler)
    assert result != diffrax.RESULTS.successful
    assert not np.all(np.isfinite(np.asarray(y_err)))


def test_pinned_implicit_euler_still_accepts_a_failed_solve():
    """diffrax 0.7.2 returns a finite error estimate with a failed solve (issue #752): when this
    fails, a release with PR #753 is pinned: drop dynslip.physics.solver.upstream.ImplicitEuler."""
    _, y_err, _, _, result = _failing_step(diffrax.ImplicitEuler)
    assert result != diffrax.RESULTS.successful
    assert np.all(np.isfinite(np.asarray(y_err)))


# ----------------------------------------------------------------------------- DampedNewton


def _root(solver, fn, x0):
    sol = optx.root_find(lambda x, _: fn(x), solver, jnp.array([x0]), throw=False, max_steps=40)
    return float(sol.value[0]), sol.result == optx.RESULTS.successful, int(sol.stats["num_steps"])


def test_damped_newton_converges_where_newton_diverges():
    """arctan x = 0 from x0 = 1.5: Newton's iterates grow in magnitude without bound
    (|x0| > 1.3917, the 2-cycle's amplitude); the backtracking safeguard halves every
    correction that raises |f| and converges to 0."""
    kw = dict(rtol=1e-10, atol=1e-12, norm=optx.max_norm)
    x, ok, _ = _root(optx.Newton(**kw), jnp.arctan, 1.5)
    assert not (ok and abs(x) < 1e-8)
    x, ok, _ = _root(DampedNewton(**kw, max_backtrack=4), jnp.arctan, 1.5)
    assert ok and abs(x) < 1e-10


def test_damped_newton_is_newton_where_the_residual_falls():
    """x^2 = 2 from x0 = 1: every Newton correction lowers |f|, so no halving happens and the
    iterates, their count and the root equal plain Newton's."""
    kw = dict(rtol=1e-12, atol=1e-12, norm=optx.max_norm)
    fn = lambda x: x**2 - 2.0  # noqa: E731
    plain, damped = (
        _root(optx.Newton(**kw), fn, 1.0),
        _root(DampedNewton(**kw, max_backtrack=4), fn, 1.0),
    )
    assert plain[1] and damped[1]
    assert damped == plain
    assert abs(damped[0] - math.sqrt(2.0)) < 1e-12


# ----------------------------------------------------------------------------- against Kvaerno5


@pytest.fixture(scope="module")
def reference():
    res = _run("kvaerno5", rtol=1e-7, atol=1e-9)
    assert res.failed is None, res.failed
    return res


@pytest.mark.slow  # the Kvaerno5 reference's compile (13 s of the quick loop): a cross-check
@pytest.mark.parametrize("backtrack", [4, 0])
def test_load_step_matches_kvaerno5_on_a_short_push_down(reference, backtrack):
    """Same end state (after the hold) within 1e-5 R in rho and z, with and without Newton's
    backtracking (the default 4 halvings, and plain Newton); far fewer steps; the Newton
    iterations and the method reported."""
    res = _run("load_step", newton_backtrack=backtrack)
    assert res.failed is None, res.failed
    fa, fb = reference.frames[-1], res.frames[-1]
    d = max(np.max(np.abs(fa["rho"] - fb["rho"])), np.max(np.abs(fa["z"] - fb["z"])))
    st = res.stats
    print(
        f"load_step vs kvaerno5 (N = {N}): max |dx| = {d:.2e} R; steps {st['steps']} "
        f"({st['rejected']} rejected, "
        f"{st['newton_iterations']} Newton iterations) vs {reference.stats['steps']}"
    )
    assert d < 1e-5
    assert abs(float(fa["theta_max"]) - float(fb["theta_max"])) < 1e-4
    assert st["method"] == "load_step" and st["newton_iterations"] >= st["accepted"] > 0
    assert st["steps"] < reference.stats["steps"]
    assert st["accepted"] + st["rejected"] == st["steps"]


# ----------------------------------------------------------------------------- energy and order


def push_down_start():
    """The push-down stage of :func:`test_forming.push_protocol` from its start: the stage,
    the layout, its loads, the start state and the stage's end time."""
    protocol = push_protocol()
    stage = protocol.stages[0]
    layout = Layout(N, 0)
    args = stage_args(stage, 0.0, protocol.ball_z0, 0.0, (0.0, 0.0), _friction(), 1e-3, TAU,
                      TAU * 4 * math.pi, 0.0)
    y0 = initial_state(MODEL, layout, PRE, Z0, protocol.ball_z0)
    return stage, layout, args, y0, jnp.asarray(stage.max_duration)


@eqx.filter_jit
def _fixed_increments(model, layout, y0, t1, h, args):
    """The push-down stage in increments of h (the cap; with h <= tau Newton converges fast, so
    every increment but the first few and a cut-back or two is h)."""
    solver = FullStateLoadStep(
        max_steps=100000, newton_max_iter=16, max_increment=h / TAU, max_increment_free=h / TAU
    )
    return solver.segment(
        model, layout, y0, jnp.asarray(0.0), t1, h, args, jnp.asarray(1e-8), jnp.asarray(1e-10)
    )


@pytest.mark.slow  # the Kvaerno5 reference's compile and four full-state paths (27-30 s of the
# quick loop); the motion Newton's increment is the full-state one (test_newton.py, quick)
def test_energy_residual_and_end_state_are_first_order_in_the_increment(reference):
    """Work = change of stored energy + drag + friction dissipation, every term accumulated
    from its backward-Euler increment; the residual is implicit Euler's numerical dissipation,
    O(h) over the path, as is the end state's error against Kvaerno5 (rtol 1e-7)."""
    stage, layout, args, y0, t1 = push_down_start()
    # Kvaerno5's state at the end of push-down (the frame at the stage boundary)
    ref = next(f for f in reference.frames if abs(f["time"] - stage.max_duration) < 1e-9)

    def energy(y):
        rho, z, zb, acc = layout.unpack(y)
        stored = MODEL.elastic_energy(rho, z) + MODEL.penalty_energy(rho, z, zb)
        return float(acc[0] + acc[1]), float(stored), float(acc[2] + acc[3])

    w0, e0, _ = energy(y0)
    hs = np.array([0.1, 0.05, 0.025, 0.0125])
    resid, err, steps = [], [], []
    for h in hs:
        out = _fixed_increments(MODEL, layout, y0, t1, jnp.asarray(h), args)
        y1, nacc, nrej, nit = out.y, out.accepted, out.rejected, out.newton_iterations
        assert bool(out.ok)
        w, e, d = energy(y1)
        resid.append(abs(w - (e - e0) - d) / abs(w))
        rho, z, _, _ = layout.unpack(y1)
        err.append(
            max(
                np.max(np.abs(np.asarray(rho) - ref["rho"])),
                np.max(np.abs(np.asarray(z) - ref["z"])),
            )
        )
        steps.append((int(nacc), int(nrej), int(nit)))

    p_res = np.polyfit(np.log(hs), np.log(resid), 1)[0]
    p_err = np.polyfit(np.log(hs), np.log(err), 1)[0]
    print(
        f"increments {hs} s: energy residual / work {np.array(resid)} (order {p_res:.2f}); "
        f"|x - x_kvaerno5| {np.array(err)} R (order {p_err:.2f}); (accepted, rejected, Newton) "
        f"{steps}"
    )
    assert resid[-1] < 1e-2
    assert 0.85 < p_res < 1.15  # measured 0.99
    assert 0.7 < p_err < 1.3  # measured 0.98


# ----------------------------------------------------------------------------- one node


MU_S, MU_K, D_C = 0.99, 0.82, 0.02


@eqx.filter_jit
def _node_segment(fr, y0, t0, t1, x_drive0, v_drive, stiff, normal, eta, heal_rate=None):
    """The one-node ramp of test_weakening under load stepping: eta x' = S(K (X(t) - x),
    mu(delta) N),
    delta' = |x'|, in increments of at most 0.01 s (the node's drag time eta / K)."""

    def vf(t, y, args):
        x, delta = y
        f = stiff * (x_drive0 + v_drive * (t - t0) - x)
        s = fr.slip_force(f, normal, delta)
        return jnp.stack([s / eta, fr.internal_rate(s / eta, normal, delta)])

    newton = optx.Newton(
        rtol=1e-10, atol=1e-12, norm=optx.max_norm, linear_solver=lx.LU(), cauchy_termination=True
    )
    solver = LoadStepEuler(root_finder=newton, root_find_max_steps=16)

    # heal_rate: the friction law's reset inside the increment loop (after every accepted increment)
    def after(t, y):  # the slip rate x' at the increment's end
        return y.at[1].set(fr.reset(y[1], vf(t, y, None)[0], normal, heal_rate))

    out = increments(
        diffrax.ODETerm(vf),
        solver,
        y0,
        t0,
        t1,
        jnp.asarray(1e-3),
        None,
        jnp.asarray(0.01),
        10000,
        after=None if heal_rate is None else after,
    )
    y1 = out.y
    f1 = stiff * (x_drive0 + v_drive * (t1 - t0) - y1[0])
    return y1, out.ok, f1, fr.slip_force(f1, normal, y1[1])


def test_one_node_ramp_under_load_stepping():
    """K = 10, V = 0.01, N = 1, eta = 0.1: exactly stuck until K V t = mu_s N (no motion at all:
    the increment's trial force is inside the cone), peak at mu_s N, sliding at mu_k N + eta V
    past d_c; unloading re-sticks it, the slip distance is reset, reloading needs mu_s N again."""
    fr = SlipWeakening(mu_s=MU_S, mu_k=MU_K, d_c=D_C, eps=1e-4)
    stiff, normal, eta, v, seg = 10.0, 1.0, 0.1, 0.01, 0.05
    y = jnp.zeros(2)
    t, xd = 0.0, 0.0
    rows = [(0.0, 0.0, 0.0, 0.0, 0.0)]
    for dur, vel in [(20.0, v), (2.0, -v), (18.0, v)]:
        for _ in range(int(round(dur / seg))):
            y, ok, f, s = _node_segment(
                fr,
                y,
                jnp.asarray(t),
                jnp.asarray(t + seg),
                jnp.asarray(xd),
                jnp.asarray(vel),
                stiff,
                normal,
                eta,
            )
            assert bool(ok)
            y = y.at[1].set(fr.reset(y[1], s / eta, normal))  # the driver's reset at a segment end
            t, xd = t + seg, xd + vel * seg
            rows.append((t, float(y[0]), float(y[1]), float(f), float(s)))
    t, x, delta, force, slip = (np.array(c) for c in zip(*rows, strict=True))
    first = t <= 20.0 + 1e-9
    t_onset = MU_S / (stiff * v)
    assert np.all(x[t < t_onset * (1 - 1e-3)] == 0.0)
    assert np.all(x[(t > t_onset * 1.01) & first] > 0.0)
    peak1 = force[first].max()
    assert abs(peak1 - MU_S) / MU_S < 1e-2, peak1
    late = (t > 17.0) & first
    assert np.all(delta[late] > D_C)
    assert np.allclose(force[late], MU_K + eta * v, rtol=1e-2), force[late]
    back = (t > 20.2) & (t <= 22.0 + 1e-9)
    assert np.all(slip[back] == 0.0) and np.all(delta[back] == 0.0)
    assert np.ptp(x[back]) == 0.0
    peak2 = force[t > 22.0].max()
    assert abs(peak2 - MU_S) / MU_S < 1e-2, peak2
    print(
        f"one-node ramp, load stepping: peaks {peak1:.5f}, {peak2:.5f} (mu_s N = {MU_S}); "
        f"sliding force "
        f"{force[late].mean():.5f} (mu_k N + eta V = {MU_K + eta * v:.5f})"
    )


def test_settling_node_heals_inside_the_increments():
    """The healing reset happens in the load step, not at save-segment ends: drive the node
    past d_c, stop the drive for 1 s, reload, with no reset between segments. With the reset
    in every increment (slip rate at most 1e-3 R/s) the settled node's slip distance is 0
    and reloading needs mu_s N again; without it the node stays weakened and slides at mu_k."""
    fr = SlipWeakening(mu_s=MU_S, mu_k=MU_K, d_c=D_C, eps=1e-4)
    stiff, normal, eta, v, seg = 10.0, 1.0, 0.1, 0.01, 0.05
    out = {}
    for heal_rate in (None, 1e-3):
        y, t, xd = jnp.zeros(2), 0.0, 0.0
        rows = []
        for dur, vel in [(20.0, v), (1.0, 0.0), (4.0, v)]:
            for _ in range(int(round(dur / seg))):
                y, ok, f, s = _node_segment(
                    fr,
                    y,
                    jnp.asarray(t),
                    jnp.asarray(t + seg),
                    jnp.asarray(xd),
                    jnp.asarray(vel),
                    stiff,
                    normal,
                    eta,
                    heal_rate,
                )
                assert bool(ok)
                t, xd = t + seg, xd + vel * seg
                rows.append((t, float(y[1]), float(f)))
        t_, delta, force = (np.array(c) for c in zip(*rows, strict=True))
        settle_end = np.flatnonzero(t_ <= 21.0 + 1e-9)[-1]
        out[heal_rate] = (delta[settle_end], force[t_ > 21.0].max())
    (d_bare, peak_bare), (d_heal, peak_heal) = out[None], out[1e-3]
    assert d_bare > D_C and abs(peak_bare - (MU_K + eta * v)) / MU_K < 2e-2, (d_bare, peak_bare)
    assert d_heal == 0.0 and abs(peak_heal - MU_S) / MU_S < 1e-2, (d_heal, peak_heal)
    print(
        f"load stepping, heal in the increment: delta after settling {d_heal:g} (bare "
        f"{d_bare:.4g}); "
        f"reload peak {peak_heal:.4f} (bare {peak_bare:.4f}; mu_s N = {MU_S})"
    )
