"""Schema of the sheet's friction law against a body (physics.md Section 4, "Friction";
docs/forming.md): physical units in the file, the core law built by :meth:`FrictionSpec.core`
(lengths by the ball radius R)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import model_validator

from dynslip.physics.reference import MEASURED_MU_K, MEASURED_MU_S
from dynslip.schema.base import F, Strict

__all__ = ["FrictionSpec", "CAPSTAN_TEST", "capstan_reference_pressure_kPa"]

#: the paper's capstan strip test (Section 2.1) as this model reads it: 5 mm wide strips over the
#: 40 mm ball, a mass at each end, hanging vertically (wrap angle pi). The paper gives no masses:
#: the hold mass is assumed (2 g, a small clip), the load mass is the one the measured mu_s = 0.99
#: implies, m_hold exp(0.99 pi) = 44.9 g.
CAPSTAN_TEST = {"strip_width_mm": 5.0, "ball_radius_mm": 20.0, "wrap_rad": math.pi,
                "hold_mass_g": 2.0, "mu": MEASURED_MU_S}


def capstan_reference_pressure_kPa(exponent: float, test: dict = CAPSTAN_TEST) -> float:
    """The contact pressure at which the strip test measures its mu, for friction following
    mu ~ p^(-exponent): T_ref / (R w) with T_ref from
    :func:`dynslip.physics.friction.capstan_reference_tension` (a strip of width w under
    tension T on radius R presses with T / (R w); the strip's narrowing under tension, 4% at
    T_ref, is left out). 1.06 kPa at exponent 1/3 with the assumed masses."""
    from dynslip.physics.friction import capstan_reference_tension

    t_hold = test["hold_mass_g"] * 1e-3 * 9.81
    t_load = t_hold * math.exp(test["mu"] * test["wrap_rad"])
    t_ref = capstan_reference_tension(t_hold, t_load, exponent)
    return t_ref / (test["ball_radius_mm"] * test["strip_width_mm"] * 1e-6) * 1e-3


class FrictionSpec(Strict):
    """Friction between sheet and ball: ideal Coulomb, or static/kinetic by slip-distance
    weakening (physics.md Section 4, "Friction"; docs/forming.md)."""

    law: Literal["coulomb", "slip_weakening", "pressure"] = F(
        "coulomb", description="coulomb: ideal Coulomb (mu), overdamped soft threshold; "
                               "slip_weakening: "
        "static/kinetic, mu falls from mu_s to mu_k over a slip distance d_c_mm, reset when the "
        "node sticks; pressure: mu = mu_ref (p / p_ref_kPa)^(-exponent) bounded by mu_max "
        "(Schallamach), p the node's contact force per reference area")
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

    exponent: float = F(1.0 / 3.0, ge=0, lt=1,
                        description="exponent a of law: pressure, in [0, 1): 1/3 is Schallamach's "
                        "(Hertzian asperities), 0 is Coulomb; at 1 the friction force would not "
                        "rise with the load")
    mu_ref: float = F(MEASURED_MU_S, ge=0, le=10,
                      description=f"coefficient of law: pressure at p_ref_kPa (paper's capstan "
                                  f"test: {MEASURED_MU_S:g})")
    p_ref_kPa: float = F(1.06, unit="kPa", gt=0,
                         le=1e6,
                         description="reference pressure of law: pressure, in (0, 1e6] kPa: the "
                         "capstan strip test's, T_ref/(R w) with 5 mm strips on the 40 mm ball "
                         "and masses 2 g and 44.9 g (assumed; docs/experiment.md)")
    mu_max: float = F(2.18, ge=0, le=10,
                      description="bound of law: pressure at low pressure (where the power law "
                      "would exceed it), >= 1.05 mu_ref; default: the top of the literature's "
                      "static range for latex, 0.86-2.18")

    @model_validator(mode="after")
    def _order(self):
        from dynslip.physics.friction import CAP_BLEND

        if self.mu_k > self.mu_s:
            raise ValueError(f"mu_k = {self.mu_k} exceeds mu_s = {self.mu_s} (kinetic friction "
                             f"must not exceed static)")
        if self.law == "pressure" and self.mu_max < self.mu_ref * math.exp(CAP_BLEND):
            raise ValueError(f"mu_max = {self.mu_max} is below mu_ref e^{CAP_BLEND:g} = "
                             f"{self.mu_ref * math.exp(CAP_BLEND):.4g} (the bound must lie above "
                             f"the reference point and the 5% band that rounds it)")
        return self

    @property
    def nominal_mu(self) -> float:
        """The coefficient a reader compares mu_mobilised_max with: mu, mu_s, or mu_ref."""
        return {"coulomb": self.mu, "slip_weakening": self.mu_s, "pressure": self.mu_ref}[self.law]

    def core(self, ball_radius_mm: float, eps: float, pressure_scale_kPa: float | None = None):
        """The core friction law (:data:`dynslip.physics.friction.FRICTION_LAWS`): lengths by
        the ball radius, ``eps`` the force-space smoothing (G h0 / R); ``pressure_scale_kPa`` the
        scale G h0 / R of pressures in kPa (needed by law: pressure only)."""
        import jax.numpy as jnp

        from dynslip.physics.friction import CAP_BLEND, FRICTION_LAWS

        f = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
        if self.law == "pressure":
            if pressure_scale_kPa is None or not pressure_scale_kPa > 0:
                raise ValueError("law: pressure needs the pressure scale G h0 / R (kPa) > 0, got "
                                 f"{pressure_scale_kPa}")
            params = {"mu_ref": f(self.mu_ref), "p_ref": f(self.p_ref_kPa / pressure_scale_kPa),
                      "a": f(self.exponent), "mu_max": f(self.mu_max), "blend": f(CAP_BLEND)}
        else:
            params = {"coulomb": {"mu": f(self.mu)},
                      "slip_weakening": {"mu_s": f(self.mu_s), "mu_k": f(self.mu_k),
                                         "d_c": f(self.d_c_mm / ball_radius_mm)}}[self.law]
        return FRICTION_LAWS[self.law](**params, eps=f(eps))
