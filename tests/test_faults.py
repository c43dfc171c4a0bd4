"""Faults while a run or a study is in flight (issue 25), each against a real ``dynslip`` process.

A 12-node let-go run (about 15 s) is the subject; the world goes wrong around it: a second
run on the same ``--out``, a SIGKILLed holder, a file-size limit, a broken compilation cache,
a window search killed mid-way.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "method2_let_go.yaml"
TINY = ["--set", "numerics.nodes=12", "--set", "numerics.max_chord_depth=0.3"]

pytestmark = pytest.mark.slow


def dynslip(*args, cwd, env=None, preexec_fn=None, timeout=600):
    return subprocess.run(
        [sys.executable, "-m", "dynslip.cli", *map(str, args)],
        check=False,
        cwd=cwd,
        env=env,
        preexec_fn=preexec_fn,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def start(*args, cwd, env=None):
    return subprocess.Popen(
        [sys.executable, "-m", "dynslip.cli", *map(str, args)],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def md5(path: Path) -> str:
    return hashlib.md5(path.read_bytes()).hexdigest()


def reap(p, timeout=120.0):
    """Wait for a signalled process; one that has not ended ``timeout`` s later (a run hung in
    its exit path) is killed and the test fails, instead of stalling the suite."""
    try:
        return p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        out = p.communicate()
        pytest.fail(f"pid {p.pid} still running {timeout:g} s after its signal: {out[1][-2000:]}")


def wait_for(pred, timeout=300.0):
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise AssertionError("timed out waiting")
        time.sleep(0.2)


@pytest.fixture(scope="module")
def earlier(tmp_path_factory):
    """An earlier, complete result at ``r/``."""
    d = tmp_path_factory.mktemp("faults")
    p = dynslip("run", SCENARIO, *TINY, "--out", d / "r", cwd=d)
    assert p.returncode == 0, p.stderr
    return d


def test_second_run_on_one_out_refused_and_killed_holder_does_not_block(tmp_path):
    a = start("run", SCENARIO, *TINY, "--out", tmp_path / "r", cwd=tmp_path)
    lock = tmp_path / ".r.lock"
    wait_for(lambda: lock.is_file() and lock.read_text().startswith("pid"))
    t0 = time.monotonic()
    b = dynslip("run", SCENARIO, *TINY, "--out", tmp_path / "r", cwd=tmp_path)
    waited = time.monotonic() - t0
    assert a.poll() is None, "the holder finished before the second run was refused"
    assert b.returncode == 2
    lines = b.stderr.strip().splitlines()
    assert (
        len(lines) == 1
        and f"pid {a.pid}" in lines[0]
        and "host" in lines[0]
        and "started" in lines[0]
    )
    assert "Traceback" not in b.stderr and waited < 60
    a.send_signal(signal.SIGKILL)
    reap(a)
    # the lock file stays behind; the dead holder's lock does not
    c = dynslip("run", SCENARIO, *TINY, "--out", tmp_path / "r", cwd=tmp_path)
    assert c.returncode == 0, c.stderr
    assert (tmp_path / "r" / "trajectory.nc").is_file()


def _fsize(limit):
    def set_limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return set_limit


def test_failed_write_keeps_earlier_result_and_marks_partial(earlier):
    d = earlier
    before = {f.name: md5(f) for f in (d / "r").iterdir()}
    size = (d / "r" / "trajectory.nc").stat().st_size
    p = dynslip("run", SCENARIO, *TINY, "--out", d / "r", cwd=d, preexec_fn=_fsize(int(size * 0.7)))
    assert p.returncode == 3, p.stderr
    lines = p.stderr.strip().splitlines()
    assert "Traceback" not in p.stderr
    assert "writing trajectory.nc failed" in lines[0] and "file-size limit" in lines[0]
    assert {f.name: md5(f) for f in (d / "r").iterdir()} == before  # byte-identical
    kept = sorted(d.glob("r.incomplete-*"))
    assert len(kept) == 1 and str(kept[0]) in lines[1]
    assert "file-size limit" in (kept[0] / "INCOMPLETE").read_text()
    import xarray as xr

    with xr.open_dataset(kept[0] / "trajectory.nc") as ds:  # an earlier flush, marked partial
        assert ds.attrs["complete"] == 0 and ds.sizes["time"] >= 1
    assert not list(kept[0].glob(".*.tmp"))  # never a half-written file left


def test_failed_first_write_keeps_nothing_and_says_so(earlier):
    d = earlier
    before = md5(d / "r" / "trajectory.nc")
    p = dynslip("run", SCENARIO, *TINY, "--out", d / "r", cwd=d, preexec_fn=_fsize(20000))
    assert p.returncode == 3 and "Traceback" not in p.stderr
    assert "failed" in p.stderr.splitlines()[0]
    assert md5(d / "r" / "trajectory.nc") == before
    assert not list(d.glob("r.staging-*"))


def _traj_values(path):
    import xarray as xr

    with xr.open_dataset(path) as ds:
        return {k: ds[k].values.copy() for k in ("rho", "z", "pressure", "time")}


@pytest.mark.parametrize("how", ["unwritable", "garbage", "shared"])
def test_compilation_cache_faults(earlier, tmp_path, how):
    import numpy as np

    cache = tmp_path / "cache"
    cache.mkdir()
    env = {**os.environ, "DYNSLIP_CACHE_DIR": str(cache)}
    if how == "unwritable":
        # a folder that cannot be made (its parent is a file): unwritable even for root, whom
        # permission bits do not stop
        (tmp_path / "afile").write_text("")
        env["DYNSLIP_CACHE_DIR"] = str(tmp_path / "afile" / "cache")
        cache.chmod(0o500)
    elif how == "garbage":
        for i in range(20):
            (cache / f"jit_fn-{i:040x}-cache").write_bytes(os.urandom(512))
            (cache / f"garbage{i}").write_text("not a cache entry")
    try:
        if how == "shared":
            ps = [
                start("run", SCENARIO, *TINY, "--out", tmp_path / f"s{i}", cwd=tmp_path, env=env)
                for i in (0, 1)
            ]
            results = [(p.wait(600), p.stderr.read()) for p in ps]
            outs = [tmp_path / "s0", tmp_path / "s1"]
        else:
            p = dynslip("run", SCENARIO, *TINY, "--out", tmp_path / "s0", cwd=tmp_path, env=env)
            results = [(p.returncode, p.stderr)]
            outs = [tmp_path / "s0"]
    finally:
        cache.chmod(0o700)
    ref = _traj_values(earlier / "r" / "trajectory.nc")
    for (rc, err), out in zip(results, outs, strict=True):
        assert rc == 0, err
        assert len([ln for ln in err.splitlines() if ln.strip()]) <= 1, err
        got = _traj_values(out / "trajectory.nc")
        for k in ref:
            np.testing.assert_array_equal(got[k], ref[k])


WINDOW = ["window", SCENARIO, *TINY, "--lo", "0.2", "--hi", "1.4", "--coarse", "3", "--tol", "0.4"]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_window_search_killed_resumes_to_the_same_window_json(tmp_path, sig):
    ref = dynslip(*WINDOW, "--out", tmp_path / "ref", cwd=tmp_path)
    assert ref.returncode == 0, ref.stderr
    ref_json = json.loads((tmp_path / "ref" / "window.json").read_text())
    n_total = ref_json["n_evaluations"]
    assert n_total >= 3
    log = tmp_path / "w" / "evaluations.json"

    def finished():
        try:
            return len(json.loads(log.read_text())["evaluations"])
        except (OSError, ValueError, KeyError):
            return 0

    p = start(*WINDOW, "--out", tmp_path / "w", cwd=tmp_path)
    wait_for(lambda: finished() >= 2 or p.poll() is not None)
    p.send_signal(sig)
    reap(p)
    kept = finished()
    assert 2 <= kept < n_total, "killed too late to test a resume"
    assert not (tmp_path / "w" / "window.json").exists()
    r = dynslip(*WINDOW, "--out", tmp_path / "w", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"resuming: {kept} evaluations" in r.stdout
    # only the missing members ran: one progress line per new evaluation
    assert (
        sum(
            ": trapped" in ln or ": not trapped" in ln or "FAILED" in ln
            for ln in r.stdout.splitlines()
        )
        == n_total - kept
    )
    assert json.loads((tmp_path / "w" / "window.json").read_text()) == ref_json


def test_run_over_the_machine_memory_refused_before_it_starts(tmp_path):
    from dynslip.app.sizes import estimate, machine_memory

    nodes, save = 4000, 0.0005
    frames = 320.0 / save  # the let-go path lasts > 320 s at its longest
    if estimate(nodes, frames) <= machine_memory():
        pytest.skip("this machine holds even this run")
    p = dynslip(
        "run",
        SCENARIO,
        "--set",
        f"numerics.nodes={nodes}",
        "--set",
        f"numerics.save_interval_s={save}",
        "--out",
        tmp_path / "big",
        cwd=tmp_path,
    )
    assert p.returncode == 2
    (line,) = p.stderr.strip().splitlines()
    assert "numerics.nodes = 4000" in line and "GiB" in line and "this machine has" in line
    assert os.listdir(tmp_path) == []  # nothing written
    s = dynslip("schema", cwd=tmp_path)
    assert s.returncode == 0 and "memory of a forming run" in s.stdout


def test_non_finite_state_mid_run_keeps_the_finite_frames(tmp_path):
    """The Hookean sheet (refused beyond stretch 3) pushed down past the ball: the state goes
    non-finite in push_down; exit 3, one line naming the stage and the time, the frames before
    it kept (every value finite), marked incomplete."""
    import numpy as np
    import xarray as xr

    p = dynslip(
        "run",
        SCENARIO,
        "--set",
        "numerics.nodes=12",
        "--set",
        "numerics.max_chord_depth=1.0",
        "--set",
        "physics.material.model=hookean",
        "--out",
        tmp_path / "nf",
        cwd=tmp_path,
    )
    assert p.returncode == 3 and "Traceback" not in p.stderr
    first = p.stderr.strip().splitlines()[0]
    assert "non-finite state" in first and "stage 'push_down'" in first and "t = " in first
    # "stage 'push_down' at t = T0 s: the solver did not reach t = T1 s: non-finite state ..."
    t_fail = float(first.split("at t = ")[1].split(" s")[0])
    (kept,) = tmp_path.glob("nf.incomplete-*")
    assert not (tmp_path / "nf").exists()
    assert "this folder" in (kept / "INCOMPLETE").read_text()
    with xr.open_dataset(kept / "trajectory.nc") as ds:
        assert ds.attrs["complete"] == 0
        assert float(ds["time"].values[-1]) == pytest.approx(t_fail, abs=1e-3)
        for v in ("rho", "z", "lambda_theta", "lambda_phi", "T_theta", "energy_elastic"):
            assert np.isfinite(ds[v].values).all(), v


SWEEP = """\
name: faults
base: {base}
overrides:
  physics.friction.law: coulomb
  numerics.nodes: 12
  numerics.max_chord_depth: 0.3
