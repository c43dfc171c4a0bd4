"""Nothing of the user's is lost (issue 13): the output folder rules, kept partial runs, SIGTERM.

Everything here goes through the real file system (``tmp_path``) and, where it can, the
in-process ``dynslip.cli.main``; the computation is replaced by stubs (nothing is
compiled or solved).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

import dynslip.app.sweep as sweep_mod
from dynslip.app import kinds
from dynslip.cli import main
from dynslip.data.files import provenance
from dynslip.data.folders import INCOMPLETE, RESULT_MARKER, is_result_folder
from dynslip.errors import ComputationError
from helpers import one_line

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
CYL = str(SCENARIOS / "cylinder.yaml")


# ---------------------------------------------------------------------------------------
# helpers


def _cli(argv, capsys):
    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return rc, cap.err


def _tree(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` (relative) with the bytes of the files."""
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(root.rglob("*"))
    }


def _stub_run(monkeypatch, fn):
    """Replace the cylinder runner by ``fn(out: Path) -> dict``."""
    calls = []

    def run(scn, out, console):
        calls.append(Path(out))
        return fn(Path(out))

    monkeypatch.setitem(kinds.RUNNERS, "cylinder", run)
    return calls


def _good(tag: str):
    def fn(out: Path) -> dict:
        (out / "summary.json").write_text(json.dumps({"tag": tag}))
        (out / "result.nc").write_bytes(b"stub")
        return {"tag": tag}

    return fn


def _failing(exc: BaseException, partial: str = "partial"):
    def fn(out: Path) -> dict:
        (out / "partial.txt").write_text(partial)
        raise exc

    return fn


def _tag(out: Path) -> str:
    return json.loads((out / "summary.json").read_text())["tag"]


def _incomplete(parent: Path, name: str) -> list[Path]:
    return sorted(parent.glob(f"{name}.incomplete-*"))


def _no_leftovers(parent: Path, name: str) -> None:
    """No staging folder and no hidden folder of the old result remain."""
    left = [
        p.name for p in parent.iterdir() if p.name.startswith((f"{name}.staging-", f".{name}.old-"))
    ]
    assert not left, left


# ---------------------------------------------------------------------------------------
# --out: what may be replaced


def test_user_folder_refused_with_files_intact(tmp_path, capsys, monkeypatch):
    calls = _stub_run(monkeypatch, _good("new"))
    out = tmp_path / "mydata"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "sub").mkdir()
    (out / "sub" / "data.csv").write_text("1,2\n")
    before = _tree(tmp_path)
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 2
    line = one_line(err)
    assert "--out" in line and str(out) in line and "--force" in line and "dynslip result" in line
    assert _tree(tmp_path) == before and not calls  # refused before anything ran or was made


@pytest.mark.parametrize("command", ["sweep", "window"])
def test_user_folder_refused_by_sweep_and_window(tmp_path, capsys, monkeypatch, command):
    monkeypatch.setattr(sweep_mod, "default_member_fn", lambda *a, **k: pytest.fail("ran a member"))
    src = _sweep_file(tmp_path) if command == "sweep" else SCENARIOS / "method2_pinned.yaml"
    out = tmp_path / "mydata"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    before = _tree(tmp_path)
    rc, err = _cli([command, src, "--out", out], capsys)
    assert rc == 2
    line = one_line(err)
    assert "--out" in line and str(out) in line and "--force" in line
    assert _tree(tmp_path) == before


def test_force_replaces_a_folder_after_success(tmp_path, capsys, monkeypatch):
    _stub_run(monkeypatch, _good("new"))
    out = tmp_path / "mydata"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    rc, err = _cli(["run", CYL, "--out", out, "--force"], capsys)
    assert rc == 0, err
    assert _tag(out) == "new" and not (out / "notes.txt").exists()
    assert (out / RESULT_MARKER).is_file() and not (out / INCOMPLETE).exists()
    _no_leftovers(tmp_path, "mydata")


@pytest.mark.parametrize("force", [False, True])
def test_existing_file_never_replaced(tmp_path, capsys, monkeypatch, force):
    calls = _stub_run(monkeypatch, _good("new"))
    out = tmp_path / "precious.txt"
    out.write_text("precious")
    rc, err = _cli(["run", CYL, "--out", out, *(["--force"] if force else [])], capsys)
    assert rc == 2
    line = one_line(err)
    assert "--out" in line and str(out) in line and "file" in line
    assert out.read_text() == "precious" and not calls
    assert sorted(p.name for p in tmp_path.iterdir()) == ["precious.txt"]


