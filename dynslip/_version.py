"""The package version and the format version of the files it writes (re-exported by
:mod:`dynslip`); a module of its own so that every layer may read them without importing
the package's public API. :func:`describe` is what ``dynslip --version`` prints: the
version and the commit it runs from."""

from __future__ import annotations

import subprocess
from pathlib import Path

__version__ = "0.1.0"
FORMAT_VERSION = "1"

__all__ = ["FORMAT_VERSION", "__version__", "commit", "describe"]


def commit() -> str | None:
    """The git commit the package is imported from (``git describe --always --dirty``, asked at
    run time), or None when it is not a git checkout (an installed copy) or git is absent."""
    here = Path(__file__).resolve().parent
    try:
        top = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "--show-toplevel"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        if not top or here.parent != Path(top).resolve():
            return None  # the package is not the top-level folder of this checkout
        return (
            subprocess.run(
                ["git", "-C", top, "describe", "--always", "--dirty", "--tags"],
                capture_output=True,
                text=True,
                timeout=5,
                check=True,
            ).stdout.strip()
            or None
        )
    except (OSError, subprocess.SubprocessError):
        return None


def describe() -> str:
    """``dynslip <version> (commit <describe>)`` from a checkout; ``dynslip <version> (installed,
    no git checkout)`` otherwise, the version then the installed distribution's."""
    sha = commit()
    if sha is not None:
        return f"dynslip {__version__} (commit {sha})"
    try:
        from importlib.metadata import version

        installed = version("dynslip")
    except Exception:  # noqa: BLE001 - not installed as a distribution: the package's own
        installed = __version__
    return f"dynslip {installed} (installed, no git checkout)"