grid:
  physics.friction.mu: {{start: 0.4, stop: 1.6, num: 4}}
"""


def _sweep_values(path):
    import xarray as xr

    with xr.open_dataset(path) as ds:
        return {k: ds[k].values.copy() for k in ds.data_vars if ds[k].dtype.kind in "fiub"}


def test_dask_worker_killed_mid_sweep_every_member_once(tmp_path):
    """A real LocalCluster; one worker SIGKILLed once the first member is written. dask reruns
    the lost member elsewhere, or the sweep stops (exit 3) and the rerun runs only the missing
    members; either way sweep.nc equals that of an uninterrupted sweep."""
    import numpy as np

    from helpers import dask_cluster

    (tmp_path / "s.yaml").write_text(SWEEP.format(base=SCENARIO))
    ref = dynslip(
        "sweep",
        tmp_path / "s.yaml",
        "--mode",
        "sequential",
        "--out",
        tmp_path / "ref",
        cwd=tmp_path,
    )
    assert ref.returncode == 0, ref.stderr
    with dask_cluster() as cluster:
        pids = cluster["pids"]
        p = start(
            "sweep",
            tmp_path / "s.yaml",
            "--mode",
            "dask",
            "--scheduler",
            cluster["address"],
            "--out",
            tmp_path / "d",
            cwd=tmp_path,
        )
        mdir = tmp_path / "d" / "members"
        wait_for(lambda: (mdir.is_dir() and any(mdir.glob("*.json"))) or p.poll() is not None)
        assert p.poll() is None, "the sweep ended before a worker could be killed"
        os.kill(pids[0], signal.SIGKILL)
        _, err = p.communicate(timeout=600)
        if p.returncode == 3:  # stopped: the rerun runs the missing members only
            n_done = len(list(mdir.glob("*.json")))
            r = dynslip(
                "sweep",
                tmp_path / "s.yaml",
                "--mode",
                "dask",
                "--scheduler",
                cluster["address"],
                "--out",
                tmp_path / "d",
                cwd=tmp_path,
            )
            assert r.returncode == 0, r.stderr
            assert f"{n_done} already done, {4 - n_done} to run" in r.stdout
        else:
            assert p.returncode == 0, err
    recs = [json.loads(f.read_text()) for f in mdir.glob("*.json")]
    assert (
        len(recs) == 4 and len({r["fingerprint"] for r in recs}) == 4
    )  # every member exactly once
    got, want = (
        _sweep_values(tmp_path / "d" / "sweep.nc"),
        _sweep_values(tmp_path / "ref" / "sweep.nc"),
    )
    assert got.keys() == want.keys()
    for k in want:
        np.testing.assert_array_equal(got[k], want[k], err_msg=k)
