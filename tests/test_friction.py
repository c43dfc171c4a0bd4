"""Friction laws: the force-space soft threshold and its derivatives."""

import jax
import jax.numpy as jnp
import numpy as np

from dynslip.physics.friction import soft_threshold


def test_soft_threshold_reverse_mode_finite_at_zero_threshold():
    """mu = 0 (c = 0) with eps = 0: the structured Newton solver takes vjps of the friction
    dissipation; they must be finite (a 1e-300 guard underflowed to 0/0 = NaN)."""
    def diss(f, c, eps):
        s = soft_threshold(f, c, eps)
        return jnp.sum((f - s) * s)

    f = jnp.array([-0.3, 0.0, 0.2])
    for c, eps in [(0.0, 0.0), (0.0, 1e-3), (0.1, 0.0), (0.1, 1e-3)]:
        g = jax.grad(diss, argnums=(0, 1))(f, jnp.full(3, c), jnp.asarray(eps))
        assert all(np.all(np.isfinite(np.asarray(x))) for x in g), (c, eps, g)
    # the ideal law at c = 0 is the identity: no friction, no dissipation
    assert np.allclose(soft_threshold(f, jnp.zeros(3), jnp.asarray(0.0)), f)
