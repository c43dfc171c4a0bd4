"""Two-pass contact (physics/bodies/corners.py): a body's corners against the sheet's segments.

- A membrane draped over a knife edge (a ring of radius 0.005 R between two nodes 0.1 R
  apart): node-only contact lets the sheet through, the two-pass contact stops it, and the
  corner's reaction is the membrane's force jump across it (closed forms below).
- The corner's force is the exact gradient of its energy (the energy balance's premise), and
  its Hessian blocks are the energy's.
- A body without corners (the unit ball) gets exactly today's contact: identical numbers.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies.corners import (
    corner_crossed,
    corner_energy,
    corner_normal,
    corner_terms,
    corners_of,
)
from dynslip.physics.bodies.disc import Disc
from dynslip.physics.bodies.sphere import Sphere
from dynslip.physics.bodies.torus import Torus
from dynslip.physics.materials import make_material
from dynslip.physics.sheet import (
    Penalty,
    SheetModel,
    make_mesh,
    penalty_energy,
    penalty_pressure,
)
from dynslip.physics.terms import forces, forces_and_hessians

N = 21
PRE = 1.2
RIM = 2.0
EDGE = 0.005  # the knife's radius (R): 1/20 of the element
RING = 1.05  # between the nodes at rho 1.0 and 1.1 of the flat pre-stretched sheet
TOP = -1e-3  # the knife's top, just below the flat sheet
DROP = 0.6  # the clamp's final depth below the flat sheet
STEPS = 150  # clamp steps of 0.004 R
CAP = 0.5 * EDGE  # the largest node move of one Newton iteration: no jump across the knife
PEN = Penalty(1.0e5, 1.0e-4)


def _model(ball):
    mesh = make_mesh(N, RIM / PRE)
    return SheetModel(mesh, make_material("neo_hookean"), PEN, ball=ball)


KNIFE = Torus(RING, EDGE, TOP - EDGE)


def _energies(model):
    """The two-pass energy (the model's) and the node-only one (the same without the
    corners)."""

    def two(rho, z):
        return model.energy(rho, z, 0.0)

    def nodes(rho, z):
        pen = jnp.sum(model.mesh.area * penalty_energy(model.penalty,
                                                       model.penetration(rho, z, 0.0)))
        return model.elastic_energy(rho, z) + pen

    return two, nodes


def _solver(energy, rho0):
    """Equilibrium of the sheet with the pole on the axis and the edge clamped at
    (RIM, zc): damped Newton on the energy, compiled once (zc traced)."""
    n = rho0.size

    def unpack(v, zc):
        rho = jnp.concatenate([jnp.zeros(1), v[: n - 2], jnp.array([RIM])])
        z = jnp.concatenate([v[n - 2:], jnp.reshape(zc, (1,))])
        return rho, z

    def f(v, zc):
        return energy(*unpack(v, zc))

    grad, hess = jax.grad(f), jax.hessian(f)

    @jax.jit
    def solve(v, zc):
        def body(_, v):
            g, h = grad(v, zc), hess(v, zc)
            # the membrane is stiff in-plane and soft out of plane: a Levenberg shift keeps the
            # step a descent direction where the Hessian is not positive definite
            lam = jnp.maximum(0.0, -jnp.min(jnp.linalg.eigvalsh(h))) * 1.1 + 1e-9
            dv = -jnp.linalg.solve(h + lam * jnp.eye(v.size), g)
            dv = dv * jnp.minimum(1.0, CAP / jnp.max(jnp.abs(dv)))

            def ls(c):
                a, _ = c
                return a * 0.5, f(v + a * 0.5 * dv, zc)

            a, _ = jax.lax.while_loop(
                lambda c: (c[1] > f(v, zc)) & (c[0] > 1e-6), ls, (1.0, f(v + dv, zc))
            )
            return v + a * dv

        return jax.lax.fori_loop(0, 30, body, v)

    def run():
        v = jnp.concatenate([jnp.asarray(rho0[1:-1]), jnp.zeros(n - 1)])
        for zc in np.linspace(0.0, -DROP, STEPS + 1)[1:]:
            v = solve(v, zc)
        return unpack(v, -DROP), grad(v, -DROP)

    return run


@pytest.fixture(scope="module")
def draped():
    model = _model(KNIFE)
    rho0 = PRE * np.asarray(model.mesh.rbar)
    two, nodes = _energies(model)
    (r2, z2), g2 = _solver(two, rho0)()
    (r1, z1), g1 = _solver(nodes, rho0)()
    return model, (np.asarray(r2), np.asarray(z2), np.asarray(g2)), (
        np.asarray(r1), np.asarray(z1), np.asarray(g1))


def _height_at(rho, z, r):
    return float(np.interp(r, rho, z))


def test_knife_edge_between_two_nodes(draped):
    """The knife (radius 1/20 of an element) lies between two nodes: with node-only contact
    the sheet passes it and lies flat at the clamp's depth; with the two-pass contact it
    stays on the knife, its straddling segment tangent to the knife's circle (penetration
    below a tenth of its radius)."""
    model, (r2, z2, g2), (r1, z1, g1) = draped
    assert np.max(np.abs(g2)) < 1e-8 and np.max(np.abs(g1)) < 1e-8  # equilibria
    j = int(np.searchsorted(r2, RING)) - 1
    assert r2[j] < RING < r2[j + 1]  # the knife falls between nodes j and j+1
    # node-only: through, flat at the clamp (no node touches the knife)
    assert _height_at(r1, z1, RING) == pytest.approx(-DROP, abs=1e-6)
    assert np.all(np.abs(np.asarray(model.penetration(r1, z1, 0.0))) > EDGE)
    # two-pass: held up by the knife between two nodes
    assert np.all(np.asarray(model.penetration(r2, z2, 0.0)) < 0)  # no node on it
    c = np.array([RING, TOP - EDGE])
    a, b = np.array([r2[j], z2[j]]), np.array([r2[j + 1], z2[j + 1]])
    s = np.clip(np.dot(c - a, b - a) / np.dot(b - a, b - a), 0, 1)
    gap = np.linalg.norm(c - (a + s * (b - a))) - EDGE
    assert -0.1 * EDGE < gap < 0.0
    # the inner disc is flat, above the knife's top (the straddling segment slopes down over it)
    assert np.ptp(z2[: j + 1]) < 1e-9 and z2[j] > TOP


def test_knife_reaction_is_the_tension_jump(draped):
    r"""The closed form of a membrane over a knife edge. Inside the knife the disc is flat:
    its axial membrane force $2\pi\rho T_\theta\sin\psi$ is 0. Outside, a free span: the axial
    force is the same through every parallel circle (no load on it), $F$. The knife's axial
    reaction is the jump, $F - 0$. The reaction is the force on the body, minus the sum of the
    corner's forces on the nodes; with node-only contact it is 0."""
    model, (r2, z2, _), _ = draped
    x = jnp.stack([jnp.asarray(r2), jnp.asarray(z2)], axis=-1)
    # the force on the knife: minus the sum of the corner's forces on the nodes
    _, g = corner_terms(KNIFE, x, PEN)
    reaction = np.asarray(jnp.sum(g, axis=0))
    axial = np.asarray(model.free_span_axial_force(jnp.asarray(r2), jnp.asarray(z2)))
    j = int(np.searchsorted(r2, RING)) - 1
    out = axial[j + 2:-1]  # the elements past those the knife touches
    assert np.ptp(out) < 2e-3 * abs(out.mean())  # a free span: one axial force
    assert np.max(np.abs(axial[: j - 1])) < 1e-6  # the flat disc: none
    # the sheet pulls the knife down by the span's axial force (closed form: the jump)
    assert reaction[1] == pytest.approx(out.mean(), rel=1e-6)
    # node-only: no reaction (the sheet passed)
    _, _, (r1, z1, _) = draped
    _, g1 = corner_terms(KNIFE, jnp.stack([jnp.asarray(r1), jnp.asarray(z1)], axis=-1), PEN)
    assert float(jnp.max(jnp.abs(g1))) == 0.0


