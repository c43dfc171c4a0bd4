r"""Friction on the held bodies: each held body carries its own law.

A held body is an entry of :attr:`dynslip.physics.sheet.SheetModel.bodies`: a bare
:class:`~.base.AbstractBody` (frictionless, the default) or a :class:`Held` pairing the body
with a friction law (:mod:`dynslip.physics.friction`: Coulomb, or any law with the interface
``threshold(fn, internal=None, area=None)``, e.g. a pressure-dependent one, or slip weakening
with healing).

**Slip weakening** (``n_internal() == 1``): a slip distance per node relative to each such body
in the state (:func:`n_memory`, :attr:`HeldFrame.delta`); mu at the increment's start, advanced
and healed as the ball's (docs/bodies.md, "Slip weakening on a held body").

**The law.** Node $i$ touching held body $k$ (penalty normal force $N_{ik} > 0$, the body's
tangent $t_k$ at the node) slips *relative to that body*, which is at rest. The sheet's drag
stays relative to the ball, $\eta A(\dot x - v_b e_z) = F + f$ (one drag frame for every
node, so the rates are continuous where a node comes into or leaves contact), and the friction
force $f_{ik} = f_{ik} t_k$ is the return map of the slip relative to the body,
$w = \dot x\cdot t_k$:

$$G_{ik} = F_i\cdot t_k + \eta A_i v_b t_{k,z},\qquad
  \eta A_i\, w = S(G_{ik}, \mu_k N_{ik}),\qquad f_{ik} = S - G_{ik},$$

$G$ the tangential force that would keep the node at rest on the body (the driving force plus
the drag the ball's motion drags it with). Stuck ($|G| \le \mu N$): $w = 0$ exactly; slipping:
$|f| = \mu N$. With the ball at rest (held, or on its support) this is the ball's law on the
body's tangent. Its power $-f w = (G - S)S/(\eta A) \ge 0$ is the friction dissipation; the
friction's reaction acts on the body, so the axial load the held bodies carry is the penalty's
$L = \sum_i \partial E_h/\partial z_i$ less $\sum_{ik} f_{ik} t_{k,z}$, and the ball does not
feel it. The pole node (no tangential motion) and the clamped edge carry no held friction.

A node touching several bodies gets the sum of each body's friction, each from the node's own
driving force (not coupled: exact for one body at a time, which is the case away from corners
where two bodies meet).

**The ball's velocity.** A force-controlled ball moves at
$v_b = (F_h + F_s + C_z - L(v_b) + F_g)/\eta_b$, and $L$ depends on $v_b$ through $G$: a
scalar equation $g(v_b) = \eta_b v_b - A_0 - \sum f_{ik}t_{k,z} = 0$, strictly increasing
($g' = \eta_b + \sum_{ik}(1 - S')\eta A_i t_{k,z}^2 \ge \eta_b$) with its root in
$[(A_0 - B)/\eta_b, (A_0 + B)/\eta_b]$, $B = \sum \mu N|t_z|$. Solved by safeguarded Newton
(:func:`free_ball_velocity`), differentiated by the implicit function theorem (one Newton step
from the stopped root).

The held entry and its placement, the friction frame built on them (slip, force, the slopes
the Newton matrix reads, dissipation, the slip distances' memory) and the ball's velocity that
is the root of the frame's axial force are one mechanism, documented here as one.

Example::

    >>> import jax.numpy as jnp
    >>> from dynslip.physics.bodies.torus import Torus
    >>> from dynslip.physics.friction import Coulomb
    >>> entries = held_entries((Torus(2.0, 0.2), Held(Torus(3.0, 0.2), Coulomb(mu=0.5))))
    >>> [e.friction is None for e in entries]
    [True, False]
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from dynslip.physics.bodies.base import AbstractBody
from dynslip.physics.bodies.corners import corner_normal, corners_of
from dynslip.physics.friction import AbstractFriction

__all__ = [
    "Held",
    "HeldFrame",
    "free_ball_velocity",
    "held_corner_normal",
    "held_entries",
    "held_frame",
    "n_free",
    "n_memory",
    "place_bodies",
    "place_free",
    "projected",
    "stage_moved",
]

#: safeguarded Newton iterations of the free ball's velocity (piecewise smooth and monotone: a
#: few steps land on the linear piece of the root; each iteration halves the bracket at worst)
BALL_ITERATIONS = 24


class Held(eqx.Module):
    """A held body and its friction law against the sheet (None: frictionless).

    ``moves_with_ball`` (static): the body is carried with the ball (the bottle in the tube's
    frame, docs/bodies.md): it sits at its reference placement displaced by the ball's height
    ``zb``, so a node's gap and its slip are relative to the ball. Its load still goes to the
    lab (the table under the bottle), not to the ball's hold.

    ``stage`` (static): the body is moved by the protocol's stages (each stage gives it an axial
    velocity, :class:`dynslip.physics.protocols.Stage` ``body_vz``). Inside a solve it is
    placed at ``offset`` (R) moving at ``velocity`` (R/s) by :func:`place_bodies`; the slip
    is relative to it, and the work it does on the sheet is the run's ``work_bodies``.

    ``free`` (static): the body moves along the axis under the sheet's pressure, the reaction of
    the sheet's friction on it (when it has a law) and the applied axial ``force`` (G h0 R,
    + up) against its drag ``drag`` (G h0 R s / R); its height is a state unknown (load
    stepping: a border unknown of Newton's system beside the ball's), placed by
    :func:`place_free` at the increment's end, moving at the increment's velocity (the slip
    relative to it)."""

    body: AbstractBody
    friction: AbstractFriction | None = None
    moves_with_ball: bool = eqx.field(static=True, default=False)
    stage: bool = eqx.field(static=True, default=False)
    offset: float | jax.Array = 0.0
    velocity: float | jax.Array = 0.0
    free: bool = eqx.field(static=True, default=False)
    force: float | jax.Array = 0.0
    drag: float | jax.Array = 1.0

    def shift(self, zb):
        """The body's axial displacement: ``zb`` when it moves with the ball, else its
        ``offset`` (0 for a body at rest)."""
        return zb if self.moves_with_ball else self.offset

    def speed(self, vb):
        """The body's axial velocity: the ball's ``vb`` when it moves with it, else its own."""
        return vb if self.moves_with_ball else self.velocity

    def __check_init__(self):
        if self.free and (self.moves_with_ball or self.stage):
            raise ValueError("a free held body has no other motion")
        if self.friction is not None and self.friction.n_internal() > 1:
            raise ValueError(
                "a held body's friction law carries at most one value per node (the slip "
                f"distance); {type(self.friction).__name__} carries "
                f"{self.friction.n_internal()}"
            )


def held_entries(bodies) -> tuple:
    """The model's held bodies as :class:`Held` entries (a bare body: frictionless)."""
    return tuple(b if isinstance(b, Held) else Held(b) for b in bodies)


