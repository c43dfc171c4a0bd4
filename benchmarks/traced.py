"""Traced parameters and sensitivities (issue 55, items 1 and 3), ratios measured in one
process or in child processes started the same way.

``python benchmarks/traced.py [sweep] [sens]`` (both by default), prints JSON:

- ``sweep``: an 8-value J_m sweep (``api.sweep`` over ``physics.material.jm``, sequential,
  the let-go path of ``scenarios/method2_let_go.yaml`` at ``DYNSLIP_BENCH_TRACED_NODES``
  nodes, default 20), each in a child process with an empty persistent compilation cache:
  once with this tree's code and once with the code at ``DYNSLIP_BENCH_TRACED_BEFORE``
  (default ``/work/main``, the code before the parameters were traced; skipped where it
  does not exist). Reports the segment step's compile count, the compile seconds and the
  sweep's wall time of each, and their ratios.
- ``sens``: :func:`dynslip.api.sensitivities`'s tangent run of the same path in one
  direction and in ``DYNSLIP_BENCH_TRACED_DIRS`` (default 3) directions at once, against a
  forward run, at ``DYNSLIP_BENCH_TRACED_SENS_NODES`` (default ``20,50``) nodes: the seconds
  of each, warm (the least of three, interleaved), the compile seconds, and the cost per
  direction over the forward run.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "method2_let_go.yaml"
JMS = [30.0, 35.0, 40.0, 45.0, 50.0, 60.0, 70.0, 80.0]


def _sweep_child(nodes: int) -> dict:
    """In a child: the J_m sweep, counting the segment step's compilations."""
    import yaml

    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    from dynslip import api
    from dynslip.physics.driver import simulate as sim

    calls = []
    real = sim.compile_step

    def counting(lowered, n):
        t0 = time.perf_counter()
        out = real(lowered, n)
        calls.append(time.perf_counter() - t0)
        return out

    sim.compile_step = counting
    with tempfile.TemporaryDirectory(prefix="dynslip-bench-traced-") as tmp:
        spec = {"base": str(SCENARIO), "overrides": {"numerics.nodes": nodes},
                "list": [{"physics.material.jm": j} for j in JMS]}
        path = Path(tmp) / "jm_sweep.yaml"
        path.write_text(yaml.safe_dump(spec))
        t0 = time.perf_counter()
        ds = api.sweep(path, mode="sequential")
        wall = time.perf_counter() - t0
    theta = [float(x) for x in ds["theta_max"].values] if "theta_max" in ds else []
    return {"compiles": len(calls), "compile_s": sum(calls), "wall_s": wall, "members": len(JMS),
            "theta_max": theta}


def sweep(nodes: int) -> dict:
    """The J_m sweep with this tree's code and with the code before (child processes)."""
    before = os.environ.get("DYNSLIP_BENCH_TRACED_BEFORE", "/work/main")
    trees = {"traced": str(ROOT)}
    if Path(before, "dynslip").is_dir():
        trees["before"] = before
    out: dict = {"nodes": nodes, "jm": JMS}
    for name, tree in trees.items():
        with tempfile.TemporaryDirectory(prefix="dynslip-bench-cache-") as cache:
            env = dict(os.environ, PYTHONPATH=tree, DYNSLIP_CACHE_DIR=cache)
            got = subprocess.run([sys.executable, __file__, "_sweep_child", str(nodes)], env=env,
                                 capture_output=True, text=True, check=True)
        out[name] = json.loads(got.stdout.strip().splitlines()[-1])
    if "before" in out:
        b, t = out["before"], out["traced"]
        out["compiles_ratio_before_over_traced"] = b["compiles"] / max(t["compiles"], 1)
        out["wall_ratio_before_over_traced"] = b["wall_s"] / t["wall_s"]
        out["compile_s_ratio_before_over_traced"] = b["compile_s"] / max(t["compile_s"], 1e-9)
    return out


def _best(fn, repeats: int = 3) -> float:
    """The least of ``repeats`` timed calls (the machine is shared: the least is the call
    that was slowed least)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def sens() -> dict:
    """Cost per direction of :func:`dynslip.api.sensitivities`'s tangent run (``check=False``;
    its ``tangent_s``, the run alone) against a forward run of the same path, both warm (each
    compiled first), the least of three, interleaved."""
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    from dynslip import api
    from dynslip.physics.driver.simulate import simulate

    dirs = int(os.environ.get("DYNSLIP_BENCH_TRACED_DIRS", "3"))
    params = ["physics.material.jm", "physics.friction.mu_s", "physics.friction.mu_k",
              "physics.friction.d_c_mm"][:dirs]
    out: dict = {"params": params}
    for nodes in (int(n) for n in
                  os.environ.get("DYNSLIP_BENCH_TRACED_SENS_NODES", "20,50").split(",")):
        scn = api.load(SCENARIO, set={"numerics.nodes": nodes})
        w = scn.world()

        def forward(w=w):
            return simulate(w.model, w.protocol, **w.simulate_kwargs())

        row: dict = {"steps": forward().stats["steps"]}
        cases = sorted({1, dirs})
        compile_s = {}
        for k in cases:  # compile each first
            compile_s[k] = api.sensitivities(scn, params[:k], check=False).stats["compile_s"]
        best = {c: float("inf") for c in cases}
        fwd = float("inf")
        for _ in range(3):
            fwd = min(fwd, _best(forward, 1))
            for k in cases:
                got = api.sensitivities(scn, params[:k], check=False)
                best[k] = min(best[k], got.stats["tangent_s"])
        row["forward_s"] = fwd
        for k, t in best.items():
            row[f"dirs_{k}"] = {"tangent_s": t, "compile_s": compile_s[k],
                                           "over_forward": t / fwd,
                                           "per_direction_over_forward": t / k / fwd}
        out[str(nodes)] = row
        print(json.dumps({nodes: row}), file=sys.stderr, flush=True)
    return out


def main(argv: list[str]) -> None:
    if argv[:1] == ["_sweep_child"]:
        print(json.dumps(_sweep_child(int(argv[1]))))
        return
    parts = argv or ["sweep", "sens"]
    res: dict = {"load_average_before": os.getloadavg()[0]}
    if "sweep" in parts:
        res["sweep"] = sweep(int(os.environ.get("DYNSLIP_BENCH_TRACED_NODES", "20")))
    if "sens" in parts:
        res["sens"] = sens()
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main(sys.argv[1:])
