"""Sweeps: schema, member expansion, resume after a kill, the three runners, bad input.

The members here run a cheap analytic stand-in for the simulator (``fake_member``,
validated by ``FakeScenario``) so that the machinery is tested without solving anything.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
import xarray as xr
import yaml
from pydantic import Field, ValidationError

import dynslip.app.sweep as sweep_mod
import dynslip.app.sweep_runners as sweep_runners
import dynslip.schema.base as scenario_mod
from dynslip.app.sweep import run_sweep
from dynslip.errors import ComputationError, InputError
from dynslip.schema.base import Strict, format_validation_error
from dynslip.schema.sweep import load_spec

HERE = Path(__file__).resolve().parent


class Friction(Strict):
    mu: float = Field(0.6, ge=0)


class Protocol(Strict):
    depth: float = Field(5.0, gt=0)
    speed: float = Field(1.0, gt=0)


class Stage(Strict):
    name: str
    clamp_to_z_mm: float


class Physics(Strict):
    friction: Friction = Friction()
    protocol: Protocol = Protocol()
    stages: list[Stage] = Field(
        default_factory=lambda: [
            Stage(name="push_down", clamp_to_z_mm=-120.0),
            Stage(name="raise", clamp_to_z_mm=-20.0),
        ]
    )
    material: Literal["neo_hookean", "gent"] = "neo_hookean"


class Numerics(Strict):
    nodes: int = Field(30, ge=5)


class FakeScenario(Strict):
    kind: Literal["fake"] = "fake"
    name: str = ""
    physics: Physics = Physics()
    numerics: Numerics = Numerics()

    def to_json(self) -> str:
        return self.model_dump_json()


def fake_validate(data, source="<fake>"):
    try:
        return FakeScenario.model_validate(data)
    except ValidationError as err:
        raise InputError(format_validation_error(err, source)) from None


def trapped_at(mu: float, depth: float) -> bool:
    """Two windows of mu; the first moves with the push-down depth."""
    return (0.2 + 0.05 * depth < mu < 0.5 + 0.05 * depth) or (1.5 < mu < 1.7)


def fake_member(data, out_dir, console=None):
    s = fake_validate(data)
    mu, depth = s.physics.friction.mu, s.physics.protocol.depth
    if abs(mu - 1.0) < 1e-12 and depth == 6.0:
        raise ComputationError("solver: step size underflow at t = 12.5")
    extra = 0.1 if s.physics.material == "gent" else 0.0
    return {
        "trapped": trapped_at(mu, depth),
        "theta_max": 1.5 + 0.1 * mu + extra,
        "rbar_max": 0.8 + 0.01 * depth,
        "opening_radius": float(np.sin(1.5 + 0.1 * mu + extra)),
        "mu_mobilised_max": 0.5 * mu,
        # a wall-clock figure, as the simulator reports: differs run to run
        "solver": {"steps": s.numerics.nodes * 10, "rejected": 3, "wall_s": time.perf_counter()},
    }


def slow_member(data, out_dir, console=None):
    """fake_member, slowly, logging each start (for the kill/resume test)."""
    log = os.environ.get("DYNSLIP_TEST_LOG")
    if log:
        with open(log, "a") as f:
            f.write(json.dumps(data["physics"]) + "\n")
    time.sleep(float(os.environ.get("DYNSLIP_TEST_SLEEP", "0")))
    return fake_member(data, out_dir, console)


def write_sweep(tmp_path: Path, body: dict, name="study.yaml") -> Path:
    (tmp_path / "base.yaml").write_text(yaml.safe_dump({"kind": "fake", "numerics": {"nodes": 30}}))
    p = tmp_path / name
    p.write_text(yaml.safe_dump({"base": "base.yaml", **body}, sort_keys=False))
    return p


GRID = {
    "overrides": {"numerics.nodes": 20},
    "grid": {
        "physics.protocol.depth": [4.0, 6.0],
        "physics.friction.mu": {"start": 0.2, "stop": 1.0, "num": 5},
    },
}


def sweep(path, out, **kw):
    return run_sweep(
        path,
        out=out,
        member_fn=kw.pop("member_fn", fake_member),
        validate_fn=fake_validate,
        plot=kw.pop("plot", False),
        **kw,
    )


def test_grid_sweep_dataset(tmp_path):
    path = write_sweep(tmp_path, GRID)
    summary = sweep(path, tmp_path / "out", plot=True)
    assert summary["n_members"] == 10 and summary["n_run"] == 10 and summary["n_failed"] == 1
    ds = xr.open_dataset(tmp_path / "out" / "sweep.nc")
    assert ds["trapped"].dims == ("physics.protocol.depth", "physics.friction.mu")
    np.testing.assert_allclose(ds["physics.friction.mu"], [0.2, 0.4, 0.6, 0.8, 1.0])
    for d in ds["physics.protocol.depth"].values:
        for mu in ds["physics.friction.mu"].values:
            at = ds.sel({"physics.protocol.depth": d, "physics.friction.mu": mu})
            if d == 6.0 and mu == 1.0:  # the failed member: NaN with its error, not "not trapped"
                assert str(at["status"].values) == "failed"
                assert "step size underflow" in str(at["error"].values)
                assert np.isnan(at["trapped"]) and np.isnan(at["theta_max"])
                continue
            assert str(at["status"].values) == "ok" and str(at["error"].values) == ""
            assert float(at["trapped"]) == float(trapped_at(mu, d))
            assert float(at["theta_max"]) == pytest.approx(1.5 + 0.1 * mu)
            assert float(at["solver_steps"]) == 200  # the override reached every member
    assert "solver_wall_s" not in ds  # timings stay in the member files, out of the dataset
    for name in ("trapped", "theta_max", "status", "physics.friction.mu"):
        assert "units" in ds[name].attrs and "long_name" in ds[name].attrs
    assert json.loads(ds.attrs["swept_fields"]) == list(GRID["grid"])
    assert (tmp_path / "out" / "sweep.png").stat().st_size > 0
    assert len(list((tmp_path / "out" / "members").glob("*.json"))) == 10


def test_list_sweep_has_a_member_dimension(tmp_path):
    body = {
        "list": [
            {"physics.friction.mu": 0.5},
            {"physics.friction.mu": 1.55, "physics.material": "gent"},
        ]
    }
    sweep(sweep_path := write_sweep(tmp_path, body), tmp_path / "out")
    ds = xr.open_dataset(tmp_path / "out" / "sweep.nc")
    assert ds["trapped"].dims == ("member",)
    assert list(ds["physics.material"].values) == [
        "neo_hookean",
        "gent",
    ]  # the base value filled in
    assert list(ds["trapped"].values) == [1.0, 1.0]
    assert ds["theta_max"].values[1] == pytest.approx(1.5 + 0.155 + 0.1)
    assert load_spec(sweep_path).list_ is not None


def test_list_items_are_named_by_name_or_index(tmp_path):
    seen = []

    def member(data, out_dir, console=None):
        seen.append([st["clamp_to_z_mm"] for st in data["physics"]["stages"]])
        return fake_member(data, out_dir, console)

    body = {
        "grid": {
            "physics.stages.push_down.clamp_to_z_mm": [-80.0, -100.0],
            "physics.stages.1.clamp_to_z_mm": [-10.0],
        }
    }
    sweep(write_sweep(tmp_path, body), tmp_path / "out", member_fn=member)
    assert seen == [[-80.0, -10.0], [-100.0, -10.0]]  # the defaults were filled in, then set
    ds = xr.open_dataset(tmp_path / "out" / "sweep.nc")
    assert ds["trapped"].dims == (
        "physics.stages.push_down.clamp_to_z_mm",
        "physics.stages.1.clamp_to_z_mm",
    )
    for bad in ("physics.stages.pushdown.clamp_to_z_mm", "physics.stages.7.clamp_to_z_mm"):
        with pytest.raises(InputError, match=bad.replace(".", r"\.")):
            sweep(write_sweep(tmp_path, {"grid": {bad: [-80.0]}}, name="bad.yaml"), tmp_path / "o2")


def test_sweep_with_windows(tmp_path):
    body = {
        "grid": {"physics.protocol.depth": [2.0, 6.0]},
        "window": {"lo": 0.0, "hi": 2.4, "coarse": 25, "tol": 1e-3},
    }
    sweep(write_sweep(tmp_path, body), tmp_path / "out", plot=True)
    ds = xr.open_dataset(tmp_path / "out" / "sweep.nc")
    for d in (2.0, 6.0):
        at = ds.sel({"physics.protocol.depth": d})
        assert int(at["n_windows"]) == 2
        truth = [(0.2 + 0.05 * d, 0.5 + 0.05 * d), (1.5, 1.7)]
        np.testing.assert_allclose(at["window_lo"], [a for a, _ in truth], atol=1e-3)
        np.testing.assert_allclose(at["window_hi"], [b for _, b in truth], atol=1e-3)
        assert (at["window_lo_err"] <= 5e-4).all()


def _members(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((out / "members").glob("*.json"))]


def test_killed_sweep_resumes_with_every_member_once(tmp_path):
    path = write_sweep(tmp_path, GRID)
    out, log = tmp_path / "out", tmp_path / "started.log"
    script = (
        "from test_sweep import slow_member, fake_validate\n"
        "from dynslip.app.sweep import run_sweep\n"
        f"run_sweep({str(path)!r}, out={str(out)!r}, member_fn=slow_member, validate_fn=fake_validate, plot=False)\n"  # noqa: E501
    )
    env = {
        **os.environ,
        "PYTHONPATH": f"{HERE}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
        "DYNSLIP_TEST_LOG": str(log),
        "DYNSLIP_TEST_SLEEP": "0.4",
    }
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "members").glob("*.json"))) < 3:
        assert proc.poll() is None, proc.stderr.read().decode()
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    before = _members(out)
    assert 3 <= len(before) < 10, "the sweep was not killed mid-way"
    assert not (out / "sweep.nc").exists()

    calls = []

    def counting(data, out_dir, console=None):
        calls.append(data["physics"])
        return fake_member(data, out_dir, console)

    summary = sweep(path, out, member_fn=counting)
    assert summary["n_run"] == 10 - len(before) == len(calls)
    done_before = {
        (m["assign"]["physics.protocol.depth"], m["assign"]["physics.friction.mu"]) for m in before
    }
    rerun = {(c["protocol"]["depth"], c["friction"]["mu"]) for c in calls}
    assert not done_before & rerun  # nothing finished before the kill ran again
    after = _members(out)
    assert len(after) == 10 and len({m["fingerprint"] for m in after}) == 10
    ds = xr.open_dataset(out / "sweep.nc")
    assert (ds["status"] != "missing").all() and int((ds["status"] == "ok").sum()) == 9
    # a third run finds everything done and runs nothing
    assert sweep(path, out, member_fn=counting)["n_run"] == 0 and len(calls) == 10 - len(before)
    # a changed scenario is not taken from the old member files
    changed = write_sweep(tmp_path, {**GRID, "overrides": {"numerics.nodes": 25}})
    assert sweep(changed, out)["n_run"] == 10


def test_sequential_batched_and_dask_give_identical_datasets(tmp_path):
    body = {
        "overrides": {"physics.friction.mu": 1.0},  # fails at depth 6: failed members travel too
        "grid": {"physics.protocol.depth": [4.0, 6.0], "physics.material": ["neo_hookean", "gent"]},
        "window": {"lo": 0.0, "hi": 2.0, "coarse": 17, "tol": 0.01},
    }
    path = write_sweep(tmp_path, body)
    sweep(path, tmp_path / "seq", mode="sequential")
    batched = sweep(path, tmp_path / "bat", mode="batched")
    assert batched["batched"].startswith("grouped sequential")
    # the dask sweep in a child process (with the cluster, helpers.dask_cluster): never
    # distributed's threads in the pytest process; the fake travels to the workers by value
    script = (
        "import cloudpickle, test_sweep\n"
        "from helpers import dask_cluster\n"
        "cloudpickle.register_pickle_by_value(test_sweep)\n"
        "with dask_cluster() as c:\n"
        f"    test_sweep.sweep({str(path)!r}, {str(tmp_path / 'dask')!r}, mode='dask', "
        "scheduler=c['address'])\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{HERE}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    r = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    dss = [xr.open_dataset(tmp_path / d / "sweep.nc") for d in ("seq", "bat", "dask")]
    assert list((dss[0]["status"] == "ok").sum("physics.material").values) == [2, 0]
    assert (dss[0]["n_windows"] == 2).all() and (
        dss[0]["window_failed_runs"].sel({"physics.protocol.depth": 6.0}) == 1
    ).all()
    for other in dss[1:]:
        xr.testing.assert_identical(dss[0], other)


def test_bad_inputs_are_one_line_input_errors(tmp_path, monkeypatch):
    cases = {
        "no field": ({"grid": {"physics.friction.mux": [0.1]}}, "physics.friction.mux"),
        "no section": ({"grid": {"physics.friction.mu.x": [0.1]}}, "physics.friction.mu"),
        "empty list": ({"grid": {"physics.friction.mu": []}}, "empty range"),
        "empty linspace": (
            {"grid": {"physics.friction.mu": {"start": 0, "stop": 1, "num": 0}}},
            "num",
        ),
        "not a number": ({"grid": {"physics.friction.mu": [0.5, "high"]}}, "physics.friction.mu"),
        "bad override": (
            {"overrides": {"physics.depth": 3}, "grid": {"physics.friction.mu": [0.5]}},
            "physics.depth",
        ),
        "both": ({"grid": {"physics.friction.mu": [0.5]}, "list": [{}]}, "exactly one"),
        "unknown key": ({"grid": {"physics.friction.mu": [0.5]}, "gird": 1}, "gird"),
        "empty window": (
            {"grid": {"physics.protocol.depth": [5]}, "window": {"lo": 1, "hi": 1}},
            "empty range",
        ),
    }
    ran = []
    for label, (body, needle) in cases.items():
        path = write_sweep(tmp_path, body, name=f"{label.replace(' ', '_')}.yaml")
        with pytest.raises(InputError) as exc:
            sweep(path, tmp_path / "out", member_fn=lambda *a: ran.append(a))
        msg = str(exc.value)
        assert needle in msg and "\n" not in msg, (label, msg)
    assert ran == []  # nothing ran: every member is validated first

    # the command line: exit 2, one line on stderr, no traceback
    from dynslip import cli

    monkeypatch.setattr(scenario_mod, "validate_data", fake_validate)
    monkeypatch.setattr(sweep_mod, "default_member_fn", fake_member)
    monkeypatch.setattr(sweep_runners, "CONNECT_TIMEOUT_S", 1.0)
    ok = write_sweep(tmp_path, {"grid": {"physics.friction.mu": [0.5]}}, name="ok.yaml")
    bad = write_sweep(tmp_path, {"grid": {"physics.friction.mu": ["x"]}}, name="bad.yaml")
    for argv, needle in [
        (["sweep", str(bad)], "physics.friction.mu"),
        (["sweep", str(ok), "--scheduler", "tcp://127.0.0.1:9"], "cannot reach"),
        (
            ["sweep", str(ok), "--scheduler", "tcp://127.0.0.1:9", "--mode", "sequential"],
            "--mode dask",
        ),
        (["sweep", str(tmp_path / "missing.yaml")], "not found"),
    ]:
        # a scheduler address is tried in a child process: distributed's client threads never
        # start in the pytest process (helpers.dask_cluster)
        proc_err = _cli_child(argv) if "--scheduler" in argv else _cli(cli, argv)
        assert proc_err[0] == 2, (argv, proc_err)
        lines = proc_err[1].strip().splitlines()
        assert len(lines) == 1 and needle in lines[0] and "Traceback" not in proc_err[1], (
            argv,
            proc_err,
        )


def _cli_child(argv):
    """``_cli`` in a child process, with the same stand-ins as the calling test patches in."""
    script = (
        "import sys, test_sweep\n"
        "import dynslip.schema.base as b, dynslip.app.sweep as s, dynslip.app.sweep_runners as r\n"
        "from dynslip import cli\n"
        "b.validate_data = test_sweep.fake_validate\n"
        "s.default_member_fn = test_sweep.fake_member\n"
        "r.CONNECT_TIMEOUT_S = 1.0\n"
        f"sys.exit(cli.main({[*argv, '--out', str(Path(argv[1]).with_suffix('.out'))]!r}))\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{HERE}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    r = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                       timeout=300)
    return r.returncode, r.stderr


def _cli(cli, argv):
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(
            [*argv, "--out", str(Path(argv[1]).with_suffix(".out"))] if len(argv) > 1 else argv
        )
    return rc, err.getvalue()


def test_run_window_on_a_scenario(tmp_path):
    from dynslip.app.window import run_window

    (tmp_path / "s.yaml").write_text(
        yaml.safe_dump({"kind": "fake", "physics": {"protocol": {"depth": 4.0}}})
    )
    res = run_window(
        tmp_path / "s.yaml",
        ["numerics.nodes=20"],
        lo=0.0,
        hi=2.0,
        coarse=21,
        tol=1e-3,
        out=tmp_path / "w",
        member_fn=fake_member,
        validate_fn=fake_validate,
    )
    np.testing.assert_allclose(res["windows"], [[0.4, 0.7], [1.5, 1.7]], atol=1e-3)
    assert json.loads((tmp_path / "w" / "window.json").read_text())["windows"] == res["windows"]
    assert (tmp_path / "w" / "window.png").stat().st_size > 0
    with pytest.raises(InputError, match="empty range"):
        run_window(
            tmp_path / "s.yaml", lo=1.0, hi=0.5, member_fn=fake_member, validate_fn=fake_validate
        )
    with pytest.raises(InputError, match="physics.friction.muu"):
        run_window(
            tmp_path / "s.yaml",
            ["physics.friction.muu=1"],
            member_fn=fake_member,
            validate_fn=fake_validate,
        )


def test_bad_inputs_against_the_forming_schema_exit_2(tmp_path, monkeypatch):
    """The real scenario schema (kind: forming): every case stops before anything runs."""
    from dynslip import cli

    monkeypatch.setattr(sweep_runners, "CONNECT_TIMEOUT_S", 1.0)
    monkeypatch.setattr(sweep_mod, "default_member_fn", lambda *a: pytest.fail("a member ran"))
    (tmp_path / "m2.yaml").write_text("kind: forming\nnumerics: {nodes: 20}\n")
    cases = [
        ({"grid": {"physics.friction.mux": [0.5]}}, [], "physics.friction.mux"),
        ({"grid": {"physics.stages.push_dwn.clamp_to_z_mm": [-80.0]}}, [], "push_dwn"),
        ({"grid": {"physics.friction.mu": [0.5, "abc"]}}, [], "physics.friction.mu"),
        ({"grid": {"physics.friction.mu": []}}, [], "empty range"),
        (
            {"grid": {"physics.friction.mu": [0.5]}},
            ["--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "1"],
            "cannot reach",
        ),
    ]
    for i, (body, extra, needle) in enumerate(cases):
        p = tmp_path / f"s{i}.yaml"
        p.write_text(yaml.safe_dump({"base": "m2.yaml", **body}))
        argv = ["sweep", str(p), *extra]
        if extra:  # a dask client: in a child process (tests/conftest.py), as a user runs it
            r = subprocess.run([sys.executable, "-m", "dynslip.cli", *argv, "--out",
                                str(p.with_suffix(".out"))], capture_output=True, text=True,
                               timeout=300, cwd=tmp_path)
            rc, err = r.returncode, r.stderr
        else:
            rc, err = _cli(cli, argv)
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and needle in lines[0], (body, rc, err)
    # the window command: an empty range, a field that does not exist
    m2 = str(tmp_path / "m2.yaml")
    for argv, needle in [
        (["window", m2, "--lo", "1.0", "--hi", "0.5"], "empty range"),
        (["window", m2, "--set", "physics.friction.muu=1"], "physics.friction.muu"),
    ]:
        rc, err = _cli(cli, argv)
        lines = err.strip().splitlines()
        assert rc == 2 and len(lines) == 1 and needle in lines[0], (argv, rc, err)


@pytest.mark.slow
def test_method2_window_agrees_with_direct_runs(tmp_path, scenarios_dir):
    """Method 2 at 20 nodes: inside each window the ball is trapped, outside it is not."""
    from dynslip.app.sweep import default_member_fn
    from dynslip.app.window import run_window

    base = scenarios_dir / "method2_let_go.yaml"
    assert base.exists(), "the shipped scenario scenarios/method2_let_go.yaml is missing"
    sets = [
        "numerics.nodes=20",
        "physics.friction.law=coulomb",
    ]  # the ideal law's mu (method2_let_go.yaml: static/kinetic)
    # coarse step 0.2: a prototype's window (trapped at 0.8 only) and the shipped one near
    # mu = 1 are narrower than 0.4
    res = run_window(base, sets, lo=0.4, hi=1.6, coarse=7, tol=0.1, out=tmp_path / "w")
    data = scenario_mod.load_data(base, sets)

    def trapped(mu):
        d = json.loads(json.dumps(data))
        d.setdefault("physics", {}).setdefault("friction", {})["mu"] = mu
        return default_member_fn(d, tmp_path / f"direct_{mu:.3f}")["trapped"]

    evaluated = {m for m, _ in res["evaluations"]}
    checks = []
    windows = res["windows"]

    def outside(mu):  # outside every window by more than an edge's uncertainty (tol / 2)
        return 0.4 < mu < 1.6 and all(not (a - 0.05 <= mu <= b + 0.05) for a, b in windows)

    for lo, hi in windows:
        checks.append((lo + 0.37 * (hi - lo), True))  # inside, and not a point the search ran
        checks += [(mu, False) for mu in (lo - 0.13, hi + 0.13) if outside(mu)]
    if not res["windows"]:
        checks = [(0.55, False), (1.25, False)]
    for mu, expected in checks:
        assert mu not in evaluated
        assert trapped(mu) is expected, (mu, res["windows"])
