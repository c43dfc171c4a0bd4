"""What a newcomer reads: compare shows whether each run trapped and never cuts a run's
name; schema never cuts a value list; a non-numeric text where a number belongs is said to
need a number; --help has no reST backticks; --version names the version and the commit; a
run that did not come to rest says so in words; a coarse window search says it is not
resolved and not checked against refinement."""

import io
import json
import re
import subprocess
import types
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

import dynslip
from dynslip.analysis.summary import outcome_words, rest_words
from dynslip.app.compare import run_compare
from dynslip.app.window import refinement_check, resolution_check
from dynslip.cli import build_parser, main
from dynslip.data.files import write_netcdf
from dynslip.schema import base as sc
from helpers import synthetic_trajectory

ROOT = Path(__file__).resolve().parents[1]


def test_compare_has_a_trapped_column_and_keeps_long_names(tmp_path):
    runs = []
    for name, trapped in (
        ("method2_let_go_at_a_long_name", True),
        ("method1_with_another_long_name", None),
    ):
        state = np.zeros((3, 21), dtype=np.int8)
        state[:, :8] = 1
        d = tmp_path / name
        write_netcdf(synthetic_trajectory(state), d / "trajectory.nc")
        if trapped is not None:
            (d / "summary.json").write_text(json.dumps({"trapped": trapped}))
        runs.append(d)
    console = Console(width=80, record=True, file=io.StringIO())
    res = run_compare(runs, out=tmp_path / "cmp", console=console)
    text = console.export_text()
    assert "trapped" in text
    lines = [ln for ln in text.splitlines() if "│" in ln]
    joined = "".join(c for ln in lines for c in ln if c not in "│ ")
    for r in runs:  # each name whole (folded onto lines, never ellipsised)
        assert str(r).replace(" ", "") in joined, text
    assert "…" not in text and "..." not in text
    assert (
        res["runs"][str(runs[0])]["trapped"] is True
        and res["runs"][str(runs[1])]["trapped"] is None
    )
    assert re.search(r"\byes\b", text) and "no answer" in text


def test_schema_never_cuts_a_value_list():
    text = sc.schema_reference()
    assert "load_step | load_step_full | kvaerno5 | kvaerno4 | kvaerno3 | implicit_euler" in text
    assert "gent | neo_hookean | mooney_rivlin | hookean" in text


@pytest.mark.parametrize(
    "value, says",
    [("abc", "a number is expected, not the text 'abc'"), ("'0.5'", "write it without quotes")],
)
def test_text_for_a_number(tmp_path, capsys, value, says):
    scn = tmp_path / "s.yaml"
    scn.write_text(
        (ROOT / "scenarios" / "method2.yaml")
        .read_text()
        .replace("thickness_um: 150.0", f"thickness_um: {value}")
    )
    assert main(["validate", str(scn)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "physics.thickness_um" in err and says in err
    if value == "abc":
        assert "quotes" not in err
    assert (
        main(["validate", str(ROOT / "scenarios" / "method2.yaml"), "--set", "numerics.nodes=abc"])
        == 2
    )
    err = capsys.readouterr().err
    assert "numerics.nodes" in err and "a number is expected" in err and "quotes" not in err


def test_help_has_no_backticks_and_version_names_the_commit(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    assert "``" not in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["--version"])
    assert exc.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith(f"dynslip {dynslip.__version__} (")
    sha = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
        check=False,
        capture_output=True,
        text=True,
    ).stdout.strip()
    if sha:  # a checkout: the commit git reports now
        assert sha[:7] in out, out


def _stage_run(met_last: bool):
    """A world-like object with a rest stage and the driver's stage ends."""
    rules = {"push": "duration", "rest": "rest"}
    p = types.SimpleNamespace(stage_names=tuple(rules), until=rules.__getitem__)
    result = types.SimpleNamespace(
        stage_end=[
            {"name": "push", "t_start": 0.0, "t_end": 2.0, "condition_met": True},
            {"name": "rest", "t_start": 2.0, "t_end": 4.0, "condition_met": met_last},
        ]
    )
    state = np.zeros((6, 11), dtype=np.int8)
    ds = synthetic_trajectory(state, stage=[0, 0, 0, 1, 1, 1], stage_names=("push", "rest"))
    ds["ball_z"] = ("time", np.array([0.0, 0.0, 0.0, -0.11, -0.2, -0.31]))
    return p, ds, result


def test_a_run_not_at_rest_says_so_in_words():
    p, ds, result = _stage_run(met_last=False)
    words = rest_words(p, ds, result, at_rest=False)
    assert words.startswith("NOT AT REST") and "'rest'" in words and "time limit" in words
    assert "-0.11" in words and "-0.31" in words
    # a stage that ended at its time limit before its condition: trapped has no answer
    summary = {
        "status": "ok",
        "trapped": None,
        "trapped_unknown_reasons": ["stage 'rest' ended at its time limit (t = 6 s) before "
                                    "its condition (until: rest)"],
        "end_at_rest": False,
        "end_at_rest_says": words,
        "theta_max": 1.8,
        "rbar_max": 0.9,
    }
    words = outcome_words(summary)
    assert words.startswith("trapped unknown: stage 'rest' ended at its time limit"), words
    p, ds, result = _stage_run(met_last=True)
    assert rest_words(p, ds, result, at_rest=True).startswith("at rest")


def test_a_coarse_window_search_says_it_is_not_resolved():
    result = {"windows": [[1.0, 1.2], [1.4, 1.7]], "failed": []}
    chk = resolution_check(result, {1.0: 0.07, 1.5: 0.03}, 20, 0.1, "scenarios/method2_let_go.yaml")
    assert chk["members_resolved"] is False and chk["marginal"] == [1.0]
    assert chk["says"].startswith("MEMBERS NOT RESOLVED at N = 20")
    assert "--nodes 20,40,80" in chk["says"] and "2 separate windows" in chk["says"]
    fine = resolution_check(
        {"windows": [[1.2, 2.2]], "failed": []}, {1.0: 0.01}, 100, 0.1, "x.yaml"
    )
    assert fine["members_resolved"] and "not checked against refinement" in fine["says"]
    per_n = {
        20: {"windows": [[1.0, 1.2], [1.4, 1.7]], "tol": 0.01},
        40: {"windows": [[1.2, 2.2]], "tol": 0.01},
        80: {"windows": [[1.21, 2.2]], "tol": 0.01},
    }
    ref = refinement_check(per_n, "physics.friction.mu_s")
    assert ref["windows_change"] and ref["changes"] == ["N = 20 -> 40: 2 -> 1 windows"]
    assert "CHANGE WITH REFINEMENT" in ref["says"]
    same = refinement_check({40: per_n[40], 80: per_n[80]}, "physics.friction.mu_s")
    assert not same["windows_change"] and "agree" in same["says"]
