"""A friction law added from outside the package: one physics class (an ``AbstractFriction``), one
spec class (a ``FrictionSpec`` with its ``law``), one registration (``FRICTION_SPECS``). The
scenario file then names it for the ball and for a held body, and the run uses it."""

from __future__ import annotations

from typing import Literal

import jax.numpy as jnp
import numpy as np
import pytest
from pydantic import Field

from dynslip.data.trajectory import SLIP_EQUATOR, SLIP_POLE, STUCK
from dynslip.physics.friction import AbstractFriction
from dynslip.schema.base import validate_data
from dynslip.schema.friction import FRICTION_SPECS, FrictionSpec
from helpers import registered

MU = 0.9


class ConstantMu(AbstractFriction):
    """Coulomb's law written again outside the package: threshold mu N."""

    mu: float | jnp.ndarray
    eps: float | jnp.ndarray

    def threshold(self, fn, internal=None, area=None):
        return self.mu * jnp.maximum(fn, 0.0)

    def coefficient(self, internal, n: int):
        return jnp.full(n, self.mu, dtype=float)


class ConstantMuSpec(FrictionSpec):
    """The scenario file's ``law: constant_mu``."""

    law: Literal["constant_mu"] = "constant_mu"
    mu: float = Field(MU, ge=0, le=10)

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):
        return ConstantMu(mu=jnp.asarray(self.mu, dtype=float), eps=jnp.asarray(eps, dtype=float))

    @property
    def nominal_mu(self) -> float:
        return self.mu


@pytest.fixture
def constant_mu():
    with registered(FRICTION_SPECS, ConstantMuSpec):
        yield ConstantMuSpec


def _scenario(friction: dict, post_friction: dict) -> dict:
    """The ball pushed 60 mm into the sheet at N = 20, a held post below it with its own law."""
    return {
        "kind": "forming",
        "physics": {
            "friction": friction,
            "bodies": [{"name": "post", "kind": "cylinder", "radius_mm": 4.0, "height_mm": 10.0,
                        "z_mm": -60.0, "friction": post_friction}],
            "stages": [{"name": "push", "clamp_to_z_mm": -40.0, "clamp_speed_mm_s": 4.0},
                       {"name": "hold", "duration_s": 3.0}],
        },
        "numerics": {"nodes": 20, "save_interval_s": 1.0},
    }


def _frames(sc):
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    model, protocol, kwargs = build_core(sc)
    res = simulate(model, protocol, **kwargs)
    assert not res.failed, res.failed
    return model, kwargs["friction"], res.frames


def test_a_law_registered_from_outside_runs_as_the_builtin_law_it_restates(constant_mu):
    """``law: constant_mu`` (registered here) for the ball and a held post: its threshold is
    mu N by construction, and the run is the run with ``law: coulomb`` at the same mu, every
    saved number to 1e-12, through frames where nodes stick and others slip."""
    outside = validate_data(_scenario({"law": "constant_mu"}, {"law": "constant_mu", "mu": 0.4}))
    builtin = validate_data(_scenario({"law": "coulomb", "mu": MU}, {"law": "coulomb", "mu": 0.4}))
    assert isinstance(outside.physics.friction, ConstantMuSpec)
    assert outside.physics.friction.nominal_mu == MU
    fn = jnp.array([-1.0, 0.0, 0.3, 2.0])
    law = outside.physics.friction.build(20.0, 1e-3)
    np.testing.assert_array_equal(law.threshold(fn), MU * np.maximum(np.asarray(fn), 0.0))

    model, fr, frames = _frames(outside)
    assert type(fr) is ConstantMu and type(model.bodies[0].friction) is ConstantMu
    _, fr_b, frames_b = _frames(builtin)
    assert type(fr_b).__name__ == "Coulomb"
    assert len(frames) == len(frames_b) > 5
    for a, b in zip(frames, frames_b, strict=True):
        for key, va in a.items():
            va, vb = np.asarray(va), np.asarray(b[key])
            if np.issubdtype(va.dtype, np.number):
                np.testing.assert_allclose(va, vb, rtol=0, atol=1e-12, err_msg=key)
    states = np.stack([np.asarray(f["state"]) for f in frames])
    # the comparison covers both regimes of the threshold: stuck nodes and slipping ones
    assert (states == STUCK).any() and np.isin(states, (SLIP_POLE, SLIP_EQUATOR)).any()


def test_a_registered_law_is_named_in_the_refusal_of_an_unknown_one(constant_mu):
    """After registration the schema lists the new law among the allowed ones; a tag already
    taken is refused."""
    from dynslip.errors import InputError

    with pytest.raises(InputError, match="constant_mu") as err:
        validate_data(_scenario({"law": "constant_muu"}, {"law": "none"}))
    assert "physics.friction.law" in str(err.value)
    with pytest.raises(ValueError, match="already registered"):
        FRICTION_SPECS.register(type("Other", (ConstantMuSpec,), {"__doc__": "another"}))