def test_empty_folder_may_be_used(tmp_path, capsys, monkeypatch):
    _stub_run(monkeypatch, _good("new"))
    out = tmp_path / "empty"
    out.mkdir()
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 0, err
    assert _tag(out) == "new"


def test_rerun_replaces_a_result_only_after_success(tmp_path, capsys, monkeypatch):
    out = tmp_path / "res"
    _stub_run(monkeypatch, _good("first"))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 0
    assert _tag(out) == "first" and is_result_folder(out)

    seen = []

    def second(staging: Path) -> dict:
        seen.append(_tag(out))  # while the new run works, the old result is untouched
        assert staging != out and staging.parent == out.parent
        return _good("second")(staging)

    _stub_run(monkeypatch, second)
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 0, err
    assert seen == ["first"] and _tag(out) == "second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_earlier_result_without_marker_recognised(tmp_path, capsys, monkeypatch):
    """A result folder written before the marker existed: known by its provenance attributes."""
    _stub_run(monkeypatch, _good("new"))
    old = tmp_path / "old"
    old.mkdir()
    ds = xr.Dataset({"a": ("x", np.arange(3.0))}, attrs=provenance("{}", "cylinder"))
    ds.to_netcdf(old / "result.nc")
    (old / "summary.json").write_text("{}")
    assert is_result_folder(old)
    rc, err = _cli(["run", CYL, "--out", old], capsys)
    assert rc == 0, err
    assert _tag(old) == "new"

    # a netCDF file without dynslip's attributes (and a summary.json) is not a result
    other = tmp_path / "other"
    other.mkdir()
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(other / "result.nc")
    (other / "summary.json").write_text("{}")
    before = _tree(other)
    rc, err = _cli(["run", CYL, "--out", other], capsys)
    assert rc == 2 and "not a dynslip result" in one_line(err)
    assert _tree(other) == before


def test_failed_runs_keep_the_good_result_and_every_incomplete_folder(
    tmp_path, capsys, monkeypatch
):
    out = tmp_path / "res"
    _stub_run(monkeypatch, _good("good"))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 0
    good = _tree(out)

    _stub_run(monkeypatch, _failing(ComputationError("solver gave up"), "first"))
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 3
    assert _tree(out) == good
    kept = _incomplete(tmp_path, "res")
    assert len(kept) == 1
    first = kept[0]
    assert (first / "partial.txt").read_text() == "first"
    assert "ComputationError: solver gave up" in (first / INCOMPLETE).read_text()
    assert str(first) in err and ".staging" not in err

    _stub_run(monkeypatch, _failing(KeyboardInterrupt(), "second"))
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 130
    assert "SIGINT" in err and "Traceback" not in err
    assert _tree(out) == good
    kept = _incomplete(tmp_path, "res")
    assert len(kept) == 2 and first in kept  # the first run's partial data survives the next run
    assert (first / "partial.txt").read_text() == "first"
    (second,) = [k for k in kept if k != first]
    assert (second / "partial.txt").read_text() == "second"
    assert "interrupted by SIGINT" in (second / INCOMPLETE).read_text()
    assert str(second) in err
    _no_leftovers(tmp_path, "res")


def test_unexpected_error_keeps_the_partial_files(tmp_path, capsys, monkeypatch):
    out = tmp_path / "res"
    _stub_run(monkeypatch, _failing(OverflowError("cannot convert float infinity to integer")))
    with pytest.raises(OverflowError):
        main(["run", CYL, "--out", str(out)])
    err = capsys.readouterr().err
    (kept,) = _incomplete(tmp_path, "res")
    assert (kept / "partial.txt").is_file() and "OverflowError" in (kept / INCOMPLETE).read_text()
    assert str(kept) in err and not out.exists()


@pytest.mark.parametrize("as_dir", [False, True])
def test_user_files_named_staging_and_old_untouched(tmp_path, capsys, monkeypatch, as_dir):
    out = tmp_path / "res"
    mine = [tmp_path / "res.staging", tmp_path / "res.old"]
    for p in mine:
        if as_dir:
            p.mkdir()
            (p / "keep.txt").write_text(p.name)
        else:
            p.write_text(p.name)
    before = {p.name: _tree(p) if as_dir else p.read_text() for p in mine}
    _stub_run(monkeypatch, _good("first"))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 0
    _stub_run(monkeypatch, _good("second"))  # a second run replaces the first result
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 0, err
    _stub_run(monkeypatch, _failing(ComputationError("boom")))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 3
    assert _tag(out) == "second" and (out / RESULT_MARKER).is_file()
    assert {p.name: _tree(p) if as_dir else p.read_text() for p in mine} == before
    _no_leftovers(tmp_path, "res")


