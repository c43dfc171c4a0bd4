"""The house style is checked, not only stated: ``ruff check`` over the package, the tests and
the benchmarks passes with the rules of ``pyproject.toml`` ([tool.ruff.lint]: pycodestyle E/W
with line length 100, pyflakes F, import order I, bugbear B, pyupgrade UP)."""

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _ruff() -> list[str]:
    exe = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    assert exe, "ruff is not installed: pip install -e '.[test]' installs it"
    return [exe]


def test_ruff_check_passes():
    run = subprocess.run([*_ruff(), "check", "--no-cache", "dynslip", "tests", "benchmarks"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, "ruff check found:\n" + run.stdout[-4000:] + run.stderr[-2000:]


def test_the_rules_are_the_stated_ones():
    """The rules this test enforces are the ones pyproject.toml states (a check of the checker):
    a line of 101 characters and an unused import are both found."""
    sample = "import os\n\nx = '" + "a" * 95 + "'\n"
    cmd = [*_ruff(), "check", "--no-cache", "--stdin-filename", "dynslip/_sample.py", "-"]
    run = subprocess.run(cmd, cwd=ROOT, input=sample, capture_output=True, text=True, timeout=60)
    assert "E501" in run.stdout and "F401" in run.stdout, run.stdout