def projected(entry: Held, k: int, x, zb, projections=None):
    """The projection of the points ``x`` onto the held body ``entry`` (the ``k``-th in held
    order), displaced by its :meth:`Held.shift` at ``zb``: ``projections[k]`` where the caller
    has them (:func:`dynslip.physics.terms.held_projections`, one evaluation shared by a
    residual's terms), else projected here."""
    if projections is not None:
        return projections[k]
    return entry.body.project(x, entry.shift(zb))


def stage_moved(bodies) -> bool:
    """Whether any held body is moved by the stages (static)."""
    return any(e.stage for e in held_entries(bodies))


def place_bodies(model, body_z0, body_v, t0, t):
    """``model`` with each stage-moved held body placed at time ``t`` of a stage that started at
    ``t0`` with the bodies at ``body_z0`` (K,) moving at ``body_v`` (K,) (one per held entry, in
    order; R and R/s); unchanged when ``body_z0`` is None (no body is moved by a stage)."""
    if body_z0 is None:
        return model
    entries = []
    for k, e in enumerate(held_entries(model.bodies)):
        if e.stage:
            e = eqx.tree_at(
                lambda h: (h.offset, h.velocity),
                e,
                (body_z0[k] + body_v[k] * (t - t0), body_v[k]),
                is_leaf=lambda x: x is None,
            )
        entries.append(e)
    return eqx.tree_at(lambda m: m.bodies, model, tuple(entries))


def n_free(bodies) -> int:
    """How many held bodies are free along the axis (static)."""
    return sum(e.free for e in held_entries(bodies))


