r"""Loading protocols: sequences of keyframed stages with stop rules (pure core objects).

Nondimensional core: lengths in units of the ball radius $R$, forces in units of
$G h_0 R$; time stays in seconds. The schema (:mod:`dynslip.schema.forming`)
converts the file's mm, mm/s, s and N into these.

Within a stage every prescribed quantity is *linear in time*, so the vector field is
smooth inside a stage and the protocol's kinks are exactly the stage boundaries, where
the driver restarts the solver (a restart is the strongest form of passing a jump to
the step-size controller). A stage prescribes

- the clamp (rim or hands): height $z_c$ and radius $\rho_c$ moving at constant
  velocities (a radial stretch $\lambda$ of the held edge is $\rho_c = \lambda\bar r_{edge}$);
- the ball: either *held* (its centre height moves at a prescribed velocity and the
  hold supplies whatever force that needs) or *force-controlled* (the hold's reaction
  ramps linearly from its value at the stage's start, or a stated value, to a stated
  end value over the stage; the ball then moves with drag);
- a stop rule: a duration, the clamp's axial force falling below a threshold (checked
  between save segments, with a maximum duration), or rest (slip and ball speeds
  below a rate for a stated hold, with a maximum duration).
"""

from __future__ import annotations

import dataclasses
from typing import Literal

__all__ = ["Stage", "Protocol", "StopRule", "BALL_HOLD", "BALL_FORCE", "CLAMP_POSITION", "CLAMP_FORCE"]

BALL_HOLD = 0
BALL_FORCE = 1
CLAMP_POSITION = 0
CLAMP_FORCE = 1


@dataclasses.dataclass(frozen=True)
class StopRule:
    """When a stage ends.

    ``kind``: ``"duration"`` (after ``duration``), ``"clamp_force_below"`` (when the
    magnitude of the clamp's axial force falls below ``force``, units of $G h_0 R$),
    or ``"rest"`` (when the largest slip speed and the ball speed stay below ``rate``
    (R/s) for ``hold`` seconds), or ``"theta_max_below"`` (when the contact edge's polar
    angle falls below ``angle``, radians, or contact is lost), or ``"ball_speed_above"`` (when the
    ball's speed exceeds ``rate``, R/s: a ramped pull has torn it out). Condition rules end at
    ``duration`` at the latest:
    reaching it without the condition holding is reported, not hidden.
    """

    kind: Literal["duration", "clamp_force_below", "rest", "theta_max_below", "ball_speed_above"] = "duration"
    duration: float = 1.0
    force: float = 0.0
    rate: float = 0.0
    hold: float = 0.0
    angle: float = 0.0

    def __post_init__(self):
        if not self.duration > 0:
            raise ValueError(f"stop rule: duration must be > 0, got {self.duration}")
        if self.kind == "clamp_force_below" and not self.force > 0:
            raise ValueError("stop rule clamp_force_below: the threshold must be > 0 (|force| < 0 never holds)")
        if self.kind == "theta_max_below" and not 0 < self.angle < 3.14159265:
            raise ValueError(f"stop rule theta_max_below: the angle must be in (0, pi), got {self.angle}")
        if self.kind == "ball_speed_above" and not self.rate > 0:
            raise ValueError("stop rule ball_speed_above: the speed threshold must be > 0")
        if self.kind == "rest" and not (self.rate > 0 and 0 < self.hold < self.duration):
            raise ValueError("stop rule rest: need rate > 0 and 0 < hold < duration")


@dataclasses.dataclass(frozen=True)
class Stage:
    """One stage of a protocol (nondimensional lengths and forces, seconds).

    ``clamp_mode``: ``CLAMP_POSITION`` (the clamp moves at ``clamp_vz``, ``clamp_vrho``,
    R/s) or ``CLAMP_FORCE`` (the clamp lets go gradually: its force on the sheet,
    (rho, z) components, ramps from its value at the stage start, or
    ``clamp_force_start``, to ``clamp_force_end``; the edge then moves with drag). ``ball_mode``: ``BALL_HOLD``
    (ball centre moves at ``ball_vz``) or ``BALL_FORCE`` (hold reaction ramps from the
    value at the stage start, or ``ball_force_start`` if given, to ``ball_force_end``
    over the stage's duration). ``support``: the ball also rests on a rigid support below it
    (the bottle neck), a unilateral contact: the support pushes the ball up where its centre
    is below ``Protocol.ball_z0`` and never pulls it down, so the pocket may lift the ball off.
    """

    name: str
    stop: StopRule
    clamp_vz: float = 0.0
    clamp_vrho: float = 0.0
    ball_mode: int = BALL_HOLD
    ball_vz: float = 0.0
    ball_force_start: float | None = None
    ball_force_end: float = 0.0
    clamp_mode: int = CLAMP_POSITION
    clamp_force_start: tuple[float, float] | None = None
    clamp_force_end: tuple[float, float] = (0.0, 0.0)
    support: bool = False

    @property
    def max_duration(self) -> float:
        return self.stop.duration


@dataclasses.dataclass(frozen=True)
class Protocol:
    """Stages run in order from the initial clamp position ``(clamp_rho0, clamp_z0)``."""

    stages: tuple[Stage, ...]
    clamp_rho0: float
    clamp_z0: float
    ball_z0: float = 0.0

    def __post_init__(self):
        if not self.stages:
            raise ValueError("a protocol needs at least one stage")
        names = [s.name for s in self.stages]
        if len(set(names)) != len(names):
            raise ValueError(f"stage names must be unique: {names}")

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.stages]

    def scaled(self, factor: float) -> Protocol:
        """The same path run ``factor`` times slower (velocities / factor, times x factor)."""
        out = []
        for s in self.stages:
            stop = dataclasses.replace(s.stop, duration=s.stop.duration * factor, hold=s.stop.hold * factor,
                                       rate=s.stop.rate / factor)
            out.append(dataclasses.replace(s, stop=stop, clamp_vz=s.clamp_vz / factor,
                                           clamp_vrho=s.clamp_vrho / factor, ball_vz=s.ball_vz / factor))
        return dataclasses.replace(self, stages=tuple(out))

    def keyframes(self) -> list[tuple[float, float, float]]:
        """(time, clamp_rho, clamp_z) at stage boundaries, assuming each stage runs its
        maximum duration (the extreme reach of condition stages)."""
        t, rho, z = 0.0, self.clamp_rho0, self.clamp_z0
        out = [(t, rho, z)]
        for s in self.stages:
            if s.clamp_mode != CLAMP_POSITION:
                break  # a clamp under force control goes where the sheet takes it
            t += s.max_duration
            rho += s.clamp_vrho * s.max_duration
            z += s.clamp_vz * s.max_duration
            out.append((t, rho, z))
        return out

    def clamp_min_distance_to_ball(self) -> float:
        """Smallest distance from the ball centre (held at ``ball_z0``) to the clamp path,
        over the keyframed straight segments (units of R)."""
        import numpy as np

        kf = self.keyframes()
        best = float("inf")
        for (_, r0, z0), (_, r1, z1) in zip(kf[:-1], kf[1:], strict=True):
            a = np.array([r0, z0 - self.ball_z0])
            d = np.array([r1 - r0, z1 - z0])
            dd = float(d @ d)
            s = 0.0 if dd == 0 else float(np.clip(-(a @ d) / dd, 0.0, 1.0))
            best = min(best, float(np.linalg.norm(a + s * d)))
        return best
