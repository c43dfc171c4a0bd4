"""Schema of a forming scenario's stages: one keyframe of the loading path each (the clamp's
motion, what holds the ball, the bodies moved by the stages, and when the stage ends), and the
default method 2 path. Physical units in the file (mm, mm/s, s, N); docs/forming.md.

A stage's ``until`` is its stop rule: one spec per ``rule`` (:data:`STOP_SPECS`), each with its
own parameters, its checks against the stage and the core rule it builds
(:class:`dynslip.physics.protocols.AbstractStop`). A new rule is one ``AbstractStop`` subclass
and one :class:`StopSpec` subclass with ``rule: Literal["name"]``, added by
``STOP_SPECS.register(TheSpec)`` (tests/test_stop_registry.py does so from outside the
package). Each section of the scenario has its own module; :mod:`dynslip.schema.forming`
re-exports :class:`StageSpec`.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import model_validator

from dynslip.physics.protocols import (
    BallReactionBelow,
    BallSpeedAbove,
    ClampForceBelow,
    Duration,
    Rest,
    ThetaMaxBelow,
)
from dynslip.schema.base import F, Strict
from dynslip.schema.registry import Registry

__all__ = ["MAX_STAGES", "MAX_TIME_S", "STOP_SPECS", "StopSpec", "Until", "DurationSpec",
           "ClampForceBelowSpec", "BallReactionBelowSpec", "ThetaMaxBelowSpec",
           "BallSpeedAboveSpec", "RestSpec", "StageSpec", "default_stages"]

#: bounds of the loading path: the longest time of a stage (s), the most stages
MAX_TIME_S = 1e6
MAX_STAGES = 100


#: the stop rules of the scenario file, by ``rule`` (the one registry: each spec builds its core
#: rule); ``until: rest`` is ``until: {rule: rest}``
STOP_SPECS = Registry("rule")


class StopSpec(Strict):
    """When a stage ends: ``rule`` names it (:data:`STOP_SPECS`), the other fields are its
    parameters (physical units)."""

    rule: str

    def build(self, duration: float, r: float, fs: float):
        """The core rule (:class:`~dynslip.physics.protocols.AbstractStop`), thresholds made
        nondimensional (lengths by ``r`` mm, forces by ``fs`` N); a condition rule ends the stage
        at ``duration`` s at the latest."""
        raise NotImplementedError

    def check_stage(self, stage: StageSpec) -> None:
        """Refuse (ValueError, one line) a stage on which this rule can never hold."""


#: a stage's ``until``: one of :data:`STOP_SPECS`, chosen by ``rule``
Until = Annotated[StopSpec, STOP_SPECS]


@STOP_SPECS.add
class DurationSpec(StopSpec):
    """The stage lasts its duration_s (or its clamp_to_z_mm move)."""

    rule: Literal["duration"] = F("duration", description="duration: the stage's duration_s")

    def build(self, duration, r, fs):

        return Duration(duration=duration)


@STOP_SPECS.add
class ClampForceBelowSpec(StopSpec):
    """Ends when the clamp's axial force, net of the sheet's drag, falls below force_N."""

    rule: Literal["clamp_force_below"] = F(
        "clamp_force_below", description="clamp_force_below: the clamp's axial force (net of "
                                         "drag) below force_N")
    force_N: float = F(..., unit="N", gt=0, le=1e6, description="the threshold, in (0, 1e6] N")

    def build(self, duration, r, fs):

        return ClampForceBelow(force=self.force_N / fs, duration=duration)

    def check_stage(self, stage):
        if stage.clamp not in ("move", "band"):
            raise ValueError("until: clamp_force_below needs a clamp that holds the edge (clamp: "
                             "move or band)")
        if stage.clamp_velocity_mm_s == 0.0 and stage.ball == "hold" \
                and stage.ball_velocity_mm_s == 0.0:
            raise ValueError("until: clamp_force_below with a clamp and ball at rest can never "
                             "hold (nothing unloads the sheet)")


@STOP_SPECS.add
class BallReactionBelowSpec(StopSpec):
    """Ends when the hold's force on the ball (+ up, net of drag) falls below force_N: a held
    ball standing in for one on its support, where the support would stop carrying it."""

    rule: Literal["ball_reaction_below"] = F(
        "ball_reaction_below", description="ball_reaction_below: the hold's force on the ball "
                                           "(net of drag) below force_N")
    force_N: float = F(..., unit="N", gt=0, le=1e6, description="the threshold, in (0, 1e6] N")

    def build(self, duration, r, fs):

        return BallReactionBelow(force=self.force_N / fs, duration=duration)

    def check_stage(self, stage):
        if stage.ball != "hold":
            raise ValueError("until: ball_reaction_below reads a held ball's reaction: it needs "
                             "ball: hold")


@STOP_SPECS.add
class ThetaMaxBelowSpec(StopSpec):
    """Ends when the contact edge's polar angle falls below angle_rad, or contact is lost."""

    rule: Literal["theta_max_below"] = F(
        "theta_max_below", description="theta_max_below: the contact edge's polar angle below "
                                       "angle_rad")
    angle_rad: float = F(..., unit="rad", gt=0, lt=math.pi,
                         description="the polar angle, in (0, pi) (pi/2: opening radius R)")

    def build(self, duration, r, fs):

        return ThetaMaxBelow(angle=self.angle_rad, duration=duration)


