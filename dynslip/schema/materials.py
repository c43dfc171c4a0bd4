"""The sheet's strain energy: one material section for every scenario kind (static and forming).

``model`` names the energy (physics.md Section 2; :mod:`dynslip.physics.materials`); the
other fields are its parameters and are ignored by models that have none, so
``--set physics.material.model=neo_hookean`` works on a file that states ``jm``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from dynslip.physics.materials import MATERIALS
from dynslip.schema.base import F, Strict

__all__ = ["MaterialSpec", "MODELS"]

MODELS = ("gent", "neo_hookean", "mooney_rivlin", "hookean")


class MaterialSpec(Strict):
    """The sheet's strain energy (physics.md Section 2), in units of the shear modulus G."""

    model: Literal["gent", "neo_hookean", "mooney_rivlin", "hookean"] = F(
        "gent",
        description="strain energy: gent -(J_m/2) ln(1 - (I1 - 3)/J_m); neo_hookean (I1 - 3)/2; "
                    "mooney_rivlin C1 (I1 - 3) + C2 (I2 - 3); hookean, the small-strain energy "
                    "(unrelaxed, as in the paper; refused beyond stretch 3)",
    )
    jm: float = F(
        50.0, gt=0, le=1e4, description="Gent locking parameter J_m (I1 < J_m + 3), in (0, 1e4]"
    )
    c1: float = F(0.4, ge=0, le=0.5, description="Mooney-Rivlin C1 / G, in [0, 0.5]")
    c2: float | None = F(None, ge=0, le=0.5, description="Mooney-Rivlin C2 / G; default 1/2 - c1 "
                                                         "(2 C1 + 2 C2 = 1: G is the unit)")

    @model_validator(mode="after")
    def _sum(self):
        if self.c2 is not None and abs(2 * self.c1 + 2 * self.c2 - 1.0) > 1e-9:
            raise ValueError(
                f"2 c1 + 2 c2 must be 1 (shear modulus G), got {2 * self.c1 + 2 * self.c2:g}"
            )
        return self

    @property
    def c2_value(self) -> float:
        return 0.5 - self.c1 if self.c2 is None else self.c2

    def core(self):
        """The core material (:data:`dynslip.physics.materials.MATERIALS`), its parameters
        from this section."""

        params = {"mooney_rivlin": {"c1": float(self.c1), "c2": float(self.c2_value)},
                  "gent": {"jm": float(self.jm)}}
        return MATERIALS[self.model](**params.get(self.model, {}))
