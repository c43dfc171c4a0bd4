r"""Load increments by Newton on the motion alone.

The same implicit Euler increment as :mod:`dynslip.physics.solver.loadstep`,
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
  ($\delta_1 = \delta_0$ out of contact): :func:`dynslip.physics.solver.increment.slip_update`,
  which states why $\mu$ is taken at the increment's start. It is continuous in the motion,
  so its autodiff derivative is the map's consistent tangent.
- **The ball friction's weighted form** (``weight``, the complementarity parameter $c$;
  ``numerics.newton_weight``, default $10^3\,G h_0$). Newton iterates on each node's tangential
  row in the form $\lambda = P(\lambda + \gamma\,\eta A u_t)$ ($\lambda$ the friction
  force, $P$ the law's projection onto the friction disc, $\gamma = \max(1, c\,\Delta t/
  (\eta A))$) in place of the law's own $\eta A u_t = S(F_t)$ ($\gamma = 1$):
  :func:`dynslip.physics.solver.increment.weighted_slip`. The roots are the law's, smoothing band
  included (:func:`dynslip.physics.friction.weighted_form` reads the same curve), so the
  converged increment is the law's; what changes is how a Newton step decides stick or slip: by
  the node's trial force *plus* $c$ times its tangential displacement, the primal-dual
  active-set choice of contact solvers (Hueber, Stadler and Wohlmuth 2008), where the law's form
  decides by the force alone and a stiff sheet's forces swing the edge nodes across their
  threshold from one iteration to the next. On the frozen let-go path it cut the Newton
  iterations 2x at N = 50 and 5-6x at N = 200-800 (docs/speed.md).
- **Energy accumulators by quadrature.** After an increment is accepted, the work and
  dissipation rates of :func:`dynslip.physics.field.evaluate` at $x_1$ times $\Delta t$ (the
  rectangle rule at the increment's end: exactly what :mod:`dynslip.physics.solver.loadstep`'s
  implicit accumulators give).
- **Jacobian from element and node derivatives.** Per element, the value, gradient and
  Hessian of its energy in its four coordinates (``vmap`` of ``jacfwd`` of ``grad``); per
  node, the penalty's, and the Jacobian of the node's rate in its own position (``vmap`` of
  ``jacfwd``) and force (closed form,
  :func:`dynslip.physics.solver.increment.node_force_jacobian`; ``jacfwd`` with held friction); the
  chain rule assembles the $2\times 2$ blocks
  $\partial u_i/\partial q_j = L^q_i\delta_{ij} + L^g_i H_{ij}$. No pass over the whole field.
- **Backtracking** as :class:`dynslip.physics.solver.loadstep.DampedNewton` (a correction that
  raises the residual's max norm is halved, at most ``backtrack`` times); the residual of
  the accepted trial is the next iteration's residual (one evaluation per trial), and its
  energy gradient, ball velocity and slip distances are the converged state's (not evaluated
  again after the loop; :func:`dynslip.physics.solver.increment.residual_and_state`).
- **Predictor.** Newton starts from the last accepted increment's rate extrapolated over
  the new increment (zero at a segment's start).
- **Convergence.** The last correction below ``atol + rtol |x|`` and the residual's max norm
  below ``atol``; or (the *residual floor*, ``floor_factor``) Newton's full correction below
  ``atol + rtol |x|`` for ``floor_count`` iterations running and the residual below
  ``floor_factor atol``. For a Newton matrix that is not exact: on the main job with the free
  ball's coupling to the rest of the sheet left out of it (exact in
  :func:`dynslip.physics.solver.newton_matrix.blocks_with_held_friction`), in the z rows of the
  sheet's edge nodes on the tube and the band, Newton's corrections fall far below the step
  tolerance while the residual stays at 2-10 ``atol``, until the increment is cut. A bounded
  relaxation of the test: the let-go end states move by at most 1.2e-7 rad (docs/speed.md);
  ``floor_factor = 0`` gives the strict test.
- **Corners.** An increment in which a segment of the sheet passes through the centre of a
  body's corner (:func:`dynslip.physics.terms.corners_crossed`) is refused and cut, as a failed
  one: the corners' penalty is unsigned (:mod:`dynslip.physics.bodies.corners`).
- **Increment size.** Grown by 1.5 after at most ``grow_below`` iterations, shrunk by 0.7 after
  at least ``shrink_above``, halved on a failure; with ``fail_cap`` the increments that follow a
  failure within a segment are held to at most ``fail_cap`` times the failed size, a bound
  relaxed by ``fail_relax`` per accepted increment (0: no memory of the failure).

The linear solve is :func:`dynslip.physics.solver.linalg.block_solve` (block cyclic reduction or
block Thomas, with the one-unknown border by a Schur complement).

**Bodies.** The contact geometry is asked of the model's bodies through
:func:`dynslip.physics.terms.contact_gap` (the ball, :attr:`SheetModel.ball`, at the
relative position $q$; the held bodies, :attr:`SheetModel.bodies`, at $q + z_b e_z$, each
with its own friction law or none: :mod:`dynslip.physics.bodies.held`, docs/bodies.md).

Where the parts live: the element and node terms (energy, penalties, their gradient and
Hessian blocks) in :mod:`dynslip.physics.terms`; the increment's data and residual in
:mod:`dynslip.physics.solver.increment`; its Newton matrix (and the free held bodies' system) in
:mod:`dynslip.physics.solver.newton_matrix`; here the increment's loop and the segment's.

The increment's Newton loop (predictor, one residual call site, backtracking, the residual
floor) and the segment's loop with its increment controller are one algorithm, documented here
as one.
"""

