"""Schema of the static scenarios: the paper's contact-region model (``static``,
``figure4``, ``family``) and its 2D case (``cylinder``). See docs/static-model.md.

Physical quantities in the file (R in mm, E in MPa, h0 in mm) set the scales of the
outputs' SI attributes only: the static results are nondimensional (lengths by R,
tensions by G h0, forces by G h0 R) and the friction coefficient does not depend on G.
Every choice the paper leaves open is a field: the initial shape of the march, the
selection rule of the fully mobilised family, the grid, the mu bracket, tolerances
and the march's integrator.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from dynslip.physics.reference import MEASURED_MU_S, PAPER_JM, PAPER_N_NODES
from dynslip.schema.base import F, ScenarioBase, Strict
from dynslip.schema.materials import MaterialSpec

__all__ = [
    "StaticScenario",
    "Figure4Scenario",
    "FamilyScenario",
    "CylinderScenario",
    "Selection",
    "StaticNumerics",
]


def _jm(description: str):
    """Gent's locking parameter J_m: one default and one range wherever a section has it."""
    return F(50.0, gt=0, le=1e4, description=description)


#: bounds of the numbers in tuples (the mu bracket, the shooting's Newton start)
MuValue = Annotated[float, Field(ge=0, le=100)]
StretchValue = Annotated[float, Field(ge=1, le=10)]
SwitchValue = Annotated[float, Field(gt=0, lt=math.pi)]


def _switch_guess(at: str):
    """The shooting's Newton start: one default and one set of bounds wherever it is asked for."""
    return F((2.2, 1.0, 0.25), description=f"Newton start (pole stretch in [1, 10], mu in [0, "
                                           f"100], switch radius in (0, pi)) {at}")


def _increasing(section, lo: str, hi: str) -> None:
    """Refuse a range of a section (its fields ``lo`` and ``hi``) that is empty or reversed."""
    if getattr(section, hi) <= getattr(section, lo):
        raise ValueError(f"{hi} must exceed {lo}")


def material_of(spec: MaterialSpec):
    """The core material (:mod:`dynslip.physics.materials`) of a material section."""
    return spec.core()


class Selection(Strict):
    """The one rule that picks the member of the fully mobilised family (same for all models)."""

    rule: Literal["switch_radius", "switch_angle"] = F(
        "switch_radius",
        description="switch_radius: F_m changes sign at undeformed radius `value` (units R); "
                    "switch_angle: at polar angle `value` (rad), which is also where the largest "
                    "stretch sits")
    value: float = F(0.25, gt=0, lt=math.pi, description="switch radius (units R) or switch angle "
                                                         "(rad), in (0, pi); when omitted: 0.25 R "
                                                         "for switch_radius, pi/4 rad (the "
                                                         "paper's statement) for switch_angle")

    @model_validator(mode="before")
    @classmethod
    def _value_of_rule(cls, data):
        # The paper states the rule as "F_m changes sign where theta = pi/4": that is the
        # default value of switch_angle (0.25 is the default of switch_radius only).
        if isinstance(data, dict) and data.get("rule") == "switch_angle" and "value" not in data:
            data = {**data, "value": math.pi / 4}
        return data


class Geometry(Strict):
    """The contact region and the physical scales (paper Section 3.3)."""

    ball_radius_mm: float = F(20.0, unit="mm", gt=0, le=1e4, description="ball radius R (sets the "
                                                                         "length scale), in (0, "
                                                                         "1e4] mm")
    youngs_modulus_MPa: float = F(2.0, unit="MPa", gt=0, le=1e6,
                                  description="Young's modulus E = 3 G (force scale only), in (0, "
                                              "1e6] MPa")
    thickness_mm: float = F(0.15, unit="mm", gt=0, le=1e4, description="sheet thickness h0 (force "
                                                                       "scale only), in (0, 1e4] "
                                                                       "mm")
    rbar_max: float = F(0.9, gt=0, le=10,
                        description="undeformed radius of the lift-off point, units R, in (0, 10]")
    theta_max: float = F(1.8, unit="rad", gt=0, lt=math.pi,
                         description="polar angle of the lift-off point")


