r"""Load increments by Newton on the motion alone.

The same implicit Euler increment as :mod:`dynslip.physics.loadstep`,
$x_1 = x_0 + \Delta t\, f(t_1, x_1)$ with the overdamped law of
:func:`dynslip.physics.field.evaluate`, solved for fewer unknowns:

- **Unknowns.** The node positions *relative to the ball*, $q_i = x_i - z_b e_z$
  ($n$ blocks of 2; the pole's $\rho_0 = 0$ stays a trivial row), and the ball height
  $z_b$, the only border unknown. A node's rate relative to the ball, $u_i$, depends on
  its relative position and on the elastic and penalty forces, i.e. on its neighbours
  (the energy is invariant under a common vertical shift), so the $q$ rows are block
  tridiagonal. The ball's rate $v_b$ couples only to the clamped edge (the clamp's force
  $C_z = \partial E/\partial z_{n-1}$ on a force-controlled ball) and to itself (the
  support), so the border is one unknown touching one block. Implicit Euler is invariant
  under this linear change of variables: the increment is the one the full state would
  give.
- **Slip distance by a local return map.** Per node, given the trial forces,
  $\delta_1 = \delta_0 + \Delta t\,|S(F_t, \mu(\delta_0) N)|/(\eta A)$ in contact
  ($\delta_1 = \delta_0$ out of contact): :func:`dynslip.physics.increment.slip_update`,
  which states why $\mu$ is taken at the increment's start. It is continuous in the motion,
  so its autodiff derivative is the map's consistent tangent.
- **The ball friction's weighted form** (``weight``, the complementarity parameter $c$;
  ``numerics.newton_weight``, default $10^3\,G h_0$). Newton iterates on each node's tangential
  row in the form $\lambda = P(\lambda + \gamma\,\eta A u_t)$ ($\lambda$ the friction
  force, $P$ the law's projection onto the friction disc, $\gamma = \max(1, c\,\Delta t/
  (\eta A))$) in place of the law's own $\eta A u_t = S(F_t)$ ($\gamma = 1$):
  :func:`dynslip.physics.increment.weighted_slip`. The roots are the law's, smoothing band
  included (:func:`dynslip.physics.friction.weighted_form` reads the same curve), so the
  converged increment is the law's; what changes is how a Newton step decides stick or slip: by
  the node's trial force *plus* $c$ times its tangential displacement, the primal-dual
  active-set choice of contact solvers (Hueber, Stadler and Wohlmuth 2008), where the law's form
  decides by the force alone and a stiff sheet's forces swing the edge nodes across their
  threshold from one iteration to the next. On the frozen let-go path it cut the Newton
  iterations 2x at N = 50 and 5-6x at N = 200-800 (docs/speed.md).
- **Energy accumulators by quadrature.** After an increment is accepted, the work and
  dissipation rates of :func:`dynslip.physics.field.evaluate` at $x_1$ times $\Delta t$ (the
  rectangle rule at the increment's end: exactly what :mod:`dynslip.physics.loadstep`'s
  implicit accumulators give).
- **Jacobian from element and node derivatives.** Per element, the value, gradient and
  Hessian of its energy in its four coordinates (``vmap`` of ``jacfwd`` of ``grad``); per
  node, the penalty's, and the Jacobian of the node's rate in its own position (``vmap`` of
  ``jacfwd``) and force (closed form,
  :func:`dynslip.physics.increment.node_force_jacobian`; ``jacfwd`` with held friction); the
  chain rule assembles the $2\times 2$ blocks
  $\partial u_i/\partial q_j = L^q_i\delta_{ij} + L^g_i H_{ij}$. No pass over the whole field.
- **Backtracking** as :class:`dynslip.physics.loadstep.DampedNewton` (a correction that
  raises the residual's max norm is halved, at most ``backtrack`` times); the residual of
  the accepted trial is the next iteration's residual (one evaluation per trial), and its
  energy gradient, ball velocity and slip distances are the converged state's (not evaluated
  again after the loop; :func:`dynslip.physics.increment.residual_and_state`).
- **Predictor.** Newton starts from the last accepted increment's rate extrapolated over
  the new increment (zero at a segment's start).
- **Convergence.** The last correction below ``atol + rtol |x|`` and the residual's max norm
  below ``atol``; or (the *residual floor*, ``floor_factor``) Newton's full correction below
  ``atol + rtol |x|`` for ``floor_count`` iterations running and the residual below
  ``floor_factor atol``. For a Newton matrix that is not exact: on the main job with the free
  ball's coupling to the rest of the sheet left out of it (exact in
  :func:`dynslip.physics.newton_matrix.blocks_with_held_friction`), in the z rows of the
  sheet's edge nodes on the tube and the band, Newton's corrections fall far below the step
  tolerance while the residual stays at 2-10 ``atol``, until the increment is cut. A bounded
  relaxation of the test: the let-go end states move by at most 1.2e-7 rad (docs/speed.md);
  ``floor_factor = 0`` gives the strict test.
- **Increment size.** Grown by 1.5 after at most ``grow_below`` iterations, shrunk by 0.7 after
  at least ``shrink_above``, halved on a failure; with ``fail_cap`` the increments that follow a
  failure within a segment are held to at most ``fail_cap`` times the failed size, a bound
  relaxed by ``fail_relax`` per accepted increment (0: no memory of the failure).

The linear solve is :func:`dynslip.physics.linalg.block_solve` (block cyclic reduction or
block Thomas, with the one-unknown border by a Schur complement).

**Bodies.** The contact geometry is asked of the model's bodies through
:func:`dynslip.physics.terms.contact_gap` (the ball, :attr:`SheetModel.ball`, at the
relative position $q$; the held bodies, :attr:`SheetModel.bodies`, at $q + z_b e_z$, each
with its own friction law or none: :mod:`dynslip.physics.bodies.held`, docs/bodies.md).

Where the parts live: the element and node terms (energy, penalties, their gradient and
Hessian blocks) in :mod:`dynslip.physics.terms`; the increment's data and residual in
:mod:`dynslip.physics.increment`; its Newton matrix (and the free held bodies' system) in
:mod:`dynslip.physics.newton_matrix`; here the increment's loop and the segment's.

The increment's Newton loop (predictor, one residual call site, backtracking, the residual
floor) and the segment's loop with its increment controller are one algorithm, documented here
as one.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics.bodies.held import place_bodies
from dynslip.physics.field import Layout, evaluate, heal
from dynslip.physics.increment import (
    Increment,
    increment_rates,
    residual_and_state,
    sheet_held_frame,
)
from dynslip.physics.linalg import bordered_solve
from dynslip.physics.newton_matrix import free_system, newton_blocks
from dynslip.physics.protocols import BALL_HOLD, CLAMP_POSITION
from dynslip.physics.terms import forces, held_projections

__all__ = ["MotionNewton", "SegmentOutput", "increment_cap", "zero_rate"]

GROW = 1.5
CUT = 0.5
SHRINK = 0.7
MIN_FRACTION = 1e-10
FAIL_CAP = 0.9  # the memory of a failed increment's size (0: none)
FAIL_RELAX = 1.05


def increment_cap(args, max_increment, max_increment_free):
    """$\\Delta t_{max}$ (s): ``max_increment`` drag times in driven stages, ``max_increment_free``
    where the ball or the clamp moves under a force (``args.drag`` is the drag time)."""
    free = (args.ball_mode != BALL_HOLD) | (args.clamp_mode != CLAMP_POSITION)
    return args.drag * jnp.where(free, max_increment_free, max_increment)


class SegmentOutput(eqx.Module):
    """What a segment solve returns (both solvers): the end state, whether it reached the
    segment's end, the steps (accepted + rejected), accepted, rejected, Newton iterations
    (0 for the time-stepped solvers), the predictor's rate, and, where the solver has them
    (Newton's last evaluation; else None), ``forces``: the energy gradient, the held bodies'
    load and their projections of the nodes at the end state, ``(g, load, projections)`` as
    :func:`dynslip.physics.terms.forces` and :func:`~dynslip.physics.terms.held_projections`
    give them (``projections`` None without held bodies), and ``ball_velocity``, the ball's
    there: the frame takes them
    (:func:`dynslip.physics.frames.frame_record`)."""

    y: jax.Array
    ok: jax.Array
    steps: jax.Array
    accepted: jax.Array
    rejected: jax.Array
    newton_iterations: jax.Array
    rate: (
        tuple  # the last accepted increment per unit time on (q, zb): the next segment's predictor
    )
    forces: tuple | None = None
    ball_velocity: jax.Array | None = None


# --------------------------------------------------------------------------- the solver object


class MotionNewton(eqx.Module):
    """Implicit Euler load increments, Newton on the motion alone (module docstring).

    ``rtol``/``atol`` (max norm; converged when the last correction is below
    ``atol + rtol |x|`` and the residual below ``atol``), at most ``max_iter`` corrections
    per increment, ``backtrack`` halvings of a correction that raises the residual,
    ``linear``: ``"auto"`` (block Thomas up to 64 nodes, block cyclic reduction above:
    :func:`dynslip.physics.linalg.block_tridiagonal_solve`), ``"cyclic"`` or ``"thomas"``.
    Increments grow by 1.5
    after at most ``grow_below`` iterations and shrink by 0.7 after at least ``shrink_above``.
    ``floor_factor``, ``floor_count``: the residual
    floor (module docstring; 0: off); ``fail_cap``, ``fail_relax``: the memory of a failed
    increment's size within a segment (module docstring; 0: off). ``weight``: the
    complementarity parameter $c$ of the ball friction's weighted form in which Newton iterates
    (:func:`dynslip.physics.increment.weighted_slip`; the law's roots for every $c$; 0: the
    law's own form; not with free bodies).
    """

    max_iter: int = eqx.field(static=True, default=20)
    backtrack: int = eqx.field(static=True, default=4)
    linear: str = eqx.field(static=True, default="auto")
    grow_below: int = eqx.field(static=True, default=12)
    shrink_above: int = eqx.field(static=True, default=18)
    max_increment: float = eqx.field(static=True, default=20.0)
    max_increment_free: float = eqx.field(static=True, default=5.0)
    heal_rate: float = eqx.field(static=True, default=0.0)
    max_steps: int = eqx.field(static=True, default=20000)
    floor_factor: float = eqx.field(static=True, default=10.0)
    floor_count: int = eqx.field(static=True, default=2)
    fail_cap: float = eqx.field(static=True, default=FAIL_CAP)
    fail_relax: float = eqx.field(static=True, default=FAIL_RELAX)
    weight: float = eqx.field(static=True, default=0.0)

    def increment(self, model, layout: Layout, t0, t1, y0, args, rate, rtol, atol):
        """One increment from ``y0`` at ``t0`` to ``t1``, Newton started from ``y0 + (t1 - t0)
        rate``
        (``rate`` on the unknowns ``(q, zb)``): ``(y1, ok, iterations, (q1 - q0, zb1 - zb0),
        ((g, load, projections), vb))``: the energy gradient, the held load and the held bodies'
        projections at ``y1`` (:class:`SegmentOutput`'s ``forces``) and the ball's velocity the
        increment took. With
        ``t1 == t0`` Newton stays at ``y0`` (a zero-length increment: the forces at the start,
        :meth:`segment`)."""
        friction = args.friction
        # the stage-moved bodies where they are at the increment's end (implicit Euler)
        model = place_bodies(model, args.body_z0, args.body_v, args.t0, t1)
        h = t1 - t0
        rho, z, zb0, acc0 = layout.unpack(y0)
        q0 = jnp.stack([rho, z - zb0], axis=1)
        delta0 = layout.internal(y0)
        hdelta0 = layout.held_internal(y0)
        inc = Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args,
                        held_delta0=hdelta0)
        rq, rz = rate
        q = q0 + h * rq
        nf = layout.n_free
        # the weighted form of the ball's friction law (``weight``; not with free bodies, whose
        # residual is built apart)
        weighted = self.weight > 0 and not nf
        n = q0.shape[0]
        if nf:
            # free bodies: the border is (zb, z_1 .. z_K), placed into the model by res/blocks
            res0, blocks0, placed = free_system(model, friction, inc, layout.free(y0))
            zb = jnp.concatenate([jnp.reshape(zb0 + h * rz, (1,)), layout.free(y0)])

            def res(q, zb):
                # the end state is evaluated after the loop (``state`` None)
                return (*res0(q, zb), None)

            def blocks(q, zb, state):
                return blocks0(q, zb)
        else:
            zb = zb0 + h * rz

            # the increment with the law's weight
            data = Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args,
                             held_delta0=hdelta0, weight=self.weight if weighted else None)

            def res(q, zb):
                # the residual and the state the increment's end reads (:func:`residual_and_state`)
                return residual_and_state(model, friction, data, q, zb)

            def blocks(q, zb, state):
                # the ball's velocity at (q, zb) from the residual's evaluation there
                return newton_blocks(model, friction, data, q, zb, vb=state[1])

        def size(rq, rz):
            return jnp.maximum(jnp.max(jnp.abs(rq)), jnp.max(jnp.abs(rz)))

        def cond(c):
            it, done, bad = c[4], c[5], c[6]
            return (~done) & (~bad) & (it < self.max_iter)

        # The loop's first pass evaluates the residual at the predictor (its correction is 0,
        # its trial accepted whatever the residual), and each pass ends with the next
        # correction, so the residual has one call site: each is compiled anew (about 10% of
        # the world's step). ``it`` counts the corrections (the predictor's pass is not one).
        def body(c):
            q, zb, r_q, r_z, it, _, _, small, state, dq, dz, first = c
            f0 = jnp.where(first, jnp.inf, size(r_q, r_z))

            # the full step, then up to ``backtrack`` halvings while the residual rises: one
            # loop whose first pass is the full step, so the residual is traced once here (each
            # call site of it is compiled anew: 2 s of the world's compile per copy)
            def bt_cond(b):
                _alpha, tq, tz, _, k = b
                f1 = size(tq, tz)
                return (k == 0) | (~((f1 <= f0) | (f1 <= atol)) & (k <= self.backtrack))

            def bt_body(b):
                alpha, _, _, _, k = b
                alpha = jnp.where(k == 0, 1.0, 0.5 * alpha)
                tq, tz, tstate = res(q - alpha * dq, zb - alpha * dz)
                return alpha, tq, tz, tstate, k + 1

            unset = (jnp.full_like(r_q, jnp.inf), jnp.full_like(r_z, jnp.inf), state)
            alpha, tq, tz, state, _ = jax.lax.while_loop(
                bt_cond, bt_body, (jnp.array(1.0), *unset, jnp.array(0))
            )
            qn, zbn = q - alpha * dq, zb - alpha * dz
            step = jnp.maximum(
                jnp.max(jnp.abs(alpha * dq) / (atol + rtol * jnp.abs(qn))),
                jnp.max(jnp.abs(alpha * dz) / (atol + rtol * jnp.abs(zbn))),
            )
            done = ~first & (step < 1.0) & (size(tq, tz) <= atol)
            if self.floor_factor:
                # the residual floor: Newton's full correction (not the damped one) below the
                # step tolerance ``floor_count`` times running, the residual within the floor
                full = jnp.maximum(
                    jnp.max(jnp.abs(dq) / (atol + rtol * jnp.abs(qn))),
                    jnp.max(jnp.abs(dz) / (atol + rtol * jnp.abs(zbn))),
                )
                small = jnp.where(~first & (full < 1.0), small + 1, 0)
                done = done | (
                    (small >= self.floor_count) & (size(tq, tz) <= self.floor_factor * atol)
                )
            bad = ~(
                jnp.all(jnp.isfinite(qn)) & jnp.all(jnp.isfinite(zbn)) & jnp.isfinite(size(tq, tz))
            )
            it = it + jnp.where(first, 0, 1)
            # the next correction, where another pass follows
            go = (~done) & (~bad) & (it < self.max_iter)
            dq, dz = jax.lax.cond(
                go,
                lambda: bordered_solve(*blocks(qn, zbn, state), tq, tz, self.linear),
                lambda: (jnp.zeros_like(dq), jnp.zeros_like(dz)),
            )
            return qn, zbn, tq, tz, it, done, bad, small, state, dq, dz, jnp.array(False)

        # the loop's carry before the first pass: the residual and state are placeholders that
        # the first pass replaces (shapes as ``res`` returns them)
        state = None
        if not nf:
            state = (jnp.zeros_like(q), jnp.zeros_like(zb0),
                     None if delta0 is None else jnp.zeros_like(delta0), jnp.zeros_like(zb0),
                     _unset_projections(model, n, 0.0))
        init = (
            q, zb, jnp.zeros_like(q), jnp.zeros_like(zb), jnp.array(0, jnp.int32),
            jnp.array(False), jnp.array(False), jnp.array(0, jnp.int32), state,
            jnp.zeros_like(q), jnp.zeros_like(zb), jnp.array(True),
        )
        q, zb, _, _, it, done, bad, _, state, _, _, _ = jax.lax.while_loop(cond, body, init)
        zk = None
        if nf:
            zb, zk = zb[0], zb[1:]
            model = placed(zk)
            ps = held_projections(model, q, zb) if model.bodies else None
            g, load = forces(model, q, zb, ps)
            _, vb1, delta1 = increment_rates(model, friction, inc, q, zb, g, load, ps)
        else:
            # the converged state's gradient and rates, from the residual's last evaluation
            g, vb1, delta1, load, ps = state
        hdelta1 = None
        if hdelta0 is not None:
            # the held bodies' return map: delta1 = delta0 + h |S(G, mu(delta0) N)|/(eta A) in
            # contact with the body, the slip relative to it at the converged motion
            hdelta1 = sheet_held_frame(model, args, q, zb, g, hdelta0, ps).advance(vb1, h)
        y1 = layout.pack(q[:, 0], q[:, 1] + zb, zb, acc0, delta1, zk, hdelta1)
        # the accumulators by the rectangle rule at x1, with the friction law the motion used: the
        # return map's coefficient at the increment's start, mu(delta0) (with mu(delta1) the
        # friction power of fully mobilised nodes is counted at the weakened threshold, which
        # the motion never saw: 5x the work on the let-go path)
        y_rates = layout.pack(q[:, 0], q[:, 1] + zb, zb, acc0, delta0, zk, hdelta0)
        # (the energy gradient and the held load from the same evaluation: no third and fourth
        # pass through the bodies' projections)
        dy, _ = evaluate(model, layout, t1, y_rates, args, vb=vb1, forces=(g, load, ps))
        y1 = y1.at[layout.accumulators].set(acc0 + h * dy[layout.accumulators])
        y1 = heal(model, layout, y1, args, self.heal_rate, vb=vb1, forces=(g, load, ps))
        ok = done & ~bad & jnp.all(jnp.isfinite(y1))
        return y1, ok, it, (q - q0, zb - zb0), ((g, load, ps), vb1)

    def next_size(self, dt, h, iters, ok, was_cut, h_fail, cap):
        """The increment controller: the size to try after an increment of ``h`` (``dt`` the
        size that was asked, ``h`` the one taken: the segment's last may be longer) that took
        ``iters`` iterations and converged (``ok``) or not; ``was_cut``: it followed a failure;
        ``h_fail``: the memory's bound (inf: no failure yet in the segment). Returns the next
        size and the new ``h_fail``."""
        factor = jnp.where(
            iters <= self.grow_below, GROW, jnp.where(iters >= self.shrink_above, SHRINK, 1.0)
        )
        factor = jnp.where(was_cut, jnp.minimum(factor, 1.0), factor)
        dt_ok = jnp.minimum(jnp.maximum(dt, h) * factor, cap)
        if self.fail_cap:
            # the memory of a failure: no growth past fail_cap times the failed size (never a
            # shrink for it), the bound relaxed by fail_relax per accepted increment
            dt_ok = jnp.minimum(dt_ok, jnp.maximum(self.fail_cap * h_fail, jnp.minimum(dt, h)))
            h_fail = jnp.where(ok, h_fail * self.fail_relax, h)
        return jnp.where(ok, dt_ok, CUT * h), h_fail

    def segment(
        self, model, layout: Layout, y0, t0, t1, dt0, args, rtol, atol, rate=None
    ) -> SegmentOutput:
        """Increments from ``t0`` to ``t1`` (``dt0`` the first tried), ending exactly on ``t1``;
        ``rate`` (on ``(q, zb)``, zero when None: a stage's start) predicts the first increment.
        The output's ``forces`` are the last accepted increment's at its end. A zero-length
        segment (``t1 == t0``: a run's initial frame) takes one zero-length increment, which
        leaves ``y0``, the rate, the increment's size and the counts as they are and gives the
        forces at ``y0``: so the frame has them from the one evaluation the loop compiles anyway
        (the frame's own differentiation of the energy was 9% of the main job's step)."""
        cap = increment_cap(args, self.max_increment, self.max_increment_free)
        dt_min = MIN_FRACTION * (t1 - t0)
        zero = jnp.array(0, dtype=jnp.int32)
        n = layout.n
        rate0 = zero_rate(n) if rate is None else rate

        def cond(c):
            t, _, _, dt, _, nacc, nrej, _, _, _, fresh = c
            return ((t < t1) | fresh) & (nacc + nrej < self.max_steps) & (dt >= dt_min)

        def body(c):
            t, y, rate, dt, was_cut, nacc, nrej, nit, h_fail, f, _ = c
            left = t1 - t
            last = left <= 1.25 * dt
            h = jnp.where(last, left, dt)
            t_next = jnp.where(last, t1, t + h)
            y1, ok, iters, (dq, dz), f1 = self.increment(
                model, layout, t, t_next, y, args, rate, rtol, atol
            )
            moved = h > 0  # not the zero-length increment of a zero-length segment
            took = ok & moved
            dt_new, h_fail_new = self.next_size(dt, h, iters, ok, was_cut, h_fail, cap)
            hs = jnp.where(moved, h, 1.0)
            new_rate = (dq / hs, dz / hs)
            keep = lambda new, old: jax.tree_util.tree_map(  # noqa: E731
                lambda a, b: jnp.where(took, a, b), new, old)
            return (
                jnp.where(ok, t_next, t),
                keep(y1, y),
                keep(new_rate, rate),
                jnp.where(moved, dt_new, dt),
                jnp.where(moved, ~ok, was_cut),
                nacc + took,
                nrej + (~ok),
                nit + jnp.where(moved, iters, 0),
                jnp.where(moved, h_fail_new, h_fail),
                jax.tree_util.tree_map(lambda a, b: jnp.where(ok, a, b), f1, f),
                jnp.array(False),
            )

        # the forces and velocity before any increment: not finite, so a frame can never read
        # them as values (a segment that ends without an accepted increment has failed, and is
        # not recorded)
        unset = ((jnp.full((n, 2), jnp.nan), jnp.full((), jnp.nan),
                  _unset_projections(model, n, jnp.nan)), jnp.full((), jnp.nan))
        init = (
            t0, y0, rate0, jnp.minimum(dt0, cap), jnp.array(False), zero, zero, zero,
            jnp.array(jnp.inf), unset, jnp.array(True),
        )
        t, y, rate, _, _, nacc, nrej, nit, _, f, _ = jax.lax.while_loop(cond, body, init)
        ok = (t >= t1) & jnp.all(jnp.isfinite(y))
        return SegmentOutput(
            y=y,
            ok=ok,
            steps=nacc + nrej,
            accepted=nacc,
            rejected=nrej,
            newton_iterations=nit,
            rate=rate,
            forces=f[0],
            ball_velocity=f[1],
        )


def _unset_projections(model, n: int, fill):
    """Placeholders of :func:`~dynslip.physics.terms.held_projections`' output for ``n`` nodes
    (None without held bodies), every value ``fill``: a loop's carry before its first
    evaluation."""
    if not model.bodies:
        return None
    shapes = jax.eval_shape(lambda: held_projections(model, jnp.zeros((n, 2)), jnp.zeros(())))
    return jax.tree_util.tree_map(lambda a: jnp.full(a.shape, fill, a.dtype), shapes)


def zero_rate(n: int):
    """The predictor's rate at a stage's start: zero on ``(q, zb)``."""
    return (jnp.zeros((n, 2)), jnp.zeros(()))
