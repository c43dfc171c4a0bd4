"""The structured Jacobian and solver against jax.jacfwd and a dense solve."""

import diffrax
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import pytest

from dynslip.physics.solver.linalg import (
    BorderedBlockTridiagonal,
    Structure,
    extract_blocks,
    to_dense,
)

S = Structure(n=13, b=2, m=3)


def field(y):
    """A stiff nonlinear chain (nodes of 2 values, neighbour coupling) with a 3-value border."""
    n, b = S.n, S.b
    u = y[: n * b].reshape(n, b)
    w = y[n * b :]
    pad = jnp.pad(u, ((1, 1), (0, 0)))
    lap = pad[:-2] - 2 * u + pad[2:]
    core = 50.0 * lap - jnp.sin(u[:, ::-1]) * u - w[0] * u**2 + w[1]
    border = jnp.stack(
        [jnp.sum(u**2) - w[0], jnp.mean(jnp.cos(u)) * w[1] - w[2], w[0] * w[2] - jnp.sum(u[:, 0])]
    )
    return jnp.concatenate([core.reshape(-1), border])


Y0 = jnp.asarray(np.random.default_rng(0).normal(size=S.size))


@pytest.mark.slow
def test_blocks_equal_jacfwd():
    jac = jax.jacfwd(field)(Y0)
    mv = lambda v: jax.jvp(field, (Y0,), (v,))[1]  # noqa: E731
    mvT = lambda w: jax.vjp(field, Y0)[1](w)[0]  # noqa: E731
    dense = to_dense(*extract_blocks(mv, mvT, S), S)
    np.testing.assert_allclose(dense, jac, rtol=1e-12, atol=1e-12 * float(jnp.abs(jac).max()))


@pytest.mark.parametrize("transpose", [False, True])
def test_solver_matches_dense_solve(transpose):
    jac = jax.jacfwd(field)(Y0)
    a = jnp.eye(S.size) - 0.01 * jac  # a Newton matrix I - h J
    op = lx.MatrixLinearOperator(a.T if transpose else a)
    rhs = jnp.arange(S.size, dtype=float)
    x = lx.linear_solve(op, rhs, BorderedBlockTridiagonal(S)).value
    np.testing.assert_allclose(x, jnp.linalg.solve(op.as_matrix(), rhs), rtol=1e-10)
    # the solver's own transpose
    solver = BorderedBlockTridiagonal(S)
    st, _ = solver.transpose(solver.init(lx.MatrixLinearOperator(a), {}), {})
    xt, _, _ = solver.compute(st, rhs, {})
    np.testing.assert_allclose(xt, jnp.linalg.solve(a.T, rhs), rtol=1e-10)


def test_diffrax_with_structured_solver_matches_dense():
    term = diffrax.ODETerm(lambda t, y, args: field(y))
    y0 = 0.1 * Y0

    def solve(linear_solver):
        solver = diffrax.Kvaerno5(
            root_finder=diffrax.VeryChord(rtol=1e-8, atol=1e-8, linear_solver=linear_solver)
        )
        sol = diffrax.diffeqsolve(
            term,
            solver,
            0.0,
            0.5,
            0.01,
            y0,
            stepsize_controller=diffrax.PIDController(rtol=1e-7, atol=1e-9),
        )
        return sol.ys[-1], sol.stats["num_steps"]

    ys, steps_s = solve(BorderedBlockTridiagonal(S))
    yd, steps_d = solve(lx.LU())
    np.testing.assert_allclose(ys, yd, rtol=1e-6, atol=1e-8)


# A sheet-like layout: y = [rho_1..rho_{K-1}, z_0..z_{K-1}, border(2)], rho_0 fixed at 0.
K = 9
SHEET = Structure(
    n=K,
    b=2,
    m=2,
    core_index=tuple(
        int(i) for pair in [(-1, K - 1)] + [(j - 1, K - 1 + j) for j in range(1, K)] for i in pair
    ),
    border_index=(2 * K - 1, 2 * K),
)


