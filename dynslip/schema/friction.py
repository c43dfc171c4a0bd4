"""Schema of the sheet's friction law against a body, the ball's (``physics.friction``) and each
held body's (``physics.bodies[].friction``) alike (physics.md Section 4, "Friction";
docs/forming.md, docs/bodies.md): physical units in the file, one spec class per ``law``, each
building its core law (:mod:`dynslip.physics.friction`, lengths by the ball radius R).

A new law is one :class:`~dynslip.physics.friction.AbstractFriction` subclass and one
:class:`FrictionSpec` subclass with ``law: Literal["name"]`` and a :meth:`FrictionSpec.build`,
added by ``FRICTION_SPECS.register(TheSpec)`` (tests/test_friction_registry.py does so from
outside the package)."""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import model_validator

from dynslip.physics.friction import (
    CAP_BLEND,
    Adhesive,
    Coulomb,
    PressureDependent,
    SlipWeakening,
    capstan_reference_tension,
)
from dynslip.physics.layout import f64
from dynslip.physics.reference import MEASURED_MU_K, MEASURED_MU_S
from dynslip.schema.base import F, Strict
from dynslip.schema.registry import Registry

__all__ = ["FrictionSpec", "FrictionLaw", "FRICTION_SPECS", "CoulombSpec", "SlipWeakeningSpec",
           "PressureSpec", "FrictionlessSpec", "AdhesiveSpec", "CAPSTAN_TEST",
           "capstan_reference_pressure_kPa"]

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

    t_hold = test["hold_mass_g"] * 1e-3 * 9.81
    t_load = t_hold * math.exp(test["mu"] * test["wrap_rad"])
    t_ref = capstan_reference_tension(t_hold, t_load, exponent)
    return t_ref / (test["ball_radius_mm"] * test["strip_width_mm"] * 1e-6) * 1e-3


#: the friction laws of the scenario file, by ``law`` (the one registry: each spec builds its core
#: law); a friction section without ``law`` is Coulomb's, and another law's parameters in it are
#: ignored (``--set physics.friction.law=coulomb`` on a file that states mu_s), as the material's
FRICTION_SPECS = Registry("law", default="coulomb", others_ignored=True)


class FrictionSpec(Strict):
    """A friction law of the sheet on a body: ``law`` names it (:data:`FRICTION_SPECS`), the
    other fields are its parameters."""

    law: str

    #: whether the law may act on the ball only (not on a held body: adhesion,
    #: :class:`AdhesiveSpec`)
    ball_only: ClassVar[bool] = False

    def cohesion(self, ball_radius_mm: float, pressure_scale_kPa: float) -> tuple[float, float]:
        """The ball penalty's cohesive well ``(adhesion, reach)`` in core units (G h0, R): no
        well for a law without normal adhesion."""
        return 0.0, 1e-3

    def build(self, ball_radius_mm: float, eps, pressure_scale_kPa: float | None = None):
        """The core law (:class:`~dynslip.physics.friction.AbstractFriction`, None: frictionless):
        lengths by the ball radius (mm), ``eps`` the force-space smoothing (G h0 / R),
        ``pressure_scale_kPa`` the scale G h0 / R of pressures in kPa."""
        raise NotImplementedError

    @property
    def nominal_mu(self) -> float:
        """The coefficient a reader compares mu_mobilised_max with."""
        raise NotImplementedError

    def static_kinetic(self) -> tuple[float, float, float]:
        """(mu_s, mu_k, d_c_mm) as the trajectory's attributes state them: the nominal mu twice
        and no weakening distance for a law that does not weaken."""
        return self.nominal_mu, self.nominal_mu, 0.0


#: a friction field of the scenario: one of :data:`FRICTION_SPECS`, chosen by ``law``
FrictionLaw = Annotated[FrictionSpec, FRICTION_SPECS]


@FRICTION_SPECS.add
class FrictionlessSpec(FrictionSpec):
    """No friction (a held body's default)."""

    law: Literal["none"] = F("none", description="none: frictionless")

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):
        return None

    @property
    def nominal_mu(self) -> float:
        return 0.0


@FRICTION_SPECS.add
class CoulombSpec(FrictionSpec):
    """Ideal Coulomb friction, mu constant, overdamped soft threshold."""

    law: Literal["coulomb"] = F("coulomb", description="coulomb: ideal Coulomb (mu), overdamped "
                                                       "soft threshold")
    mu: float = F(1.15, ge=0, le=10, description="the Coulomb coefficient, in [0, 10]")

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):

        return Coulomb(mu=f64(self.mu), eps=f64(eps))

    @property
    def nominal_mu(self) -> float:
        return self.mu


