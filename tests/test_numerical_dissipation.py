r"""Load stepping's energy balance with implicit Euler's numerical dissipation accounted.

The accumulators gain each increment's work and dissipation by the rectangle rule at its end
(:mod:`dynslip.physics.solver.newton`, :mod:`dynslip.physics.solver.loadstep`). On the
push-down path (the clamp moved, the ball held) the increment $x_0 \to x_1$ of implicit Euler
makes that exact in one sense: every node's drag law at $x_1$, $\eta A\,u = F_n n + S\,t$ with
$F = -\nabla E(x_1)$ and $u = \Delta x/h$, gives $F\cdot\Delta x = h\,(\eta A|u|^2 + (F_t -
S)\,S/(\eta A))$, the increment's drag and friction dissipation as accumulated, and the clamped
edge's $\nabla_{edge} E(x_1)\cdot\Delta x_{edge}$ is the clamp's work as accumulated (its force
at $x_1$ times its prescribed displacement; the ball's work is zero). So, to Newton's
tolerance,

$$W_k - D_k = \nabla E(x_1)\cdot\Delta x ,$$

with no quadrature error in the friction (its rectangle rule is the one the motion obeys) or
the clamp. The stored energy's change is the integral of $\nabla E$ along the segment, which
the trapezoid rule gives to third order: $\Delta E_k = \tfrac12(\nabla E(x_0) + \nabla
E(x_1))\cdot\Delta x + O(|\Delta x|^3)$. The balance's residual per increment is therefore

$$W_k - \Delta E_k - D_k = D_{num,k} + O(|\Delta x|^3),\qquad
  D_{num,k} = \tfrac12(\nabla E(x_1) - \nabla E(x_0))\cdot\Delta x
  = \tfrac12\Delta x^T \bar H \Delta x ,$$

implicit Euler's numerical dissipation, $\bar H$ the Hessian averaged along the segment.
Summed over the $T/h$ increments $D_{num}$ is first order in $h$ and what is left, $W - \Delta
E - D - D_{num}$, second order: the trapezoid rule's error, plus where a node crosses into
the contact penalty (pressure $C^1$, its slope jumps) an $O(|\Delta x|^2)$ term once per
node, still $O(h^2)$ over the path. The gradient is taken in every coordinate of the state
that moves ($\rho_{1..n-1}$, $z$, and $z_b$, whose change is zero here), by ``jax.grad``.

Measured on the push-down stage of test_forming (N = 24, mu = 0.8, as tests/test_loadstep.py)
in fixed increments h, one increment per segment, every segment checked to take exactly one.
"""


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.solver.loadstep import FullStateLoadStep
from dynslip.physics.solver.newton import zero_rate
from numerics import named_solver
from test_loadstep import MODEL, push_down_start

HS = np.array([0.1, 0.05, 0.025, 0.0125])  # s: the increments, 1 to 1/8 drag time
# Newton's tolerances: tight, so that its residual is far below the quadrature's error (the
# identity W_k - D_k = grad E(x_1) . dx holds to it). At the scenarios' default 1e-5, 1e-7 the
# identity's defect reached 6e-8 per increment and the accounted residual at h = 0.0125 s was
# 4.8e-7 of the work (3.4e-7 here), its fitted order 1.82
RTOL, ATOL = 1e-8, 1e-10


def _stored(layout):
    def energy(y):
        rho, z, zb, _ = layout.unpack(y)
        return MODEL.elastic_energy(rho, z) + MODEL.penalty_energy(rho, z, zb)

    return energy


class Path(eqx.Module):
    """The sums over the path's increments: work, stored energy's change, dissipation, the
    numerical dissipation D_num and the identity's defect |W_k - D_k - grad E(x_1) . dx|
    (its largest); the smallest D_num of one increment; the increments taken, those that took
    more than one (a cut-back) and whether every segment reached its end."""

    work: jax.Array
    stored: jax.Array
    dissipation: jax.Array
    numerical: jax.Array
    defect: jax.Array
    least: jax.Array
    count: jax.Array
    split: jax.Array
    ok: jax.Array