def test_run_failing_before_writing_leaves_nothing(tmp_path, capsys, monkeypatch):
    out = tmp_path / "res"

    def fn(out):
        raise ComputationError("failed at once")

    _stub_run(monkeypatch, fn)
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 3 and "failed at once" in err
    assert list(tmp_path.iterdir()) == []


def test_scenario_inside_out_refused(tmp_path, capsys, monkeypatch):
    """Replacing the folder would delete the scenario file the user runs from it."""
    out = tmp_path / "res"
    _stub_run(monkeypatch, _good("first"))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 0
    scen = out / "mine.yaml"
    scen.write_text(Path(CYL).read_text())
    calls = _stub_run(monkeypatch, _good("second"))
    rc, err = _cli(["run", scen, "--out", out], capsys)
    assert rc == 2 and "scenario" in one_line(err)
    assert scen.is_file() and _tag(out) == "first" and not calls


def test_start_from_run_folder_follows_the_same_rule(tmp_path, capsys, monkeypatch):
    """The run a ``start_from`` scenario makes (into outputs/<stem>/) never replaces a
    user's folder: exit 2 before anything runs."""
    import dynslip.app.forming as af

    monkeypatch.setattr(af, "run_forming", lambda sc, out, console: pytest.fail("ran"))
    monkeypatch.setitem(kinds.RUNNERS, "forming", lambda sc, out, console: pytest.fail("ran"))
    monkeypatch.chdir(tmp_path)
    start = tmp_path / "start.yaml"
    start.write_text(yaml.safe_dump({"kind": "forming"}))
    rel = tmp_path / "rel.yaml"
    rel.write_text(yaml.safe_dump({"kind": "forming", "start_from": "start.yaml"}))
    mine = tmp_path / "outputs" / "start"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("mine")
    before = _tree(tmp_path)
    rc, err = _cli(["run", rel, "--out", tmp_path / "res"], capsys)
    assert rc == 2
    line = one_line(err)
    assert "start_from" in line and "outputs/start" in line and "not a dynslip result" in line
    assert _tree(tmp_path) == before


# ---------------------------------------------------------------------------------------
# --out: paths that cannot be used


def test_out_dot_refused(tmp_path, capsys, monkeypatch):
    calls = _stub_run(monkeypatch, _good("new"))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.txt").write_text("x")
    for out in (".", "..", str(tmp_path)):
        before = _tree(tmp_path)
        rc, err = _cli(["run", CYL, "--out", out], capsys)
        assert rc == 2
        assert "--out" in one_line(err)
        assert _tree(tmp_path) == before
    assert not calls


def test_parent_is_a_file_refused(tmp_path, capsys, monkeypatch):
    calls = _stub_run(monkeypatch, _good("new"))
    (tmp_path / "f").write_text("x")
    rc, err = _cli(["run", CYL, "--out", tmp_path / "f" / "sub" / "out"], capsys)
    assert rc == 2
    line = one_line(err)
    assert "--out" in line and "is a file" in line
    assert (tmp_path / "f").read_text() == "x" and not calls


def _unprivileged() -> list[str] | None:
    """The argv prefix that runs a command without the power to write into a read-only folder:
    nothing for an ordinary user; as root, setpriv (or runuser) to the user nobody (65534), or
    capsh dropping CAP_DAC_OVERRIDE; None where none of them exists."""
    import shutil

    if os.geteuid() != 0:
        return []
    if shutil.which("setpriv"):
        return [shutil.which("setpriv"), "--reuid=65534", "--regid=65534", "--clear-groups"]
    if shutil.which("runuser"):
        return [shutil.which("runuser"), "-u", "nobody", "--"]
    if shutil.which("capsh"):
        return [shutil.which("capsh"), "--drop=cap_dac_override", "--"]
    return None


