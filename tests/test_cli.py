"""Bad input through the CLI: exit 2, one line, no traceback, no output files."""

import subprocess
import sys
from pathlib import Path

import pytest

from dynslip.cli import main
from dynslip.schema.base import parse_override, schema_reference
from helpers import one_line

ROOT = Path(__file__).resolve().parents[1]


def _run(argv, capsys):
    rc = main(argv)
    err = capsys.readouterr().err
    return rc, err


def test_missing_file(tmp_path, capsys):
    out = tmp_path / "out"
    rc, err = _run(["run", str(tmp_path / "nope.yaml"), "--out", str(out)], capsys)
    assert rc == 2
    assert "not found" in one_line(err)
    assert not out.exists() and not Path(str(out) + ".staging").exists()


def test_malformed_yaml(tmp_path, capsys):
    f = tmp_path / "bad.yaml"
    f.write_text("kind: static\nphysics: [1, 2\n")
    out = tmp_path / "out"
    rc, err = _run(["run", str(f), "--out", str(out)], capsys)
    assert rc == 2
    assert "malformed YAML" in one_line(err)
    assert not out.exists() and not Path(str(out) + ".staging").exists()


def test_unknown_kind(tmp_path, capsys):
    f = tmp_path / "k.yaml"
    f.write_text("kind: teleport\n")
    rc, err = _run(["validate", str(f)], capsys)
    assert rc == 2
    line = one_line(err)
    assert "kind" in line and "teleport" in line


def test_bad_override_syntax(tmp_path, capsys):
    f = tmp_path / "k.yaml"
    f.write_text("kind: static\n")
    rc, err = _run(["validate", str(f), "--set", "novalue"], capsys)
    assert rc == 2
    assert "section.key=value" in one_line(err)


@pytest.mark.parametrize("value", ["0", "-1", "inf", "nan", "soon"])
def test_connect_timeout_is_a_positive_number_of_seconds(tmp_path, capsys, value):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_:
        main(["sweep", str(tmp_path / "s.yaml"), "--connect-timeout", value, "--out", str(out)])
    line = one_line(capsys.readouterr().err)
    assert exit_.value.code == 2
    assert "--connect-timeout" in line and repr(value) in line and "positive" in line
    assert not out.exists()


def test_parse_override_types():
    assert parse_override("numerics.nodes=40") == ("numerics.nodes", 40)
    assert parse_override("physics.material.model=gent") == ("physics.material.model", "gent")
    assert parse_override("a.b=[1, 2.5]") == ("a.b", [1, 2.5])


def test_schema_lists_units():
    """Every field whose name carries a unit suffix lists that unit in the unit column."""
    text = schema_reference()
    suffix = {"_N_per_mm": "N/mm", "_mm_s": "mm/s", "_mm": "mm", "_MPa": "MPa", "_N": "N"}
    checked = 0
    for line in text.splitlines():
        cols = line.split()
        if len(cols) < 2 or not cols[0].startswith("physics."):
            continue
        for end, unit in suffix.items():
            if cols[0].endswith(end):
                assert f" {unit} " in line, line
                checked += 1
                break
    assert checked >= 10, checked


