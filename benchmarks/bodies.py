"""The cost of asking a body for the contact geometry (issue 21 phase 2), as ratios in one
process: one Newton iteration of load stepping (increment residual + Newton matrix + bordered
cyclic solve, :mod:`dynslip.physics.solver.newton`) at the end state of the frozen let-go path
(``benchmarks/method2_let_go.yaml``), for

- ``inline``: today's closed form before the change, ``1 - |q|`` and ``q/|q|`` (a body whose
  ``project`` is exactly that arithmetic: the baseline);
- ``sphere``: the ball as :class:`dynslip.physics.bodies.Sphere` (the default);
- ``sphere_torus``: the sphere and one held body, a torus rim the sheet lies on (frictionless);
- ``sphere_torus_friction``: the same rim with its own Coulomb friction (mu 0.5,
  :class:`dynslip.physics.bodies.held.Held`), the ball held (the stage's);
- ``sphere_torus_friction_free``: the same with the ball under force (its velocity then solves
  the held friction's scalar equation, and Newton's matrix carries the coupling).

``python benchmarks/run.py bodies`` (``DYNSLIP_BENCH_BODIES_NODES`` picks sizes, default
50,200). Times in ms per call, dispatch included; the ratios are the targets' measure (sphere
at most 1.1x inline, each added body at most 1.3x).
"""

import os
from pathlib import Path

from timing import ms_per_call  # benchmarks/timing.py (this folder runs as the script's)

SCENARIO = Path(__file__).resolve().parent / "method2_let_go.yaml"
REPEAT = 200
ROUNDS = 7


def _ms(f, *a) -> float:
    return ms_per_call(f, *a, repeat=REPEAT)


def _inline_ball():
    import equinox as eqx
    import jax.numpy as jnp

    from dynslip.physics.bodies import AbstractBody
    from dynslip.physics.bodies.segments import Projection

    class InlineBall(AbstractBody):
        """The unit ball by the arithmetic terms.contact_gap had before bodies."""

        segments: tuple = eqx.field(static=True, default=())

        def project(self, x, z=0.0):
            q = jnp.stack([x[..., 0], x[..., 1] - z], axis=-1)
            r = jnp.sqrt(q[..., 0] ** 2 + q[..., 1] ** 2)
            rs = jnp.where(r > 0, r, 1.0)
            n = q / rs[..., None]
            return Projection(
                distance=r - 1.0,
                normal=n,
                s=jnp.zeros_like(r),
                tangent=jnp.stack([n[..., 1], -n[..., 0]], axis=-1),
                curvature=1.0 / rs,  # the distance |q| - 1 has the Hessian t t^T / |q|
            )

    return InlineBall()


def _one(nodes: int) -> dict:
    import dataclasses

    import jax
    import jax.numpy as jnp

    from dynslip.app.forming import build_core
    from dynslip.physics.bodies import Sphere, Torus
    from dynslip.physics.bodies.held import Held
    from dynslip.physics.driver.member import MemberRun
    from dynslip.physics.driver.simulate import simulate
    from dynslip.physics.friction import Coulomb
    from dynslip.physics.solver import increment as ni
    from dynslip.physics.solver import newton_matrix as nm
    from dynslip.physics.solver.linalg import bordered_solve
    from dynslip.schema.base import load

    model, protocol, kw = build_core(load(SCENARIO, [f"numerics.nodes={nodes}"]))
    res = simulate(model, protocol, **kw)
    end = res.frames[-1]
    run = MemberRun(
        model,
        protocol,
        **kw,
        start={
            "rho": end["rho"],
            "z": end["z"],
            "zb": end["ball_z"],
            "slip_distance": end["slip_distance"],
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
    # a rim the end state's free span lies on: centred 0.1 R below the node at rbar ~ 0.6 of
    # the edge
    k = int(0.6 * (nodes - 1))
    rim = Torus(ring_radius=float(rho[k]), minor_radius=0.2, centre_z=float(z[k]) - 0.19)
    held = Held(rim, Coulomb(mu=jnp.asarray(0.5), eps=jnp.asarray(1e-3)))
    models = {
        "inline": (dataclasses.replace(model, ball=_inline_ball()), inc),
        "sphere": (dataclasses.replace(model, ball=Sphere()), inc),
        "sphere_torus": (dataclasses.replace(model, ball=Sphere(), bodies=(rim,)), inc),
        "sphere_torus_friction": (
            dataclasses.replace(model, ball=Sphere(), bodies=(held,)),
            dataclasses.replace(inc, args=dataclasses.replace(args, ball_mode=jnp.asarray(0))),
        ),
        "sphere_torus_friction_free": (
            dataclasses.replace(model, ball=Sphere(), bodies=(held,)),
            dataclasses.replace(inc, args=dataclasses.replace(args, ball_mode=jnp.asarray(1))),
        ),
    }
    out = {}
    calls = {}
    for name, (m, inc_m) in models.items():

        def iteration(inc, q, zb, m=m):
            r = ni.residual(m, fr, inc, q, zb)
            b = nm.newton_blocks(m, fr, inc, q, zb)
            return bordered_solve(*b, *r, "cyclic")

        calls[name] = (jax.jit(iteration), inc_m)
    # interleaved rounds, the fastest of each: a call of 0.1-0.5 ms timed over 200 repeats is
    # at the mercy of the other core's load; the minimum over rounds is the call's own cost
    for _ in range(ROUNDS):
        for name, (f, inc_m) in calls.items():
            ms = _ms(f, inc_m, q, zb)
            key = f"{name}_iteration_ms"
            out[key] = min(out.get(key, ms), ms)
    out["ratio_sphere_vs_inline"] = out["sphere_iteration_ms"] / out["inline_iteration_ms"]
    out["ratio_one_body_vs_sphere"] = out["sphere_torus_iteration_ms"] / out["sphere_iteration_ms"]
    out["ratio_frictional_body_vs_sphere"] = (
        out["sphere_torus_friction_iteration_ms"] / out["sphere_iteration_ms"]
    )
    out["ratio_frictional_body_free_ball_vs_sphere"] = (
        out["sphere_torus_friction_free_iteration_ms"] / out["sphere_iteration_ms"]
    )
    return out


def run() -> dict:
    import dynslip  # noqa: F401  (x64, compilation cache)

    sizes = [int(v) for v in os.environ.get("DYNSLIP_BENCH_BODIES_NODES", "50,200").split(",") if v]
    return {f"N{n}": _one(n) for n in sizes}