def test_read_only_parent_refused():
    """The real command line, run as an unprivileged user (root writes into a 0555 folder
    anyway): exit 2, one line naming --out, nothing written."""
    import tempfile

    prefix = _unprivileged()
    if prefix is None:
        pytest.skip("running as root and none of setpriv, runuser, capsh is installed")
    # tmp_path's parents are 0700 (root's): an unprivileged user could not reach them
    base = Path(tempfile.mkdtemp(prefix="dynslip-ro-", dir="/tmp"))
    try:
        base.chmod(0o777)
        ro = base / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        env = {**os.environ, "HOME": str(base), "DYNSLIP_CACHE_DIR": str(base / "cache")}
        # the unprivileged user must reach the checkout and its virtual environment (a clone
        # in a 0700 folder, as mktemp -d makes, hides them): else the command cannot start
        probe = subprocess.run([*prefix, sys.executable, "-c", "import dynslip.cli"],
                               capture_output=True, text=True, cwd=base, env=env, timeout=120,
                               check=False)
        if probe.returncode != 0:
            pytest.skip("the unprivileged user cannot import dynslip from this checkout (a "
                        "parent folder it cannot enter): " + probe.stderr.strip()[-200:])
        res = subprocess.run([*prefix, sys.executable, "-m", "dynslip.cli", "run", CYL, "--out",
                              str(ro / "out")], capture_output=True, text=True, cwd=base, env=env,
                             timeout=300, check=False)
        assert res.returncode == 2, res.stderr[-2000:]
        line = one_line(res.stderr)
        assert "--out" in line and "not writable" in line
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)
        import shutil

        shutil.rmtree(base)


def _sweep_file(tmp_path: Path) -> Path:
    p = tmp_path / "study.yaml"
    p.write_text(
        yaml.safe_dump(
            {"base": str(SCENARIOS / "cylinder.yaml"), "grid": {"physics.mu": [0.5, 0.9]}}
        )
    )
    return p


def _fake_member(data, out_dir, console=None):
    return {"trapped": False, "theta_max": 1.0 + data["physics"]["mu"]}


def test_sweep_out_file_fronts_out_file_animate_out_dir(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sweep_mod, "default_member_fn", _fake_member)
    f = tmp_path / "file.txt"
    f.write_text("mine")
    d = tmp_path / "folder"
    d.mkdir()
    traj = tmp_path / "trajectory.nc"
    from helpers import synthetic_trajectory

    state = np.zeros((6, 8), np.int8)
    state[:, :3] = 1
    synthetic_trajectory(state).to_netcdf(traj)
    before = _tree(tmp_path)
    for argv in (
        ["sweep", _sweep_file(tmp_path), "--out", f],
        ["sweep", _sweep_file(tmp_path), "--out", f, "--force"],
        ["window", SCENARIOS / "method2_pinned.yaml", "--out", f],
        ["fronts", traj, "--out", f],
        ["compare", traj, "--out", f],
        ["animate", traj, "--out", d],
    ):
        rc, err = _cli(argv, capsys)
        assert rc == 2, (argv, err)
        line = one_line(err)
        assert "--out" in line and str(argv[3]) in line, line
    after = _tree(tmp_path)
    after.pop("study.yaml", None)
    before.pop("study.yaml", None)
    assert after == before


# ---------------------------------------------------------------------------------------
# sweep and window folders