def test_corner_force_is_the_energy_gradient():
    """The corners' forces are the exact gradient of their energy (so the energy balance
    stays a test): the gradient against central differences, the Hessian blocks against
    jax.hessian of the whole energy, and the normal shares sum to the pairs' normal forces."""
    coin = Disc(1.0, 0.15, 0.03)
    rng = np.random.default_rng(3)
    # a sheet draped over the coin's edge: segments crossing its rounded corner
    t = np.linspace(0.0, 1.0, 9)
    x = np.stack([0.9 + 0.2 * t, 0.081 - 0.2 * t**2], axis=-1) + 1e-3 * rng.standard_normal((9, 2))
    x = jnp.asarray(x)
    pen = Penalty(1.0e4, 1.0e-3)
    e, g, (hd, hu) = corner_terms(coin, x, pen, 0.0, hessian=True)
    assert float(e) > 0  # the chords cut the corner
    assert float(e) == pytest.approx(float(corner_energy(coin, x, pen)), rel=1e-14)
    num = np.zeros((9, 2))
    for i in range(9):
        for k in range(2):
            dx = jnp.zeros((9, 2)).at[i, k].set(1e-7)
            num[i, k] = (float(corner_energy(coin, x + dx, pen))
                         - float(corner_energy(coin, x - dx, pen))) / 2e-7
    np.testing.assert_allclose(np.asarray(g), num, rtol=1e-5, atol=1e-8)
    full = np.asarray(jax.hessian(lambda v: corner_energy(coin, v.reshape(9, 2), pen))(
        x.reshape(-1))).reshape(9, 2, 9, 2)
    for i in range(9):
        np.testing.assert_allclose(np.asarray(hd[i]), full[i, :, i, :], rtol=1e-9, atol=1e-6)
        if i < 8:
            np.testing.assert_allclose(np.asarray(hu[i]), full[i, :, i + 1, :], rtol=1e-9,
                                       atol=1e-6)
    far = np.abs(np.subtract.outer(np.arange(9), np.arange(9))) > 1
    assert np.all(full.transpose(0, 2, 1, 3)[far] == 0.0)  # block tridiagonal
    # the normal shares: every pair's w phi'(delta) split over its two nodes, summed
    a, b = np.asarray(x[:-1]), np.asarray(x[1:])
    lo, hi = np.zeros(8), np.zeros(8)
    for cen, r, w in zip(*corners_of(coin), strict=True):
        s = np.clip(np.einsum("ij,ij->i", cen - a, b - a) / np.einsum("ij,ij->i", b - a, b - a),
                    0, 1)
        dist = np.linalg.norm(cen - (a + s[:, None] * (b - a)), axis=-1)
        pair = w * np.asarray(penalty_pressure(pen, jnp.asarray(r - dist)))
        lo, hi = lo + (1 - s) * pair, hi + s * pair
    shares = np.asarray(corner_normal(coin, x, pen))
    assert np.sum(lo + hi) > 0
    np.testing.assert_allclose(shares, np.concatenate([lo, [0.0]]) + np.concatenate([[0.0], hi]),
                               rtol=1e-12, atol=1e-14)