@FRICTION_SPECS.add
class SlipWeakeningSpec(FrictionSpec):
    """Static/kinetic friction by slip-distance weakening: mu falls from mu_s to mu_k over the
    slip distance d_c_mm relative to the body, reset where the node heals
    (numerics.heal_rate_mm_s)."""

    law: Literal["slip_weakening"] = F(
        "slip_weakening", description="slip_weakening: static/kinetic, mu falls from mu_s to mu_k "
                                      "over a slip distance d_c_mm, reset when the node sticks")
    mu_s: float = F(MEASURED_MU_S, ge=0, le=10,
                    description=f"static coefficient, in [0, 10] (paper: {MEASURED_MU_S:g})")
    mu_k: float = F(MEASURED_MU_K, ge=0, le=10,
                    description=f"kinetic coefficient, in [0, mu_s] (paper: {MEASURED_MU_K:g})")
    d_c_mm: float = F(0.4, unit="mm", gt=0, le=1e4,
                      description="weakening slip distance, in (0, 1e4] mm; the mesh must be much "
                                  "finer than 15 sqrt(d_c R) (about 42 mm = 2.1 R at the default)")

    @model_validator(mode="after")
    def _order(self):
        if self.mu_k > self.mu_s:
            raise ValueError(f"mu_k = {self.mu_k} exceeds mu_s = {self.mu_s} (kinetic friction "
                             f"must not exceed static)")
        return self

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):

        return SlipWeakening(mu_s=f64(self.mu_s), mu_k=f64(self.mu_k),
                             d_c=f64(self.d_c_mm / ball_radius_mm), eps=f64(eps))

    @property
    def nominal_mu(self) -> float:
        return self.mu_s

    def static_kinetic(self) -> tuple[float, float, float]:
        return self.mu_s, self.mu_k, self.d_c_mm


@FRICTION_SPECS.add
class PressureSpec(FrictionSpec):
    """Friction falling with the contact pressure (Schallamach): mu = mu_ref (p /
    p_ref_kPa)^(-exponent) bounded by mu_max, p the node's contact force per area (deformed, or
    reference: ``pressure_on``)."""

    law: Literal["pressure"] = F(
        "pressure", description="pressure: mu = mu_ref (p / p_ref_kPa)^(-exponent) bounded by "
                                "mu_max (Schallamach), p the node's contact force per area "
                                "(pressure_on)")
    pressure_on: Literal["deformed", "reference"] = F(
        "deformed", description="the area p is taken on: deformed (the true contact pressure, the "
                                "node's reference area times its areal stretch; in the load "
                                "increment, the stretch at the increment's start) or reference "
                                "(the undeformed area: overstates p by the areal stretch, up to "
                                "about 20 in a pocket)")
    exponent: float = F(1.0 / 3.0, ge=0, lt=1,
                        description="exponent a, in [0, 1): 1/3 is Schallamach's (Hertzian "
                                    "asperities), 0 is Coulomb; at 1 the friction force would not "
                                    "rise with the load")
    mu_ref: float = F(MEASURED_MU_S, ge=0, le=10,
                      description=f"coefficient at p_ref_kPa (paper's capstan test: "
                                  f"{MEASURED_MU_S:g})")
    p_ref_kPa: float = F(1.06, unit="kPa", gt=0, le=1e6,
                         description="reference pressure, in (0, 1e6] kPa: the capstan strip "
                                     "test's, T_ref/(R w) with 5 mm strips on the 40 mm ball and "
                                     "masses 2 g and 44.9 g (assumed; docs/experiment.md)")
    mu_max: float = F(2.18, ge=0, le=10,
                      description="bound at low pressure (where the power law would exceed it), "
                                  ">= 1.05 mu_ref; default: the top of the literature's static "
                                  "range for latex, 0.86-2.18")

    @model_validator(mode="after")
    def _bound(self):

        if self.mu_max < self.mu_ref * math.exp(CAP_BLEND):
            raise ValueError(f"mu_max = {self.mu_max} is below mu_ref e^{CAP_BLEND:g} = "
                             f"{self.mu_ref * math.exp(CAP_BLEND):.4g} (the bound must lie above "
                             f"the reference point and the 5% band that rounds it)")
        return self

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):

        if pressure_scale_kPa is None or not pressure_scale_kPa > 0:
            raise ValueError(f"law: pressure needs the pressure scale G h0 / R (kPa) > 0, got "
                             f"{pressure_scale_kPa}")
        return PressureDependent(mu_ref=f64(self.mu_ref), p_ref=f64(self.p_ref_kPa /
                                                                  pressure_scale_kPa),
                                 a=f64(self.exponent), mu_max=f64(self.mu_max),
                                 blend=f64(CAP_BLEND), eps=f64(eps),
                                 deformed_area=self.pressure_on == "deformed")

    @property
    def nominal_mu(self) -> float:
        return self.mu_ref


