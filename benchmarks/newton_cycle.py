"""Diagnosis of load stepping's step growth with N (docs/speed.md, "Why the steps grow with N").

Two measurements on the frozen let-go path (``benchmarks/method2_let_go.yaml``):

``python benchmarks/newton_cycle.py stages N [dotted=value ...]``
    the whole path at N nodes, steps / rejected / Newton iterations per stage (the
    driver's per-segment solve outputs, summed by stage).

``python benchmarks/newton_cycle.py increment N T DT [LIMIT]``
    one load increment of DT seconds from the push-down's state at time T (a save time),
    solved by dense Newton from k = 0 (diffrax's implicit relation
    ``k - DT f(t + DT, y + k)``, the Jacobian by ``jax.jacfwd``): per iteration the max
    residual, the
    largest nodal update and where it is, and which nodes changed contact or stick/slip.
    ``LIMIT`` (R) scales each update so that no nodal coordinate moves by more than
    ``max(LIMIT, max |k|)`` (the trust bound tried in docs/speed.md); none by default.

A diagnostic, not a benchmark: it prints and writes nothing.
"""

from __future__ import annotations

import sys
from collections import defaultdict

import jax
import jax.numpy as jnp
import numpy as np

import dynslip
from dynslip.physics.driver.member import MemberRun
from dynslip.physics.field import evaluate, vector_field

PATH = "benchmarks/method2_let_go.yaml"
TOP_MM = 20.4  # the clamp's start height (ball radius + sheet gap)
SPEED_MM_S = 2.0  # the push-down's clamp speed


def _capture(hook):
    """Run ``hook(run, seg, out)`` on every save segment the driver solves."""
    orig = MemberRun.advance

    def advance(self, seg, out, run_s):
        hook(self, seg, out)
        return orig(self, seg, out, run_s)

    MemberRun.advance = advance


def _value(v: str):
    try:
        return float(v)
    except ValueError:
        return v


def stages(n: int, sets: list[str]) -> None:
    per = defaultdict(
        lambda: np.zeros(4, int)
    )  # stage -> steps, rejected, Newton iterations, segments

    def count(run, seg, out):
        per[run.stage.name] += [int(out.steps), int(out.rejected), int(out.newton_iterations), 1]

    _capture(count)
    values = {"numerics.nodes": n} | {k: _value(v) for k, v in (a.split("=", 1) for a in sets)}
    res = dynslip.run(dynslip.load(PATH, set=values))
    for name, (steps, rej, newton, segs) in per.items():
        print(
            f"N={n} {name:10s} steps {steps:6d} rejected {rej:5d} newton {newton:6d} segments "
            f"{segs}"
        )
    print(
        f"N={n} total steps {sum(int(v[0]) for v in per.values())}, trapped "
        f"{res.summary['trapped']}"
    )


def _component(i: int, n: int) -> str:
    """The name of state component ``i`` (field.Layout's order)."""
    if i < n - 1:
        return f"rho node {i + 1}"
    if i < 2 * n - 1:
        return f"z node {i - (n - 1)}"
    if i == 2 * n - 1:
        return "ball z"
    if i < 2 * n + 4:
        return f"energy accumulator {i - 2 * n}"
    return f"slip distance node {i - 2 * n - 4}"


def increment(n: int, t: float, dt: float, limit: float | None) -> None:
    box = {}
    _capture(lambda run, seg, out: box.update(run=run, seg=seg) if abs(seg.t0 - t) < 1e-6 else None)
    # the push-down ends 4 s after t: the run stops soon after the captured state
    dynslip.run(
        dynslip.load(
            PATH,
            set={
                "numerics.nodes": n,
                "physics.stages.0.clamp_to_z_mm": TOP_MM - SPEED_MM_S * (t + 4),
            },
        )
    )
    run, seg = box["run"], box["seg"]
    model, lay, y0, args = run.model, run.layout, seg.y, seg.args
    vf = vector_field(model, lay)
    t1 = seg.t0 + dt

    def residual(k):
        return k - dt * vf(t1, y0 + k, args)

    res_fn, jac_fn = jax.jit(residual), jax.jit(jax.jacfwd(residual))

    def status(y):
        kin = evaluate(model, lay, t1, y, args)[1].kin
        return np.asarray(kin.normal > 0), np.asarray(kin.slip != 0)

    mech = 2 * n - 1  # rho_1..rho_{n-1}, z_0..z_{n-1}
    k = jnp.zeros_like(y0)
    prev = None
    for it in range(40):
        r = res_fn(k)
        dk = -jnp.linalg.solve(jac_fn(k), r)
        contact, slip = status(y0 + k)
        i = int(jnp.argmax(jnp.abs(dk[:mech])))
        where = _component(i, n)
        line = (
            f"{it:2d} max|r| {float(jnp.max(jnp.abs(r))):.2e} at "
            f"{_component(int(jnp.argmax(jnp.abs(r))), n)};"
            f" nodal max|r| {float(jnp.max(jnp.abs(r[:mech]))):.2e}; max nodal |dk| "
            f"{float(jnp.max(jnp.abs(dk[:mech]))):.2e}"
            f" at {where}; {int(contact.sum())} in contact, {int(slip.sum())} slipping"
        )
        if prev is not None:
            line += (
                f"; contact changed {np.nonzero(contact != prev[0])[0].tolist()},"
                f" stick/slip changed {np.nonzero(slip != prev[1])[0].tolist()}"
            )
        print(line)
        if float(jnp.max(jnp.abs(r))) < 1e-9:
            print(f"converged in {it} iterations")
            return
        prev = (contact, slip)
        scale = 1.0
        if limit is not None:
            bound = max(limit, float(jnp.max(jnp.abs(k[:mech]))))
            scale = min(1.0, bound / float(jnp.max(jnp.abs(dk[:mech]))))
        k = k + scale * dk
    print("not converged in 40 iterations")


if __name__ == "__main__":
    from dynslip._jaxconfig import configure_runtime

    configure_runtime()  # the command line's platform, flags and compilation cache
    what, rest = sys.argv[1], sys.argv[2:]
    if what == "stages":
        stages(int(rest[0]), rest[1:])
    elif what == "increment":
        increment(
            int(rest[0]), float(rest[1]), float(rest[2]), float(rest[3]) if len(rest) > 3 else None
        )
    else:
        raise SystemExit(
            "usage: newton_cycle.py stages N [dotted=value ...] | increment N T DT [LIMIT]"
        )