def test_smooth_body_adds_nothing():
    """On a body without corners (the unit ball, a coin whose edge radius exceeds the
    corner radius) the second pass is not traced: the forces, Hessian blocks and energy are
    the node-only contact's, bit for bit."""
    assert corners_of(Sphere()) is None
    assert corners_of(Disc(1.0, 0.4, 0.15)) is None
    assert corners_of(Disc(1.0, 0.15, 0.03)) is not None
    model = _model(Sphere())
    n = model.mesh.n
    rb = np.asarray(model.mesh.rbar)
    q = jnp.stack([jnp.asarray(np.sin(rb) * 1.001), jnp.asarray(np.cos(rb) * 0.999)], axis=-1)
    g, _ = forces(model, q, 0.0)
    g2, hd, hu, _, _ = forces_and_hessians(model, q, 0.0)

    def node_only(v):  # today's contact, written out: the elastic energy and the node penalty
        d = 1.0 - jnp.linalg.norm(v, axis=-1)
        return model.elastic_energy(v[:, 0], v[:, 1]) + jnp.sum(
            model.mesh.area * penalty_energy(PEN, d))

    assert float(model.energy(q[:, 0], q[:, 1], 0.0)) == float(node_only(q))
    np.testing.assert_allclose(np.asarray(g), np.asarray(jax.grad(node_only)(q)), rtol=1e-12,
                               atol=1e-13)
    assert np.array_equal(np.asarray(g), np.asarray(g2))
    d = 1.0 - jnp.linalg.norm(q, axis=-1)
    assert np.array_equal(np.asarray(model.normal_force(q[:, 0], q[:, 1], 0.0)),
                          np.asarray(model.mesh.area * penalty_pressure(PEN, d)))
    full = jax.hessian(lambda v: node_only(v.reshape(n, 2)))(q.reshape(-1)).reshape(n, 2, n, 2)
    for i in range(n):
        np.testing.assert_allclose(np.asarray(hd[i]), np.asarray(full[i, :, i, :]),
                                   rtol=1e-9, atol=1e-9)
    assert hu.shape == (n - 1, 2, 2)


