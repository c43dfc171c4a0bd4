"""Schema of the sheet's friction law against a body (physics.md Section 4, "Friction";
docs/forming.md): physical units in the file, the core law built by :meth:`FrictionSpec.core`
(lengths by the ball radius R)."""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from dynslip.physics.reference import MEASURED_MU_K, MEASURED_MU_S
from dynslip.schema.base import F, Strict

__all__ = ["FrictionSpec"]


class FrictionSpec(Strict):
    """Friction between sheet and ball: ideal Coulomb, or static/kinetic by slip-distance
    weakening (physics.md Section 4, "Friction"; docs/forming.md)."""

    law: Literal["coulomb", "slip_weakening"] = F(
        "coulomb", description="coulomb: ideal Coulomb (mu), overdamped soft threshold; "
                               "slip_weakening: "
        "static/kinetic, mu falls from mu_s to mu_k over a slip distance d_c_mm, reset when the "
        "node sticks")
    mu: float = F(1.15, ge=0, le=10, description="friction coefficient of law: coulomb")
    mu_s: float = F(MEASURED_MU_S, ge=0, le=10,
                    description=f"static coefficient of law: slip_weakening (paper: "
                                f"{MEASURED_MU_S:g})")
    mu_k: float = F(MEASURED_MU_K, ge=0, le=10,
                    description=f"kinetic coefficient of law: slip_weakening (paper: "
                                f"{MEASURED_MU_K:g}); <= mu_s")
    d_c_mm: float = F(0.4, unit="mm", gt=0, le=1e4, description="weakening slip distance of law: "
                                                                "slip_weakening, "
                      "in (0, 1e4] mm; the mesh "
                      "must be much finer than 15 sqrt(d_c R) (about 42 mm = 2.1 R at the default)")

    @model_validator(mode="after")
    def _order(self):
        if self.mu_k > self.mu_s:
            raise ValueError(f"mu_k = {self.mu_k} exceeds mu_s = {self.mu_s} (kinetic friction "
                             f"must not exceed static)")
        return self

    @property
    def nominal_mu(self) -> float:
        """The coefficient a reader compares mu_mobilised_max with: mu, or mu_s."""
        return self.mu if self.law == "coulomb" else self.mu_s

    def core(self, ball_radius_mm: float, eps: float):
        """The core friction law (:data:`dynslip.physics.friction.FRICTION_LAWS`): lengths by
        the ball radius, ``eps`` the force-space smoothing (G h0 / R)."""
        import jax.numpy as jnp

        from dynslip.physics.friction import FRICTION_LAWS

        f = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
        params = {"coulomb": {"mu": f(self.mu)},
                  "slip_weakening": {"mu_s": f(self.mu_s), "mu_k": f(self.mu_k),
                                     "d_c": f(self.d_c_mm / ball_radius_mm)}}[self.law]
        return FRICTION_LAWS[self.law](**params, eps=f(eps))
