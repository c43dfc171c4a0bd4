"""JAX set-up shared by every entry point: float64 and a persistent compilation cache.

The cache lives in ``$DYNSLIP_CACHE_DIR`` (default ``~/.cache/dynslip/jax``), so a
second run with the same shapes skips XLA compilation (tracing still costs).
"""

import os
from pathlib import Path

import jax

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
