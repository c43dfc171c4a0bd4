"""The benchmarks' shared clock: milliseconds per call of a compiled function, warm."""

from __future__ import annotations

import time


def ms_per_call(f, *a, repeat: int = 200) -> float:
    """Mean wall time of ``f(*a)`` over ``repeat`` calls (ms), after one call that compiles and
    warms it; each timed run waits for the device (``block_until_ready``)."""
    import jax

    jax.block_until_ready(f(*a))
    t = time.perf_counter()
    for _ in range(repeat):
        out = f(*a)
    jax.block_until_ready(out)
    return 1e3 * (time.perf_counter() - t) / repeat
