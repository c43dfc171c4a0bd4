"""JAX set-up: float64 at import; everything else by :func:`configure_runtime`, which the
command line (:func:`dynslip.cli.main`) and the test suite (``tests/conftest.py``) call.

Importing this module (and so ``import dynslip``) turns on ``jax_enable_x64`` and nothing
else: the package's numerics are float64 (its tolerances, Newton's down to 1e-12, and its
stored trajectories assume it). It does not choose the device, edit the environment or
create a folder (/work/shared/docs/style.md, "A library has no side effects at import";
tests/test_import.py).

:func:`configure_runtime` sets up what a run of the command line needs, in this process and
in the processes it starts (a sweep's spawned workers and dask's local workers inherit the
environment, and JAX reads its settings from it when imported):

- the platform: ``JAX_PLATFORMS`` when set, else the CPU;
- XLA's CPU fusion emitters off (``XLA_FLAGS``);
- equinox's runtime checks as NaN, not host callbacks (``EQX_ON_ERROR``);
- the persistent compilation cache in ``$DYNSLIP_CACHE_DIR`` (default
  ``~/.cache/dynslip/jax``), so a second run with the same shapes skips XLA compilation
  (tracing and lowering still cost: they are what the cache cannot save); none when that
  folder cannot be made (a read-only home).

The platform and the XLA flags are read when JAX starts its backend, and equinox's checks
when they are traced: call it first, before any JAX computation.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

#: XLA's CPU fusion emitters off for every program compiled in the process: dynslip's programs
#: are small and their compiles dominate, about a quarter shorter without the emitters
#: (docs/speed.md has the timings), the answers the same to rounding. The segment step of a
#: mesh of more than 200 nodes, whose run they shorten, asks for them
#: (dynslip.physics.driver.simulate.compile_step). An XLA_FLAGS that names the option wins. The
#: pinned
#: jaxlib knows it (constraints.txt); one that did not would refuse to start, and this is the
#: line to change.
XLA_FLAG = "--xla_cpu_use_fusion_emitters=false"

#: the persistent cache's thresholds: programs compiled in 0.5 s or more, of any size
CACHE_MIN_COMPILE_TIME_S = 0.5
CACHE_MIN_ENTRY_SIZE_BYTES = 0

_configured: list[Path | None] = []


def cache_dir() -> Path:
    """The persistent compilation cache's folder: ``$DYNSLIP_CACHE_DIR``, default
    ``~/.cache/dynslip/jax`` (not created here)."""
    return Path(os.environ.get("DYNSLIP_CACHE_DIR", Path.home() / ".cache" / "dynslip" / "jax"))


def _too_late() -> list[str]:
    """What has already started that the settings of :func:`configure_runtime` act on."""
    late = []
    try:
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            late.append("JAX's backend (the platform and XLA_FLAGS)")
    except (ImportError, AttributeError):  # a jax without this private function: not checked
        pass
    return late


def configure_runtime() -> Path | None:
    """Configure JAX for a dynslip run (the module docstring says what and why); idempotent.
    Returns the persistent compilation cache's folder, None when it could not be made.

    Every setting is also put in ``os.environ`` (``JAX_PLATFORMS``, ``XLA_FLAGS``,
    ``EQX_ON_ERROR``, ``JAX_COMPILATION_CACHE_DIR`` and the cache's thresholds), which the
    processes this one starts inherit. ``JAX_PLATFORMS``, an ``XLA_FLAGS`` that names the
    fusion emitters and ``EQX_ON_ERROR`` already in the environment win.
    """
    if _configured:
        return _configured[0]
    late = _too_late()
    if late:
        warnings.warn(
            "dynslip._jaxconfig.configure_runtime() called after "
            + " and ".join(late) + " started: those settings apply to new processes only",
            RuntimeWarning, stacklevel=2,
        )

    # Equinox's runtime checks (eqx.error_if inside diffrax/lineax) are host callbacks by
    # default, and JAX never writes executables with host callbacks to the persistent cache:
    # the segment solve would be recompiled by every process. With "nan" a failed check poisons
    # the result instead, which the driver reports as a non-finite state (exit 3). Read when
    # equinox is imported, into ``equinox._errors.EQX_ON_ERROR`` (equinox/_config.py), which
    # its checks read when they are traced. ``import dynslip`` imports equinox, so every caller
    # of this function comes after that read: a mode the user did not choose is set there too.
    if "EQX_ON_ERROR" not in os.environ:
        os.environ["EQX_ON_ERROR"] = "nan"
        errors = sys.modules.get("equinox._errors")
        if errors is not None:
            errors.EQX_ON_ERROR = "nan"  # type: ignore[attr-defined]

    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {XLA_FLAG}".strip()

    platform = os.environ.get("JAX_PLATFORMS") or "cpu"
    os.environ["JAX_PLATFORMS"] = platform
    jax.config.update("jax_platforms", platform)

    cache = cache_dir()
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only home: run without the persistent cache
        jax.config.update("jax_compilation_cache_dir", None)
        os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
        _configured.append(None)
        return None
    settings = {
        "jax_compilation_cache_dir": str(cache),
        "jax_persistent_cache_min_compile_time_secs": CACHE_MIN_COMPILE_TIME_S,
        "jax_persistent_cache_min_entry_size_bytes": CACHE_MIN_ENTRY_SIZE_BYTES,
    }
    for name, value in settings.items():
        jax.config.update(name, value)
        os.environ[name.upper()] = str(value)
    _configured.append(cache)
    return cache