@STOP_SPECS.add
class BallSpeedAboveSpec(StopSpec):
    """Ends when the ball's speed exceeds speed_mm_s: a pull has torn the ball out."""

    rule: Literal["ball_speed_above"] = F(
        "ball_speed_above", description="ball_speed_above: the ball's speed above speed_mm_s")
    speed_mm_s: float = F(..., unit="mm/s", gt=0, le=1e3,
                          description="the ball-speed threshold, in (0, 1e3] mm/s")

    def build(self, duration, r, fs):

        return BallSpeedAbove(rate=self.speed_mm_s / r, duration=duration)


@STOP_SPECS.add
class RestSpec(StopSpec):
    """Ends when the largest slip speed and the ball's speed have stayed below rate_mm_s for
    hold_s."""

    rule: Literal["rest"] = F("rest", description="rest: slip and ball speeds below rate_mm_s for "
                                                  "hold_s")
    rate_mm_s: float = F(..., unit="mm/s", gt=0, le=1e4,
                         description="largest slip speed and ball speed, in (0, 1e4] mm/s")
    hold_s: float = F(..., unit="s", gt=0, le=MAX_TIME_S,
                      description="for this long, in (0, 1e6] s; shorter than the stage's "
                                  "duration_s")

    def build(self, duration, r, fs):

        return Rest(rate=self.rate_mm_s / r, hold=self.hold_s, duration=duration)

    def check_stage(self, stage):
        if stage.duration_s is not None and self.hold_s >= stage.duration_s:
            raise ValueError(f"until: rest can never hold: hold_s = {self.hold_s} must be shorter "
                             f"than duration_s = {stage.duration_s}")


