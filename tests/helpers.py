"""Helpers shared by the tests: a small contract-conforming trajectory whose ``state``
field is prescribed (fronts, animations, comparisons and the command line are tested on it
without running the simulator); :func:`one_line`, the check of a one-line error message;
the Newton matrix against ``jax.jacfwd`` of the increment's residual
(:func:`newton_matrix_and_jacfwd`) and the small model, state and stage it is checked at
(:func:`small_model`, :func:`draped`, :func:`increment_args`); a run of the core simulator
(:func:`run_sheet`, :func:`push_and_hold`); scenario files written and run
(:func:`load_data`, :func:`run_kept`, :func:`banded_tube`, :func:`capstan_tube`); a spec
registered for one test (:func:`registered`)."""

from __future__ import annotations

import contextlib
import json
import math
import subprocess
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr
import yaml

from dynslip import api
from dynslip.cli import main
from dynslip.data.files import provenance, variable
from dynslip.data.trajectory import FREE, SLIP_EQUATOR, SLIP_POLE, STATE_MEANINGS
from dynslip.physics.driver.member import stage_args
from dynslip.physics.driver.simulate import simulate
from dynslip.physics.materials import make_material
from dynslip.physics.protocols import CLAMP_POSITION, Duration, Stage
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh


def synthetic_trajectory(
    state,
    time=None,
    rbar=None,
    stage=None,
    stage_names=("push", "release"),
    theta_of_rbar: float = 2.0,
    clamp_rho: float = 2.54,
    clamp_z=-1.5,
    clamp_force=None,
    attrs: dict | None = None,
) -> xr.Dataset:
    """A small contract-conforming trajectory whose ``state`` field is prescribed.

    For tests and examples: ``state`` (time, rbar) holds the contract's flags; nodes in
    contact sit on the unit ball at ``theta = theta_of_rbar * rbar``; free nodes lie on the
    straight line from the last contact node to the clamp at (``clamp_rho``, ``clamp_z``).
    Pressure is 1 in contact and 0 elsewhere; the other fields are simple but consistent
    placeholders. ``rbar`` defaults to ``linspace(0, clamp_rho, n)``, ``time`` to
    ``arange(n_time)`` s, ``stage`` to 0 for the first half of the frames and 1 after.
    """
    state = np.asarray(state, dtype=np.int8)
    nt, nr = state.shape
    time = np.arange(nt, dtype=float) if time is None else np.asarray(time, dtype=float)
    rbar = np.linspace(0.0, clamp_rho, nr) if rbar is None else np.asarray(rbar, dtype=float)
    if stage is None:
        stage = (np.arange(nt) >= nt // 2).astype(np.int8) if len(stage_names) > 1 else np.zeros(nt)
    stage = np.asarray(stage, dtype=np.int8)
    clamp_z = np.broadcast_to(np.asarray(clamp_z, dtype=float), (nt,)).copy()
    contact = state != FREE
    theta = np.where(contact, theta_of_rbar * rbar[None, :], np.nan)
    rho = np.empty((nt, nr))
    z = np.empty((nt, nr))
    theta_max = np.full(nt, np.nan)
    rbar_max = np.full(nt, np.nan)
    for k in range(nt):
        on = np.flatnonzero(contact[k])
        last = on.max() if on.size else -1
        th = theta_of_rbar * rbar
        rho[k] = np.sin(th)
        z[k] = np.cos(th)
        r0, z0, rb0 = (0.0, 1.0, 0.0) if last < 0 else (rho[k, last], z[k, last], rbar[last])
        if last >= 0:
            theta_max[k], rbar_max[k] = th[last], rbar[last]
        free = np.arange(nr) > last
        frac = (rbar[free] - rb0) / max(rbar[-1] - rb0, 1e-12)
        rho[k, free] = r0 + frac * (clamp_rho - r0)
        z[k, free] = z0 + frac * (clamp_z[k] - z0)
    pressure = np.where(contact, 1.0, 0.0)
    slip_v = np.select([state == SLIP_POLE, state == SLIP_EQUATOR], [-1.0, 1.0], 0.0)
    force = np.zeros(nt) if clamp_force is None else np.asarray(clamp_force, dtype=float)
    tn = ("time", "rbar")
    scen = json.dumps({"kind": "forming", "name": "synthetic"})
    data = {
        "rho": variable(rho, tn, "1", "deformed distance from the axis", scale="R"),
        "z": variable(z, tn, "1", "deformed height", scale="R"),
        "theta": variable(theta, tn, "1", "polar angle on the ball where in contact"),
        "lambda_theta": variable(np.ones((nt, nr)), tn, "1", "meridional stretch"),
        "lambda_phi": variable(np.ones((nt, nr)), tn, "1", "hoop stretch"),
        "T_theta": variable(np.zeros((nt, nr)), tn, "1", "meridional tension", scale="G*h0"),
        "T_phi": variable(np.zeros((nt, nr)), tn, "1", "hoop tension", scale="G*h0"),
        "pressure": variable(pressure, tn, "1", "contact pressure", scale="G*h0/R"),
        "friction": variable(np.zeros((nt, nr)), tn, "1", "meridional friction", scale="G*h0/R"),
        "slip_velocity": variable(slip_v, tn, "1/s", "meridional slip speed", scale="R/s"),
        "mu_mobilised": variable(np.where(contact, 0.5, np.nan), tn, "1", "mobilised friction"),
        "state": variable(
            state,
            tn,
            "1",
            "contact state",
            flag_values=np.array([0, 1, 2, 3], dtype=np.int8),
            flag_meanings=" ".join(STATE_MEANINGS),
        ),
        "stage": variable(stage, ("time",), "1", "index into stage_names"),
        "clamp_z": variable(clamp_z, ("time",), "1", "clamp height", scale="R"),
        "clamp_rho": variable(np.full(nt, clamp_rho), ("time",), "1", "clamp radius", scale="R"),
        "clamp_force": variable(force, ("time",), "1", "clamp axial force", scale="G*h0*R"),
        "ball_z": variable(np.zeros(nt), ("time",), "1", "ball centre height", scale="R"),
        "ball_reaction": variable(force, ("time",), "1", "force of the hold", scale="G*h0*R"),
        "theta_max": variable(theta_max, ("time",), "1", "largest polar angle in contact"),
        "rbar_max": variable(rbar_max, ("time",), "1", "outermost contact radius", scale="R"),
    }
    coords = {
        "time": variable(time, ("time",), "s", "time"),
        "rbar": variable(rbar, ("rbar",), "1", "undeformed radius", scale="R"),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(provenance(scen, "trajectory"))
    ds.attrs.update(
        complete=1,
        R_m=0.02,
        G_Pa=2e6 / 3,
        h0_m=150e-6,
        force_scale_N=2.0,
        stage_names=json.dumps(list(stage_names)),
        contact_threshold=1e-6,
    )
    ds.attrs.update(attrs or {})
    return ds


def one_line(err: str) -> str:
    """The one non-blank line of ``err`` (asserted: exactly one, and no traceback)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


#: a dask LocalCluster (2 single-threaded worker processes on loopback) in a child process,
#: which prints its scheduler's address and the workers' pids as one JSON line and lives until
#: its stdin closes. Never in the pytest process: distributed's event-loop and offload threads
#: outlive the cluster there, and a later XLA compile in that process crashed CI (segfault).
_CLUSTER_CHILD = """
import json, os, sys
from distributed import Client, LocalCluster
with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                  dashboard_address=None) as cluster, Client(cluster) as client:
    pids = list(client.run(os.getpid).values())
    print(json.dumps({"address": cluster.scheduler_address, "pids": pids}), flush=True)
    sys.stdin.read()
"""


@contextlib.contextmanager
def dask_cluster():
    """A dask cluster out of the test process; yields ``{"address": ..., "pids": [...]}``."""
    p = subprocess.Popen([sys.executable, "-c", _CLUSTER_CHILD], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True)
    try:
        line = p.stdout.readline()
        assert line, f"the dask cluster did not start (exit {p.poll()})"
        yield json.loads(line)
    finally:
        p.stdin.close()
        try:
            p.wait(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def set_field(dotted: str, value):
    """An edit of a scenario's data: the field at ``dotted`` (list items by index) set to value."""

    def edit(data):
        node = data
        keys = dotted.split(".")
        for k in keys[:-1]:
            node = node[int(k)] if k.isdigit() else node[k]
        node[keys[-1]] = value

    return edit


def cli_in_process(capsys, argv) -> tuple[int, str, str]:
    """``dynslip ARGV`` through :func:`dynslip.cli.main` in this process: (exit status, stdout,
    stderr). tests/test_cli.py runs the installed entry point as a child process."""
    capsys.readouterr()
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as err:  # argparse
        rc = err.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def run_refused(tmp_path, capsys, scenario, edit, *words):
    """``dynslip run`` on ``scenario`` with ``edit`` applied to its data: exit 2, one line naming
    every one of ``words``, nothing written beside the bad file."""
    data = yaml.safe_load(scenario.read_text())
    edit(data)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    rc, _, err = cli_in_process(capsys, ["run", path, "--out", out])
    assert rc == 2, err
    line = one_line(err)
    for w in words:
        assert w in line, line
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["bad.yaml"]


def dense_tridiagonal(lower, diag, upper, size=None):
    """The block-tridiagonal matrix of blocks (n, b, b) as a dense array, (size, size) with the
    blocks at its top left (default: n b)."""
    n, b = diag.shape[0], diag.shape[1]
    j = np.zeros((size or n * b,) * 2)
    for i in range(n):
        r = slice(b * i, b * i + b)
        j[r, r] = diag[i]
        if i > 0:
            j[r, b * i - b : b * i] = lower[i]
        if i < n - 1:
            j[r, b * i + b : b * i + 2 * b] = upper[i]
    return j


def dense_blocks(lower, diag, upper, B, C, D):
    """The bordered block-tridiagonal matrix as a dense array (a border of m = D's size)."""
    n, m = diag.shape[0], np.shape(D)[0]
    j = dense_tridiagonal(lower, diag, upper, 2 * n + m)
    j[: 2 * n, 2 * n :] = np.asarray(B).reshape(2 * n, m)
    j[2 * n :, : 2 * n] = np.asarray(C).reshape(m, 2 * n)
    j[2 * n :, 2 * n :] = np.asarray(D)
    return j


@eqx.filter_jit
def _jacfwd_residual(model, friction, inc, v):
    """``jax.jacfwd`` of the increment's residual flattened over ``v = (q, zb)``, compiled whole
    with the model and the increment traced (op by op, through the bodies' loops, it took 20-35 s
    a test; compiled per model it was 10 s a parameter): one compile per model structure."""
    from dynslip.physics.solver import increment as ni

    n = (v.shape[0] - 1) // 2

    def flat(v):
        rq, rz = ni.residual(model, friction, inc, v[:-1].reshape(n, 2), v[-1])
        return jnp.concatenate([rq.reshape(-1), rz[None]])

    return jax.jacfwd(flat)(v)


@eqx.filter_jit
def _newton_blocks(model, friction, inc, q, zb, exact):
    """``newton_blocks``, compiled as :func:`_jacfwd_residual`."""
    from dynslip.physics.solver import newton_matrix as nm

    return nm.newton_blocks(model, friction, inc, q, zb, exact=exact)


def newton_matrix_and_jacfwd(model, friction, inc, q, zb, exact=True):
    """The increment's Newton matrix (``newton_blocks(exact=)``, dense, its auxiliary border
    unknowns past ``z_b`` eliminated by their Schur complement) and ``jax.jacfwd`` of its
    residual flattened over ``(q, zb)``: ``(got, ref)``, both (2n + 1, 2n + 1)."""
    n = q.shape[0]
    v = jnp.concatenate([q.reshape(-1), zb[None]])
    ref = np.asarray(_jacfwd_residual(model, friction, inc, v))
    got = dense_blocks(*_newton_blocks(model, friction, inc, q, zb, exact))
    k = 2 * n + 1
    if got.shape[0] > k:
        got = got[:k, :k] - got[:k, k:] @ np.linalg.solve(got[k:, k:], got[k:, :k])
    return got, ref


def near_diagonal(n):
    """The mask (2n + 1, 2n + 1) of a Newton matrix without the node blocks more than one node
    off the diagonal (the rank-one coupling through a free ball's velocity the matrix leaves
    out, docs/bodies.md); the border row and column kept."""
    mask = np.ones((2 * n + 1, 2 * n + 1), dtype=bool)
    node = np.arange(2 * n) // 2
    mask[: 2 * n, : 2 * n] = np.abs(node[:, None] - node[None, :]) <= 1
    return mask


def check_newton_matrix(model, friction, inc, q, zb, free_ball: bool, rel: float):
    """The Newton matrix against ``jax.jacfwd`` of the increment's residual, to ``rel`` of its
    largest entry: every entry with ``exact=True``; with ``exact=False`` (the border of one that
    ``free_system`` builds on) all but the far rank-one coupling through a free ball's velocity
    (``free_ball``: the ball under force), and that coupling must be there for the exact
    matrix to have something to add. Returns the reference."""
    got, ref = newton_matrix_and_jacfwd(model, friction, inc, q, zb)
    tol = rel * np.abs(ref).max()
    np.testing.assert_allclose(got, ref, rtol=0, atol=tol)
    banded, _ = newton_matrix_and_jacfwd(model, friction, inc, q, zb, exact=False)
    mask = near_diagonal(q.shape[0]) if free_ball else np.ones_like(ref, dtype=bool)
    np.testing.assert_allclose(banded[mask], ref[mask], rtol=0, atol=tol)
    if free_ball:
        assert np.abs(ref[~mask]).max() > 1e3 * tol
    return ref


# ------------------------------------------- the small model the Newton matrix is checked at


def small_model(n: int = 9, bodies: tuple = ()) -> SheetModel:
    """A small Gent sheet (jm 50; ``n`` nodes out to 2.4 R, the contact penalty k = 1e4,
    w = 1e-3) with the held ``bodies``."""
    return SheetModel(
        make_mesh(n, 2.4),
        make_material("gent", jm=50.0),
        Penalty(jnp.asarray(1e4), jnp.asarray(1e-3)),
        bodies=bodies,
    )


def draped(rbar, rng):
    """A sheet draped over the ball (nodes near its surface, some pressed in), its heights
    perturbed by ``rng``: ``(rho, z)`` at the nodes ``rbar``, numpy arrays."""
    rbar = np.asarray(rbar)
    th = np.minimum(1.05 * rbar, 1.5)
    rho = 0.999 * np.sin(th) + 0.1 * rbar
    z = 0.999 * np.cos(th) + 0.01 * rng.normal(size=rbar.size)
    rho[0] = 0.0
    return rho, z


def increment_args(friction, ball_mode, clamp_mode=CLAMP_POSITION, **stage):
    """The stage arguments of a 5 s stage (the clamp moving down at 0.2 R/s in
    ``clamp_mode``, the ball in ``ball_mode``, its force ramped to 0; more of the stage's
    fields in ``stage``) at time 0, the ball on a support at -0.01 R."""
    st = Stage(
        "s",
        Duration(duration=5.0),
        clamp_vz=-0.2,
        ball_mode=ball_mode,
        clamp_mode=clamp_mode,
        ball_force_end=0.0,
        **stage,
    )
    return stage_args(
        st,
        0.0,
        0.0,
        0.3,
        (0.1, -0.2),
        friction,
        1e-3,
        0.1,
        0.4,
        0.05,
        support_z=-0.01,
        support_k=1e3,
    )


# ------------------------------------------------------------------ runs of the core simulator


def push_and_hold(z_sheet: float, depth: float, speed: float = 0.2, hold: float = 4.0):
    """The stages of a push: the clamp from ``z_sheet`` down to ``depth`` at ``speed`` (R/s),
    then held for ``hold`` s."""
    return (
        Stage("push", Duration(duration=(z_sheet - depth) / speed), clamp_vz=-speed),
        Stage("hold", Duration(duration=hold)),
    )


def run_sheet(model, protocol, friction, settings, *, pre, z_sheet, tau=0.1, eps=1e-3, **kw):
    """``simulate`` with the sheet's drag time ``tau`` (s) and the ball's drag that of the sheet
    over the ball's area (4 pi tau), the friction smoothed over ``eps``; more of ``simulate``'s
    keywords in ``kw``. The run must not fail."""
    res = simulate(
        model,
        protocol,
        friction=friction,
        eps=eps,
        drag=tau,
        ball_drag=tau * 4 * math.pi,
        pre_stretch=pre,
        z_sheet=z_sheet,
        settings=settings,
        **kw,
    )
    assert res.failed is None, res.failed
    return res


# --------------------------------------------------------------- scenario files, written and run


def load_data(tmp, data: dict, name: str, **sets):
    """The scenario ``data`` written to ``tmp/<name>.yaml`` and loaded, with the ``--set``
    values ``sets`` (dotted names as keywords: ``**{"numerics.nodes": 12}``)."""
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return api.load(path, set=sets or None)


def run_kept(scenario, **kw):
    """``api.run`` (its keywords in ``kw``), and where the run ends without an answer (a
    ``ComputationError``: the verdict unknown, the ball run away) what it computed, which is
    kept."""
    try:
        return api.run(scenario, **kw)
    except api.ComputationError as err:
        return err.partial


def banded_tube(name, *, mu, rim_radius_mm, pre_stretch, tube, grip, stages, numerics, **physics):
    """A forming scenario's data: a Gent sheet (jm 50; Coulomb ``mu`` on the ball) over the rim
    of a ``tube`` (its wall's sizes and friction, mm) whose wall is at ``rim_radius_mm``, held
    on its outer wall by a band of ``grip`` (N/mm); more ``physics`` fields as keywords."""
    return {
        "name": name,
        "kind": "forming",
        "physics": {
            "material": {"model": "gent", "jm": 50.0},
            "friction": {"law": "coulomb", "mu": mu},
            "rim_radius_mm": rim_radius_mm,
            "pre_stretch": pre_stretch,
            **physics,
            "tube": tube,
            "band_grip_N_per_mm": grip,
            "stages": stages,
        },
        "numerics": numerics,
    }


def capstan_tube(name: str, tube_mu: float, save_interval_s: float, grip: float = 0.005,
                 wall_radius_mm: float = 48.0) -> dict:
    """The sheet over a tube's rounded rim (wall 16 mm: a half torus of radius 0.4 R, resolved
    at N = 32; Coulomb ``tube_mu`` on it), folded up its outer wall to a band of ``grip`` (N/mm);
    in the lab frame the tube is pushed down over the held ball at 0.4 mm/s for 66 s, which
    draws the sheet inward over the rim. A slow push and a short drag time: the sheet's drag on
    the nodes resting on the rim (eta v, relative to the ball) is a regularisation's share of
    the pull (docs/bodies.md)."""
    return banded_tube(
        name,
        mu=0.5,
        rim_radius_mm=wall_radius_mm,
        pre_stretch=0.8,
        sheet_gap_mm=1.0,
        tube={"wall_mm": 16.0, "height_mm": 80.0, "rim_gap_mm": 1.0, "mu": tube_mu},
        grip=grip,
        stages=[
            {"name": "fold", "clamp_to_z_mm": 36.0, "clamp_speed_mm_s": 4.0},
            {"name": "push", "clamp": "band", "ball": "hold", "tube_velocity_mm_s": -0.4,
             "duration_s": 66.0},
        ],
        numerics={"nodes": 32, "save_interval_s": save_interval_s, "drag_time_s": 0.02},
    )


@contextlib.contextmanager
def registered(registry, spec):
    """``spec`` registered in ``registry`` (a schema's tagged union: ``FRICTION_SPECS``,
    ``STOP_SPECS``, ``BODY_KINDS``) for the block, unregistered after it; yields ``spec``."""
    registry.register(spec)
    try:
        yield spec
    finally:
        registry.unregister(spec)