from __future__ import annotations

import abc
from typing import ClassVar, NamedTuple, cast

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics import conditions
from dynslip.physics.bodies.held import place_bodies
from dynslip.physics.field import Layout, evaluate, heal
from dynslip.physics.solver.increment import (
    Increment,
    increment_rates,
    residual_and_state,
    sheet_held_frame,
)
from dynslip.physics.solver.linalg import Blocks, bordered_solve
from dynslip.physics.solver.newton_matrix import free_system, newton_blocks
from dynslip.physics.terms import corners_crossed, forces, held_projections

__all__ = [
    "AbstractSegmentSolver",
    "EndState",
    "Forces",
    "IncrementResult",
    "MotionNewton",
    "NewtonIterate",
    "Rate",
    "SegmentCarry",
    "SegmentOutput",
    "Trial",
    "increment_cap",
    "segment_output",
    "zero_rate",
]

GROW = 1.5
CUT = 0.5
SHRINK = 0.7
MIN_FRACTION = 1e-10
FAIL_CAP = 0.9  # the memory of a failed increment's size (0: none)
FAIL_RELAX = 1.05


def increment_cap(args, max_increment, max_increment_free):
    """$\\Delta t_{max}$ (s): ``max_increment`` drag times in driven stages, ``max_increment_free``
    where the ball or the clamp moves under a force (``args.drag`` is the drag time)."""
    return args.drag * jnp.where(conditions.driven(args), max_increment, max_increment_free)


class Rate(NamedTuple):
    """A change of the unknowns per unit time (or, as an increment's ``change``, the change
    itself): ``q`` (n, 2) of the nodes relative to the ball, ``zb`` () of the ball. The last
    accepted increment's is the next increment's predictor."""

    q: jax.Array
    zb: jax.Array


class Forces(NamedTuple):
    """The energy gradient ``g`` (n, 2), the held bodies' load on the clamped edge ``load`` and
    their ``projections`` of the nodes (None without held bodies) at one state, as
    :func:`dynslip.physics.terms.forces` and :func:`~dynslip.physics.terms.held_projections`
    give them: read by :func:`dynslip.physics.field.evaluate` and the frame."""

    g: jax.Array
    load: jax.Array
    projections: object = None


