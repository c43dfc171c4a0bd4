"""JAX set-up shared by every entry point: float64, a persistent compilation cache, and XLA's
CPU fusion emitters off (compiles a quarter shorter).

The cache lives in ``$DYNSLIP_CACHE_DIR`` (default ``~/.cache/dynslip/jax``), so a
second run with the same shapes skips XLA compilation (tracing and lowering still cost:
they are what the cache cannot save).
"""

import os
from pathlib import Path

# Equinox's runtime checks (eqx.error_if inside diffrax/lineax) are host callbacks by
# default, and JAX never writes executables with host callbacks to the persistent cache:
# the segment solve was recompiled by every process. With "nan" a failed check poisons
# the result instead, which the driver reports as a non-finite state (exit 3). Set before
# equinox is imported; an explicit EQX_ON_ERROR in the environment wins.
os.environ.setdefault("EQX_ON_ERROR", "nan")

# XLA's CPU fusion emitters off for every program compiled in the process: dynslip's programs
# are small and their compiles dominate, about a quarter shorter without the emitters (the
# static model's figure 4 cold 30.7 / 33.2 -> 26.7 / 28.2 s, the tests' quick loop 618-677 ->
# 529 s; docs/speed.md, "2026-12-06"), the answers the same to rounding. The segment step of a
# mesh of more than 200 nodes, whose run they shorten, asks for them
# (dynslip.physics.simulate.compile_step). Read when JAX starts its backend; an XLA_FLAGS that
# names the option wins. The pinned jaxlib knows it (constraints.txt); one that did not would
# refuse to start, and this is the line to change.
if "xla_cpu_use_fusion_emitters" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + " --xla_cpu_use_fusion_emitters=false"
    ).strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_platforms", os.environ.get("JAX_PLATFORMS", "cpu") or "cpu")

_cache = Path(os.environ.get("DYNSLIP_CACHE_DIR", Path.home() / ".cache" / "dynslip" / "jax"))
try:
    _cache.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(_cache))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
except OSError:  # read-only home: run without the persistent cache
    pass
