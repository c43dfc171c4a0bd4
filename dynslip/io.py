"""Files: atomic writes, staged run folders, dataset provenance and unit checks.

Every file is written whole or not at all (written beside its target, then renamed).
A run writes into a staging folder ``<out>.staging/`` that holds a file ``INCOMPLETE``
until the run succeeds; only then does the staging folder replace ``<out>/``. A run that
fails or is interrupted leaves the staging folder readable, with the reason in
``INCOMPLETE``.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

import dynslip

INCOMPLETE = "INCOMPLETE"


def _atomic_target(path: Path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are ordinary files
    return path, Path(tmp)


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    path, tmp = _atomic_target(path)
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj


def write_json(path, data: dict) -> Path:
    """Write ``data`` as indented JSON atomically (NaN and inf become null)."""
    return write_text(path, json.dumps(_jsonable(data), indent=2) + "\n")


def write_netcdf(ds: xr.Dataset, path) -> Path:
    """Write a dataset to netCDF4 atomically."""
    path, tmp = _atomic_target(path)
    ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4")
    os.replace(tmp, path)
    return path


def save_figure(fig, path, **kw) -> Path:
    """Save a matplotlib figure atomically (format from the target's suffix)."""
    path, tmp = _atomic_target(path)
    fig.savefig(tmp, format=Path(path).suffix.lstrip(".") or "png", **kw)
    os.replace(tmp, path)
    return path


def git_commit() -> str:
    """The git commit of the package source, or ``"unknown"``."""
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=5,
        )
        return out.stdout.strip() if out.returncode == 0 else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def provenance(scenario_json: str, kind: str) -> dict:
    """Global attributes every dataset carries."""
    return {
        "dynslip_version": dynslip.__version__,
        "format_version": dynslip.FORMAT_VERSION,
        "git_commit": git_commit(),
        "scenario": scenario_json,
        "kind": kind,
        "Conventions": "CF-1.8",
    }


def check_units(ds: xr.Dataset) -> None:
    """Raise if a data variable or coordinate lacks a ``units`` string pint can parse."""
    import pint

    ureg = pint.UnitRegistry()
    for name, var in {**ds.coords, **ds.data_vars}.items():
        u = var.attrs.get("units")
        if u is None:
            raise ValueError(f"variable {name!r} has no units attribute")
        ureg.parse_units(u) if u not in ("1", "") else None


class StagedRun:
    """A run folder written through ``<out>.staging/`` and swapped in on success."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.staging = self.out.with_name(self.out.name + ".staging")

    def __enter__(self) -> Path:
        if self.staging.exists():
            shutil.rmtree(self.staging)
        self.staging.mkdir(parents=True)
        write_text(self.staging / INCOMPLETE, "run in progress\n")
        return self.staging

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            (self.staging / INCOMPLETE).unlink()
            old = self.out.with_name(self.out.name + ".old")
            if old.exists():
                shutil.rmtree(old)
            if self.out.exists():
                os.replace(self.out, old)
            os.replace(self.staging, self.out)
            if old.exists():
                shutil.rmtree(old)
            return False
        with contextlib.suppress(OSError):
            write_text(
                self.staging / INCOMPLETE,
                f"run did not complete: {exc_type.__name__}: {exc}\n"
                "files here hold what was computed before it stopped\n",
            )
        return False


def variable(data, dims, units: str, long_name: str, **attrs) -> xr.Variable:
    """An xarray variable with the ``units`` and ``long_name`` every variable carries."""
    return xr.Variable(dims, np.asarray(data), attrs={"units": units, "long_name": long_name, **attrs})