class EndState(NamedTuple):
    """What the increment's end reads from the residual's evaluation at an iterate
    (:func:`dynslip.physics.solver.increment.residual_and_state`'s third output, in its order): the
    energy gradient, the ball's velocity, the slip distances after the return map (None
    without a memory law), the held load and the held bodies' projections."""

    g: jax.Array
    ball_velocity: jax.Array
    delta: jax.Array | None
    load: jax.Array
    projections: object


class Trial(NamedTuple):
    """The backtracking loop's carry: the step length ``alpha`` along the Newton correction,
    the residual (``r_q``, ``r_z``) and end state at the trial point, and the trials taken."""

    alpha: jax.Array
    r_q: jax.Array
    r_z: jax.Array
    state: EndState | None
    trials: jax.Array


class NewtonIterate(NamedTuple):
    """The increment's Newton loop carry: the iterate (``q``, ``zb``), its residual (``r_q``,
    ``r_z``) and end state (None with free bodies: evaluated after the loop), the corrections
    taken (``iterations``), whether it converged (``done``) or went non-finite (``bad``), the
    residual floor's count of small full corrections running (``small``), the next
    correction (``dq``, ``dz``), and ``first``: the predictor's pass is still to come."""

    q: jax.Array
    zb: jax.Array
    r_q: jax.Array
    r_z: jax.Array
    iterations: jax.Array
    done: jax.Array
    bad: jax.Array
    small: jax.Array
    state: EndState | None
    dq: jax.Array
    dz: jax.Array
    first: jax.Array


class IncrementResult(NamedTuple):
    """One increment (:meth:`MotionNewton.increment`): the end state ``y``, whether Newton
    converged (``ok``), its corrections (``iterations``), the change of the unknowns
    (``change``: ``q1 - q0``, ``zb1 - zb0``), the :class:`Forces` at ``y`` and the ball's
    velocity the increment took."""

    y: jax.Array
    ok: jax.Array
    iterations: jax.Array
    change: Rate
    forces: Forces
    ball_velocity: jax.Array


class SegmentCarry(NamedTuple):
    """The segment's loop carry (:meth:`MotionNewton.segment`): the time ``t`` and state ``y``
    reached, the predictor's ``rate``, the next increment's size ``dt``, whether the last
    increment failed (``was_cut``), the counts (``accepted``, ``rejected``, Newton
    ``iterations``), the failure memory's bound ``h_fail`` (inf: no failure yet), the last
    converged increment's :class:`Forces` and ball velocity, and ``fresh``: no increment
    taken yet (a zero-length segment takes one)."""

    t: jax.Array
    y: jax.Array
    rate: Rate
    dt: jax.Array
    was_cut: jax.Array
    accepted: jax.Array
    rejected: jax.Array
    iterations: jax.Array
    h_fail: jax.Array
    forces: Forces
    ball_velocity: jax.Array
    fresh: jax.Array


class SegmentOutput(eqx.Module):
    """What a segment solve returns (every solver): the end state, whether it reached the
    segment's end, the steps (accepted + rejected), accepted, rejected, Newton iterations
    (0 for the time-stepped solvers), the predictor's :class:`Rate`, and, where the solver has
    them (Newton's last evaluation; else None), the :class:`Forces` at the end state and
    ``ball_velocity``, the ball's there: the frame takes them
    (:func:`dynslip.physics.frames.frame_record`)."""

    y: jax.Array
    ok: jax.Array
    steps: jax.Array
    accepted: jax.Array
    rejected: jax.Array
    newton_iterations: jax.Array
    # the last accepted increment per unit time on (q, zb): the next predictor (the load-step
    # solver's increment loop: of the whole state, flat)
    rate: Rate | jax.Array
    forces: Forces | None = None
    ball_velocity: jax.Array | None = None


