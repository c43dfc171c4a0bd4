"""The smooth observables (dynslip.physics.observables): the contact edge located between
nodes, continuous where the node-based edge jumps, and theta at fixed material radii."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from dynslip.physics.friction import Coulomb
from dynslip.physics.materials import NeoHookean
from dynslip.physics.observables import (
    OBS_RBAR,
    contact_function,
    located_edge,
    polar_angle,
    theta_at,
    threshold_penetration,
)
from dynslip.physics.penalty import Penalty, penalty_pressure
from dynslip.physics.sheet import SheetModel, make_mesh

N = 31
THRESHOLD = 1e-2  # G h0 / R, the default contact threshold
MODEL = SheetModel(make_mesh(N, 2.0), NeoHookean(), Penalty())


def wrapped(alpha, slope=2e-3):
    """A sheet on the unit ball whose node i sits at the polar angle 1.5 rbar_i and at the
    distance 1 - slope (alpha - theta) from the ball's centre: it penetrates the ball up to the
    polar angle ``alpha`` and lifts off past it (an edge at alpha by construction)."""
    th = 1.5 * MODEL.mesh.rbar
    r = 1.0 - slope * (alpha - th)
    return r * jnp.sin(th), r * jnp.cos(th)


@jax.jit
def observe(alpha):
    rho, z = wrapped(alpha)
    contact = MODEL.diagnostics(rho, z, 0.0, Coulomb(1.0), contact_threshold=THRESHOLD)["contact"]
    theta = polar_angle(rho, z, 0.0)
    last = jnp.max(jnp.where(contact, jnp.arange(N), -1))
    edge = located_edge(MODEL.mesh.rbar, theta, contact_function(MODEL, rho, z, 0.0, THRESHOLD),
                        contact)
    return edge.theta, edge.rbar, theta[last], MODEL.mesh.rbar[last], contact


def test_the_threshold_penetration_inverts_the_penalty_pressure():
    pen = Penalty()
    p = jnp.array([1e-6, 1e-2, 4.99, 5.01, 300.0])  # both sides of k w / 2 = 5
    assert np.allclose(penalty_pressure(pen, threshold_penetration(pen, p)), p, rtol=1e-12)


def test_the_contact_function_is_positive_exactly_on_the_contact_set():
    for alpha in np.linspace(0.3, 2.4, 23):
        rho, z = wrapped(alpha)
        d = MODEL.diagnostics(rho, z, 0.0, Coulomb(1.0), contact_threshold=THRESHOLD)
        c = np.asarray(contact_function(MODEL, rho, z, 0.0, THRESHOLD))
        np.testing.assert_array_equal((c > 0)[:-1], np.asarray(d["contact"])[:-1])


def test_the_edge_of_a_linear_contact_function_is_its_zero():
    rbar = jnp.linspace(0.0, 2.0, N)
    for x0 in (0.05, 0.71, 1.333, 1.93):
        c = x0 - rbar
        e = located_edge(rbar, 3.0 * rbar**2, c, c > 0)
        h = float(rbar[1])
        j = int(x0 // h)
        assert abs(float(e.rbar) - x0) < 1e-14
        # theta interpolated linearly between the bracketing nodes (3 rbar^2 there)
        f = (x0 - j * h) / h
        assert abs(float(e.theta) - 3 * ((1 - f) * (j * h) ** 2 + f * ((j + 1) * h) ** 2)) < 1e-13
    none = located_edge(rbar, rbar, -jnp.ones(N), jnp.zeros(N, bool))
    assert np.isnan(float(none.rbar)) and np.isnan(float(none.theta))


def test_the_located_edge_of_the_wrapped_profile():
    """The constructed edge: the penetration slope (alpha - theta) is linear in theta, so the
    contact function crosses zero where it equals the threshold's penetration d*
    (:func:`threshold_penetration` of the threshold times the areal stretch, 5e-5 R here), at
    theta = alpha - d*/slope, to d*'s change over an element: the located edge lies between
    the zeros with d* frozen at either bracketing node (9e-4 rad apart at most), within 2e-3
    rad of alpha - d*/slope; the node-based edge is off by up to an element (h = 0.1 rad)."""
    slope = 2e-3
    h = 1.5 * float(MODEL.mesh.rbar[1])
    worst_node, worst_edge = 0.0, 0.0
    for alpha in np.linspace(0.4, 2.2, 37):
        th_e, rb_e, th_n, _, contact = observe(alpha)
        rho, z = wrapped(alpha)
        j = int(np.sum(contact)) - 1
        d_j, d_k = (float(threshold_penetration(MODEL.penalty, THRESHOLD * ls))
                    for ls in MODEL.areal_stretch(rho, z)[j:j + 2])
        # the zero lies between those with d* frozen at either bracketing node
        lo, hi = sorted((alpha - d_j / slope, alpha - d_k / slope))
        assert lo - 1e-12 <= float(th_e) <= hi + 1e-12
        worst_edge = max(worst_edge, abs(float(th_e) - (alpha - d_j / slope)))
        worst_node = max(worst_node, abs(float(th_n) - alpha))
        assert abs(float(rb_e) - float(th_e) / 1.5) < 1e-12  # theta = 1.5 rbar on this profile
    print(f"located edge within {worst_edge:.2e} rad, node-based within {worst_node:.2e} (h {h})")
    assert worst_edge < 2e-3
    assert worst_node > 0.5 * h


def test_a_fine_sweep_moves_the_located_edge_continuously_where_the_node_edge_jumps():
    """alpha swept in steps of h/40 across several changes of the contact set: every step of
    theta_edge is about the step of alpha (no jump), while theta_max (the last node's) jumps by
    a whole element where the set changes and stays put in between."""
    h = 1.5 * float(MODEL.mesh.rbar[1])
    alphas = np.arange(1.0, 1.0 + 3.2 * h, h / 40)
    out = [observe(a) for a in alphas]
    th_e = np.array([float(o[0]) for o in out])
    th_n = np.array([float(o[2]) for o in out])
    n_c = np.array([int(np.sum(o[4])) for o in out])
    changes = np.flatnonzero(np.diff(n_c))
    assert len(changes) >= 3
    step = h / 40
    d_edge, d_node = np.abs(np.diff(th_e)), np.abs(np.diff(th_n))
    print(f"largest step: located {d_edge.max():.3e}, node-based {d_node.max():.3e} rad "
          f"(alpha step {step:.3e})")
    assert d_edge.max() < 1.2 * step
    assert np.all(d_node[changes] > 0.9 * h)  # the node-based value jumps by an element
    assert np.all(d_node[np.setdiff1d(np.arange(len(d_node)), changes)] < 1e-12)


def test_theta_at_a_nodes_radius_is_the_nodes_theta():
    rng = np.random.default_rng(3)
    rbar = jnp.asarray(np.sort(np.concatenate([[0.0], rng.uniform(0, 2, N - 2), [2.0]])))
    theta = jnp.asarray(np.cumsum(rng.uniform(0, 0.2, N)))
    got = theta_at(rbar, theta, rbar[1:-1])
    np.testing.assert_array_equal(np.asarray(got), np.asarray(theta[1:-1]))
    # between nodes: linear in the material coordinate; outside the mesh: NaN
    mid = 0.5 * (rbar[4] + rbar[5])
    assert abs(float(theta_at(rbar, theta, [mid])[0]) - 0.5 * float(theta[4] + theta[5])) < 1e-14
    assert np.isnan(float(theta_at(rbar, theta, [2.5])[0]))


@pytest.mark.parametrize("r", OBS_RBAR[::4])
def test_theta_at_is_differentiable_and_exact_on_the_profile(r):
    """On the wrapped profile theta = 1.5 rbar exactly, and d theta(rbar)/d alpha = 0 (the
    profile's angles do not move with alpha): forward mode through the interpolation."""
    def f(alpha):
        rho, z = wrapped(alpha)
        return theta_at(MODEL.mesh.rbar, polar_angle(rho, z, 0.0), (r,))[0]

    val, tan = jax.jvp(f, (1.2,), (1.0,))
    assert abs(float(val) - 1.5 * r) < 1e-12 and abs(float(tan)) < 1e-12