class StaticPhysics(Geometry):
    """Physics of one static solve."""

    material: MaterialSpec = F(MaterialSpec(model="neo_hookean"),
                               description="strain energy (schema/materials.py)")
    initial_shape: Literal["fully_mobilised", "linear"] = F(
        "fully_mobilised",
        description="initial shape of the march: the selected fully mobilised member, or theta = "
                    "theta_max rbar / rbar_max (= 2 rbar for the paper's pair)")
    selection: Selection = F(Selection(),
                             description="selection rule of the fully mobilised member")


class StaticNumerics(Strict):
    """Grid, march and search settings."""

    n_nodes: int = F(100, ge=8, le=2000,
                     description=f"grid nodes from the pole to rbar_max (paper: {PAPER_N_NODES})")
    march: Literal["implicit", "explicit", "diffrax"] = F(
        "implicit", description="march integrator: implicit (backward Euler, semi-smooth Newton, "
                                "growing steps), explicit (forward-Euler jitted loop at the "
                                "stable step) or diffrax")
    diffrax_solver: Literal["euler", "tsit5"] = F(
        "euler", description="diffrax solver: euler (constant stable step) or tsit5 (adaptive)")
    diffrax_rtol: float = F(1e-6, gt=0, lt=1, description="tsit5 relative tolerance")
    dt_safety: float = F(0.4, gt=0, le=1, description="explicit step as a fraction of h^2 / (2 D)")
    rest_velocity: float = F(1e-6, gt=0, lt=1, description="rest when max |d theta/dt| is below "
                                                           "this (units rad per time unit), in "
                                                           "(0, 1)")
    max_steps: int = F(400_000, ge=100, le=100_000_000,
                       description="largest number of march steps per mu, 100..1e8")
    mu_bracket: tuple[MuValue, MuValue] = F((0.1, 5.0), description="search bracket for mu [low, "
                                                                    "high], 0 <= low < high <= "
                                                                    "100")
    mu_tol: float = F(1e-4, gt=0, lt=0.1, description="relative width of the final mu bracket")
    fv_tol: float | None = F(None, ge=0, le=1, unit="1",
                             description="F_v counts as vanished at or below this (units G*h0*R); "
                                         "null: 1e-3 (99/(n_nodes-1))^2, the O(h^2) "
                                         "discretisation error of F_v scaled from N=100")
    ode_rtol: float = F(1e-10, gt=0, lt=1e-3,
                        description="tolerance of the fully mobilised shooting ODE")
    switch_guess: tuple[StretchValue, MuValue, SwitchValue] = _switch_guess("of the shooting")

    def fv_tolerance(self) -> float:
        """The F_v tolerance of the search (``fv_tol``, or its O(h^2) default)."""
        return self.fv_tol if self.fv_tol is not None else 1e-3 * (99.0 / (self.n_nodes - 1)) ** 2

    @field_validator("mu_bracket")
    @classmethod
    def _bracket(cls, v):
        lo, hi = v
        if not (0 <= lo < hi):
            raise ValueError(f"allowed: 0 <= low < high (mu is never negative), got {list(v)}")
        return v


class StaticScenario(ScenarioBase):
    """The paper's static contact-region model for one material (Fig. 4 row)."""

    kind: Literal["static"] = "static"
    physics: StaticPhysics = F(StaticPhysics(), description="physics")
    numerics: StaticNumerics = F(StaticNumerics(), description="numerics")


class Figure4Physics(Geometry):
    """The three models of the paper's Fig. 4 (Hookean, neo-Hookean, Gent)."""

    jm: float = _jm(f"Gent J_m (paper: {PAPER_JM:g}), in (0, 1e4]")
    initial_shape: Literal["fully_mobilised", "linear"] = F("fully_mobilised",
                                                            description="as in kind static")
    selection: Selection = F(Selection(), description="one selection rule for all three models")