class AbstractSegmentSolver(eqx.Module):
    """A segment solver of the driver (``Settings.solver``): load stepping
    (:class:`MotionNewton`), a stiff diffrax scheme
    (:class:`dynslip.physics.solver.methods.TimeStepping`), the full-state baseline
    (:class:`dynslip.physics.solver.loadstep.FullStateLoadStep`), or one written outside the
    package. An equinox module, so that equal settings hash equal: the driver keys its
    compiled steps by the solver."""

    #: whether ``SegmentOutput.newton_iterations`` counts anything (False for the time-stepped
    #: solvers, whose Newton iterations diffrax keeps to itself)
    counts_newton: eqx.AbstractClassVar[bool]

    @property
    @abc.abstractmethod
    def name(self) -> str:
        """The run's ``method`` in its statistics."""

    # a property, not an abstract field (``eqx.AbstractVar``), which would move the subclasses'
    # ``max_steps`` field to the front of their fields and reprs
    @property
    @abc.abstractmethod
    def max_steps(self) -> int:
        """The step (increment) limit of one save segment."""

    @abc.abstractmethod
    def segment(self, model, layout, y0, t0, t1, dt0, args, rtol, atol, rate=None) -> SegmentOutput:
        """One save segment from ``y0`` at ``t0`` to ``t1`` (``dt0`` the first step tried;
        ``rate``: the previous segment's last rate, a predictor, where the solver uses one)."""


def segment_output(end, t1, rate, **extra) -> SegmentOutput:
    """The :class:`SegmentOutput` of an increment loop that ended in the carry ``end`` (its
    time ``t``, state ``y`` and counts ``accepted``, ``rejected``, ``iterations``): it reached
    ``t1`` with a finite state, or failed; ``rate`` and ``extra`` as the loop keeps them."""
    return SegmentOutput(
        y=end.y,
        ok=(end.t >= t1) & jnp.all(jnp.isfinite(end.y)),
        steps=end.accepted + end.rejected,
        accepted=end.accepted,
        rejected=end.rejected,
        newton_iterations=end.iterations,
        rate=rate,
        **extra,
    )


# --------------------------------------------------------------------------- the solver object