def test_a_segment_through_a_corner_is_caught():
    """A segment that passes through the knife's centre between two states is caught (the
    penalty's distance is unsigned, so the solver refuses such an increment); one that slides
    along over it, or moves far from it, is not."""
    c = np.array([RING, TOP - EDGE])
    over = jnp.asarray([[0.0, 0.0], [RING - 0.05, c[1] + 0.004], [RING + 0.05, c[1] + 0.004],
                        [2.0, -0.5]])
    through = over.at[1:3, 1].set(c[1] - 0.004)
    slid = over.at[1:3, 0].add(0.03)
    assert bool(corner_crossed(KNIFE, over, through))
    assert bool(corner_crossed(KNIFE, over, over.at[1:3, 1].set(c[1] - 0.5)))  # a jump past it
    assert not bool(corner_crossed(KNIFE, over, slid))
    assert not bool(corner_crossed(KNIFE, over, over.at[1:3, 1].add(0.3)))
    assert not bool(corner_crossed(Sphere(), over, through))  # no corners


def test_a_node_through_a_thin_cornered_ball_is_caught():
    """A node on a coin's top face (the ball, with corners) that comes out of its bottom face
    in one increment is caught; one that slides along the face is not."""
    from dynslip.physics.terms import corners_crossed

    coin = Disc(1.0, 0.15, 0.03)
    model = _model(coin)
    n = model.mesh.n
    q0 = jnp.stack([jnp.linspace(0.0, 0.9, n), jnp.full(n, 0.0749)], axis=1)
    through = q0.at[:, 1].set(-0.0751)
    slid = q0.at[1:, 0].add(0.01)
    zb = jnp.asarray(0.0)
    assert bool(corners_crossed(model, q0, zb, through, zb))
    assert not bool(corners_crossed(model, q0, zb, slid, zb))
    smooth = _model(Sphere())
    q1 = jnp.stack([jnp.linspace(0.0, 0.5, n), jnp.full(n, 0.999)], axis=1)
    assert not bool(corners_crossed(smooth, q1, zb, q1.at[:, 1].set(-0.999), zb))  # not traced