def place_free(model, zk, vk=None):
    """``model`` with its free bodies at the heights ``zk`` (n_free,) (R, in held order) and,
    when given, moving at ``vk`` (R/s: the slip relative to a frictional one); unchanged when
    ``zk`` is None."""
    if zk is None:
        return model
    entries, j = [], 0
    for e in held_entries(model.bodies):
        if e.free:
            e = eqx.tree_at(lambda h: h.offset, e, zk[j])
            if vk is not None:
                e = eqx.tree_at(lambda h: h.velocity, e, vk[j])
            j += 1
        entries.append(e)
    return eqx.tree_at(lambda m: m.bodies, model, tuple(entries))


def n_memory(bodies) -> int:
    """How many held bodies have a friction law with memory (one slip distance per node, e.g.
    :class:`~dynslip.physics.friction.SlipWeakening`; static): the rows of the state's
    held-internal block (:meth:`dynslip.physics.field.Layout.held_internal`), in held order."""
    return sum(e.friction is not None and e.friction.n_internal() == 1
               for e in held_entries(bodies))


def frictional(bodies) -> bool:
    """Whether any held body carries a friction law (static)."""
    return any(e.friction is not None for e in held_entries(bodies))


class HeldFrame(eqx.Module):
    """Per frictional held body k and node (trailing shape ``...``): the tangent ``t`` (K, ..., 2),
    the normal force ``normal`` (K, ...), the driving force along the tangent ``ft`` (K, ...),
    and the drag coefficient ``eta_a`` (...). ``laws`` the K friction laws, ``eps`` the
    smoothing per node, ``area`` the reference areas, ``live`` where held friction acts."""

    t: jnp.ndarray
    normal: jnp.ndarray
    ft: jnp.ndarray
    eta_a: jnp.ndarray
    eps: jnp.ndarray
    area: jnp.ndarray
    live: jnp.ndarray
    laws: tuple
    moving: tuple = eqx.field(static=True, default=())
    speeds: tuple = ()  # the bodies' own axial velocities (R/s; empty: all at rest)
    # per frictional body, its slip distances (...) at which mu is taken (a law with memory:
    # the increment's start, delta0), None for a memoryless law; empty: no law has memory
    delta: tuple = ()

    def _delta(self, k):
        return self.delta[k] if self.delta else None

    def _carried(self, k, vb):
        # the drag the ball's motion drags a node with, relative to the body: eta A (vb - v_k)
        # t_z (v_k = 0 at rest); none on a body that moves with the ball
        if self.moving and self.moving[k]:
            return 0.0
        rel = vb - self.speeds[k] if self.speeds else vb
        return self.eta_a * rel * self.t[k][..., 1]

    def _drive(self, vb):
        # G per body and node (K, ...)
        return jnp.stack([self.ft[k] + self._carried(k, vb) for k in range(len(self.laws))])

    def _slip_of(self, g):
        # S(G, mu N) per body and node (K, ...)
        return jnp.stack(
            [
                law.slip_force(g[k], self.normal[k], self._delta(k), eps=self.eps,
                               area=self.area)
                for k, law in enumerate(self.laws)
            ]
        )

    def slip(self, vb):
        """``(G, S)`` per body and node (K, ...) at the ball's velocity ``vb``."""
        g = self._drive(vb)
        return g, self._slip_of(g)

    def slopes(self, vb):
        r"""``(G, S, dS/dG, dG/dv_b)`` per body and node (K, ...): the laws' slopes in the
        driving force (one forward pass; each $S_k$ reads its own $G_k$ only) and the drag the
        ball's motion adds to $G$ per unit velocity ($\eta A\,t_{k,z}$; 0 on a body that moves
        with the ball). With them the friction force $f_k = S_k - G_k$ has the closed-form
        derivatives $\partial f_k/\partial G_k = S'_k - 1$ and $\partial f_k/\partial v_b =
        (S'_k - 1)\,\partial G_k/\partial v_b$ (:func:`dynslip.physics.solver.newton_matrix.
        blocks_with_held_friction`)."""
        g, dg = jax.jvp(self._drive, (vb,), (jnp.ones_like(vb),))
        s, ds = jax.jvp(self._slip_of, (g,), (jnp.ones_like(g),))
        return g, s, ds, dg

    def force(self, vb):
        """The held friction force on each node (..., 2), summed over the bodies."""
        g, s = self.slip(vb)
        f = jnp.where(self.live, s - g, 0.0)
        return jnp.sum(f[..., None] * self.t, axis=0)

    def dissipation(self, vb):
        """Friction power on the held bodies per node (...), $(G - S)S/(\\eta A) \\ge 0$."""
        g, s = self.slip(vb)
        return jnp.sum(jnp.where(self.live, (g - s) * s / self.eta_a, 0.0), axis=0)

    def axial_per_body(self, vb):
        """$\\sum_i f_{ik} t_{k,z}$ per frictional body (K,)."""
        g, s = self.slip(vb)
        f = jnp.where(self.live, s - g, 0.0)
        return jnp.sum(f * self.t[..., 1], axis=tuple(range(1, f.ndim)))

    def axial(self, vb):
        """$\\sum_{ik} f_{ik} t_{k,z}$: the axial friction force on the sheet (its reaction on the
        bodies)."""
        return jnp.sum(self.force(vb)[..., 1])

    def bound(self):
        """$B = \\sum \\mu N |t_z|$, the largest the axial friction can be."""
        thr = jnp.stack(
            [law.threshold(self.normal[k], self._delta(k), self.area)
             for k, law in enumerate(self.laws)]
        )
        return jnp.sum(jnp.where(self.live, thr * jnp.abs(self.t[..., 1]), 0.0))

    def _each_memory(self, vb, fn):
        # fn(k, S_k) for each body whose law has memory, stacked (K_mem, ...); None without any
        mem = [k for k in range(len(self.laws)) if self._delta(k) is not None]
        if not mem:
            return None
        _, s = self.slip(vb)
        return jnp.stack([fn(k, s[k]) for k in mem])

    def internal_rates(self, vb):
        r"""The slip distances' rates (K_mem, ...): $|S|/(\eta A)$ in contact (the law's
        ``internal_rate``), 0 where held friction does not act; None without memory."""
        return self._each_memory(vb, lambda k, s: jnp.where(
            self.live, self.laws[k].internal_rate(s / self.eta_a, self.normal[k], self.delta[k]),
            0.0))

    def advance(self, vb, h):
        r"""The return map (K_mem, ...): $\delta_0 + h|S(G, \mu(\delta_0) N)|/(\eta A)$ where
        the node touches the body ($N > 0$, held friction acting), else $\delta_0$."""
        return self._each_memory(vb, lambda k, s: jnp.where(
            self.live & (self.normal[k] > 0), self.delta[k] + h * jnp.abs(s) / self.eta_a,
            self.delta[k]))

    def reset(self, vb, heal_rate):
        """The slip distances after healing (K_mem, ...): 0 where the slip speed relative to the
        body is at most ``heal_rate``, out of contact, or held friction does not act."""
        return self._each_memory(vb, lambda k, s: jnp.where(
            self.live, self.laws[k].reset(self.delta[k], s / self.eta_a, self.normal[k],
                                          heal_rate), 0.0))


