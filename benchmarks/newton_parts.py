"""The parts of one Newton iteration of load stepping (:mod:`dynslip.physics.solver.newton`), each
jitted
alone: one increment residual, the Newton matrix from element and node derivatives, and the
bordered solve by block cyclic reduction (against the same reduction with ``jnp.linalg.solve``
and batched ``@`` on the 2x2 blocks, as it was before
:func:`dynslip.physics.solver.linalg.small_matmul`:
the ratio in one process) and by block Thomas; at the end state of the frozen
let-go path (``benchmarks/method2_let_go.yaml``) for N = 50, 200, 800
(``DYNSLIP_BENCH_PARTS_NODES`` picks sizes). Times in ms per call, dispatch included (inside
the compiled Newton loop they cost somewhat less). ``python benchmarks/run.py newton_parts``.
"""

from __future__ import annotations

import os
from pathlib import Path

from timing import ms_per_call  # benchmarks/timing.py (this folder runs as the script's)

SCENARIO = Path(__file__).resolve().parent / "method2_let_go.yaml"
REPEAT = 300


def _ms(f, *a) -> float:
    return ms_per_call(f, *a, repeat=REPEAT)


def _generic_cyclic(lower, diag, upper, f):
    """The block cyclic reduction as it was before the blocks' products were written out
    (``jnp.linalg.solve`` and batched ``@`` on the 2x2 blocks): the baseline of the solve's
    ratio, in this process."""
    import jax.numpy as jnp

    n, b = diag.shape[0], diag.shape[1]
    lower, upper = lower.at[0].set(0.0), upper.at[-1].set(0.0)
    if n == 1:
        return jnp.linalg.solve(diag[0], f[0])[None]
    if n % 2:
        eye = jnp.eye(b, dtype=diag.dtype)[None]
        lower = jnp.concatenate([lower, jnp.zeros_like(lower[:1])])
        upper = jnp.concatenate([upper, jnp.zeros_like(upper[:1])])
        diag, f = jnp.concatenate([diag, eye]), jnp.concatenate([f, jnp.zeros_like(f[:1])])
    le, de, ue, fe = lower[0::2], diag[0::2], upper[0::2], f[0::2]
    lo, do, uo, fo = lower[1::2], diag[1::2], upper[1::2], f[1::2]
    sol = jnp.linalg.solve(do, jnp.concatenate([lo, uo, fo], axis=-1))
    il, iu, if_ = sol[..., :b], sol[..., b : 2 * b], sol[..., 2 * b :]

    def prev(a):
        return jnp.concatenate([jnp.zeros_like(a[:1]), a[:-1]])

    il_p, iu_p, if_p = prev(il), prev(iu), prev(if_)
    xe = _generic_cyclic(-le @ il_p, de - le @ iu_p - ue @ il, -ue @ iu,
                         fe - le @ if_p - ue @ if_)
    xe_next = jnp.concatenate([xe[1:], jnp.zeros_like(xe[:1])])
    xo = if_ - il @ xe - iu @ xe_next
    return jnp.stack([xe, xo], axis=1).reshape((-1,) + xe.shape[1:])[:n]


def _generic_bordered(lower, diag, upper, B, C, D, f, g):
    import jax.numpy as jnp

    n, b = f.shape
    sol = _generic_cyclic(lower, diag, upper, jnp.concatenate([f[:, :, None], B], axis=-1))
    ainv_f, ainv_b = sol[:, :, 0], sol[:, :, 1:]
    cflat = C.reshape(1, n * b)
    schur = D - cflat @ ainv_b.reshape(n * b, 1)
    y = jnp.linalg.solve(schur, jnp.reshape(g, (1,)) - cflat @ ainv_f.reshape(n * b))
    return ainv_f - ainv_b @ y, jnp.reshape(y, jnp.shape(g))


def _one(nodes: int) -> dict:
    import jax
    import jax.numpy as jnp

    from dynslip.app.forming import build_core
    from dynslip.physics.driver.member import MemberRun
    from dynslip.physics.driver.simulate import simulate
    from dynslip.physics.solver import increment as ni
    from dynslip.physics.solver import newton_matrix as nm
    from dynslip.physics.solver.linalg import bordered_solve
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
    inc = ni.Increment(
        q0=q,
        zb0=zb,
        delta0=layout.internal(run.y),
        t1=jnp.asarray(1.0),
        h=jnp.asarray(1.0),
        args=args,
    )
    fr = args.friction
    residual = jax.jit(lambda inc, q, zb: ni.residual(model, fr, inc, q, zb))
    blocks = jax.jit(lambda inc, q, zb: nm.newton_blocks(model, fr, inc, q, zb))
    cyclic = jax.jit(lambda b, r1, r2: bordered_solve(*b, r1, r2, "cyclic"))
    thomas = jax.jit(lambda b, r1, r2: bordered_solve(*b, r1, r2, "thomas"))
    generic = jax.jit(lambda b, r1, r2: _generic_bordered(*b, r1, r2))
    b, r = blocks(inc, q, zb), residual(inc, q, zb)
    agree = float(jnp.max(jnp.abs(cyclic(b, *r)[0] - generic(b, *r)[0])))
    # the fastest of 3 rounds each, interleaved (single timings move by 10-20% on this machine)
    t_cyc = min(_ms(cyclic, b, *r) for _ in range(3))
    t_gen = min(_ms(generic, b, *r) for _ in range(3))
    return {
        "residual_ms": _ms(residual, inc, q, zb),
        "newton_matrix_ms": _ms(blocks, inc, q, zb),
        "solve_cyclic_ms": t_cyc,
        "solve_cyclic_generic_ms": t_gen,
        "solve_speedup_vs_generic": t_gen / t_cyc,
        "solve_max_abs_difference_vs_generic": agree,
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