class Figure4Scenario(ScenarioBase):
    """The whole 3x3 Fig. 4 of the paper in one run."""

    kind: Literal["figure4"] = "figure4"
    physics: Figure4Physics = F(Figure4Physics(), description="physics")
    numerics: StaticNumerics = F(StaticNumerics(), description="numerics")


class FamilyPhysics(Geometry):
    """The fully mobilised family of the three models, swept along its switch point."""

    jm: float = _jm("Gent J_m, in (0, 1e4]")
    switch_by: Literal["switch_radius", "switch_angle"] = F(
        "switch_radius", description="parameter of the family")
    switch_from: float = F(0.15, gt=0, lt=math.pi,
                           description="first switch value (units R, or rad), in (0, pi)")
    switch_to: float = F(0.32, gt=0, lt=math.pi,
                         description="last switch value (units R, or rad), in (0, pi)")
    selection: Selection = F(Selection(), description="rule marked on the plot")

    @model_validator(mode="after")
    def _range(self):
        _increasing(self, "switch_from", "switch_to")
        if self.switch_by == "switch_radius" and self.switch_to >= self.rbar_max:
            raise ValueError("switch_to must lie inside the contact region (< rbar_max)")
        return self


class FamilyNumerics(Strict):
    """Sweep resolution and shooting settings."""

    n_members: int = F(18, ge=2, le=400, description="members along the switch range")
    ode_rtol: float = F(1e-10, gt=0, lt=1e-3, description="tolerance of the shooting ODE")
    switch_guess: tuple[StretchValue, MuValue, SwitchValue] = _switch_guess("at the middle member")


class FamilyScenario(ScenarioBase):
    """mu across the fully mobilised family for Hookean, neo-Hookean and Gent."""

    kind: Literal["family"] = "family"
    physics: FamilyPhysics = F(FamilyPhysics(), description="physics")
    numerics: FamilyNumerics = F(FamilyNumerics(), description="numerics")


class CylinderPhysics(Strict):
    """A membrane on a rigid cylinder (paper Section 5)."""

    mu: float = F(MEASURED_MU_S, ge=0, le=10,
                  description=f"friction coefficient (paper: static {MEASURED_MU_S:g})")
    theta_max_from: float = F(0.1, unit="rad", gt=0, lt=math.pi,
                              description="smallest lift-off angle")
    theta_max_to: float = F(3.0, unit="rad", gt=0, lt=math.pi, description="largest lift-off angle")

    @model_validator(mode="after")
    def _range(self):
        _increasing(self, "theta_max_from", "theta_max_to")
        return self


class CylinderNumerics(Strict):
    """Random admissible friction profiles and their grid."""

    n_profiles: int = F(200, ge=1, le=10_000, description="random admissible friction profiles, "
                                                          "1..1e4 (n_profiles * n_nodes <= 1e7)")
    n_nodes: int = F(400, ge=8, le=10_000, description="nodes on [0, theta_max], 8..1e4")
    n_angles: int = F(30, ge=2, le=1000, description="lift-off angles sampled, 2..1000")
    seed: int = F(0, ge=0, le=2**31 - 2,
                  description="random seed, 0..2^31-2 (seed + 1 seeds the plotted profiles)")

    @model_validator(mode="after")
    def _size(self):
        if self.n_profiles * self.n_nodes > 10_000_000:
            raise ValueError(f"n_profiles * n_nodes = {self.n_profiles * self.n_nodes}: allowed "
                             f"at most 1e7 (the profiles of one angle are held in memory at once)")
        return self


class CylinderScenario(ScenarioBase):
    """The 2D case: capstan bounds and the vertical force (no invagination in 2D)."""

    kind: Literal["cylinder"] = "cylinder"
    physics: CylinderPhysics = F(CylinderPhysics(), description="physics")
    numerics: CylinderNumerics = F(CylinderNumerics(), description="numerics")