#: whether a held body's corners' normal force enters its friction (:func:`held_corner_normal`).
#: Off: with it on, the lab frame and the tube's frame no longer give one path
#: (tests/test_lab_frame.py: 2.5e-4 R apart instead of 4e-10; the cause is not found), so a
#: held body's corners are frictionless; its Newton matrix terms are kept and checked
#: (tests/test_sharp_edges_newton.py switches it on)
HELD_CORNER_FRICTION = False


def held_corner_normal(bodies, x, pen, zb=0.0):
    """Each held body's corners' normal force shared over the nodes ``x`` (n, 2) (absolute)
    (:func:`~dynslip.physics.bodies.corners.corner_normal`), as (K, n) in held order, or None
    when no held body has corners: the held friction reads it beside the nodes' own penalty
    force (:func:`held_frame`'s ``corners``)."""
    entries = held_entries(bodies)
    if not HELD_CORNER_FRICTION or all(corners_of(e.body) is None for e in entries):
        return None
    return jnp.stack([corner_normal(e.body, x, pen, e.shift(zb)) for e in entries])


def held_frame(bodies, x, f, normal_of, area, drag, eps, live, zb=0.0,
               delta=None, projections=None, corners=None) -> HeldFrame | None:
    """The :class:`HeldFrame` of the frictional held bodies at node positions ``x`` (..., 2)
    (absolute), driving forces ``f`` (..., 2), reference areas ``area`` (...); ``normal_of(d)``
    the penalty's normal force per reference area of a signed distance; ``live`` where held
    friction acts (not the pole, not the clamped edge); ``zb`` the ball's height (displaces a
    body that moves with the ball); ``delta`` (K_mem, ...) the slip distances of the bodies
    whose law has memory (:func:`n_memory`, in held order; None: none has, or each at 0);
    ``projections`` every held body's projection of ``x`` (in held order: one evaluation shared
    with the penalty's, :func:`dynslip.physics.terms.held_projections`; None: projected here);
    ``corners`` (K, ...) each held body's corners' normal force on the nodes
    (:func:`held_corner_normal`; None: none), added to the nodes' own.
    None when no held body has friction."""
    laws, ts, ns, fts, moving, speeds, deltas = [], [], [], [], [], [], []
    j = 0
    for k, e in enumerate(held_entries(bodies)):
        if e.friction is None:
            continue
        if e.friction.n_internal() == 1:
            deltas.append(jnp.zeros_like(area) if delta is None else delta[j])
            j += 1
        else:
            deltas.append(None)
        p = projected(e, k, x, zb, projections)
        laws.append(e.friction)
        moving.append(e.moves_with_ball)
        speeds.append(e.velocity)
        ts.append(p.tangent)
        normal = area * normal_of(p.distance)
        ns.append(normal if corners is None else normal + corners[k])
        fts.append(jnp.sum(f * p.tangent, axis=-1))
    if not laws:
        return None
    return HeldFrame(
        t=jnp.stack(ts),
        normal=jnp.stack(ns),
        ft=jnp.stack(fts),
        eta_a=drag * area,
        eps=eps * area,
        area=area,
        live=live,
        laws=tuple(laws),
        moving=tuple(moving) if any(moving) else (),
        # the bodies' own velocities where one moves on its own (by the stages, or free)
        speeds=tuple(speeds) if any(e.stage or e.free for e in held_entries(bodies)) else (),
        delta=tuple(deltas) if j else (),
    )