#: the range of the cohesive law by default (mm): the penalty's width at the default 1e-3 R on the
#: 20 mm ball, so that the well and the repulsion act over the same small gap
DEFAULT_REACH_MM = 0.02


@FRICTION_SPECS.add
class AdhesiveSpec(FrictionSpec):
    """Slip weakening with adhesion (docs/adhesion.md): the friction threshold per node is
    tau_0 A + mu N (Bowden-Tabor, tau_0 from tau0_s_kPa to tau0_k_kPa as mu from mu_s to mu_k
    over d_c_mm), A the node's deformed contact area within the cohesive range; and a cohesive
    well of energy w_J_m2 over the gap reach_mm in the ball's contact penalty (normal adhesion,
    peeling at Kendall's condition). On the ball only. Zero tau_0 and w: slip_weakening exactly."""

    law: Literal["adhesive"] = F(
        "adhesive", description="adhesive: slip_weakening plus an interfacial shear strength "
                                "tau_0 (kPa, static and kinetic) added to the threshold and an "
                                "adhesion energy w (J/m^2) by a cohesive law over reach_mm; the "
                                "ball only")
    mu_s: float = F(MEASURED_MU_S, ge=0, le=10,
                    description=f"static coefficient, in [0, 10] (paper: {MEASURED_MU_S:g})")
    mu_k: float = F(MEASURED_MU_K, ge=0, le=10,
                    description=f"kinetic coefficient, in [0, mu_s] (paper: {MEASURED_MU_K:g})")
    d_c_mm: float = F(0.4, unit="mm", gt=0, le=1e4,
                      description="weakening slip distance of mu and tau_0, in (0, 1e4] mm")
    tau0_s_kPa: float = F(0.0, unit="kPa", ge=0, le=1e4,
                          description="static interfacial shear strength tau_0, in [0, 1e4] kPa "
                                      "(per deformed contact area; rubber on glass: kPa to "
                                      "0.1 MPa, docs/adhesion.md)")
    tau0_k_kPa: float = F(0.0, unit="kPa", ge=0, le=1e4,
                          description="kinetic shear strength, in [0, tau0_s_kPa] kPa, reached "
                                      "over d_c_mm of slip as mu_k")
    w_J_m2: float = F(0.0, unit="J/m^2", ge=0, le=1e2,
                      description="adhesion energy w of the sheet on the ball, in [0, 100] J/m^2 "
                                  "(the area of the cohesive traction-separation curve; per "
                                  "reference area; rubber on glass 0.01-0.1 by JKR, more in peel, "
                                  "docs/adhesion.md)")
    reach_mm: float = F(DEFAULT_REACH_MM, unit="mm", gt=0, le=10,
                        description="range of the cohesive law: the gap at which the adhesion "
                                    "and tau_0 vanish, in (0, 10] mm; the largest tension is "
                                    "15 w / (8 reach)")
    shear_on: Literal["deformed", "reference"] = F(
        "deformed", description="the area tau_0 acts on: deformed (the true contact area) or "
                                "reference (the undeformed area)")

    ball_only: ClassVar[bool] = True

    @model_validator(mode="after")
    def _tau_order(self):
        if self.mu_k > self.mu_s:
            raise ValueError(f"mu_k = {self.mu_k} exceeds mu_s = {self.mu_s} (kinetic friction "
                             f"must not exceed static)")
        if self.tau0_k_kPa > self.tau0_s_kPa:
            raise ValueError(f"tau0_k_kPa = {self.tau0_k_kPa} exceeds tau0_s_kPa = "
                             f"{self.tau0_s_kPa} (the kinetic shear strength must not exceed the "
                             f"static)")
        return self

    def cohesion(self, ball_radius_mm, pressure_scale_kPa):
        # G h0 in N/m is the pressure scale (kPa) times R (mm)
        return self.w_J_m2 / (pressure_scale_kPa * ball_radius_mm), self.reach_mm / ball_radius_mm

    def build(self, ball_radius_mm, eps, pressure_scale_kPa=None):

        if pressure_scale_kPa is None or not pressure_scale_kPa > 0:
            raise ValueError(f"law: adhesive needs the pressure scale G h0 / R (kPa) > 0, got "
                             f"{pressure_scale_kPa}")
        return Adhesive(mu_s=f64(self.mu_s), mu_k=f64(self.mu_k),
                        d_c=f64(self.d_c_mm / ball_radius_mm), eps=f64(eps),
                        tau_s=f64(self.tau0_s_kPa / pressure_scale_kPa),
                        tau_k=f64(self.tau0_k_kPa / pressure_scale_kPa),
                        reach=f64(self.reach_mm / ball_radius_mm),
                        deformed_area=self.shear_on == "deformed")

    @property
    def nominal_mu(self) -> float:
        return self.mu_s

    def static_kinetic(self) -> tuple[float, float, float]:
        return self.mu_s, self.mu_k, self.d_c_mm