def sheet_field(y):
    rho = jnp.concatenate([jnp.zeros(1), y[: K - 1]])
    z = y[K - 1 : 2 * K - 1]
    zb, e = y[2 * K - 1], y[2 * K]
    x = jnp.stack([rho, z], 1)
    seg = jnp.linalg.norm(jnp.diff(x, axis=0), axis=1)
    energy = jnp.sum((seg - 0.3) ** 2 * (1 + rho[1:] + rho[:-1])) + jnp.sum((z - zb) ** 4) + zb**2
    g = jax.grad(
        lambda rz: (
            jnp.sum(
                (jnp.linalg.norm(jnp.diff(rz, axis=0), axis=1) - 0.3) ** 2
                * (1 + rz[1:, 0] + rz[:-1, 0])
            )
            + jnp.sum((rz[:, 1] - zb) ** 4)
        )
    )(x)
    return jnp.concatenate([-g[1:, 0], -g[:, 1], jnp.stack([jnp.sum(z) - zb, energy - e])])


@pytest.mark.slow
def test_permuted_layout_blocks_equal_jacfwd():
    y0 = jnp.asarray(np.random.default_rng(1).normal(size=SHEET.size))
    jac = jax.jacfwd(sheet_field)(y0)
    mv = lambda v: jax.jvp(sheet_field, (y0,), (v,))[1]  # noqa: E731
    mvT = lambda w: jax.vjp(sheet_field, y0)[1](w)[0]  # noqa: E731
    dense = to_dense(*extract_blocks(mv, mvT, SHEET), SHEET)
    np.testing.assert_allclose(dense, jac, rtol=1e-10, atol=1e-10 * float(jnp.abs(jac).max()))
    a = jnp.eye(SHEET.size) - 0.05 * jac
    rhs = jnp.linspace(-1, 1, SHEET.size)
    x = lx.linear_solve(lx.MatrixLinearOperator(a), rhs, BorderedBlockTridiagonal(SHEET)).value
    np.testing.assert_allclose(x, jnp.linalg.solve(a, rhs), rtol=1e-9)


@pytest.mark.parametrize("b", [2, 3])
def test_small_block_ops_equal_numpy(b):
    """The written-out block products, inverses and solves (2x2 closed form; LU for 3x3) equal
    numpy's on random stacks, including ill-conditioned blocks (Cramer's rule for 2x2 is forward
    stable: the error bound is the condition number times the round-off)."""
    from dynslip.physics.solver.linalg import small_inverse, small_matmul, small_solve

    rng = np.random.default_rng(b)
    a = rng.normal(size=(64, b, b))
    a[:8] = a[:8] + 1e6 * np.eye(b)  # well-conditioned, scaled
    a[8:16, 0] = a[8:16, 1] + 1e-9 * rng.normal(size=(8, b))  # nearly singular rows
    f = rng.normal(size=(64, b, 5))
    np.testing.assert_allclose(small_matmul(jnp.asarray(a), jnp.asarray(f)), a @ f, rtol=1e-13,
                               atol=1e-13 * np.abs(a).max() * np.abs(f).max())
    cond = np.linalg.cond(a)
    x = np.asarray(small_solve(jnp.asarray(a), jnp.asarray(f)))
    x_ref = np.linalg.solve(a, f)
    err = np.abs(x - x_ref).max(axis=(1, 2)) / np.abs(x_ref).max(axis=(1, 2))
    assert np.all(err <= 50 * cond * np.finfo(float).eps), (err / cond).max()
    inv = np.asarray(small_inverse(jnp.asarray(a)))
    inv_ref = np.linalg.inv(a)
    err = np.abs(inv - inv_ref).max(axis=(1, 2)) / np.abs(inv_ref).max(axis=(1, 2))
    assert np.all(err <= 50 * cond * np.finfo(float).eps)