def test_subprocess_no_traceback(tmp_path):
    """The installed entry point itself: exit 2 and one line for an unknown option value."""
    f = tmp_path / "bad.yaml"
    f.write_text(": : :\n")
    proc = subprocess.run(
        [sys.executable, "-m", "dynslip.cli", "validate", str(f)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    one_line(proc.stderr)


@pytest.mark.parametrize(
    "scenario, override, field",
    [
        ("paper_gent.yaml", "physics.colour=blue", "physics.colour"),  # unknown key
        ("paper_gent.yaml", "numerics.n_nodes=many", "numerics.n_nodes"),  # wrong type
        ("paper_gent.yaml", "physics.material.jm=0", "physics.material.jm"),  # J_m <= 0
        ("paper_gent.yaml", "physics.material.jm=-3", "physics.material.jm"),
        ("paper_gent.yaml", "physics.rbar_max=0", "physics.rbar_max"),  # rbar_max <= 0
        ("paper_gent.yaml", "physics.rbar_max=-0.9", "physics.rbar_max"),
        ("paper_gent.yaml", "physics.theta_max=0", "physics.theta_max"),  # outside (0, pi)
        ("paper_gent.yaml", "physics.theta_max=3.2", "physics.theta_max"),
        (
            "paper_gent.yaml",
            "numerics.mu_bracket=[-1.0, 5.0]",
            "numerics.mu_bracket",
        ),  # negative mu
        ("cylinder.yaml", "physics.mu=-0.5", "physics.mu"),
        ("method2_pinned.yaml", "physics.friction.mu_s=-1", "physics.friction.mu_s"),
        (
            "method2_pinned.yaml",
            "physics.pre_stretch=0.4",
            "physics.pre_stretch",
        ),  # below the slack bound 0.5
    ],
)
def test_bad_field_exits_2_one_line_naming_it_and_writes_nothing(
    tmp_path, capsys, scenario, override, field
):
    out = tmp_path / "out"
    rc, err = _run(
        ["run", str(ROOT / "scenarios" / scenario), "--out", str(out), "--set", override], capsys
    )
    assert rc == 2
    line = one_line(err)
    assert field in line, line
    assert not out.exists() and not Path(str(out) + ".staging").exists()


@pytest.mark.parametrize(
    "command, case",
    [
        (c, k)
        for c in ("animate", "fronts")
        for k in ("not_netcdf", "not_trajectory", "format_version")
    ]
    + [("animate", "time_range")],
)
def test_trajectory_readers_bad_input_exit_2(tmp_path, capsys, command, case):
    """dynslip animate / fronts: a file that is not a dynslip trajectory, another format
    version, a time range outside the run: exit 2, one line, nothing written."""
    import numpy as np
    import xarray as xr

    from helpers import synthetic_trajectory

    state = np.zeros((6, 8), np.int8)
    state[:, :3] = 1
    ds = synthetic_trajectory(state)
    path = tmp_path / "trajectory.nc"
    extra = []
    if case == "not_netcdf":
        path.write_text("hello\n")
    elif case == "not_trajectory":
        xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(path)
    elif case == "format_version":
        ds.attrs["format_version"] = "99"
        ds.to_netcdf(path)
    else:
        ds.to_netcdf(path)
        extra = ["--t-start", "100"]  # the run lasts 5 s
    out = tmp_path / "out"
    rc, err = _run([command, str(path), "--out", str(out), *extra], capsys)
    assert rc == 2, err
    line = one_line(err)
    assert ("t_start" in line) if case == "time_range" else ("trajectory" in line)
    assert not out.exists()


def test_every_option_has_a_help_line_with_its_default_and_every_command_examples():
    """``dynslip COMMAND --help`` explains every option (what it does, its unit where it has one,
    its default) and ends with examples (issue 24: ``window --help`` said nothing of --set, --lo,
    --hi, --coarse and --tol)."""
    import argparse

    from dynslip.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, parser in sub.choices.items():
        assert parser.epilog and "dynslip " + name in parser.epilog, f"{name}: no examples"
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            text = action.help or ""
            label = f"{name} {'/'.join(action.option_strings) or action.dest}"
            if not text:
                missing.append(f"{label}: no help")
            elif action.option_strings and "default" not in text:
                missing.append(f"{label}: help names no default")
    assert not missing, "\n".join(missing)
    from dynslip.schema.sweep import WindowSpec

    window = {a.dest: a.help for a in sub.choices["window"]._actions}
    for opt in ("lo", "hi", "coarse", "tol"):  # the defaults are the sweep window's
        assert f"default {WindowSpec.model_fields[opt].default:g}" in window[opt], window[opt]
        assert opt == "coarse" or "dimensionless" in window[opt]
