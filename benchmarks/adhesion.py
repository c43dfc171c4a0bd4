"""Benchmark of the adhesive contact law against today's on the main job: time per increment of
``scenarios/method2.yaml`` (slip weakening), of the same file with ``law: adhesive`` at zero
adhesion (the same path, so the same increments: the law's own overhead), and of
``scenarios/method2_adhesive.yaml`` (its own path), in one process, interleaved ``repeats``
times (``DYNSLIP_BENCH_ADHESION_REPEATS``, default 2; the first run of each compiles, its
compile timed apart); the least time per increment of each is kept (the machine is shared).

``python benchmarks/adhesion.py`` (``DYNSLIP_BENCH_ADHESION_NODES``: N, default 150, the main
job's). The target (docs/adhesion.md): at most 1.2 times today's time per increment.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _scenario(name: str, nodes: int, sets=()):
    from dynslip.schema.base import load_data, validate_data

    path = ROOT / "scenarios" / name
    return validate_data(load_data(path, [f"numerics.nodes={nodes}", *sets]), str(path))


def run_one(sc) -> dict:
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    model, protocol, kw = build_core(sc)
    t0 = time.perf_counter()
    res = simulate(model, protocol, **kw)
    wall = time.perf_counter() - t0
    st = res.stats
    return {"ok": res.failed is None, "steps": st["steps"], "rejected": st["rejected"],
            "time_per_step_ms": st["time_per_step_ms"], "compile_s": st["compile_s"],
            "run_s": st["run_s"], "wall_s": wall}


def run() -> dict:
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    nodes = int(os.environ.get("DYNSLIP_BENCH_ADHESION_NODES", "150"))
    zero = ["physics.friction.law=adhesive"]
    cases = {"today": ("method2.yaml", ()), "adhesive_zero": ("method2.yaml", zero),
             "adhesive": ("method2_adhesive.yaml", ())}
    repeats = int(os.environ.get("DYNSLIP_BENCH_ADHESION_REPEATS", "2"))
    out: dict = {"nodes": nodes, "repeats": repeats}
    for _ in range(repeats):
        for key, (name, sets) in cases.items():
            one = run_one(_scenario(name, nodes, sets))
            if key not in out or one["time_per_step_ms"] < out[key]["time_per_step_ms"]:
                out[key] = one
    base = out["today"]["time_per_step_ms"]
    for key in ("adhesive_zero", "adhesive"):
        out[key]["ratio_per_increment"] = out[key]["time_per_step_ms"] / base
    return out


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
