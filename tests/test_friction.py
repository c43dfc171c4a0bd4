"""Friction laws: the force-space soft threshold and its derivatives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

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


def test_the_schema_builds_the_physics_from_the_one_registry_of_each_kind():
    """Friction laws, materials and stop rules are built by the schema from one registry each
    (physics.friction.FRICTION_LAWS, physics.materials.MATERIALS, physics.protocols.STOPS), and
    the name-based factories kept for schema-less callers build the same objects."""
    import equinox as eqx

    from dynslip.physics.friction import FRICTION_LAWS, make_friction
    from dynslip.physics.materials import MATERIALS, make_material
    from dynslip.physics.protocols import STOPS
    from dynslip.schema.forming import FrictionSpec, StageSpec
    from dynslip.schema.materials import MaterialSpec
    from dynslip.schema.protocol import stop_rule

    r, eps, p_scale = 20.0, 1e-3, 5.0
    for law in FRICTION_LAWS:
        spec = FrictionSpec(law=law)
        built = spec.core(r, eps, pressure_scale_kPa=p_scale)
        assert type(built) is FRICTION_LAWS[law]
        same = make_friction(law, mu=spec.mu, mu_s=spec.mu_s, mu_k=spec.mu_k, d_c=spec.d_c_mm / r,
                             eps=eps, mu_ref=spec.mu_ref, p_ref=spec.p_ref_kPa / p_scale,
                             a=spec.exponent, mu_max=spec.mu_max)
        assert eqx.tree_equal(built, same)
    for model in MATERIALS:
        spec = MaterialSpec(model=model, jm=40.0, c1=0.3)
        built = spec.core()
        assert type(built) is MATERIALS[model]
        assert eqx.tree_equal(built, make_material(model, jm=40.0, c1=0.3, c2=0.2))
    stages = {"duration": {},
              "clamp_force_below": {"force_threshold_N": 0.02, "clamp_velocity_mm_s": 1.0},
              "rest": {"rest_rate_mm_s": 0.002, "rest_hold_s": 2.0},
              "theta_max_below": {"theta_stop_rad": 1.0},
              "ball_speed_above": {"ball_speed_mm_s": 0.1},
              "ball_reaction_below": {"force_threshold_N": 0.02, "ball": "hold",
                                      "ball_velocity_mm_s": -1.0}}
    assert set(stages) == set(STOPS)
    for until, kw in stages.items():
        stop = stop_rule(StageSpec(name="s", until=until, duration_s=5.0, **kw), 5.0, r, 2.0)
        assert type(stop) is STOPS[until] and stop.duration == 5.0
    built = stop_rule(StageSpec(name="s", until="rest", duration_s=5.0, **stages["rest"]), 5.0,
                       r, 2.0)
    # thresholds made nondimensional: speeds by R (mm), forces by the force scale (N)
    assert built.rate == pytest.approx(0.002 / r) and built.hold == 2.0
    clamp = stop_rule(StageSpec(name="s", until="clamp_force_below", duration_s=5.0,
                                 **stages["clamp_force_below"]), 5.0, r, 2.0)
    assert clamp.force == pytest.approx(0.02 / 2.0)
    reaction = stop_rule(StageSpec(name="s", until="ball_reaction_below", duration_s=5.0,
                                    **stages["ball_reaction_below"]), 5.0, r, 2.0)
    assert reaction.force == pytest.approx(0.02 / 2.0)
