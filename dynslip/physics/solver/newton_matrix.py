r"""The Newton matrix of the increment's residual (:mod:`dynslip.physics.solver.increment`) as the
blocks of a bordered block-tridiagonal system
(:func:`dynslip.physics.solver.linalg.bordered_solve`):
the chain rule $\partial u_i/\partial q_j = L^q_i\delta_{ij} + L^g_i H_{ij}$ from the node
rates' derivatives and the energy's Hessian blocks (:func:`newton_blocks`); with friction on the
held bodies, the ball's velocity couples every node (:func:`blocks_with_held_friction`); with
free held bodies, their heights join the border (:func:`free_system`). Checked block by block
against ``jacfwd`` of the residual (tests/test_newton.py, tests/test_bodies_sheet.py).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from dynslip.physics import conditions
from dynslip.physics.bodies.held import frictional, held_entries, place_free
from dynslip.physics.field import free_body_rates
from dynslip.physics.solver.increment import (
    Increment,
    ball_rate,
    ball_velocity,
    corner_share_jacobians,
    corner_shares,
    edge_rate,
    held_share_jacobians,
    held_shares,
    node_force_jacobian,
    node_held_frame,
    node_rate,
    residual,
    sheet_held_frame,
    untouched,
)
from dynslip.physics.solver.linalg import small_matmul
from dynslip.physics.terms import forces, forces_and_hessians, held_projections

__all__ = ["blocks_with_held_friction", "free_system", "newton_blocks"]


def newton_blocks(model, friction, inc: Increment, q, zb, vb=None, exact=True):
    """The Newton matrix of :func:`residual` as blocks ``(lower, diag, upper, B, C, D)``
    (shapes (n,2,2) x3, (n,2,m), (m,n,2), (m,m); the border m = 1, ``zb``, or with held friction
    and ``exact`` m = 2, ``zb`` and the ball's velocity change) from element and node
    derivatives. ``vb``:
    the ball's velocity at ``(q, zb)`` where the caller has it (the residual's, which Newton
    carries), read with held friction only (None: :func:`ball_velocity`'s); ``exact``: with
    held friction, :func:`blocks_with_held_friction`'s border of two."""
    if frictional(model.bodies):
        return blocks_with_held_friction(model, friction, inc, q, zb, vb, exact)
    n = q.shape[0]
    g, h_diag, h_up, load, hh = forces_and_hessians(model, q, zb)
    idx = jnp.arange(n)
    d0 = inc.delta0 if inc.delta0 is not None else jnp.zeros(n)
    mem = inc.delta0 is not None

    cs = corner_shares(model, q)  # held at the iterate's value (corner_shares)

    def local(i, qi, gi, di, ci):
        return node_rate(model, friction, inc, i, qi, gi, di if mem else None, corner=ci)[0]

    if cs is None:
        lq = jax.vmap(jax.jacfwd(local, argnums=1))(idx, q, g, d0, cs)  # (n, 2, 2)
        share = None
    else:
        # the rate reads the node's share of the corners' normal force, which reads the
        # node and its two neighbours (block tridiagonal)
        lq, ln = jax.vmap(jax.jacfwd(local, argnums=(1, 4)))(idx, q, g, d0, cs)
        share = _share_blocks(ln, corner_share_jacobians(model, q))
        lq = lq + share[0]
    lg = jax.vmap(
        lambda i, qi, gi, di, ci: node_force_jacobian(model, friction, inc, i, qi, gi,
                                                      di if mem else None, corner=ci)
    )(idx, q, g, d0, cs)
    # the clamped edge: rate from its force and the ball height only
    eg, ez, el, er = jax.jacfwd(
        lambda ge, z, ld, r: edge_rate(model, inc, ge, z, ld, None, r), argnums=(0, 1, 2, 3)
    )(g[-1], zb, load, q[-1, 0])
    bg, bz, bl = jax.jacfwd(lambda ge, z, ld: ball_rate(inc, ge, z, ld), argnums=(0, 1, 2))(
        g[-1], zb, load
    )
    lq = lq.at[-1].set(jnp.zeros((2, 2)).at[:, 0].set(er))  # the band's grip reads rho_edge
    lg = lg.at[-1].set(eg)
    h_low = jnp.swapaxes(h_up, 1, 2)  # d2E/dx_{i+1} dx_i
    h = inc.h
    eye = jnp.eye(2)
    diag = eye - h * (lq + small_matmul(lg, h_diag))
    upper = jnp.concatenate([-h * small_matmul(lg[:-1], h_up), jnp.zeros((1, 2, 2))])
    lower = jnp.concatenate([jnp.zeros((1, 2, 2)), -h * small_matmul(lg[1:], h_low)])
    if share is not None:
        upper, lower = upper - h * share[1], lower - h * share[2]
    B = jnp.zeros((n, 2, 1)).at[-1, :, 0].set(-h * ez)
    C = jnp.zeros((1, n, 2))
    C = C.at[0, -1].set(-h * bg @ h_diag[-1]).at[0, -2].set(-h * bg @ h_low[-1])
    D = jnp.reshape(1.0 - h * bz, (1, 1))
    if hh is not None:
        # the held bodies see q + zb: every node's force moves with zb (d g_i/d zb = hh_i e_z;
        # not a body that moves with the ball), and the load L = sum_i dE_h/dz_i enters the
        # ball's and the edge's rates
        hh, hz = hh
        dg_dz = hz[:, :, 1]  # (n, 2)
        dl_dq = hh[:, 1, :]  # (n, 2)
        dl_dz = jnp.sum(hz[:, 1, 1])
        col = jnp.einsum("nij,nj->ni", lg, dg_dz).at[-1].set(eg @ dg_dz[-1] + el * dl_dz)
        B = B - h * col[:, :, None]
        C = C - h * bl * dl_dq[None]
        D = D - h * (bg @ dg_dz[-1] + bl * dl_dz)
        # a pinned edge on a free ball moves with the ball, whose rate reads every node's load:
        # the edge's and its neighbour's part is kept (the rest is not block tridiagonal and
        # is left out: an inexact Newton matrix, the residual exact; exact for a held ball)
        diag = diag.at[-1].add(-h * jnp.outer(el, dl_dq[-1]))
        lower = lower.at[-1].add(-h * jnp.outer(el, dl_dq[-2]))
    return lower, diag, upper, B, C, D


def _share_blocks(ln, jac):
    """The rates' derivatives through the nodes' shares of corner normal forces: ``ln`` (n, 2)
    or (n, 2, K) the rate's derivative in the node's share(s) (the clamped edge's row left at
    0), ``jac`` the shares' ``(own, up, low)`` ((n, 2) or (K, n, 2)); returns the (n, 2, 2)
    blocks on the diagonal, above and below (row i, column i + 1 and i - 1)."""
    ln = ln.at[-1].set(0.0)
    if ln.ndim == 2:
        return tuple(ln[:, :, None] * d[:, None, :] for d in jac)
    return tuple(jnp.einsum("nik,knj->nij", ln, d) for d in jac)


def _held_node_terms(model, friction, inc: Increment, moving, i, q, g, delta0, zb, vb,
                     projections, corner=None, held_corner=None):
    r"""Node ``i``'s rate's derivatives in $(q_i, g_i, z_b, v_b)$ with held friction, and
    those of the axial friction force on it, $\sum_k f_{ik} t_{k,z}$ (the ball's velocity
    reads them): ``(lq, lg, lz, lv, aq, ag, az, av)``. The held bodies' friction $f_k = (S_k -
    G_k)\,t_k$ reads the force only through $G_k = f\cdot t_k + (\partial G_k/\partial v_b)
    v_b$ ($f = -g$), so its derivatives in $g$ and $v_b$ are closed forms in the laws' slopes
    (:meth:`~dynslip.physics.bodies.held.HeldFrame.slopes`): $\partial f_k/\partial g =
    (1 - S'_k)\,t_k t_k^T$, $\partial f_k/\partial v_b = (S'_k - 1)(\partial G_k/\partial
    v_b)\,t_k$; the ball's part in $g$ is :func:`node_force_jacobian`'s. Forward mode in the
    position alone (two directions), per body, so that $\partial f_k/\partial z_b$ is the
    position's $z$ derivative for a body at rest and 0 for one that moves with the ball (its
    projection reads $x_z - z_b$). ``moving`` (static): per frictional body, whether it moves
    with the ball. ``projections``: the held bodies' of the node, computed once with the
    penalty's and moved with the position here to first order
    (:meth:`~dynslip.physics.bodies.segments.Projection.linearised`: their value and first
    derivative, which is all a Jacobian reads)."""
    eta_a = inc.args.drag * model.mesh.area[i]

    def parts(qi, ci, hi):
        dx = qi - jax.lax.stop_gradient(qi)
        ps = tuple(p.linearised(dx) for p in projections)
        hf = node_held_frame(model, inc, i, qi, g, zb, ps, hi)
        # the ball's law in its weighted form where no held friction acts on the node
        alone = untouched(hf)
        u = node_rate(model, friction, inc, i, qi, g, delta0, held=False, alone=alone,
                      corner=ci)[0]
        gk, sk = hf.slip(vb)
        fk = jnp.where(hf.live, sk - gk, 0.0)[:, None] * hf.t  # (K, 2)
        # the slopes at the primal point (no derivative of them is taken)
        stop = jax.tree_util.tree_map(jax.lax.stop_gradient, hf)
        _, _, ds, dgv = stop.slopes(jax.lax.stop_gradient(vb))
        return (u, fk), (stop.t, stop.live, ds, dgv, alone)

    # the derivatives in the node's shares of the corners' normal forces too, where any
    nums = (0,) + ((1,) if corner is not None else ()) + ((2,) if held_corner is not None else ())
    (uj, fj), (t, live, ds, dgv, alone) = jax.jacfwd(parts, argnums=nums, has_aux=True)(
        q, corner, held_corner)
    uq, fq = uj[0], fj[0]
    lnb = uj[1] if corner is not None else None
    lnh = anh = None
    if held_corner is not None:
        fh = fj[-1]  # (K, 2, K'): the held frictions in the node's held shares
        lnh = uj[-1] + jnp.sum(fh, axis=0) / eta_a
        anh = jnp.sum(fh, axis=0)[1]
    w = jnp.where(live, 1.0 - ds, 0.0)  # (K,): -df_k/dG_k
    fg = jnp.einsum("k,ki,kj->kij", w, t, t)  # (K, 2, 2)
    fv = -(w * dgv)[:, None] * t  # (K, 2)
    rest = jnp.asarray([0.0 if m else 1.0 for m in moving])
    fz = jnp.einsum("k,ki->i", rest, fq[:, :, 1])
    fq, fg, fv = jnp.sum(fq, axis=0), jnp.sum(fg, axis=0), jnp.sum(fv, axis=0)
    lq = uq + fq / eta_a
    lg = node_force_jacobian(model, friction, inc, i, q, g, delta0, alone, corner) + fg / eta_a
    return lq, lg, fz / eta_a, fv / eta_a, fq[1], fg[1], fz[1], fv[1], lnb, lnh, anh


def blocks_with_held_friction(model, friction, inc: Increment, q, zb, vb=None, exact=True):
    r""":func:`newton_blocks` with friction on the held bodies. The node rates depend on the
    ball's velocity $v_b$ (:func:`ball_velocity`), which reads every node in contact with a
    frictional body: with $V_j = dv_b/dq_j$ and $V_z = dv_b/dz_b$ (the implicit function
    theorem on the ball's equation $\eta_b v_b - A_0 - \sum_i a_i(v_b) = 0$, $a_i$ node $i$'s
    axial held friction, whose derivatives :func:`_held_node_terms` gives with the node's
    rate's, and the chain rule through the energy's Hessian), the border row
    is $-h V$, the column $-h(\ell^g_i\,\partial g_i/\partial z_b + \ell^z_i + \ell^v_i V_z)$,
    and the node rates' rank-one coupling $\ell^v_i V_j$ through the ball's velocity couples
    every node to every other (not block tridiagonal).

    ``exact`` (the default): the coupling enters through a second border unknown, the ball's
    velocity change $w = \sum_j V_j\,dq_j + V_z\,dz_b$: the node rows read $-h\ell^v_i w$, the
    ball's row $dz_b - h w$, and $w$'s own row $\sum_j V_j\,dq_j + V_z\,dz_b - w = 0$ (right-hand
    side 0: :func:`dynslip.physics.solver.linalg.bordered_solve` pads it). Eliminating $w$ gives the
    exact Newton matrix. ``exact=False``: the border of one, $z_b$, with the coupling kept
    where $|i - j| \le 1$ and the rest left out (an inexact matrix, the residual exact; what
    :func:`free_system` builds on). With the ball held $V = 0$ and both are exact.
    ``vb``: :func:`newton_blocks`'s."""
    n = q.shape[0]
    args = inc.args
    # the held bodies' projections once, for the penalty and the held friction
    ps = held_projections(model, q, zb)
    g, h_diag, h_up, load, hh = forces_and_hessians(model, q, zb, ps)
    if vb is None:
        # the ball's velocity (held: prescribed, the root search skipped by lax.cond)
        vb = ball_velocity(model, inc, q, zb, g, load, ps)
    idx = jnp.arange(n)
    mem = inc.delta0 is not None
    d0 = inc.delta0 if mem else jnp.zeros(n)
    moving = tuple(e.moves_with_ball for e in held_entries(model.bodies)
                   if e.friction is not None)

    # held at the iterate's value (corner_shares)
    cs, hs = corner_shares(model, q), held_shares(model, q, zb)

    def local(i, qi, gi, di, pi, ci, hi):
        return _held_node_terms(model, friction, inc, moving, i, qi, gi, di if mem else None,
                                zb, vb, pi, ci, hi)

    lq, lg, lz, lv, aq, ag, az, av, lnb, lnh, anh = jax.vmap(local)(idx, q, g, d0, ps, cs, hs)
    # the rates' and the axial friction's derivatives through the nodes' shares of the corners'
    # normal forces (each reads the node and its two neighbours)
    share = [jnp.zeros((n, 2, 2))] * 3
    if lnb is not None:
        share = [s + b for s, b in zip(share, _share_blocks(lnb, corner_share_jacobians(
            model, q)), strict=True)]
    if lnh is not None:
        hj = held_share_jacobians(model, q, zb)
        share = [s + b for s, b in zip(share, _share_blocks(lnh, hj), strict=True)]
        a_own, a_up, a_low = (jnp.einsum("nk,knj->nj", anh.at[-1].set(0.0), d) for d in hj)
        # dA_i/dq_j summed over the rows i that read q_j
        aq = aq + a_own
        aq = aq.at[1:].add(a_up[:-1]).at[:-1].add(a_low[1:])
        # z_b at fixed q moves every node against a body at rest: the shares move with it
        rest = jnp.asarray([0.0 if e.moves_with_ball else 1.0 for e in held_entries(model.bodies)])
        dn_dz = rest[:, None] * (hj[0][..., 1] + hj[1][..., 1] + hj[2][..., 1])  # (K, n)
        lz = lz + jnp.einsum("nik,kn->ni", lnh.at[-1].set(0.0), dn_dz)
        az = az + jnp.einsum("nk,kn->n", anh.at[-1].set(0.0), dn_dz)
    lq = lq + share[0]
    eg, ev, er = jax.jacfwd(
        lambda ge, v, r: edge_rate(model, inc, ge, zb, load, v, r), argnums=(0, 1, 2)
    )(g[-1], vb, q[-1, 0])
    lq, lz = lq.at[-1].set(jnp.zeros((2, 2)).at[:, 0].set(er)), lz.at[-1].set(0.0)
    lg, lv = lg.at[-1].set(eg), lv.at[-1].set(ev)
    # the ball's equation eta_b v - A_0(C_z, z_b, L) - sum_i a_i = 0 (a free ball; held: its
    # velocity is prescribed, V = 0): dv_b/dy = (dA_0/dy + sum_i da_i/dy) dv_b/dA, the
    # compliance dv_b/dA = 1/(eta_b - sum_i da_i/dv_b) (conditions.ball_compliance); A_0's
    # derivatives in the edge's gradient (the clamp's force), z_b (the support) and L
    inv = conditions.ball_compliance(args, jnp.sum(av))
    a_g, a_z, a_l = jax.jacfwd(
        lambda ge, z, ld: conditions.ball_load(
            args, inc.t1, z, conditions.clamp_force(args, inc.t1, ge)[1] - ld),
        argnums=(0, 1, 2),
    )(g[-1], zb, load)
    vq = inv * aq
    vg = (inv * ag).at[-1].add(inv * a_g)
    vz = inv * (a_z + jnp.sum(az))
    vl = inv * a_l
    h_low = jnp.swapaxes(h_up, 1, 2)  # h_low[j] = d2E/dx_{j+1} dx_j
    hh, hz = hh
    dg_dz = hz[:, :, 1]  # (n, 2): the held bodies at rest see q + zb
    dl_dq = hh[:, 1, :]
    dl_dz = jnp.sum(hz[:, 1, 1])
    # dv_b/dq_j through the forces: sum_i (dv_b/dg_i) H_ij, H tridiagonal
    big_v = vq + jnp.einsum("ni,nij->nj", vg, h_diag) + vl * dl_dq
    big_v = big_v.at[1:].add(jnp.einsum("ni,nij->nj", vg[:-1], h_up))
    big_v = big_v.at[:-1].add(jnp.einsum("ni,nij->nj", vg[1:], h_low))
    v_z = vz + jnp.sum(vg * dg_dz) + vl * dl_dz
    h = inc.h
    eye = jnp.eye(2)
    diag = eye - h * (lq + small_matmul(lg, h_diag))
    upper = -h * (small_matmul(lg[:-1], h_up) + share[1][:-1])
    lower = -h * (small_matmul(lg[1:], h_low) + share[2][1:])
    col = jnp.einsum("nij,nj->ni", lg, dg_dz) + lz
    if exact:
        # the border (z_b, w): w the ball's velocity change, its row sum_j V_j dq_j + V_z dz_b
        B = -h * jnp.stack([col, lv], axis=-1)  # (n, 2, 2)
        C = jnp.stack([jnp.zeros_like(big_v), big_v])  # (2, n, 2)
        D = jnp.stack([jnp.stack([jnp.ones_like(v_z), -h]), jnp.stack([v_z, -jnp.ones_like(v_z)])])
    else:
        diag = diag - h * jnp.einsum("ni,nj->nij", lv, big_v)
        upper = upper - h * jnp.einsum("ni,nj->nij", lv[:-1], big_v[1:])
        lower = lower - h * jnp.einsum("ni,nj->nij", lv[1:], big_v[:-1])
        B = -h * (col + lv * v_z)[:, :, None]
        C = -h * big_v[None]
        D = jnp.reshape(1.0 - h * v_z, (1, 1))
    upper = jnp.concatenate([upper, jnp.zeros((1, 2, 2))])
    lower = jnp.concatenate([jnp.zeros((1, 2, 2)), lower])
    return lower, diag, upper, B, C, D


def free_system(model, friction, inc: Increment, zk0):
    r"""The increment's residual and Newton matrix with free held bodies
    (:attr:`dynslip.physics.bodies.held.Held.free`): the border unknowns are $(z_b, z_1 ..
    z_K)$, the bodies' residuals $z_k - z_{k,0} - \Delta t\,v_k$ with $v_k = (L_k + F_k)/\eta_k$
    (:func:`dynslip.physics.field.free_body_rates`). The block-tridiagonal part and the ball's
    border are :func:`newton_blocks`' at the bodies' heights; the bodies' columns (K forward
    passes of the residual) and rows (K reverse passes) are exact. Returns ``(res, blocks,
    placed)``, ``placed(zk)`` the model with the bodies at ``zk``."""
    def placed(zk):
        # at the increment's end, moving at the increment's velocity (the slip relative to a
        # frictional free body); at rest over a zero-length increment (a segment's start)
        moved = inc.h > 0
        v = jnp.where(moved, zk - zk0, 0.0) / jnp.where(moved, inc.h, 1.0)
        return place_free(model, zk, v)

    def body_res(q, zb, zk):
        m = placed(zk)
        hf = vb = None
        if frictional(m.bodies):
            g, load = forces(m, q, zb)
            hf = sheet_held_frame(m, inc.args, q, zb, g, inc.held_delta0)
            vb = ball_velocity(m, inc, q, zb, g, load)
        v, _, _ = free_body_rates(m, q[:, 0], q[:, 1] + zb, zb, hf, vb)
        return zk - zk0 - inc.h * v

    def res(q, w):
        zb, zk = w[0], w[1:]
        r_q, r_z = residual(placed(zk), friction, inc, q, zb)
        return r_q, jnp.concatenate([jnp.reshape(r_z, (1,)), body_res(q, zb, zk)])

    def blocks(q, w):
        zb, zk = w[0], w[1:]
        lower, diag, upper, b, c, d = newton_blocks(placed(zk), friction, inc, q, zb,
                                                    exact=False)
        cq, cz = jax.jacfwd(lambda zk: residual(placed(zk), friction, inc, q, zb))(zk)
        rq, rzb, rzk = jax.jacrev(body_res, argnums=(0, 1, 2))(q, zb, zk)
        b = jnp.concatenate([b, cq], axis=-1)  # (n, 2, 1 + K)
        c = jnp.concatenate([c, rq], axis=0)  # (1 + K, n, 2)
        d = jnp.block([[d, cz[None, :]], [rzb[:, None], rzk]])
        return lower, diag, upper, b, c, d

    return res, blocks, placed
