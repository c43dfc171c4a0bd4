"""The host driver's share of a whole run: the frozen let-go path
(``benchmarks/method2_let_go.yaml``) run twice per N in one process
(``DYNSLIP_BENCH_DRIVER_NODES=50,200``), the second run warm (no compile): its wall time against
``run_s``, the time inside the compiled segment calls, measured in the same run. ``host_s =
wall_s - run_s`` is what the driver costs between the calls (stage set-up, inputs, transfers,
frames, stop rules); per save segment and as a share of the wall."""

from __future__ import annotations

import os
import time
from pathlib import Path

SCENARIO = Path(__file__).resolve().parent / "method2_let_go.yaml"


def _one(nodes: int) -> dict:
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate
    from dynslip.schema.base import load

    model, protocol, kw = build_core(load(SCENARIO, [f"numerics.nodes={nodes}"]))
    simulate(model, protocol, **kw)  # compiles
    w0 = time.perf_counter()
    res = simulate(model, protocol, **kw)
    wall = time.perf_counter() - w0
    st = res.stats
    host = wall - st["run_s"]
    return {
        "segments": st["segments"],
        "steps": st["steps"],
        "wall_s": wall,
        "run_s": st["run_s"],
        "host_s": host,
        "host_ms_per_segment": 1e3 * host / st["segments"],
        "host_share": host / wall,
    }


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [int(v) for v in os.environ.get("DYNSLIP_BENCH_DRIVER_NODES", "50,200").split(",") if v]
    return {f"N{n}": _one(n) for n in sizes}
