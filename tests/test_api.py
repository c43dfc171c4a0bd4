"""The Python API (dynslip/api.py): the worked example of docs/python-api.md runs as it is
(a pocket at 20 nodes, a figure, a sweep of 3 members), runs in memory leave nothing on
disk, ``out=`` follows the command line's folder rules, and errors carry what was computed."""

import re
import shutil
import tempfile
from pathlib import Path

import pytest
import xarray as xr

import dynslip

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "python-api.md"
SMALL_STATIC = {"numerics.n_nodes": 30}


def _doc_blocks() -> list[str]:
    """The code blocks of the doc fenced ```python (those fenced ```python skip are not run)."""
    return re.findall(r"^```python\n(.*?)^```", DOC.read_text(), flags=re.S | re.M)


@pytest.mark.slow
def test_worked_example_of_the_doc_runs(tmp_path, monkeypatch):
    """About 40 s with a warm compilation cache, 2.5 min cold (20 nodes, 4 runs in all)."""
    shutil.copytree(ROOT / "scenarios", tmp_path / "scenarios")
    monkeypatch.chdir(tmp_path)
    blocks = _doc_blocks()
    assert len(blocks) >= 4
    text = "\n".join(blocks)
    nodes = [int(n) for n in re.findall(r"numerics\.nodes\"?:\s*(\d+)", text)]
    assert nodes and max(nodes) <= 40
    ns: dict = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), ns)  # noqa: S102 - the documentation's own code
    assert isinstance(ns["res"].trajectory, xr.Dataset) and ns["res"].summary["status"] == "ok"
    assert ns["ds"].sizes["physics.friction.mu_s"] <= 4
    assert (tmp_path / "meridian.png").stat().st_size > 0
    assert not (tmp_path / "outputs").exists()  # in memory: no run folder


def test_public_names_are_re_exported():
    for name in (
        "load",
        "run",
        "sweep",
        "window",
        "plot",
        "InputError",
        "ComputationError",
        "RunResult",
    ):
        assert hasattr(dynslip, name), name
    assert dynslip.InputError is dynslip.errors.InputError
    assert callable(dynslip.plot.meridian) and callable(dynslip.plot.state_map)


def test_run_in_memory_writes_nothing(tmp_path, monkeypatch, scenarios_dir):
    monkeypatch.chdir(tmp_path)
    scn = dynslip.load(scenarios_dir / "paper_neohookean.yaml", set=SMALL_STATIC)
    assert scn.numerics.n_nodes == 30
    res = dynslip.run(scn)
    assert res.out is None and res.trajectory is None
    assert res.summary["status"] == "ok" and res.summary["n_nodes"] == 30
    assert res.dataset.attrs["kind"] == "static" and res.dataset["theta"].size == 30
    assert list(tmp_path.iterdir()) == []


def test_run_in_memory_makes_no_file_round_trip(tmp_path, monkeypatch, scenarios_dir):
    """Without ``out`` no file is written or read (no temporary folder either): every writer and
    reader of the data layer fails the test; the result equals the folder's files."""
    from dynslip.data import files

    scn = dynslip.load(scenarios_dir / "paper_neohookean.yaml", set=SMALL_STATIC)
    on_disk = dynslip.run(scn, out=tmp_path / "o")
    with monkeypatch.context() as m:
        for name in ("write_netcdf", "write_json", "write_text", "save_figure"):
            m.setattr(files, name, lambda *a, **k: pytest.fail("a file was written"))
        m.setattr(xr, "load_dataset", lambda *a, **k: pytest.fail("a file was read back"))
        m.setattr(tempfile, "TemporaryDirectory", lambda *a, **k: pytest.fail("a temporary folder"))
        res = dynslip.run(scn)
    timing = ("t_bvp_s", "t_search_s")  # wall-clock times of this process, not results
    assert ({k: v for k, v in res.summary.items() if k not in timing}
            == {k: v for k, v in on_disk.summary.items() if k not in timing})
    xr.testing.assert_allclose(res.dataset, on_disk.dataset, rtol=0, atol=0)


def test_run_out_follows_the_folder_rules(tmp_path, scenarios_dir):
    scn = dynslip.load(scenarios_dir / "paper_neohookean.yaml", set=SMALL_STATIC)
    out = tmp_path / "o"
    res = dynslip.run(scn, out=out)
    assert res.out == out and (out / "result.nc").is_file() and (out / "summary.json").is_file()
    assert res.summary == __import__("json").loads((out / "summary.json").read_text())
    dynslip.run(scn, out=out)  # an earlier dynslip result is replaced
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(dynslip.InputError, match="not a dynslip result"):
        dynslip.run(scn, out=mine)
    assert (mine / "notes.txt").read_text() == "mine"
    (tmp_path / "file").write_text("x")
    with pytest.raises(dynslip.InputError, match="existing file"):
        dynslip.run(scn, out=tmp_path / "file")


def test_bad_input_names_the_field(scenarios_dir):
    with pytest.raises(dynslip.InputError, match="numerics.n_nodes"):
        dynslip.load(scenarios_dir / "paper_neohookean.yaml", set={"numerics.n_nodes": 2})
    with pytest.raises(dynslip.InputError, match="physics.nope"):
        dynslip.load(scenarios_dir / "paper_neohookean.yaml", set={"physics.nope": 1})


def test_failed_run_carries_the_partial_result(scenarios_dir, tmp_path, monkeypatch):
    """No root of F_v in the bracket (as tests/test_static_runs.py): ComputationError whose
    ``partial`` holds the result.nc (complete = 0) and summary (status failed) computed."""
    monkeypatch.chdir(tmp_path)
    scn = dynslip.load(scenarios_dir / "paper_neohookean.yaml",
                       set={"numerics.n_nodes": 30, "physics.initial_shape": "linear",
                            "numerics.max_steps": 20000, "numerics.mu_bracket": [1.0, 3.0]})
    with pytest.raises(dynslip.ComputationError) as exc:
        dynslip.run(scn)
    part = exc.value.partial
    assert isinstance(part, dynslip.RunResult)
    assert part.dataset.attrs["complete"] == 0 and part.summary["status"] == "failed"
    assert "dynslip-run-" not in str(exc.value)  # the deleted temporary folder is not named
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(dynslip.ComputationError) as exc:
        dynslip.run(scn, out=tmp_path / "o")
    kept = exc.value.partial.out
    assert kept.name.startswith("o.incomplete-") and (kept / "result.nc").is_file()