class StageSpec(Strict):
    """One stage: clamp motion, what holds the ball, and when the stage ends."""

    name: str = F(..., min_length=1, description="stage name (unique)")
    clamp_to_z_mm: float | None = F(None, unit="mm", ge=-1e4, le=1e4,
                                    description="clamp height to move to (from the ball centre), "
                                                "in [-1e4, 1e4] mm; needs clamp_speed_mm_s")
    clamp_speed_mm_s: float | None = F(None, unit="mm/s", ge=1e-6, le=1e4,
                                       description="speed of a clamp_to_z_mm move, in [1e-6, 1e4] "
                                                   "mm/s")
    clamp_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                   description="signed vertical clamp velocity (up > 0) for "
                                               "stages ended by a condition or duration, in "
                                               "[-1e4, 1e4] mm/s")
    duration_s: float | None = F(None, unit="s", gt=0, le=MAX_TIME_S,
                                 description="stage duration, in (0, 1e6] s; for condition stages "
                                             "the longest it may run")
    until: Until = F(
        DurationSpec(),
        description="stop rule, by rule: duration (the default), clamp_force_below (force_N), "
                    "ball_reaction_below (force_N: a held ball standing in for one on its "
                    "support: the support would stop carrying it), theta_max_below (angle_rad), "
                    "ball_speed_above (speed_mm_s: a pull has torn the ball out), rest "
                    "(rate_mm_s, hold_s); a rule without parameters may be written as its name")
    ball_force_N: float | None = F(None, unit="N", ge=-1e3, le=1e3,
                                   description="ball: pull: the applied force on the ball at the "
                                               "stage's end (up > 0; toward the pocket's opening "
                                               "< 0), ramped linearly from 0 over duration_s")
    ball_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                  description="signed velocity (up > 0), in [-1e4, 1e4] mm/s, of "
                                              "a held ball (ball: hold); the pole of the ball "
                                              "points up, the pocket's opening down")
    tube_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                  description="signed velocity (up > 0) in the lab of the tube "
                                              "(its wall, rim and band; physics.tube) over this "
                                              "stage, in [-1e4, 1e4] mm/s: the push-down < 0, the "
                                              "raise > 0; it needs ball: hold or support (the "
                                              "ball on its support) and a clamp that moves with "
                                              "the tube (clamp: band or move, no clamp_to_z_mm)")
    body_velocity_mm_s: dict[str, float] = F(
        default_factory=dict, unit="mm/s",
        description="signed axial velocity (up > 0), in [-1e4, 1e4] mm/s, over this stage of each "
                    "held body with motion: stage (physics.bodies), by name; a body not named "
                    "stays where the previous stage left it")
    clamp: Literal["move", "let_go", "free", "band"] = F(
        "move", description="move: the clamp holds the edge and moves as given; let_go: its force "
                            "on the sheet is ramped to zero over the stage (the band lets the "
                            "sheet go); free: the edge is not held; band: the band on the tube's "
                            "wall (moving as given) holds the edge while the sheet's pull along "
                            "the wall is below physics.band_grip_N_per_mm times the band's "
                            "circumference, and lets it slide beyond")
    ball: Literal["hold", "release", "free", "support", "pull"] = F(
        "hold", description="hold: ball held in place; release: the hold's reaction ramped to "
                            "zero over the stage; free: no hold; support: the ball rests on the "
                            "bottle neck (a rigid unilateral support below it: the pocket may "
                            "lift it off); pull: a force ramped from 0 (from the previous stage's "
                            "final force when that stage is a pull too: a preload, then a ramp) "
                            "to ball_force_N over the stage")

    @model_validator(mode="after")
    def _consistent(self):
        if self.clamp not in ("move", "band") and (
            self.clamp_to_z_mm is not None or self.clamp_velocity_mm_s != 0.0
        ):
            raise ValueError(f"clamp: {self.clamp} prescribes no clamp motion; drop clamp_to_z_mm "
                             f"/ clamp_velocity_mm_s")
        if self.clamp_to_z_mm is not None:
            if self.clamp_speed_mm_s is None:
                raise ValueError("clamp_to_z_mm needs clamp_speed_mm_s")
            if self.clamp_velocity_mm_s != 0.0:
                raise ValueError("overlapping clamp motions: give clamp_to_z_mm (with "
                                 "clamp_speed_mm_s) or clamp_velocity_mm_s, not both")
            if self.duration_s is not None:
                raise ValueError("overlapping timing: a clamp_to_z_mm move takes |dz|/speed; drop "
                                 "duration_s")
            if self.until.rule != "duration":
                raise ValueError("a clamp_to_z_mm move ends at its target: use until: duration")
        elif self.clamp_speed_mm_s is not None:
            raise ValueError("clamp_speed_mm_s without clamp_to_z_mm")
        elif self.duration_s is None:
            raise ValueError("duration_s is required (the duration, or the longest a condition "
                             "stage may run)")
        if (self.ball == "pull") != (self.ball_force_N is not None):
            raise ValueError("ball_force_N goes with ball: pull (and ball: pull needs it)")
        for name, v in self.body_velocity_mm_s.items():
            if not (math.isfinite(v) and -1e4 <= v <= 1e4):
                raise ValueError(f"body_velocity_mm_s[{name!r}] = {v}: allowed [-1e4, 1e4] mm/s")
        if self.tube_velocity_mm_s != 0.0 and (
                self.ball not in ("hold", "support") or self.clamp_to_z_mm is not None
                or self.clamp not in ("move", "band")):
            raise ValueError(f"tube_velocity_mm_s = {self.tube_velocity_mm_s}: the tube moves "
                             f"with the ball on its support and the sheet's edge on the tube; "
                             f"allowed with ball: hold or support and clamp: band or move, "
                             f"without clamp_to_z_mm")
        if self.ball_velocity_mm_s != 0.0 and self.ball != "hold":
            raise ValueError("ball_velocity_mm_s moves a held ball: it needs ball: hold")
        self.until.check_stage(self)
        return self


def default_stages() -> list[StageSpec]:
    """The default method 2 path (scenarios/method2_pinned.yaml): push down, hold, the rim lets the
    sheet go, the ball's hold is released, hold until at rest."""
    return [
        StageSpec(name="push_down", clamp_to_z_mm=-160.0, clamp_speed_mm_s=2.0),
        StageSpec(name="hold", duration_s=10.0),
        StageSpec(name="let_go", clamp="let_go", duration_s=10.0),
        StageSpec(name="release", clamp="free", ball="release", duration_s=10.0),
        StageSpec(
            name="rest",
            clamp="free",
            ball="free",
            duration_s=200.0,
            until=RestSpec(rate_mm_s=0.002, hold_s=10.0),
        ),
    ]
