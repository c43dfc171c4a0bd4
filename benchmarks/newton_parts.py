"""The parts of one Newton iteration of load stepping (:mod:`dynslip.physics.newton`), each jitted
alone: one increment residual, the Newton matrix from element and node derivatives, and the
bordered solve by block cyclic reduction and by block Thomas; at the end state of the frozen
let-go path (``benchmarks/method2_let_go.yaml``) for N = 50, 200, 800
(``DYNSLIP_BENCH_PARTS_NODES`` picks sizes). Times in ms per call, dispatch included (inside
the compiled Newton loop they cost somewhat less). ``python benchmarks/run.py newton_parts``.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

SCENARIO = Path(__file__).resolve().parent / "method2_let_go.yaml"
REPEAT = 300


def _ms(f, *a) -> float:
    import jax

    jax.block_until_ready(f(*a))
    t = time.perf_counter()
    for _ in range(REPEAT):
        out = f(*a)
    jax.block_until_ready(out)
    return 1e3 * (time.perf_counter() - t) / REPEAT


def _one(nodes: int) -> dict:
    import jax
    import jax.numpy as jnp

    from dynslip.app.forming import build_core
    from dynslip.physics import newton as nw
    from dynslip.physics.linalg import bordered_solve
    from dynslip.physics.simulate import MemberRun, simulate
    from dynslip.schema.base import load

    model, protocol, kw = build_core(load(SCENARIO, [f"numerics.nodes={nodes}"]))
    res = simulate(model, protocol, **kw)
    run = MemberRun(
        model,
        protocol,
        **kw,
        start={
            "rho": res.frames[-1]["rho"],
            "z": res.frames[-1]["z"],
            "zb": res.frames[-1]["ball_z"],
            "slip_distance": res.frames[-1]["slip_distance"],
        },
    )
    layout, args = run.layout, run.args
    rho, z, zb, _ = layout.unpack(run.y)
    q = jnp.stack([rho, z - zb], 1)
    inc = nw.Increment(
        q0=q,
        zb0=zb,
        delta0=layout.internal(run.y),
        t1=jnp.asarray(1.0),
        h=jnp.asarray(1.0),
        args=args,
    )
    fr = args.friction
    residual = jax.jit(lambda inc, q, zb: nw.residual(model, fr, inc, q, zb))
    blocks = jax.jit(lambda inc, q, zb: nw.newton_blocks(model, fr, inc, q, zb))
    cyclic = jax.jit(lambda b, r1, r2: bordered_solve(*b, r1, r2, "cyclic"))
    thomas = jax.jit(lambda b, r1, r2: bordered_solve(*b, r1, r2, "thomas"))
    b, r = blocks(inc, q, zb), residual(inc, q, zb)
    return {
        "residual_ms": _ms(residual, inc, q, zb),
        "newton_matrix_ms": _ms(blocks, inc, q, zb),
        "solve_cyclic_ms": _ms(cyclic, b, *r),
        "solve_thomas_ms": _ms(thomas, b, *r),
        "path_run_s": res.stats["run_s"],
        "path_newton_iterations": res.stats["newton_iterations"],
    }


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [
        int(v) for v in os.environ.get("DYNSLIP_BENCH_PARTS_NODES", "50,200,800").split(",") if v
    ]
    return {f"N{n}": _one(n) for n in sizes}
