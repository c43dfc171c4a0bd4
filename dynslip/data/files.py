"""Files: atomic writes, dataset provenance and unit checks.

Every file is written whole or not at all (written beside its target, then renamed). A write
that fails (disk full, a file-size limit, an I/O error) raises :class:`WriteFailed` (exit 3)
naming the file and the cause; the partial file is removed, the target untouched. The rules
for the folders results go into (which a run may replace, staging, the markers of incomplete
and interrupted runs) are :mod:`dynslip.data.folders`.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import signal
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dynslip._version import FORMAT_VERSION, __version__
from dynslip.errors import ComputationError

if TYPE_CHECKING:  # imported where used: a run imports xarray while its step compiles
    import xarray as xr


def _atomic_target(path: Path):
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:
        raise WriteFailed(f"writing {str(path)!r} failed: {err.strerror or err}") from None
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are ordinary files
    return path, Path(tmp)


class WriteFailed(ComputationError):
    """A result file could not be written (disk full, file-size limit, I/O error): exit 3.

    The target is untouched (the partial file beside it is removed)."""


@contextlib.contextmanager
def _writing(path: Path, tmp: Path):
    """Write ``tmp`` then rename it ``path``; on an OS error remove ``tmp``, raise
    :class:`WriteFailed`."""
    try:
        yield
        os.replace(tmp, path)
    except (OSError, RuntimeError) as err:  # netCDF4 reports HDF5 write errors as RuntimeError
        reason = _write_failure(err, tmp)
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise WriteFailed(f"writing {path.name} failed: {reason}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_failure(err, tmp: Path) -> str:
    """Why a write failed, in words: the file-size limit or a full disk when that is what it met
    (netCDF4 reports either as a bare "HDF error")."""
    import resource

    reason = getattr(err, "strerror", None) or str(err) or type(err).__name__
    try:
        size = tmp.stat().st_size
        soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
        if soft != resource.RLIM_INFINITY and size >= soft - 65536:
            return f"{reason} (the file-size limit of {soft} bytes was reached)"
        vfs = os.statvfs(tmp.parent)
        if vfs.f_bavail * vfs.f_frsize < 1 << 20:
            return f"{reason} (the disk is full)"
    except (OSError, ValueError):
        pass
    return reason


def write_text(path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    path, tmp = _atomic_target(path)
    with _writing(path, tmp):
        tmp.write_text(text)
    return path


def jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj


def write_json(path, data: dict) -> Path:
    """Write ``data`` as indented JSON atomically (NaN and inf become null)."""
    return write_text(path, json.dumps(jsonable(data), indent=2) + "\n")


@contextlib.contextmanager
def signals_deferred():
    """SIGINT and SIGTERM held back while inside (main thread only) and delivered on leaving,
    to their previous handlers. An interruption raised inside xarray's and netCDF4's locked
    sections (or inside a file manager's destructor there, where Python prints and swallows
    it) can leave the HDF5 lock held, and the run's next write then waits on it forever: seen
    once as a hung ``dynslip window`` after SIGTERM (tests/test_faults.py)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []

    def hold(signum, frame):
        caught.append(signum)

    previous = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        # a signal the kernel handed to another thread (JAX's) reaches its Python handler only
        # when the main thread next checks: signal.signal() checks, so setting ``hold`` again
        # lets such a pending one be caught here rather than run after ``caught`` is read
        for s in previous:
            signal.signal(s, hold)
        for s, handler in previous.items():
            signal.signal(s, handler)
        if caught:
            handler = previous[caught[0]]
            if callable(handler):
                handler(caught[0], None)
            elif handler != signal.SIG_IGN:  # the default action (or a handler set in C)
                signal.raise_signal(caught[0])


def write_netcdf(ds: xr.Dataset, path) -> Path:
    """Write a dataset to netCDF4 atomically, interruptions deferred to the write's end
    (:func:`signals_deferred`)."""
    path, tmp = _atomic_target(path)
    with signals_deferred(), _writing(path, tmp):
        ds.to_netcdf(tmp, engine="netcdf4", format="NETCDF4")
    return path


def save_figure(fig, path, **kw) -> Path:
    """Save a matplotlib figure atomically (format from the target's suffix)."""
    path, tmp = _atomic_target(path)
    with _writing(path, tmp):
        fig.savefig(tmp, format=Path(path).suffix.lstrip(".") or "png", **kw)
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
        "dynslip_version": __version__,
        "format_version": FORMAT_VERSION,
        "git_commit": git_commit(),
        "scenario": scenario_json,
        "kind": kind,
        "Conventions": "CF-1.8",
    }


@functools.lru_cache(maxsize=1)
def _units():
    """pint's unit registry, built once (0.15 s: its definitions parsed)."""
    import pint

    return pint.UnitRegistry()


def check_units(ds: xr.Dataset) -> None:
    """Raise if a data variable or coordinate lacks a ``units`` string pint can parse."""
    ureg = _units()
    for name, var in {**ds.coords, **ds.data_vars}.items():
        u = var.attrs.get("units")
        if u is None:
            raise ValueError(f"variable {name!r} has no units attribute")
        ureg.parse_units(u) if u not in ("1", "") else None


def variable(data, dims, units: str, long_name: str, **attrs) -> xr.Variable:
    """An xarray variable with the ``units`` and ``long_name`` every variable carries."""
    import xarray as xr

    return xr.Variable(
        dims, np.asarray(data), attrs={"units": units, "long_name": long_name, **attrs}
    )
