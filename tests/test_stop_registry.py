"""A stop rule added from outside the package: one core rule (an ``AbstractStop``), one spec (a
``StopSpec`` with its ``rule``, its parameters and its check against the stage), one
registration (``STOP_SPECS``). A stage's ``until`` then names it and the run stops by it."""

from __future__ import annotations

from typing import ClassVar, Literal

import pytest
from pydantic import Field

from dynslip.physics.protocols import AbstractStop
from dynslip.schema.base import validate_data
from dynslip.schema.stages import STOP_SPECS, StopSpec
from helpers import registered

SPEED_MM_S = 4.0  # the clamp's descent
TARGET_MM = 0.0  # the height at which the stage ends: the ball's centre
SAVE_S = 1.0
SHEET_START_MM = 20.4  # the flat sheet's default start: the ball's top and the 0.4 mm gap


class ClampBelow(AbstractStop):
    """Ends when the clamp's height (R) is below ``z``."""

    duration: float
    z: float
    kind: ClassVar[str] = "clamp_below"
    met_at_duration: ClassVar[bool] = False

    def check(self, frame, t, state):
        return bool(float(frame["clamp_z"]) < self.z), state

    def scaled(self, factor):
        return ClampBelow(duration=self.duration * factor, z=self.z)


class ClampBelowSpec(StopSpec):
    """The scenario file's ``until: {rule: clamp_below, z_mm: ...}``."""

    rule: Literal["clamp_below"] = "clamp_below"
    z_mm: float = Field(..., ge=-1e4, le=1e4)

    def build(self, duration, r, fs):
        return ClampBelow(duration=duration, z=self.z_mm / r)

    def check_stage(self, stage):
        if not stage.clamp_velocity_mm_s < 0:
            raise ValueError(f"until: clamp_below needs the clamp moving down, got "
                             f"clamp_velocity_mm_s = {stage.clamp_velocity_mm_s}")


@pytest.fixture
def clamp_below():
    with registered(STOP_SPECS, ClampBelowSpec):
        yield ClampBelowSpec


def _scenario(velocity: float) -> dict:
    return {
        "kind": "forming",
        "physics": {"stages": [
            {"name": "down", "clamp_velocity_mm_s": velocity, "duration_s": 20.0,
             "until": {"rule": "clamp_below", "z_mm": TARGET_MM}},
            {"name": "hold", "duration_s": 1.0}]},
        "numerics": {"nodes": 12, "save_interval_s": SAVE_S},
    }


def test_a_rule_registered_from_outside_stops_the_run_where_its_physics_says(clamp_below):
    """The clamp descends at 4 mm/s from the sheet's start, 20.4 mm above the ball's centre,
    under ``until: {rule: clamp_below, z_mm: 0}``: it passes 0 at 5.1 s, and the stage ends at
    the first save after that (the rule is read at each save), its condition met, the clamp
    within one save interval's travel below the target."""
    from dynslip.app.forming import build_core
    from dynslip.physics.driver.simulate import simulate

    sc = validate_data(_scenario(-SPEED_MM_S))
    assert isinstance(sc.physics.stages[0].until, ClampBelowSpec)
    model, protocol, kwargs = build_core(sc)
    assert type(protocol.stages[0].stop) is ClampBelow
    res = simulate(model, protocol, **kwargs)
    assert not res.failed, res.failed
    down = res.stage_end[0]
    crossing = (SHEET_START_MM - TARGET_MM) / SPEED_MM_S
    assert down["condition_met"]
    assert crossing < down["t_end"] <= crossing + SAVE_S + 1e-9
    r = sc.physics.ball_radius_mm
    z_end = float(next(f["clamp_z"] for f in res.frames if f["stage"] == 0 and
                       abs(f["time"] - down["t_end"]) < 1e-9)) * r
    assert TARGET_MM - SPEED_MM_S * SAVE_S - 1e-9 <= z_end < TARGET_MM
    assert res.stage_end[1]["name"] == "hold"


def test_a_registered_rule_checks_its_stage(clamp_below):
    """The rule's own check against its stage refuses a clamp that does not descend, as one
    line naming the stage and the rule."""
    from dynslip.errors import InputError

    with pytest.raises(InputError) as err:
        validate_data(_scenario(0.0))
    line = str(err.value)
    assert "\n" not in line and "physics.stages.0" in line and "clamp_below" in line
