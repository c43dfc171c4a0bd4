"""Schema of a forming scenario's stages: one keyframe of the loading path each (the clamp's
motion, what holds the ball, the bodies moved by the stages, and when the stage ends), and the
default method 2 path. Physical units in the file (mm, mm/s, s, N); docs/forming.md.

Each section of the scenario has its own module; :mod:`dynslip.schema.forming` re-exports
:class:`StageSpec`.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import model_validator

from dynslip.schema.base import F, Strict

__all__ = ["MAX_STAGES", "MAX_TIME_S", "StageSpec", "default_stages"]

#: bounds of the loading path: the longest time of a stage (s), the most stages
MAX_TIME_S = 1e6
MAX_STAGES = 100


class StageSpec(Strict):
    """One stage: clamp motion, what holds the ball, and when the stage ends."""

    name: str = F(..., min_length=1, description="stage name (unique)")
    clamp_to_z_mm: float | None = F(None, unit="mm", ge=-1e4, le=1e4,
                                    description="clamp height to move to (from the ball centre), "
                                                "in [-1e4, 1e4] mm; "
                                    "needs clamp_speed_mm_s")
    clamp_speed_mm_s: float | None = F(None, unit="mm/s", ge=1e-6, le=1e4,
                                       description="speed of a clamp_to_z_mm move, in [1e-6, 1e4] "
                                                   "mm/s")
    clamp_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                   description="signed vertical clamp velocity (up > 0) for stages "
                                               "ended by a condition "
                                   "or duration, in [-1e4, 1e4] mm/s")
    duration_s: float | None = F(None, unit="s", gt=0, le=MAX_TIME_S,
                                 description="stage duration, in (0, 1e6] s; for condition stages "
                                             "the longest it may run")
    until: Literal[
        "duration", "clamp_force_below", "rest", "theta_max_below", "ball_speed_above",
        "ball_reaction_below",
    ] = F(
        "duration",
        description="stop rule: the duration, the clamp's axial force below a "
        "threshold, rest, "
        "the contact edge's polar angle below theta_stop_rad, or the ball's speed above "
        "ball_speed_mm_s (a pull "
        "has torn the ball out), or the hold's force on the ball below force_threshold_N (a held "
        "ball standing in for one on its support: the support would stop carrying it)",
    )
    ball_speed_mm_s: float | None = F(None, unit="mm/s", gt=0, le=1e3,
                                      description="until: ball_speed_above: the ball-speed "
                                                  "threshold")
    ball_force_N: float | None = F(None, unit="N", ge=-1e3, le=1e3,
                                   description="ball: pull: the applied force on the ball at the "
                                               "stage's end (up > 0; "
                                   "toward the pocket's opening < 0), ramped linearly from 0 over "
                                   "duration_s")
    theta_stop_rad: float | None = F(None, unit="rad", gt=0, lt=math.pi,
                                     description="until: theta_max_below: the polar angle (pi/2: "
                                                 "opening radius R)")
    ball_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                  description="signed velocity (up > 0), in [-1e4, 1e4] mm/s, of a "
                                              "held ball (ball: "
                                  "hold); the pole of the "
                                  "ball points up, the pocket's opening down")
    tube_velocity_mm_s: float = F(0.0, unit="mm/s", ge=-1e4, le=1e4,
                                  description="signed velocity (up > 0) in the lab of the tube "
                                              "(its wall, rim and band; physics.tube) over this "
                                              "stage, in [-1e4, 1e4] mm/s: the push-down < 0, the "
                                              "raise > 0; it needs ball: hold or support (the "
                                              "ball on its support) and a clamp that moves with "
                                              "the tube (clamp: band or move, no clamp_to_z_mm)")
    body_velocity_mm_s: dict[str, float] = F(
        default_factory=dict, unit="mm/s",
        description="signed axial velocity (up > 0), in [-1e4, 1e4] mm/s, over this stage of "
        "each held body with motion: stage (physics.bodies), by name; a body not named stays "
        "where the previous stage left it")
    force_threshold_N: float | None = F(None, unit="N", gt=0, le=1e6,
                                        description="threshold of until: clamp_force_below, in (0, "
                                                    "1e6] N")
    rest_rate_mm_s: float | None = F(None, unit="mm/s", gt=0, le=1e4,
                                     description="until: rest: largest slip speed and ball speed "
                                                 "below this, "
                                     "in (0, 1e4] mm/s")
    rest_hold_s: float | None = F(None, unit="s", gt=0, le=MAX_TIME_S,
                                  description="until: rest: for this long, in (0, 1e6] s")
    clamp: Literal["move", "let_go", "free", "band"] = F(
        "move", description="move: the clamp holds the edge and moves as given; let_go: its force "
                            "on the sheet is "
        "ramped to zero over the stage (the band lets the sheet go); free: the edge is not held; "
        "band: the band on the tube's wall (moving as given) holds the edge while the sheet's "
        "pull along the wall is below physics.band_grip_N_per_mm times the band's circumference, "
        "and lets it slide beyond")
    ball: Literal["hold", "release", "free", "support", "pull"] = F(
        "hold", description="hold: ball held in place; release: the hold's reaction ramped to zero "
                            "over the "
        "stage; free: no hold; support: the ball rests on the bottle neck (a rigid unilateral "
        "support below it: "
        "the pocket may lift it off); pull: a force ramped from 0 (from the previous stage's final "
        "force when that "
        "stage is a pull too: a preload, then a ramp) to ball_force_N over the stage")

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
                                 "clamp_speed_mm_s) "
                                 "or clamp_velocity_mm_s, not both")
            if self.duration_s is not None:
                raise ValueError("overlapping timing: a clamp_to_z_mm move takes |dz|/speed; drop "
                                 "duration_s")
            if self.until != "duration":
                raise ValueError("a clamp_to_z_mm move ends at its target: use until: duration")
        elif self.clamp_speed_mm_s is not None:
            raise ValueError("clamp_speed_mm_s without clamp_to_z_mm")
        elif self.duration_s is None:
            raise ValueError("duration_s is required (the duration, or the longest a condition "
                             "stage may run)")
        if self.until == "clamp_force_below":
            if self.force_threshold_N is None:
                raise ValueError("until: clamp_force_below needs force_threshold_N")
            if self.clamp not in ("move", "band"):
                raise ValueError("until: clamp_force_below needs a clamp that holds the edge "
                                 "(clamp: move or band)")
            if (
                self.clamp_velocity_mm_s == 0.0
                and self.ball == "hold"
                and self.ball_velocity_mm_s == 0.0
            ):
                raise ValueError("until: clamp_force_below with a clamp and ball at rest can never "
                                 "hold "
                                 "(nothing unloads the sheet)")
        if self.until == "ball_reaction_below":
            if self.force_threshold_N is None:
                raise ValueError("until: ball_reaction_below needs force_threshold_N")
            if self.ball != "hold":
                raise ValueError("until: ball_reaction_below reads a held ball's reaction: it "
                                 "needs ball: hold")
        if self.until == "ball_speed_above" and self.ball_speed_mm_s is None:
            raise ValueError("until: ball_speed_above needs ball_speed_mm_s")
        if (self.ball == "pull") != (self.ball_force_N is not None):
            raise ValueError("ball_force_N goes with ball: pull (and ball: pull needs it)")
        if self.until == "theta_max_below" and self.theta_stop_rad is None:
            raise ValueError("until: theta_max_below needs theta_stop_rad")
        for name, v in self.body_velocity_mm_s.items():
            if not (math.isfinite(v) and -1e4 <= v <= 1e4):
                raise ValueError(f"body_velocity_mm_s[{name!r}] = {v}: allowed [-1e4, 1e4] mm/s")
        if self.tube_velocity_mm_s != 0.0 and (
                self.ball not in ("hold", "support") or self.clamp_to_z_mm is not None
                or self.clamp not in ("move", "band")):
            raise ValueError(f"tube_velocity_mm_s = {self.tube_velocity_mm_s}: the tube moves "
                             "with the ball on its support and the sheet's edge on the tube; "
                             "allowed with ball: hold or support and clamp: band or move, "
                             "without clamp_to_z_mm")
        if self.ball_velocity_mm_s != 0.0 and self.ball != "hold":
            raise ValueError("ball_velocity_mm_s moves a held ball: it needs ball: hold")
        if self.until == "rest":
            if self.rest_rate_mm_s is None or self.rest_hold_s is None:
                raise ValueError("until: rest needs rest_rate_mm_s and rest_hold_s")
            if self.rest_hold_s >= self.duration_s:
                raise ValueError("until: rest can never hold: rest_hold_s must be shorter than "
                                 "duration_s")
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
            until="rest",
            rest_rate_mm_s=0.002,
            rest_hold_s=10.0,
        ),
    ]
