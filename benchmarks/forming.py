"""Benchmark of the whole-sheet forming simulator: steps, rejected steps, time per step and
compile time at N = 50, 100, 200, with the scenario's solver (load stepping by default, the
structured linear solver; the prototype's Kvaerno5 took 26 ms per step at N = 200 and
10k-19k steps per path). ``benchmarks/speed.py`` compares the solvers on one path.

``run()`` times the let-go method 2 scenario (``scenarios/method2_let_go.yaml``) on a shortened
path (the push-down to
-80 mm and a 10 s hold: the part of the path where the sheet stretches and slips) at each
N; ``DYNSLIP_BENCH_FORMING_NODES=50,100`` picks the sizes and
``DYNSLIP_BENCH_FORMING_FULL=1`` runs the whole default path instead.
Compile time is the ahead-of-time lowering and compilation of the segment solve (cold
unless the persistent cache already holds it: ``compile_cache`` says which).
"""

from __future__ import annotations

import os
import time


def _scenario(nodes: int, full: bool):
    from pathlib import Path

    from dynslip.schema.base import load_data, validate_data

    path = Path(__file__).resolve().parents[1] / "scenarios" / "method2_let_go.yaml"
    data = load_data(path, [f"numerics.nodes={nodes}"])
    if not full:
        data["physics"]["stages"] = [
            {"name": "push_down", "clamp_to_z_mm": -80.0, "clamp_speed_mm_s": 2.0},
            {"name": "hold", "duration_s": 10.0},
        ]
    return validate_data(data, str(path))


def run_one(nodes: int, full: bool = False) -> dict:
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    sc = _scenario(nodes, full)
    model, protocol, kw = build_core(sc)
    t0 = time.perf_counter()
    res = simulate(model, protocol, **kw)
    wall = time.perf_counter() - t0
    st = res.stats
    return {
        "ok": res.failed is None,
        "steps": st["steps"],
        "rejected": st["rejected"],
        "rejected_fraction": st["rejected"] / max(st["steps"], 1),
        "time_per_step_ms": st["time_per_step_ms"],
        "compile_s": st["compile_s"],
        "compile_cache": "warm" if st["compile_s"] < 5.0 else "cold",
        "run_s": st["run_s"],
        "wall_s": wall,
        "simulated_s": res.frames[-1]["time"],
    }


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [
        int(s) for s in os.environ.get("DYNSLIP_BENCH_FORMING_NODES", "50,100,200").split(",") if s
    ]
    full = os.environ.get("DYNSLIP_BENCH_FORMING_FULL", "0") == "1"
    out = {
        "path": "method2 (full)" if full else "method2 push-down to -80 mm + 10 s hold",
        "solver": "kvaerno5, dense LU",
        "prototype_ms_per_step_N200": 26.0,
    }
    for n in sizes:
        out[f"N{n}"] = run_one(n, full)
    return out


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    import json

    print(json.dumps(run(), indent=2))
