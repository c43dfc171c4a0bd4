"""Bad input through the CLI: exit 2, one line, no traceback, no output files."""

import subprocess
import sys
from pathlib import Path

import pytest

from dynslip.cli import main
from dynslip.scenario import parse_override, schema_reference

ROOT = Path(__file__).resolve().parents[1]


def _run(argv, capsys):
    rc = main(argv)
    err = capsys.readouterr().err
    return rc, err


def _one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def test_missing_file(tmp_path, capsys):
    out = tmp_path / "out"
    rc, err = _run(["run", str(tmp_path / "nope.yaml"), "--out", str(out)], capsys)
    assert rc == 2
    assert "not found" in _one_line(err)
    assert not out.exists() and not Path(str(out) + ".staging").exists()


def test_malformed_yaml(tmp_path, capsys):
    f = tmp_path / "bad.yaml"
    f.write_text("kind: static\nphysics: [1, 2\n")
    out = tmp_path / "out"
    rc, err = _run(["run", str(f), "--out", str(out)], capsys)
    assert rc == 2
    assert "malformed YAML" in _one_line(err)
    assert not out.exists() and not Path(str(out) + ".staging").exists()


def test_unknown_kind(tmp_path, capsys):
    f = tmp_path / "k.yaml"
    f.write_text("kind: teleport\n")
    rc, err = _run(["validate", str(f)], capsys)
    assert rc == 2
    line = _one_line(err)
    assert "kind" in line and "teleport" in line


def test_bad_override_syntax(tmp_path, capsys):
    f = tmp_path / "k.yaml"
    f.write_text("kind: static\n")
    rc, err = _run(["validate", str(f), "--set", "novalue"], capsys)
    assert rc == 2
    assert "section.key=value" in _one_line(err)


def test_parse_override_types():
    assert parse_override("numerics.nodes=40") == ("numerics.nodes", 40)
    assert parse_override("physics.material.model=gent") == ("physics.material.model", "gent")
    assert parse_override("a.b=[1, 2.5]") == ("a.b", [1, 2.5])


def test_schema_lists_units():
    text = schema_reference()
    assert "kind:" in text


def test_subprocess_no_traceback(tmp_path):
    """The installed entry point itself: exit 2 and one line for an unknown option value."""
    f = tmp_path / "bad.yaml"
    f.write_text(": : :\n")
    proc = subprocess.run(
        [sys.executable, "-m", "dynslip.cli", "validate", str(f)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    _one_line(proc.stderr)
