r"""Structured linear algebra for the implicit solvers: a block-tridiagonal Jacobian
with a dense border, built by coloured forward-mode passes, solved by block Thomas
elimination and a Schur complement.

A one-dimensional sheet couples each node only to its neighbours; a few global states
(the ball's position, energy accumulators) couple to everything. With the state laid
out as ``y = [node 0 (b values), node 1, ..., node n-1, border (m values)]`` the
Jacobian is

$$ J = \begin{pmatrix} A & B \\ C & D \end{pmatrix},\qquad A \text{ block tridiagonal }
(n\times n \text{ blocks of } b\times b). $$

:class:`BorderedBlockTridiagonal` is a :class:`lineax.AbstractLinearSolver`: given any
linear operator with that sparsity (in diffrax, the Newton matrix $I - h\gamma J$
that :class:`diffrax.VeryChord` hands to its linear solver), ``init`` recovers the
blocks from $3b + m$ matrix-vector products (columns of the same colour never share
a row of $A$) and $m$ transposed products (the dense border rows), then factorises
$A$ in $O(n b^3)$ and the Schur complement $S = D - C A^{-1} B$ in $O(n b m + m^3)$.
``compute`` costs $O(n b^2 + n b m)$. Cost per Newton matrix therefore grows linearly
in $n$, against $O(n^2)$ evaluations and $O(n^3)$ factorisation for a dense LU.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
from jax.flatten_util import ravel_pytree
from lineax._solver.misc import (  # the helpers lineax's own solvers use
    pack_structures,
    ravel_vector,
    transpose_packed_structures,
    unravel_solution,
)

from dynslip.physics.field import EDGE_NODES
from dynslip.physics.layout import N_ACC, Layout


class Structure(eqx.Module):
    """Sparsity of the state: ``n`` nodes of ``b`` values each, then ``m`` border values.

    ``core_index`` (length ``n*b``) maps each blocked position to its index in the
    flat state, ``-1`` for padding (e.g. the pole's fixed rho); ``border_index``
    (length ``m``) likewise for the border. ``None`` means the identity layout.
    """

    n: int = eqx.field(static=True)
    b: int = eqx.field(static=True)
    m: int = eqx.field(static=True)
    core_index: tuple | None = eqx.field(static=True, default=None)
    border_index: tuple | None = eqx.field(static=True, default=None)

    @property
    def size(self) -> int:
        """Length of the flat state (padding excluded)."""
        if self.core_index is None:
            return self.n * self.b + self.m
        return sum(1 for i in self.core_index if i >= 0) + self.m

    def _indices(self):
        nb = self.n * self.b
        core = np.arange(nb) if self.core_index is None else np.asarray(self.core_index)
        border = (
            np.arange(nb, nb + self.m)
            if self.border_index is None
            else np.asarray(self.border_index)
        )
        return core, border

    def to_blocked(self, v):
        """Flat state vector -> blocked order ``[nodes (padded with 0), border]``."""
        core, border = self._indices()
        vc = jnp.where(core >= 0, v[np.maximum(core, 0)], 0.0)
        return jnp.concatenate([vc, v[border]])

    def from_blocked(self, w):
        """Blocked order -> flat state vector (padding dropped)."""
        core, border = self._indices()
        nb = self.n * self.b
        keep = np.flatnonzero(core >= 0)
        out = jnp.zeros(self.size, w.dtype)
        out = out.at[core[keep]].set(w[keep])
        return out.at[border].set(w[nb:])

    def padding(self):
        """Boolean mask over the blocked core: True at padding positions."""
        core, _ = self._indices()
        return core < 0


def _matvec(operator: lx.AbstractLinearOperator):
    """Flat matrix-vector product of an operator whose input/output are any pytrees."""
    zeros = jax.tree_util.tree_map(
        lambda sd: jnp.zeros(sd.shape, sd.dtype), operator.in_structure()
    )
    _, unravel = ravel_pytree(zeros)

    def mv(v):
        return ravel_pytree(operator.mv(unravel(v)))[0]

    return mv


class Blocks(NamedTuple):
    """A bordered block-tridiagonal matrix $\\begin{pmatrix}A & B\\\\ C & D\\end{pmatrix}$:
    ``lower[i] = A[i, i-1]``, ``diag[i] = A[i, i]``, ``upper[i] = A[i, i+1]`` (n, b, b), the
    border's columns ``B`` (n b, m), rows ``C`` (m, n b) and corner ``D`` (m, m)."""

    lower: jax.Array
    diag: jax.Array
    upper: jax.Array
    B: jax.Array
    C: jax.Array
    D: jax.Array


class Factorisation(NamedTuple):
    """:func:`factorise`'s output: the off-diagonal blocks, the block Thomas pivots' inverses
    ``invs``, $A^{-1}B$ (``ainv_b``), the border's rows ``C`` and the Schur complement's
    inverse."""

    lower: jax.Array
    upper: jax.Array
    invs: jax.Array
    ainv_b: jax.Array
    C: jax.Array
    schur_inv: jax.Array


class SolverState(NamedTuple):
    """:class:`BorderedBlockTridiagonal`'s state: the factorisation, the blocks it was made of
    (the transpose's) and the operator's packed input and output structures."""

    factorisation: Factorisation
    blocks: Blocks
    packed: Any


def extract_blocks(mv, mvT, s: Structure) -> Blocks:
    """The blocks of a bordered block-tridiagonal matrix from products with it.

    ``mv(v) = J v`` and ``mvT(w) = J^T w`` on flat vectors. Returns the :class:`Blocks`,
    ``lower[0]`` and ``upper[n-1]`` zero.
    """
    n, b, m = s.n, s.b, s.m
    nb = n * b
    pad = jnp.asarray(s.padding())

    def mv_blocked(v):  # blocked-order product, zero on padding
        r = s.to_blocked(mv(s.from_blocked(v)))
        return r.at[:nb].set(jnp.where(pad, 0.0, r[:nb]))

    def mvT_blocked(w):
        r = s.to_blocked(mvT(s.from_blocked(w)))
        return r.at[:nb].set(jnp.where(pad, 0.0, r[:nb]))

    node = jnp.arange(n)
    # probes[c, k] has ones at component k of every node i with i % 3 == c
    probes = jnp.zeros((3, b, n, b))
    probes = probes.at[node % 3, :, node, :].set(jnp.eye(b)[None, :, :])
    probes = probes.reshape(3 * b, nb)
    probes = jnp.concatenate([probes, jnp.zeros((3 * b, m))], axis=1)
    cols = jax.vmap(mv_blocked)(probes)[:, :nb].reshape(3, b, n, b)  # [c, k, row node, row comp]
    # Entry A[r, j][:, k] sits in probe (j % 3, k) at row node r, for |r - j| <= 1.
    cols = jnp.transpose(cols, (0, 2, 3, 1))  # [c, row node, row comp, k]

    def block(offset):
        j = node + offset
        valid = (j >= 0) & (j < n)
        blk = cols[jnp.clip(j, 0, n - 1) % 3, node]  # (n, b, b)
        return jnp.where(valid[:, None, None], blk, 0.0)

    lower, diag, upper = block(-1), block(0), block(+1)
    # identity on padding so that the factorisation stays regular
    diag = diag + jnp.eye(b)[None] * pad.reshape(n, b)[:, :, None]
    eye_m = jnp.concatenate([jnp.zeros((m, nb)), jnp.eye(m)], axis=1)
    right = jax.vmap(mv_blocked)(eye_m).T  # (nb + m, m): columns of [B; D]
    bottom = jax.vmap(mvT_blocked)(eye_m)  # (m, nb + m): rows of [C D]
    return Blocks(lower, diag, upper, right[:nb], bottom[:, :nb], right[nb:])


def small_matmul(a, b):
    r"""``a @ b`` for stacks of small blocks, ``a`` (..., p, r), ``b`` (..., r, k): the sum over
    the inner index unrolled into elementwise products. XLA on CPU runs a batched
    ``dot_general`` of 2x2 blocks as a loop of tiny matrix products; written out, the products
    fuse into one elementwise kernel (the block solves 5-8x faster at N = 50-800:
    ``python benchmarks/run.py newton_parts``, docs/speed.md)."""
    out = a[..., :, 0:1] * b[..., None, 0, :]
    for k in range(1, a.shape[-1]):
        out = out + a[..., :, k : k + 1] * b[..., None, k, :]
    return out


def small_inverse(a):
    r"""Inverses of a stack of small blocks (..., b, b): the closed form (the adjugate over the
    determinant) for b = 2, for which it is forward stable (Cramer's rule for 2x2 systems:
    Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Section 1.10.1); LU
    (``jnp.linalg.inv``) otherwise."""
    if a.shape[-1] != 2:
        return jnp.linalg.inv(a)
    a00, a01, a10, a11 = a[..., 0, 0], a[..., 0, 1], a[..., 1, 0], a[..., 1, 1]
    det = a00 * a11 - a01 * a10
    adj = jnp.stack([jnp.stack([a11, -a01], axis=-1), jnp.stack([-a10, a00], axis=-1)], axis=-2)
    return adj / det[..., None, None]


def small_solve(a, f):
    """Solve a stack of small systems ``a x = f``, ``a`` (..., b, b), ``f`` (..., b, k)."""
    if a.shape[-1] != 2:
        return jnp.linalg.solve(a, f)
    return small_matmul(small_inverse(a), f)


def _factor_tridiag(lower, diag, upper):
    """Block Thomas factorisation: inverses of the pivots S_i = D_i - L_i S_{i-1}^{-1} U_{i-1}."""

    def step(prev_inv, x):
        low, dia, up_prev = x
        s = dia - small_matmul(low, small_matmul(prev_inv, up_prev))
        inv = small_inverse(s)
        return inv, inv

    up_prev = jnp.concatenate([jnp.zeros_like(upper[:1]), upper[:-1]])
    first = small_inverse(diag[0])
    _, invs = jax.lax.scan(step, first, (lower[1:], diag[1:], up_prev[1:]))
    return jnp.concatenate([first[None], invs])


def _solve_tridiag(lower, upper, invs, f):
    """Solve A x = f for f of shape (n, b, k) with the factorisation of :func:`_factor_tridiag`."""

    def fwd(g_prev, x):
        low, inv_prev, fi = x
        g = fi - small_matmul(low, small_matmul(inv_prev, g_prev))
        return g, g

    inv_prev = jnp.concatenate([jnp.zeros_like(invs[:1]), invs[:-1]])
    g0 = f[0]
    _, g = jax.lax.scan(fwd, g0, (lower[1:], inv_prev[1:], f[1:]))
    g = jnp.concatenate([g0[None], g])

    def bwd(x_next, x):
        inv, up, gi = x
        xi = small_matmul(inv, gi - small_matmul(up, x_next))
        return xi, xi

    x_last = small_matmul(invs[-1], g[-1])
    _, xs = jax.lax.scan(bwd, x_last, (invs[:-1], upper[:-1], g[:-1]), reverse=True)
    return jnp.concatenate([xs, x_last[None]])


def factorise(lower, diag, upper, B, C, D, s: Structure) -> Factorisation:
    """Factorise the bordered block-tridiagonal matrix (block Thomas + Schur complement)."""
    invs = _factor_tridiag(lower, diag, upper)
    if s.m:
        ainv_b = _solve_tridiag(lower, upper, invs, B.reshape(s.n, s.b, s.m))  # (n, b, m)
        schur = D - C @ ainv_b.reshape(s.n * s.b, s.m)
        schur_inv = jnp.linalg.inv(schur)
    else:
        ainv_b = jnp.zeros((s.n, s.b, 0))
        schur_inv = jnp.zeros((0, 0))
    return Factorisation(lower, upper, invs, ainv_b, C, schur_inv)


def solve_factorised(fac: Factorisation, rhs, s: Structure):
    """Solve with the output of :func:`factorise`; ``rhs`` is flat (n b + m,)."""
    nb = s.n * s.b
    f, g = rhs[:nb], rhs[nb:]
    ainv_f = _solve_tridiag(fac.lower, fac.upper, fac.invs, f.reshape(s.n, s.b, 1)).reshape(nb)
    if not s.m:
        return ainv_f
    y = fac.schur_inv @ (g - fac.C @ ainv_f)
    x = ainv_f - fac.ainv_b.reshape(nb, s.m) @ y
    return jnp.concatenate([x, y])


def to_dense(lower, diag, upper, B, C, D, s: Structure):
    """The dense matrix of the blocks, in the flat state order (for tests)."""
    n, b = s.n, s.b
    A = jnp.zeros((n, b, n, b))
    i = jnp.arange(n)
    A = A.at[i, :, i, :].set(diag)
    A = A.at[i[1:], :, i[1:] - 1, :].set(lower[1:])
    A = A.at[i[:-1], :, i[:-1] + 1, :].set(upper[:-1])
    A = A.reshape(n * b, n * b)
    blocked = jnp.block([[A, B], [C, D]])
    core, border = s._indices()
    sel = np.concatenate([np.flatnonzero(core >= 0), n * b + np.arange(s.m)])
    flat_idx = np.concatenate([core[core >= 0], border])
    out = jnp.zeros((s.size, s.size))
    return out.at[np.ix_(flat_idx, flat_idx)].set(blocked[np.ix_(sel, sel)])


class BorderedBlockTridiagonal(lx.AbstractLinearSolver):
    """lineax solver for operators with the sparsity of :class:`Structure`.

    Use it as the linear solver of diffrax's root finder, e.g.
    ``diffrax.Kvaerno5(root_finder=diffrax.VeryChord(rtol, atol,
    linear_solver=BorderedBlockTridiagonal(structure)))``. The operator's input and
    output may be any pytrees whose flattened layout is ``[nodes..., border]``.
    Correctness rests on the declared sparsity: entries outside it are silently
    dropped, so check a new model with :func:`extract_blocks` against ``jax.jacfwd``.
    """

    structure: Structure

    def init(self, operator: lx.AbstractLinearOperator, options: dict[str, Any]):
        del options
        mv = _matvec(operator)
        mvT = _matvec(operator.transpose())
        blocks = extract_blocks(mv, mvT, self.structure)
        return SolverState(factorise(*blocks, self.structure), blocks,
                           pack_structures(operator))

    def compute(self, state: SolverState, vector, options):
        del options
        s = self.structure
        sol = s.from_blocked(solve_factorised(
            state.factorisation, s.to_blocked(ravel_vector(vector, state.packed)), s))
        return unravel_solution(sol, state.packed), lx.RESULTS.successful, {}

    def transpose(self, state: SolverState, options):
        b = state.blocks
        sw = lambda a: jnp.swapaxes(a, -1, -2)  # noqa: E731
        # (A^T)[i, i-1] = A[i-1, i]^T = upper[i-1]^T ; (A^T)[i, i+1] = lower[i+1]^T
        lower_t = jnp.concatenate([jnp.zeros_like(b.upper[:1]), sw(b.upper[:-1])])
        upper_t = jnp.concatenate([sw(b.lower[1:]), jnp.zeros_like(b.lower[:1])])
        blocks_t = Blocks(lower_t, sw(b.diag), upper_t, b.C.T, b.B.T, b.D.T)
        return SolverState(
            factorise(*blocks_t, self.structure),
            blocks_t,
            transpose_packed_structures(state.packed),
        ), {}

    def conj(self, state, options):
        return state, {}

    def assume_full_rank(self):
        return True


def cyclic_reduction(lower, diag, upper, f):
    r"""Solve the block-tridiagonal system $L_i x_{i-1} + D_i x_i + U_i x_{i+1} = f_i$ by block
    cyclic reduction: each level eliminates the odd-indexed rows from the even ones,
    $D'_i = D_i - \alpha U_{i-1} - \beta L_{i+1}$, $L'_i = -\alpha L_{i-1}$,
    $U'_i = -\beta U_{i+1}$, $f'_i = f_i - \alpha f_{i-1} - \beta f_{i+1}$ with
    $\alpha = L_i D_{i-1}^{-1}$, $\beta = U_i D_{i+1}^{-1}$, all rows at once; the half-size
    system is solved the same way and the odd unknowns follow from their own rows.
    $\lceil\log_2 n\rceil$ levels of batched $b\times b$ work (no sequential scan). Shapes as
    :func:`_solve_tridiag`: blocks (n, b, b), ``f`` (n, b, k); ``lower[0]`` and
    ``upper[-1]`` are ignored."""
    n, b = diag.shape[0], diag.shape[1]
    lower = lower.at[0].set(0.0)
    upper = upper.at[-1].set(0.0)
    if n == 1:
        return small_solve(diag[0], f[0])[None]
    if n % 2:  # pad with a decoupled identity row
        eye = jnp.eye(b, dtype=diag.dtype)[None]
        lower = jnp.concatenate([lower, jnp.zeros_like(lower[:1])])
        upper = jnp.concatenate([upper, jnp.zeros_like(upper[:1])])
        diag = jnp.concatenate([diag, eye])
        f = jnp.concatenate([f, jnp.zeros_like(f[:1])])
    le, de, ue, fe = lower[0::2], diag[0::2], upper[0::2], f[0::2]
    lo, do, uo, fo = lower[1::2], diag[1::2], upper[1::2], f[1::2]
    # D_odd^{-1} applied to [L_odd, U_odd, f_odd] in one batched solve
    sol = small_solve(do, jnp.concatenate([lo, uo, fo], axis=-1))
    il, iu, if_ = sol[..., :b], sol[..., b : 2 * b], sol[..., 2 * b :]

    # even row i couples to odd rows i-1 (index i//2 - 1) and i+1 (index i//2)
    def prev(a):
        return jnp.concatenate([jnp.zeros_like(a[:1]), a[:-1]])

    il_p, iu_p, if_p = prev(il), prev(iu), prev(if_)
    d2 = de - small_matmul(le, iu_p) - small_matmul(ue, il)
    l2 = -small_matmul(le, il_p)
    u2 = -small_matmul(ue, iu)
    f2 = fe - small_matmul(le, if_p) - small_matmul(ue, if_)
    xe = cyclic_reduction(l2, d2, u2, f2)
    xe_next = jnp.concatenate([xe[1:], jnp.zeros_like(xe[:1])])
    xo = if_ - small_matmul(il, xe) - small_matmul(iu, xe_next)
    x = jnp.stack([xe, xo], axis=1).reshape((-1,) + xe.shape[1:])
    return x[:n]


#: ``"auto"``'s choice: block Thomas up to this many blocks, cyclic reduction above
THOMAS_MAX_BLOCKS = 64


def block_tridiagonal_solve(lower, diag, upper, f, method: str = "cyclic"):
    """Solve the block-tridiagonal system for ``f`` (n, b, k): ``"cyclic"``
    (:func:`cyclic_reduction`), ``"thomas"`` (block Thomas, three sequential scans), or
    ``"auto"``: Thomas for n <= :data:`THOMAS_MAX_BLOCKS`, else cyclic reduction. At n = 50
    the two solve in the same time (0.097 and 0.100 ms, ``benchmarks/newton_parts.py``) and
    Thomas's scans compile smaller than the reduction's unrolled levels (the main job's step
    14652 -> 13494 ops, 0.4 s of its compile); from n = 200 cyclic reduction is 1.8-2.4x
    faster (docs/speed.md)."""
    if method == "auto":
        method = "thomas" if f.shape[0] <= THOMAS_MAX_BLOCKS else "cyclic"
    if method == "cyclic":
        return cyclic_reduction(lower, diag, upper, f)
    if method == "thomas":
        invs = _factor_tridiag(lower, diag, upper)
        return _solve_tridiag(lower, upper, invs, f)
    raise ValueError(f"unknown block-tridiagonal method {method!r} (cyclic, thomas, auto)")


def bordered_solve(lower, diag, upper, B, C, D, f, g, method: str = "cyclic"):
    r"""Solve $\begin{pmatrix}A & B\\ C & D\end{pmatrix}\begin{pmatrix}x\\ y\end{pmatrix} =
    \begin{pmatrix}f\\ g\end{pmatrix}$, $A$ block tridiagonal (blocks (n, b, b)), border of m
    unknowns (``B`` (n, b, m), ``C`` (m, n, b), ``D`` (m, m)), ``f`` (n, b), ``g`` (m,) or a scalar
    for m = 1: one block-tridiagonal solve for $[f, B]$ together, then the Schur complement
    $S = D - C A^{-1} B$. Returns ``(x, y)`` shaped as ``(f, g)``. A ``g`` of fewer than m
    entries is the first of them, the rest 0 (auxiliary unknowns, such as the ball's velocity
    change in :func:`dynslip.physics.solver.newton_matrix.blocks_with_held_friction`), and ``y`` its
    first entries."""
    n, b = f.shape
    m = D.shape[0]
    sol = block_tridiagonal_solve(
        lower, diag, upper, jnp.concatenate([f[:, :, None], B], axis=-1), method
    )
    ainv_f, ainv_b = sol[:, :, 0], sol[:, :, 1:]
    cflat = C.reshape(m, n * b)
    schur = D - cflat @ ainv_b.reshape(n * b, m)
    gv = jnp.reshape(g, (-1,))
    k = gv.shape[0]
    gv = jnp.concatenate([gv, jnp.zeros(m - k, gv.dtype)]) if k < m else gv
    y = jnp.linalg.solve(schur, gv - cflat @ ainv_f.reshape(n * b))
    x = ainv_f - ainv_b @ y
    return x, jnp.reshape(y[:k], jnp.shape(g))


def sheet_structure(layout: Layout) -> Structure:
    r"""Sparsity of the state for :class:`BorderedBlockTridiagonal`.

    Node ``i`` is the block ``(rho_i, z_i)`` (``rho_0`` fixed: padding); a node's rate
    relative to the ball depends only on its neighbours (element energies, the hoop
    stretch at element midpoints, the node's own contact frame), so those blocks are
    tridiagonal. A friction law's per-node state (slip distance) joins its node's block
    (``b = 3``): its rate depends on the node's slip, i.e. on the node and its neighbours.

    The dense border holds the ball height, the accumulators, and the last
    :data:`EDGE_NODES` nodes (the clamped edge and its neighbour). Every node moves with the
    ball (``v = u + v_b e_z``), and a force-controlled ball's velocity
    $v_b = (F_b + C_z + F_g)/\eta_b$ depends on the clamp's force $C_z = \partial E/\partial
    z_{n-1}$,
    i.e. on the last element's two nodes: every row depends on them, so they belong in the
    border (with a held ball the coupling vanishes and the border simply holds a few zeros).
    ``tests/test_structured.py`` checks the pattern against ``jax.jacfwd`` with the ball
    held and force-controlled.
    """
    n = layout.n
    n_core = n - EDGE_NODES

    def node(i):
        return (
            [-1 if i == 0 else i - 1, n - 1 + i]
            + ([layout.internal_start + i] if layout.n_int else [])
            + [layout.held_start + k * n + i for k in range(layout.n_held_int)]
        )

    core = [j for i in range(n_core) for j in node(i)]
    edge = [j for i in range(n_core, n) for j in node(i)]
    border = tuple(edge + list(range(2 * n - 1, 2 * n + N_ACC)))
    return Structure(
        n=n_core, b=2 + layout.n_int + layout.n_held_int, m=len(border), core_index=tuple(core),
        border_index=border,
    )