@eqx.filter_jit
def _path(solver, layout, y0, t1, h, args):
    """The push-down stage in segments of one increment h each (``solver.segment`` from t_k to
    t_k + h with dt0 = h: the segment's last increment is stretched to its end, so one accepted
    increment is exactly h), D_num and the identity accumulated increment by increment."""
    energy = _stored(layout)
    grad = jax.grad(energy)
    acc = layout.accumulators
    steps = jnp.round(t1 / h).astype(jnp.int32)
    zero = jnp.zeros(())

    def body(k, c):
        y, rate, s = c
        out = solver.segment(
            MODEL,
            layout,
            y,
            k * h,
            (k + 1) * h,
            h,
            args,
            jnp.asarray(RTOL),
            jnp.asarray(ATOL),
            rate,
        )
        y1 = out.y
        da = y1[acc] - y[acc]
        w, d = da[0] + da[1], da[2] + da[3]
        dy = (y1 - y).at[acc].set(0.0)
        g0, g1 = grad(y), grad(y1)
        dnum = 0.5 * jnp.dot(g1 - g0, dy)
        s = Path(
            work=s.work + w,
            stored=s.stored + energy(y1) - energy(y),
            dissipation=s.dissipation + d,
            numerical=s.numerical + dnum,
            defect=jnp.maximum(s.defect, jnp.abs(w - d - jnp.dot(g1, dy))),
            least=jnp.minimum(s.least, dnum),
            count=s.count + 1,
            split=s.split + (out.accepted + out.rejected != 1),
            ok=s.ok & out.ok,
        )
        return y1, out.rate, s

    s0 = Path(zero, zero, zero, zero, zero, jnp.asarray(jnp.inf), 0, 0, jnp.asarray(True))
    _, _, s = jax.lax.fori_loop(0, steps, body, (y0, zero_rate(layout.n), s0))
    return s


def _measure(solver):
    _, layout, args, y0, t1 = push_down_start()
    rows = []
    for h in HS:
        s = _path(solver, layout, y0, t1, jnp.asarray(h), args)
        assert bool(s.ok) and int(s.count) == round(float(t1) / h) and int(s.split) == 0, s
        rows.append(jax.tree_util.tree_map(float, s))
    return rows


@pytest.mark.parametrize(
    "solver",
    # the full-state baseline is the slower cross-check (its own compile): with the slow tests
    [named_solver(), pytest.param(FullStateLoadStep(newton_max_iter=16), marks=pytest.mark.slow)],
    ids=["motion_newton", "full_state"],
)
def test_numerical_dissipation_closes_the_balance_to_second_order(solver):
    """The scenarios' default solver (``numerics.solver: load_step``, Newton on the motion,
    its numerics' defaults but the tolerances) and the full-state baseline: the balance with
    D_num accounted closes to second order in h, D_num is the plain residual to leading
    order, and the work and dissipation satisfy the increment's identity."""
    rows = _measure(solver)
    w = np.array([r.work for r in rows])
    plain = np.array([r.work - r.stored - r.dissipation for r in rows]) / w
    dnum = np.array([r.numerical for r in rows]) / w
    left = plain - dnum
    defect = np.array([r.defect for r in rows])
    least = np.array([r.least for r in rows])
    p_plain = np.polyfit(np.log(HS), np.log(np.abs(plain)), 1)[0]
    p_left = np.polyfit(np.log(HS), np.log(np.abs(left)), 1)[0]
    print(
        f"\n{type(solver).__name__}: h {HS} s; work {w}\n  plain residual / W {plain} (order "
        f"{p_plain:.3f})\n  D_num / W {dnum}\n  accounted residual / W {left} (order "
        f"{p_left:.3f})\n  plain / D_num {plain / dnum}\n  identity defect (max per "
        f"increment) {defect}\n  least D_num per increment {least}"
    )
    # Measured (``pytest -s -n 0 tests/test_numerical_dissipation.py``), both solvers alike to
    # 4 digits, h = 0.1 .. 0.0125 s: plain residual / W 9.68e-3, 4.87e-3, 2.44e-3, 1.22e-3
    # (order 0.995); D_num / W 9.66e-3 .. 1.22e-3; accounted residual / W 2.00e-5, 5.05e-6,
    # 1.25e-6, 3.41e-7 (order 1.963); plain / D_num - 1 = 2.07e-3, 1.04e-3, 5.1e-4, 2.8e-4;
    # identity defect at most 2.0e-11 (motion Newton), 1.6e-15 (full state); least D_num of
    # one increment 8.6e-5 .. 9.5e-7, all positive.
    # The rectangle rule is exact for the work and dissipation: a missing or misplaced term
    # (the friction at another threshold, the clamp's force at the start) leaves O(h) here.
    assert np.all(defect < 1e-9)
    # D_num = 1/2 dx^T H dx: positive in every increment of this path (measured: E is convex
    # along each segment here, which nothing guarantees on a buckling path), so summed too
    assert np.all(least > 0.0) and np.all(dnum > 0.0)
    # the plain residual is first order and D_num to leading order; their difference is O(h)
    # relative to either
    assert 0.95 < p_plain < 1.05
    assert np.all(np.abs(plain / dnum - 1.0) < 3e-3 * HS / HS[0])
    # with D_num accounted, second order and far below: at most 3e-3 of the plain residual
    # (measured 2.1e-3 at h = 0.1 s, 2.8e-4 at 0.0125 s), 1e-6 of the work at h = 0.0125 s
    # (measured 3.4e-7)
    assert 1.85 < p_left < 2.1
    assert np.all(np.abs(left) < 3e-3 * plain)
    assert abs(left[-1]) < 1e-6
