"""Penalty contact with every body (issue 21, physics.bodies.contact): for the unit ball
alone it is today's contact of physics.sheet (normal force, frame, penalty energy and its
gradient, the ball's included); a node feels every body it penetrates and none it does not;
the force is minus the gradient of the energy."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.bodies import Disc, Sphere, Torus, contact_energy_density, contact_forces
from dynslip.physics.bodies.chords import chord_depths
from dynslip.physics.materials import NeoHookean
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.sheet import ball_chord_depths as sheet_chord_depths

PEN = Penalty(k=1.0e4, w=1.0e-3)
MESH = make_mesh(30, 2.0)
SHEET = SheetModel(mesh=MESH, material=NeoHookean(), penalty=PEN)
BALL = (Sphere(),)


def _sheet_on_ball(zb):
    """A sheet draped over the ball at centre zb: nodes at polar angles up to 2.2, some
    penetrating by up to 3 w, some at a positive gap, the outer ones free."""
    rng = np.random.default_rng(0)
    th = np.linspace(0.0, 2.2, MESH.n)
    r = 1.0 + rng.uniform(-3e-3, 1e-3, MESH.n)
    r[-8:] = 1.2
    return jnp.asarray(r * np.sin(th)), jnp.asarray(zb + r * np.cos(th))


@eqx.filter_jit
def body_energy(bodies, rho, z, zs):
    x = jnp.stack([rho, z], axis=-1)
    return jnp.sum(MESH.area * contact_energy_density(bodies, x, PEN, zs))


@eqx.filter_jit
def forces(bodies, x, zs):
    return contact_forces(bodies, x, PEN, zs)


def test_ball_as_a_body_gives_todays_contact():
    """Against SheetModel's own methods, to 1e-12: N_i = A_i p_i, the normal and tangent of
    SheetModel.frame, the penalty energy, and its gradient in (rho, z, zb)."""
    zb = 0.21
    rho, z = _sheet_on_ball(zb)
    c = forces(BALL, jnp.stack([rho, z], -1), jnp.array([zb]))
    today = np.asarray(SHEET.normal_force(rho, z, zb))
    assert (today > 0).sum() >= 10 and (today == 0).sum() >= 8  # contact and gaps both tested
    np.testing.assert_allclose(MESH.area * c.pressure[0], today, rtol=1e-12, atol=1e-12)
    assert np.array_equal(np.asarray(c.pressure[0]) == 0, today == 0)  # same nodes in contact
    n, t = (np.asarray(a) for a in SHEET.frame(rho, z, zb))
    np.testing.assert_allclose(c.normal[0], n.T, atol=1e-12)
    np.testing.assert_allclose(c.tangent[0], t.T, atol=1e-12)
    np.testing.assert_allclose(-c.distance[0], SHEET.penetration(rho, z, zb), atol=1e-15)
    e_today = float(SHEET.penalty_energy(rho, z, zb))
    e_body = float(body_energy(BALL, rho, z, jnp.array([zb])))
    assert abs(e_body - e_today) <= 1e-12 * abs(e_today)
    g_today = jax.grad(SHEET.penalty_energy, argnums=(0, 1, 2))(rho, z, zb)
    g_body = jax.grad(lambda a, b, c_: body_energy(BALL, a, b, c_[None]), argnums=(0, 1, 2))(
        rho, z, zb
    )
    for a, b in zip(g_body, g_today, strict=False):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(g_today[1]))))


def test_a_node_feels_every_body_it_penetrates():
    """Two bodies overlapping on purpose: a node inside both is pushed by both, along each
    body's own normal and by each one's own penetration; a node inside one only feels that
    one, exactly zero from the other."""
    ball = Sphere()
    ring = Torus(ring_radius=1.0, minor_radius=0.3, centre_z=0.0)  # overlaps the ball's equator
    x = jnp.array(
        [
            [0.8, 0.0],
            [math.sin(0.5) * 0.9995, math.cos(0.5) * 0.9995],
            [1.2995, 0.0],
            [1.0, 0.2997],
            [3.0, 0.0],
        ]
    )
    c = forces((ball, ring), x, jnp.zeros(2))
    p = np.asarray(c.pressure)
    both, ball_only, ring_side, ring_top, none = range(5)
    assert p[0, both] > 0 and p[1, both] > 0
    # the ball's pressure at the first node is set by its depth 0.2: k (d - w/2)
    np.testing.assert_allclose(p[0, both], PEN.k * (0.2 - PEN.w / 2), rtol=1e-13)
    np.testing.assert_allclose(p[1, both], PEN.k * (0.3 - 0.2 - PEN.w / 2), rtol=1e-13)
    np.testing.assert_allclose(c.normal[0, both], [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(c.normal[1, both], [-1.0, 0.0], atol=1e-15)
    # penetration 5e-4 < w: the C2 branch k d^2 / (2 w); nothing from the ring
    np.testing.assert_allclose(p[0, ball_only], PEN.k * 5e-4**2 / (2 * PEN.w), rtol=1e-9)
    assert p[1, ball_only] == 0.0
    np.testing.assert_allclose(p[1, ring_side], PEN.k * 5e-4**2 / (2 * PEN.w), rtol=1e-9)
    np.testing.assert_allclose(c.normal[1, ring_side], [1.0, 0.0], atol=1e-15)
    assert p[0, ring_side] == 0.0
    np.testing.assert_allclose(p[1, ring_top], PEN.k * 3e-4**2 / (2 * PEN.w), rtol=1e-9)
    np.testing.assert_allclose(c.normal[1, ring_top], [0.0, 1.0], atol=1e-12)
    assert p[0, none] == 0.0 and p[1, none] == 0.0


def test_force_is_minus_the_gradient_of_the_energy_for_several_bodies():
    """sum_k p_ik n_k = -d/dx_i sum_k phi(-d_k), and the axial force on each body is the
    derivative in its position, -sum_i A_i p_ik n_k,z, for a ball, a coin on it and a ring."""
    bodies = (
        Sphere(),
        Disc(radius=0.6, thickness=0.09, edge_radius=0.015, centre_z=1.04),
        Torus(ring_radius=0.635, minor_radius=0.05, centre_z=-0.78),
    )
    zs = jnp.array([0.0, -0.003, 0.001])
    rng = np.random.default_rng(1)
    th = np.linspace(0.0, math.pi, MESH.n)
    r = 1.0 + rng.uniform(-2e-3, 2e-3, MESH.n)
    rho, z = jnp.asarray(r * np.sin(th)), jnp.asarray(r * np.cos(th))
    x = jnp.stack([rho, z], -1)
    c = forces(bodies, x, zs)
    p = np.asarray(c.pressure)
    assert (p[1] > 0).sum() >= 2 and (p[2] > 0).sum() >= 1  # coin and ring touched too
    g_rho, g_z, g_zs = jax.grad(lambda a, b, s: body_energy(bodies, a, b, s), argnums=(0, 1, 2))(
        rho, z, zs
    )
    f = np.asarray(jnp.sum(c.force, axis=0)) * np.asarray(MESH.area)[:, None]
    scale = float(np.max(np.abs(f)))
    np.testing.assert_allclose(-np.asarray(g_rho), f[:, 0], atol=1e-12 * scale)
    np.testing.assert_allclose(-np.asarray(g_z), f[:, 1], atol=1e-12 * scale)
    on_body = -np.sum(
        np.asarray(MESH.area) * np.asarray(c.pressure) * np.asarray(c.normal[..., 1]), axis=1
    )
    np.testing.assert_allclose(-np.asarray(g_zs), on_body, atol=1e-12 * scale)


def test_chord_depths_against_every_body():
    """The mesh check against any body: for the ball it is sheet.ball_chord_depths (frames on a
    leading axis, one ball height per frame); across a torus's tube a horizontal chord at
    height h above the tube's centre dips r - h deep at the chord's middle; a chord inside the
    coin under its top face is as deep as it lies under it."""
    rng = np.random.default_rng(2)
    th = np.sort(rng.uniform(0.0, 2.5, (3, 12)), axis=-1)
    r = 1.0 + rng.uniform(-2e-3, 2e-2, (3, 12))
    zb = np.array([0.0, 0.1, -0.2])
    rho, z = r * np.sin(th), zb[:, None] + r * np.cos(th)
    np.testing.assert_allclose(
        chord_depths(Sphere(), rho, z, zb), sheet_chord_depths(rho, z, zb), rtol=0, atol=1e-12
    )
    ring = Torus(ring_radius=1.5, minor_radius=0.3, centre_z=-0.2)
    d = chord_depths(ring, np.array([1.1, 1.9]), np.array([-0.1, -0.1]), 0.0)
    np.testing.assert_allclose(d, [0.2], atol=1e-12)
    coin = Disc(radius=0.6, thickness=0.09, edge_radius=0.015, centre_z=1.04)
    d = chord_depths(coin, np.array([0.1, 0.3, 0.9]), np.array([1.075, 1.075, 1.075]), 0.0)
    np.testing.assert_allclose(d[0], 0.01, atol=1e-12)
    assert d[1] == pytest.approx(0.01, abs=1e-12)  # the deepest point of the chord into the coin
