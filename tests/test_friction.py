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
    (schema.friction.FRICTION_SPECS, physics.materials.MATERIALS, schema.stages.STOP_SPECS):
    each friction spec builds its law with the file's lengths over R and pressures over the
    pressure scale."""
    import equinox as eqx

    from dynslip.physics import protocols as P
    from dynslip.physics.friction import Coulomb, PressureDependent, SlipWeakening
    from dynslip.physics.materials import MATERIALS, make_material
    from dynslip.schema.forming import StageSpec
    from dynslip.schema.friction import FRICTION_SPECS
    from dynslip.schema.materials import MaterialSpec
    from dynslip.schema.stages import STOP_SPECS

    r, eps, p_scale = 20.0, 1e-3, 5.0
    f = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
    expected = {
        "none": None,
        "coulomb": Coulomb(mu=f(1.15), eps=f(eps)),
        "slip_weakening": SlipWeakening(mu_s=f(0.99), mu_k=f(0.82), d_c=f(0.4 / r), eps=f(eps)),
        "pressure": PressureDependent(mu_ref=f(0.99), p_ref=f(1.06 / p_scale), a=f(1 / 3),
                                      mu_max=f(2.18), blend=f(0.05), eps=f(eps)),
    }
    assert set(FRICTION_SPECS.specs) >= set(expected)
    for law, want in expected.items():
        built = FRICTION_SPECS.specs[law]().build(r, eps, pressure_scale_kPa=p_scale)
        assert type(built) is type(want) and eqx.tree_equal(built, want), law
    for model in MATERIALS:
        spec = MaterialSpec(model=model, jm=40.0, c1=0.3)
        built = spec.core()
        assert type(built) is MATERIALS[model]
        assert eqx.tree_equal(built, make_material(model, jm=40.0, c1=0.3, c2=0.2))
    # each rule's spec builds its core rule, thresholds made nondimensional: speeds by R (mm),
    # forces by the force scale (N), angles and times as given
    stages = {"duration": ({}, {}, P.Duration, {}),
              "clamp_force_below": ({"force_N": 0.02}, {"clamp_velocity_mm_s": 1.0},
                                    P.ClampForceBelow, {"force": 0.02 / 2.0}),
              "rest": ({"rate_mm_s": 0.002, "hold_s": 2.0}, {}, P.Rest,
                       {"rate": 0.002 / r, "hold": 2.0}),
              "theta_max_below": ({"angle_rad": 1.0}, {}, P.ThetaMaxBelow, {"angle": 1.0}),
              "ball_speed_above": ({"speed_mm_s": 0.1}, {}, P.BallSpeedAbove, {"rate": 0.1 / r}),
              "ball_reaction_below": ({"force_N": 0.02}, {"ball": "hold",
                                                          "ball_velocity_mm_s": -1.0},
                                      P.BallReactionBelow, {"force": 0.02 / 2.0})}
    assert set(stages) <= set(STOP_SPECS.specs)
    for rule, (params, kw, cls, scaled) in stages.items():
        spec = StageSpec(name="s", until={"rule": rule, **params}, duration_s=5.0, **kw)
        stop = spec.until.build(5.0, r, 2.0)
        assert type(stop) is cls and stop.duration == 5.0
        for name, value in scaled.items():
            assert getattr(stop, name) == pytest.approx(value, rel=1e-15), (rule, name)