def free_ball_velocity(frame: HeldFrame | None, a0, ball_drag, held=None):
    r"""The force-controlled ball's velocity: the root of $\eta_b v - A_0 - \sum f t_z(v) = 0$
    (module docstring), ``a0`` $= F_h + F_s + C_z - L_{pen} + F_g$. Without frictional held
    bodies, $A_0/\eta_b$. ``held`` (a traced bool): the ball is held and the caller discards
    this value, so the root search is skipped (``lax.cond``; under ``vmap`` both branches run)."""
    if frame is None:
        return a0 / ball_drag

    def g(v):
        return ball_drag * v - a0 - frame.axial(v)

    # the root search runs on stopped values (its derivative is the last line's)
    fs = jax.tree_util.tree_map(lambda a: jax.lax.stop_gradient(a) if eqx.is_array(a) else a, frame)
    a0s = jax.lax.stop_gradient(a0)

    def gs(v):
        return ball_drag * v - a0s - fs.axial(v)

    b = fs.bound()
    lo0, hi0 = (a0s - b) / ball_drag, (a0s + b) / ball_drag

    def step(_, c):
        v, lo, hi = c
        gv, dg = jax.jvp(gs, (v,), (jnp.ones_like(v),))
        lo = jnp.where(gv < 0, v, lo)
        hi = jnp.where(gv > 0, v, hi)
        vn = v - gv / jnp.where(dg > 0, dg, 1.0)
        inside = (vn > lo) & (vn < hi)
        vn = jnp.where(gv == 0, v, jnp.where(inside, vn, 0.5 * (lo + hi)))
        return vn, lo, hi

    v0 = jnp.clip(a0s / ball_drag, lo0, hi0)

    def search():
        # safeguarded Newton until the iterate stops moving (round-off), at most
        # BALL_ITERATIONS steps
        def more(c):
            k, (v, _, _), moved = c
            return (k < BALL_ITERATIONS) & moved

        def once(c):
            k, (v, lo, hi), _ = c
            vn, lo, hi = step(k, (v, lo, hi))
            return k + 1, (vn, lo, hi), jnp.abs(vn - v) > 4 * jnp.finfo(v.dtype).eps * jnp.abs(v)

        return jax.lax.while_loop(more, once, (0, (v0, lo0, hi0), jnp.array(True)))[1][0]

    root = search() if held is None else jax.lax.cond(held, lambda: v0, search)
    root = jax.lax.stop_gradient(root)
    # one Newton step from the stopped root: its value is the root, its derivative the implicit
    # function theorem's -g_x / g_v
    gv, dg = jax.jvp(g, (root,), (jnp.ones_like(root),))
    return root - gv / dg