def test_sweep_folder_marked_resumed_and_force_writes_beside_user_files(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.setattr(sweep_mod, "default_member_fn", _fake_member)
    study = _sweep_file(tmp_path)
    out = tmp_path / "sw"
    assert _cli(["sweep", study, "--out", out], capsys)[0] == 0
    assert (out / RESULT_MARKER).is_file() and (out / "sweep.nc").is_file()
    # a sweep folder is a result: running again resumes in it
    assert _cli(["sweep", study, "--out", out], capsys)[0] == 0

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    assert _cli(["sweep", study, "--out", mine], capsys)[0] == 2
    rc, err = _cli(["sweep", study, "--out", mine, "--force"], capsys)
    assert rc == 0, err
    assert (mine / "notes.txt").read_text() == "mine" and (mine / "sweep.nc").is_file()


def test_unreachable_scheduler_creates_nothing(tmp_path):
    """In a child process (the command line as a user runs it): a dask client's threads never
    start in the pytest process (tests/conftest.py)."""
    out = tmp_path / "sw"
    r = subprocess.run(
        [sys.executable, "-m", "dynslip.cli", "sweep", str(_sweep_file(tmp_path)), "--out",
         str(out), "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "1"],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )
    assert r.returncode == 2 and "cannot reach" in one_line(r.stderr), r.stderr
    assert "within 1 s" in one_line(r.stderr)  # --connect-timeout, not the 10 s default
    assert not out.exists()


def test_window_folder_marked(tmp_path, monkeypatch):
    from dynslip.app.window import run_window

    def member(data, out_dir, console=None):
        mu = data["physics"]["friction"]["mu"]
        return {"trapped": 0.4 < mu < 0.6}

    s = tmp_path / "s.yaml"
    s.write_text(
        yaml.safe_dump({"kind": "forming", "physics": {"friction": {"law": "coulomb", "mu": 0.5}}})
    )
    out = tmp_path / "w"
    run_window(s, lo=0.0, hi=1.0, coarse=5, tol=0.1, out=out, member_fn=member, console=_quiet())
    assert (out / RESULT_MARKER).is_file() and is_result_folder(out)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("a")
    from dynslip.errors import InputError

    with pytest.raises(InputError, match="--force"):
        run_window(
            s, lo=0.0, hi=1.0, coarse=5, tol=0.1, out=mine, member_fn=member, console=_quiet()
        )
    assert sorted(p.name for p in mine.iterdir()) == ["a.txt"]


def _quiet():
    from rich.console import Console

    return Console(quiet=True)


# ---------------------------------------------------------------------------------------
# SIGTERM


def test_sigterm_in_process_exit_143_and_marked(tmp_path, capsys, monkeypatch):
    out = tmp_path / "res"
    _stub_run(monkeypatch, _good("good"))
    assert _cli(["run", CYL, "--out", out], capsys)[0] == 0

    def killed(staging: Path) -> dict:
        (staging / "partial.txt").write_text("partial")
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(200):  # the handler raises at the next bytecode
            time.sleep(0.01)
        pytest.fail("SIGTERM did not interrupt the run")

    _stub_run(monkeypatch, killed)
    before = signal.getsignal(signal.SIGTERM)
    rc, err = _cli(["run", CYL, "--out", out], capsys)
    assert rc == 143
    assert "interrupted by SIGTERM" in err and "Traceback" not in err
    assert _tag(out) == "good"
    (kept,) = _incomplete(tmp_path, "res")
    assert "interrupted by SIGTERM" in (kept / INCOMPLETE).read_text()
    assert (kept / "partial.txt").read_text() == "partial"
    assert (
        signal.getsignal(signal.SIGTERM) == before
    )  # the handler is only there during the command


def test_sigterm_subprocess_exit_143(tmp_path):
    """The real signal from outside, to ``python -m``-style process running ``main``."""
    out = tmp_path / "res"
    script = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from dynslip.cli import main
        from dynslip.app import kinds

        def run(scn, out, console):
            (Path(out) / "partial.txt").write_text("partial")
            print("READY", flush=True)
            time.sleep(60)

        kinds.RUNNERS["cylinder"] = run
        sys.exit(main(["run", {CYL!r}, "--out", {str(out)!r}]))
    """)
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        deadline = time.monotonic() + 120
        line = ""
        while "READY" not in line:
            assert time.monotonic() < deadline and proc.poll() is None, proc.stderr.read()
            line = proc.stdout.readline()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err
    assert "interrupted by SIGTERM" in err and "Traceback" not in err
    assert not out.exists()
    (kept,) = _incomplete(tmp_path, "res")
    assert "interrupted by SIGTERM" in (kept / INCOMPLETE).read_text()
    assert (kept / "partial.txt").read_text() == "partial"


def test_signals_deferred_during_a_netcdf_write_are_delivered_after_it():
    """A SIGTERM (or SIGINT) that arrives inside a netCDF write is held back to the write's end
    (an exception inside xarray's locked sections can leave the HDF5 lock held) and then raised
    by the handler in force: the write is whole, the interruption not lost."""
    from dynslip.data.files import signals_deferred
    from dynslip.data.folders import Terminated, sigterm_raises

    reached = []
    with pytest.raises(Terminated), sigterm_raises(), signals_deferred():
        os.kill(os.getpid(), signal.SIGTERM)
        reached.append("after the signal")
    assert reached == ["after the signal"]
    # the handler in force is Python's own (a test run earlier in the process may have left
    # another: the full suite once left SIGINT without a raising handler here)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt), signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            reached.append("after SIGINT")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert reached[-1] == "after SIGINT"