class MotionNewton(AbstractSegmentSolver):
    """Implicit Euler load increments, Newton on the motion alone (module docstring).

    ``rtol``/``atol`` (max norm; converged when the last correction is below
    ``atol + rtol |x|`` and the residual below ``atol``), at most ``max_iter`` corrections
    per increment, ``backtrack`` halvings of a correction that raises the residual,
    ``linear``: ``"auto"`` (block Thomas up to 64 nodes, block cyclic reduction above:
    :func:`dynslip.physics.solver.linalg.block_tridiagonal_solve`), ``"cyclic"`` or ``"thomas"``.
    Increments grow by 1.5
    after at most ``grow_below`` iterations and shrink by 0.7 after at least ``shrink_above``.
    ``floor_factor``, ``floor_count``: the residual
    floor (module docstring; 0: off); ``fail_cap``, ``fail_relax``: the memory of a failed
    increment's size within a segment (module docstring; 0: off). ``weight``: the
    complementarity parameter $c$ of the ball friction's weighted form in which Newton iterates
    (:func:`dynslip.physics.solver.increment.weighted_slip`; the law's roots for every $c$; 0: the
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

    #: the run's ``method`` in its statistics (the schema's ``numerics.solver``)
    name: ClassVar[str] = "load_step"
    counts_newton: ClassVar[bool] = True

    def increment(
        self, model, layout: Layout, t0, t1, y0, args, rate, rtol, atol
    ) -> IncrementResult:
        """One increment from ``y0`` at ``t0`` to ``t1``, Newton started from ``y0 + (t1 - t0)
        rate`` (``rate``: a :class:`Rate`, or any pair on the unknowns ``(q, zb)``): an
        :class:`IncrementResult` (its forces: the energy gradient, the held load and the held
        bodies' projections at ``y1``; its ball velocity: the one the increment took). With
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
        stretch = model.areal_stretch(rho, z)
        inc = Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args,
                        held_delta0=hdelta0, areal_stretch=stretch)
        rate = Rate(*rate)
        q = q0 + h * rate.q
        nf = layout.n_free
        # the weighted form of the ball's friction law (``weight``; not with free bodies, whose
        # residual is built apart)
        weighted = self.weight > 0 and not nf
        n = q0.shape[0]
        if nf:
            # free bodies: the border is (zb, z_1 .. z_K), placed into the model by res/blocks
            res0, blocks0, placed = free_system(model, friction, inc, layout.free(y0))
            zb = jnp.concatenate([jnp.reshape(zb0 + h * rate.zb, (1,)), layout.free(y0)])

            def res(q, zb):
                # the end state is evaluated after the loop (``state`` None)
                return (*res0(q, zb), None)

            def blocks(q, zb, state):
                return blocks0(q, zb)
        else:
            zb = zb0 + h * rate.zb

            # the increment with the law's weight
            data = Increment(q0=q0, zb0=zb0, delta0=delta0, t1=t1, h=h, args=args,
                             held_delta0=hdelta0, areal_stretch=stretch,
                             weight=self.weight if weighted else None)

            def res(q, zb):
                # the residual and the state the increment's end reads (:func:`residual_and_state`)
                r_q, r_z, state = residual_and_state(model, friction, data, q, zb)
                return r_q, r_z, EndState(*state)

            def blocks(q, zb, state):
                # the ball's velocity at (q, zb) from the residual's evaluation there
                return newton_blocks(model, friction, data, q, zb, vb=state.ball_velocity)

        def size(rq, rz):
            return jnp.maximum(jnp.max(jnp.abs(rq)), jnp.max(jnp.abs(rz)))

        def cond(c: NewtonIterate):
            return (~c.done) & (~c.bad) & (c.iterations < self.max_iter)

        # The loop's first pass evaluates the residual at the predictor (its correction is 0,
        # its trial accepted whatever the residual), and each pass ends with the next
        # correction, so the residual has one call site: each is compiled anew (about 10% of
        # the world's step). ``iterations`` counts the corrections (the predictor's pass is not
        # one).
        def body(c: NewtonIterate) -> NewtonIterate:
            f0 = jnp.where(c.first, jnp.inf, size(c.r_q, c.r_z))

            # the full step, then up to ``backtrack`` halvings while the residual rises: one
            # loop whose first pass is the full step, so the residual is traced once here (each
            # call site of it is compiled anew: 2 s of the world's compile per copy)
            def bt_cond(b: Trial):
                f1 = size(b.r_q, b.r_z)
                return (b.trials == 0) | (
                    ~((f1 <= f0) | (f1 <= atol)) & (b.trials <= self.backtrack)
                )

            def bt_body(b: Trial) -> Trial:
                alpha = jnp.where(b.trials == 0, 1.0, 0.5 * b.alpha)
                r_q, r_z, state = res(c.q - alpha * c.dq, c.zb - alpha * c.dz)
                return Trial(alpha, r_q, r_z, state, b.trials + 1)

            unset = Trial(jnp.array(1.0), jnp.full_like(c.r_q, jnp.inf),
                          jnp.full_like(c.r_z, jnp.inf), c.state, jnp.array(0))
            trial = jax.lax.while_loop(bt_cond, bt_body, unset)
            alpha, tq, tz = trial.alpha, trial.r_q, trial.r_z
            qn, zbn = c.q - alpha * c.dq, c.zb - alpha * c.dz
            step = jnp.maximum(
                jnp.max(jnp.abs(alpha * c.dq) / (atol + rtol * jnp.abs(qn))),
                jnp.max(jnp.abs(alpha * c.dz) / (atol + rtol * jnp.abs(zbn))),
            )
            done = ~c.first & (step < 1.0) & (size(tq, tz) <= atol)
            small = c.small
            if self.floor_factor:
                # the residual floor: Newton's full correction (not the damped one) below the
                # step tolerance ``floor_count`` times running, the residual within the floor
                full = jnp.maximum(
                    jnp.max(jnp.abs(c.dq) / (atol + rtol * jnp.abs(qn))),
                    jnp.max(jnp.abs(c.dz) / (atol + rtol * jnp.abs(zbn))),
                )
                small = jnp.where(~c.first & (full < 1.0), small + 1, 0)
                done = done | (
                    (small >= self.floor_count) & (size(tq, tz) <= self.floor_factor * atol)
                )
            bad = ~(
                jnp.all(jnp.isfinite(qn)) & jnp.all(jnp.isfinite(zbn)) & jnp.isfinite(size(tq, tz))
            )
            it = c.iterations + jnp.where(c.first, 0, 1)
            # the next correction, where another pass follows
            go = (~done) & (~bad) & (it < self.max_iter)
            dq, dz = jax.lax.cond(
                go,
                # Blocks: six arrays (mypy spreads an untyped star argument over every parameter)
                lambda: bordered_solve(
                    *cast(Blocks, blocks(qn, zbn, trial.state)), tq, tz, self.linear
                ),
                lambda: (jnp.zeros_like(c.dq), jnp.zeros_like(c.dz)),
            )
            return NewtonIterate(q=qn, zb=zbn, r_q=tq, r_z=tz, iterations=it, done=done,
                                 bad=bad, small=small, state=trial.state, dq=dq, dz=dz,
                                 first=jnp.array(False))

        # the loop's carry before the first pass: the residual and state are placeholders that
        # the first pass replaces (shapes as ``res`` returns them)
        state = None
        if not nf:
            state = EndState(g=jnp.zeros_like(q), ball_velocity=jnp.zeros_like(zb0),
                             delta=None if delta0 is None else jnp.zeros_like(delta0),
                             load=jnp.zeros_like(zb0),
                             projections=_unset_projections(model, n, 0.0))
        init = NewtonIterate(
            q=q, zb=zb, r_q=jnp.zeros_like(q), r_z=jnp.zeros_like(zb),
            iterations=jnp.array(0, jnp.int32), done=jnp.array(False), bad=jnp.array(False),
            small=jnp.array(0, jnp.int32), state=state, dq=jnp.zeros_like(q),
            dz=jnp.zeros_like(zb), first=jnp.array(True),
        )
        last = jax.lax.while_loop(cond, body, init)
        q, zb = last.q, last.zb
        zk = None
        if nf:
            zb, zk = zb[0], zb[1:]
            model = placed(zk)
            ps = held_projections(model, q, zb) if model.bodies else None
            g, load = forces(model, q, zb, ps)
            _, vb1, delta1 = increment_rates(model, friction, inc, q, zb, g, load, ps)
        else:
            # the converged state's gradient and rates, from the residual's last evaluation
            assert last.state is not None  # an EndState from the loop's start
            g, vb1, delta1 = last.state.g, last.state.ball_velocity, last.state.delta
            load, ps = last.state.load, last.state.projections
        f1 = Forces(g, load, ps)
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
        dy, _ = evaluate(model, layout, t1, y_rates, args, vb=vb1, forces=f1)
        y1 = y1.at[layout.accumulators].set(acc0 + h * dy[layout.accumulators])
        y1 = heal(model, layout, y1, args, self.heal_rate, vb=vb1, forces=f1)
        ok = last.done & ~last.bad & jnp.all(jnp.isfinite(y1))
        # a segment through a corner's centre: the corners' unsigned penalty would hold it on
        # the far side (physics/bodies/corners.py), so the increment is refused and cut
        ok = ok & ~corners_crossed(model, q0, zb0, q, zb)
        return IncrementResult(y=y1, ok=ok, iterations=last.iterations,
                               change=Rate(q - q0, zb - zb0), forces=f1, ball_velocity=vb1)

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
        ``rate`` (a :class:`Rate` or any pair on ``(q, zb)``; zero when None: a stage's start)
        predicts the first increment.
        The output's ``forces`` are the last accepted increment's at its end. A zero-length
        segment (``t1 == t0``: a run's initial frame) takes one zero-length increment, which
        leaves ``y0``, the rate, the increment's size and the counts as they are and gives the
        forces at ``y0``: so the frame has them from the one evaluation the loop compiles anyway
        (the frame's own differentiation of the energy was 9% of the main job's step)."""
        cap = increment_cap(args, self.max_increment, self.max_increment_free)
        dt_min = MIN_FRACTION * (t1 - t0)
        zero = jnp.array(0, dtype=jnp.int32)
        n = layout.n
        rate0 = zero_rate(n) if rate is None else Rate(*rate)

        def cond(c: SegmentCarry):
            return (
                ((c.t < t1) | c.fresh)
                & (c.accepted + c.rejected < self.max_steps)
                & (c.dt >= dt_min)
            )

        def body(c: SegmentCarry) -> SegmentCarry:
            left = t1 - c.t
            last = left <= 1.25 * c.dt
            h = jnp.where(last, left, c.dt)
            t_next = jnp.where(last, t1, c.t + h)
            r = self.increment(model, layout, c.t, t_next, c.y, args, c.rate, rtol, atol)
            moved = h > 0  # not the zero-length increment of a zero-length segment
            took = r.ok & moved
            dt_new, h_fail_new = self.next_size(
                c.dt, h, r.iterations, r.ok, c.was_cut, c.h_fail, cap
            )
            hs = jnp.where(moved, h, 1.0)
            new_rate = Rate(r.change.q / hs, r.change.zb / hs)
            keep = lambda new, old: jax.tree_util.tree_map(  # noqa: E731
                lambda a, b: jnp.where(took, a, b), new, old)
            return SegmentCarry(
                t=jnp.where(r.ok, t_next, c.t),
                y=keep(r.y, c.y),
                rate=keep(new_rate, c.rate),
                dt=jnp.where(moved, dt_new, c.dt),
                was_cut=jnp.where(moved, ~r.ok, c.was_cut),
                accepted=c.accepted + took,
                rejected=c.rejected + (~r.ok),
                iterations=c.iterations + jnp.where(moved, r.iterations, 0),
                h_fail=jnp.where(moved, h_fail_new, c.h_fail),
                forces=jax.tree_util.tree_map(lambda a, b: jnp.where(r.ok, a, b), r.forces,
                                              c.forces),
                ball_velocity=jnp.where(r.ok, r.ball_velocity, c.ball_velocity),
                fresh=jnp.array(False),
            )

        # the forces and velocity before any increment: not finite, so a frame can never read
        # them as values (a segment that ends without an accepted increment has failed, and is
        # not recorded)
        unset = Forces(jnp.full((n, 2), jnp.nan), jnp.full((), jnp.nan),
                       _unset_projections(model, n, jnp.nan))
        vb_unset = jnp.full((), jnp.nan)
        init = SegmentCarry(
            t=t0, y=y0, rate=rate0, dt=jnp.minimum(dt0, cap), was_cut=jnp.array(False),
            accepted=zero, rejected=zero, iterations=zero, h_fail=jnp.array(jnp.inf),
            forces=unset, ball_velocity=vb_unset, fresh=jnp.array(True),
        )
        end = jax.lax.while_loop(cond, body, init)
        return segment_output(end, t1, end.rate, forces=end.forces,
                              ball_velocity=end.ball_velocity)


def _unset_projections(model, n: int, fill):
    """Placeholders of :func:`~dynslip.physics.terms.held_projections`' output for ``n`` nodes
    (None without held bodies), every value ``fill``: a loop's carry before its first
    evaluation."""
    if not model.bodies:
        return None
    shapes = jax.eval_shape(lambda: held_projections(model, jnp.zeros((n, 2)), jnp.zeros(())))
    return jax.tree_util.tree_map(lambda a: jnp.full(a.shape, fill, a.dtype), shapes)


def zero_rate(n: int) -> Rate:
    """The predictor's rate at a stage's start: zero on ``(q, zb)``."""
    return Rate(jnp.zeros((n, 2)), jnp.zeros(()))
