"""Speed at scale: dynslip's structured solver against the dense diffrax path and scipy BDF.

Same vector field (method 2's push-down stage, the sheet stretching and slipping over
the held ball), same tolerances (rtol 1e-5, atol 1e-7), same simulated interval, at
N = 100, 200, 400, 800 nodes:

- ``structured``: diffrax Kvaerno5, VeryChord with :class:`dynslip.physics.linalg.BorderedBlockTridiagonal`
  (Jacobian from 6 coloured jvps + border, block Thomas + Schur complement);
- ``dense``: diffrax Kvaerno5 with its default dense Jacobian and LU; above
  ``DENSE_FULL_MAX`` nodes only the first ``DENSE_STEPS`` steps are timed (time per step);
- ``scipy_bdf``: ``scipy.integrate.solve_ivp(method="BDF")`` with ``jac_sparsity`` (the
  same block pattern), calling the jitted vector field.

``DYNSLIP_BENCH_SPEED_NODES=100,200`` picks sizes, ``DYNSLIP_BENCH_SPEED_T=2`` the
simulated seconds. Reported: steps, rejected steps, time per step, wall time, compile
time, and ratios against scipy in the same process.
"""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path

DENSE_FULL_MAX = 200
DENSE_STEPS = 500


def _setup(nodes: int):
    from dynslip.app.forming import build_core
    from dynslip.schema.base import load
    from dynslip.physics.simulate import Layout, _stage_args, initial_state

    # the ideal law: the vector field the speed issue was posed on (the shipped static/kinetic
    # law adds one state per node to the same block structure)
    law = os.environ.get("DYNSLIP_BENCH_SPEED_LAW", "coulomb")
    sc = load(Path(__file__).resolve().parents[1] / "scenarios" / "method2_let_go.yaml",
              [f"numerics.nodes={nodes}", f"physics.friction.law={law}"])
    model, protocol, kw = build_core(sc)
    layout = Layout(nodes, kw["friction"].n_internal())
    stage = protocol.stages[0]
    args = _stage_args(stage, 0.0, float(protocol.ball_z0), 0.0, 0.0, kw["friction"], kw["eps"], kw["drag"],
                       kw["ball_drag"], kw["weight"])
    y0 = initial_state(model, layout, kw["pre_stretch"], kw["z_sheet"], protocol.ball_z0)
    return model, layout, args, y0, kw["settings"]


def _diffrax(nodes: int, linear_solver: str, t1: float, max_steps: int) -> dict:
    import jax.numpy as jnp

    from dynslip.physics.simulate import segment_solver

    model, layout, args, y0, settings = _setup(nodes)
    settings = dataclasses.replace(settings, linear_solver=linear_solver, max_steps=max_steps)
    solve = segment_solver(settings)
    f = jnp.asarray
    call = (model, layout, y0, f(0.0), f(t1), f(1e-3), args, f(settings.rtol), f(settings.atol))
    c0 = time.perf_counter()
    compiled = solve.lower(*call).compile()
    compile_s = time.perf_counter() - c0
    r0 = time.perf_counter()
    y1, ok, steps, acc, rej = compiled(*call)
    y1.block_until_ready()
    run_s = time.perf_counter() - r0
    steps = int(steps)
    return {"ok": bool(ok), "steps": steps, "rejected": int(rej), "compile_s": compile_s, "run_s": run_s,
            "time_per_step_ms": 1e3 * run_s / max(steps, 1), "complete": steps < max_steps}


def _scipy(nodes: int, t1: float) -> dict:
    import jax
    import numpy as np
    import scipy.sparse as sp
    from scipy.integrate import solve_ivp

    from dynslip.physics.linalg import to_dense
    from dynslip.physics.simulate import sheet_structure, vector_field

    model, layout, args, y0, settings = _setup(nodes)
    vf = jax.jit(vector_field(model, layout))
    s = sheet_structure(layout)
    n, b, m = s.n, s.b, s.m
    ones = np.ones((n, b, b))
    pattern = np.asarray(to_dense(ones, ones, ones, np.ones((n * b, m)), np.ones((m, n * b)), np.ones((m, m)), s))
    c0 = time.perf_counter()
    vf(0.0, y0, args).block_until_ready()
    compile_s = time.perf_counter() - c0
    calls = [0]

    def fun(t, y):
        calls[0] += 1
        return np.asarray(vf(t, y, args))

    r0 = time.perf_counter()
    sol = solve_ivp(fun, (0.0, t1), np.asarray(y0), method="BDF", rtol=settings.rtol, atol=settings.atol,
                    jac_sparsity=sp.csr_matrix(pattern != 0))
    run_s = time.perf_counter() - r0
    steps = int(sol.t.size - 1)
    return {"ok": bool(sol.success), "steps": steps, "rhs_calls": calls[0], "jacobians": int(sol.njev),
            "lu": int(sol.nlu), "compile_s": compile_s, "run_s": run_s,
            "time_per_step_ms": 1e3 * run_s / max(steps, 1)}


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [int(v) for v in os.environ.get("DYNSLIP_BENCH_SPEED_NODES", "100,200,400,800").split(",") if v]
    t1 = float(os.environ.get("DYNSLIP_BENCH_SPEED_T", "2.0"))
    out: dict = {"segment": f"method 2 push-down, first {t1} s", "tolerances": "rtol 1e-5, atol 1e-7"}
    for n in sizes:
        row = {"structured": _diffrax(n, "structured", t1, 100000)}
        dense_steps = 100000 if n <= DENSE_FULL_MAX else DENSE_STEPS
        row["dense"] = _diffrax(n, "dense", t1, dense_steps)
        try:
            row["scipy_bdf"] = _scipy(n, t1)
        except (RuntimeError, ValueError, FloatingPointError) as err:  # a baseline that fails is reported
            row["scipy_bdf"] = {"ok": False, "error": f"{type(err).__name__}: {err}", "run_s": float("nan")}
        st, de, sc = row["structured"], row["dense"], row["scipy_bdf"]
        row["speedup_vs_scipy_wall"] = sc["run_s"] / st["run_s"]
        row["speedup_vs_dense_per_step"] = de["time_per_step_ms"] / st["time_per_step_ms"]
        out[f"N{n}"] = row
        print(f"speed N={n}: {row}", flush=True)
    if len(sizes) > 1:
        a, b = out[f"N{sizes[0]}"], out[f"N{sizes[-1]}"]
        out["structured_per_step_growth"] = (b["structured"]["time_per_step_ms"]
                                             / a["structured"]["time_per_step_ms"])
        out["nodes_growth"] = sizes[-1] / sizes[0]
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
