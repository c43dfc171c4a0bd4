"""The 2D case (paper Section 5): capstan relation and bounds, and the vertical force."""

import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.static import plane_strain as C


def test_capstan_relation_from_the_fully_mobilised_ode():
    """dT/dtheta = mu T integrated on a grid converges to T0 e^(mu theta) at second order."""
    mu, wrap = 0.99, 2.0
    errs, hs = [], []
    for n in (41, 81, 161):
        th = jnp.linspace(0.0, wrap, n)
        t, ff = C.tension_from_friction(mu * jnp.ones(n), th)
        # trapezoid on the exponent is exact for a constant mobilisation: use a varying one too
        errs.append(abs(float(t[-1]) - float(C.capstan_ratio(mu, wrap))))
        m = mu * jnp.cos(th)
        t2, _ = C.tension_from_friction(m, th)
        exact = np.exp(mu * np.sin(wrap))
        errs[-1] = max(errs[-1], abs(float(t2[-1]) - exact))
        hs.append(float(th[1]))
        np.testing.assert_allclose(ff, -mu * t, rtol=1e-14)
    assert abs(float(C.capstan_ratio(0.99, np.pi)) - np.exp(0.99 * np.pi)) < 1e-12
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order > 1.8


def test_admissible_states_obey_the_capstan_bounds_and_push_off():
    """Random admissible states (|F_f| <= mu T): within the bounds, F_v equal to its closed form
    R T(theta_max) sin(theta_max), and F_v > 0 for every theta_max in (0, pi)."""
    mu = 0.99
    key = jax.random.PRNGKey(1)
    for tmax in (0.3, 1.2, np.pi / 2, 2.5, 3.1):
        key, sub = jax.random.split(key)
        th, t, ff = C.random_admissible(sub, mu, tmax, 64, 801)
        lo, hi = C.capstan_bounds(mu, th)
        assert bool(jnp.all(t >= lo * (1 - 1e-12))) and bool(jnp.all(t <= hi * (1 + 1e-12)))
        assert bool(jnp.all(jnp.abs(ff) <= mu * t * (1 + 1e-12)))
        fv = jax.vmap(lambda a, b: C.vertical_force(a, b, th))(t, ff)  # noqa: B023 - called here
        closed = C.vertical_force_closed(t[:, -1], tmax)
        # quadrature error at 801 nodes, relative to the size of the integrand (order: next test)
        np.testing.assert_allclose(fv, closed, rtol=0, atol=1e-4 * float(jnp.max(t)))
        assert bool(jnp.all(fv > 0))
        assert bool(jnp.all(closed >= np.exp(-mu * tmax) * np.sin(tmax) * (1 - 1e-12)))


def test_vertical_force_converges_to_the_boundary_term():
    """The quadrature of F_v converges to T(theta_max) sin(theta_max) at second order."""
    mu, tmax = 0.8, 2.4
    errs, hs = [], []
    for n in (51, 101, 201, 401):
        th = jnp.linspace(0.0, tmax, n)
        m = mu * jnp.sin(3 * th)
        t = jnp.exp(-mu * (jnp.cos(3 * th) - 1) / 3)  # exact T for this mobilisation
        ff = -m * t
        errs.append(
            abs(float(C.vertical_force(t, ff, th)) - float(C.vertical_force_closed(t[-1], tmax)))
        )
        hs.append(float(th[1]))
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert order > 1.8
