"""The cost of two-pass contact (:mod:`dynslip.physics.bodies.corners`) per Newton iteration of
the main job: ``scenarios/method2.yaml`` with the paper's 3 mm tube wall (its rim a corner:
radius 0.075 R) at N = 150 (``DYNSLIP_BENCH_CORNERS_NODES`` picks sizes). The path is run
once; at its end state (the sheet over the rim, the tube placed at its height) the parts of
one Newton iteration (the increment's residual, the Newton matrix, the bordered solve) are
timed with the corners, then without them (``CORNER_RADIUS`` set to 0: the node-only contact
of before), in this process, the fastest of 3 rounds each, interleaved. The issue's target:
the contact costs at most 1.5 times the node-only contact's per increment (issue 56).
``python benchmarks/run.py corners``.
"""

from __future__ import annotations

import os
from pathlib import Path

from timing import ms_per_call  # benchmarks/timing.py (this folder runs as the script's)

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "method2.yaml"
REPEAT = 200
TARGET = 1.5


def _ms(f, *a) -> float:
    return ms_per_call(f, *a, repeat=REPEAT)


def _one(nodes: int) -> dict:
    import jax
    import jax.numpy as jnp
    import numpy as np

    from dynslip.app.forming import build_core
    from dynslip.physics.bodies import corners
    from dynslip.physics.bodies.held import held_entries, place_bodies
    from dynslip.physics.driver.member import MemberRun
    from dynslip.physics.driver.simulate import simulate
    from dynslip.physics.solver import increment as ni
    from dynslip.physics.solver import newton_matrix as nm
    from dynslip.physics.solver.linalg import bordered_solve
    from dynslip.schema.base import load

    model, protocol, kw = build_core(load(SCENARIO, [f"numerics.nodes={nodes}",
                                                     "physics.tube.wall_mm=3.0"]))
    res = simulate(model, protocol, **kw)
    last = res.frames[-1]
    run = MemberRun(model, protocol, **kw, start={
        "rho": last["rho"], "z": last["z"], "zb": last["ball_z"],
        "slip_distance": last["slip_distance"]})
    layout, args = run.layout, run.args
    k = len(model.bodies)
    placed = place_bodies(model, np.asarray(last["body_z"], float), np.zeros(k), 0.0, 0.0)
    rho, z, zb, _ = layout.unpack(run.y)
    q = jnp.stack([rho, z - zb], 1)
    inc = ni.Increment(q0=q, zb0=zb, delta0=layout.internal(run.y), t1=jnp.asarray(1.0),
                       h=jnp.asarray(1.0), args=args,
                       held_delta0=layout.held_internal(run.y))
    fr = args.friction

    def parts():
        residual = jax.jit(lambda inc, q, zb: ni.residual(placed, fr, inc, q, zb))
        blocks = jax.jit(lambda inc, q, zb: nm.newton_blocks(placed, fr, inc, q, zb))
        solve = jax.jit(lambda b, r1, r2: bordered_solve(*b, r1, r2, "cyclic"))
        b, r = blocks(inc, q, zb), residual(inc, q, zb)
        return (lambda: _ms(residual, inc, q, zb), lambda: _ms(blocks, inc, q, zb),
                lambda: _ms(solve, b, *r))

    n_corners = sum(corners.corners_of(e.body) is not None for e in held_entries(placed.bodies))
    with_c = parts()
    saved = corners.CORNER_RADIUS
    corners.CORNER_RADIUS = 0.0
    corners.corners_of.cache_clear()
    try:
        without = parts()
        rounds = [[sum(f() for f in p) for p in (with_c, without)] for _ in range(3)]
    finally:
        corners.CORNER_RADIUS = saved
        corners.corners_of.cache_clear()
    t_with = min(r[0] for r in rounds)
    t_without = min(r[1] for r in rounds)
    ratio = t_with / t_without
    return {
        "held_bodies_with_corners": int(n_corners),
        "iteration_ms_two_pass": t_with,
        "iteration_ms_node_only": t_without,
        "ratio": ratio,
        "target": TARGET,
        "met": bool(ratio <= TARGET),
        "path_steps": int(res.stats["steps"]) if "steps" in res.stats else None,
        "path_run_s": res.stats["run_s"],
    }


def run() -> dict:
    import dynslip  # noqa: F401  (x64)
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()
    sizes = [int(v) for v in os.environ.get("DYNSLIP_BENCH_CORNERS_NODES", "150").split(",")
             if v]
    return {f"N{n}": _one(n) for n in sizes}


if __name__ == "__main__":
    import json

    print(json.dumps(run(), indent=2))
