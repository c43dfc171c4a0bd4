"""Schema of the apparatus around the ball in a forming scenario: the tube's wall and the
bottle, each a set of held bodies with the sheet's Coulomb friction on it (docs/bodies.md).
Physical units in the file (mm).

:mod:`dynslip.schema.forming` re-exports both.
"""

from __future__ import annotations

from pydantic import model_validator

from dynslip.physics.bodies.apparatus import check_bottle_fillets
from dynslip.physics.bodies.base import BodyGeometryError
from dynslip.schema.base import F, Strict

__all__ = ["BottleSpec", "TubeSpec"]


class TubeSpec(Strict):
    """The tube's wall as a held body, in the tube's frame (scenarios/method2_band.yaml): its
    outer wall at rim_radius_mm, its end fully rounded (a torus of radius wall_mm / 2), the
    rim's lowest point rim_gap_mm above the flat sheet, the wall up to height_mm above it;
    Coulomb friction of the sheet on it."""

    wall_mm: float = F(3.0, unit="mm", gt=0, le=1e3,
                       description="wall thickness (its end a half torus of radius wall_mm / 2), "
                                   "in (0, 1e3] mm, below the rim's radius")
    height_mm: float = F(101.6, unit="mm", gt=0, le=1e4,
                         description="tube height above the rim, in (0, 1e4] mm; the tube is an "
                                     "open cylinder: its height is geometry only and does not "
                                     "bound the push (the ball and the sheet's tent can leave "
                                     "through its top end)")
    rim_gap_mm: float = F(0.2, unit="mm", gt=0, le=1e3,
                          description="the rim's lowest point above the flat sheet's initial "
                                      "height, in (0, 1e3] mm")
    mu: float = F(0.5, ge=0, le=10,
                  description="Coulomb coefficient of the sheet on the tube (latex on PVC: "
                              "0.3-1.0 assumed, docs/bodies.md), in [0, 10]")


class BottleSpec(Strict):
    """The bottle the ball sits on, one closed smooth held solid (docs/bodies.md): a neck
    whose rounded lip is the ball's support ring (tangent-below the ball), a conical shoulder,
    a cylindrical body, their corners rounded by the stated fillets
    (:func:`~dynslip.physics.bodies.apparatus.bottle`); Coulomb friction of the sheet on the
    glass."""

    neck_od_mm: float = F(25.4, unit="mm", gt=0, le=1e3,
                          description="the neck's outer diameter (the paper's 1 in), in (0, 1e3] "
                                      "mm, below the ball's diameter")
    neck_wall_mm: float = F(2.0, unit="mm", gt=0, le=1e3,
                            description="the neck's glass wall (its lip a half torus of radius "
                                        "neck_wall_mm / 2), in (0, 1e3] mm, below the neck's "
                                        "radius")
    neck_length_mm: float = F(65.0, unit="mm", gt=0, le=1e4,
                              description="the neck's length from its lip to the shoulder "
                                          "(bottles with a 1 in neck: 50-80 mm), in (0, 1e4] mm")
    shoulder_height_mm: float = F(18.6, unit="mm", gt=0, le=1e4,
                                  description="the conical shoulder's height from the neck to the "
                                              "body, in (0, 1e4] mm")
    body_od_mm: float = F(70.0, unit="mm", gt=0, le=1e4,
                          description="the body's outer diameter (typically 60-75 mm), in (0, "
                                      "1e4] mm, wider than the neck and inside the tube")
    body_height_mm: float = F(140.0, unit="mm", gt=0, le=1e4,
                              description="the body's height below the shoulder, in (0, 1e4] mm")
    neck_fillet_mm: float = F(5.0, unit="mm", gt=0, le=1e3,
                              description="radius of the hollow fillet between the neck and the "
                                          "shoulder (glass bottles: a few mm assumed), in (0, "
                                          "1e3] mm, fitting the neck and the shoulder")
    shoulder_fillet_mm: float = F(10.0, unit="mm", gt=0, le=1e3,
                                  description="radius of the rounded edge between the shoulder "
                                              "and the body (glass bottles: 5-15 mm assumed), in "
                                              "(0, 1e3] mm, fitting the shoulder and the body")
    base_fillet_mm: float = F(5.0, unit="mm", gt=0, le=1e3,
                              description="radius of the rounded edge of the body's base (glass "
                                          "bottles: a few mm assumed), in (0, 1e3] mm, below the "
                                          "body's radius")
    mu: float = F(0.7, ge=0, le=10,
                  description="Coulomb coefficient of the sheet on the glass (latex on smooth "
                              "clean glass: 0.5-1.0 assumed, docs/bodies.md), in [0, 10]")

    @model_validator(mode="after")
    def _fillets_fit(self):

        if not self.body_od_mm > self.neck_od_mm:
            return self  # refused where the ball is known (FormingPhysics), naming the neck
        try:
            check_bottle_fillets(self.neck_od_mm, self.neck_wall_mm, self.neck_length_mm,
                                 self.shoulder_height_mm, self.body_od_mm, self.body_height_mm,
                                 self.neck_fillet_mm, self.shoulder_fillet_mm,
                                 self.base_fillet_mm)
        except BodyGeometryError as err:
            raise ValueError(str(err).removeprefix("bottle ")) from None
        return self
