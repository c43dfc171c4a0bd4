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

import abc
import dataclasses
import math
from typing import Any, ClassVar

import equinox as eqx

__all__ = [
    "Stage",
    "Protocol",
    "AbstractStop",
    "Duration",
    "ClampForceBelow",
    "ThetaMaxBelow",
    "BallSpeedAbove",
    "Rest",
    "BALL_HOLD",
    "BALL_FORCE",
    "CLAMP_POSITION",
    "CLAMP_FORCE",
    "CLAMP_BAND",
    "BallReactionBelow",
]

BALL_HOLD = 0
BALL_FORCE = 1
CLAMP_POSITION = 0
CLAMP_FORCE = 1
#: the edge held by a band on the tube's wall: carried radially with the clamp, it holds along
#: the wall while the sheet's pull there is below the band's grip and slides beyond it
#: (:attr:`dynslip.physics.sheet.SheetModel.band_grip`, :func:`dynslip.physics.field.evaluate`)
CLAMP_BAND = 2


class AbstractStop(eqx.Module):
    """When a stage ends: decided on the host from each saved frame.

    A stage runs in save segments up to ``duration`` (s, its maximum length). After every
    segment the driver calls :meth:`check` with the frame just recorded (the dict of
    :func:`dynslip.physics.driver.simulate.frame_record`, numpy values), the time and the rule's
    carried state (from :meth:`init` at the stage's start); it returns whether the stage
    ends now and the new state. Reaching ``duration`` ends the stage in any case; whether
    that meets the rule is :attr:`met_at_duration` (a duration rule: yes; a condition
    rule: no, and the run reports it rather than hide it).

    Final classes: :class:`Duration`, :class:`ClampForceBelow`, :class:`ThetaMaxBelow`,
    :class:`BallSpeedAbove`, :class:`Rest`, :class:`BallReactionBelow`; the schema's stop-rule
    specs (:data:`dynslip.schema.stages.STOP_SPECS`) build them. ``kind`` names each.
    """

    duration: eqx.AbstractVar[float]
    kind: eqx.AbstractClassVar[str]
    met_at_duration: eqx.AbstractClassVar[bool]

    def __check_init__(self):
        # equinox runs every class's __check_init__: a subclass adds its own checks
        if not self.duration > 0:
            raise ValueError(f"stop rule: duration must be > 0, got {self.duration}")

    def init(self) -> Any:
        """The carried state at the stage's start (None: a rule whose frames decide alone)."""
        return None

    @abc.abstractmethod
    def check(self, frame: dict, t: float, state: Any) -> tuple[bool, Any]:
        """(the stage ends now, the new state) from the frame saved at time ``t``."""

    @abc.abstractmethod
    def scaled(self, factor: float) -> AbstractStop:
        """The rule of the same path run ``factor`` times slower (times x factor, rates /
        factor)."""


class Duration(AbstractStop):
    """The stage lasts ``duration`` seconds."""

    duration: float
    kind: ClassVar[str] = "duration"
    met_at_duration: ClassVar[bool] = True

    def check(self, frame, t, state):
        return False, state

    def scaled(self, factor):
        return Duration(duration=self.duration * factor)


class ClampForceBelow(AbstractStop):
    """Ends when the magnitude of the clamp's axial force, net of the sheet's drag (the frame's
    ``clamp_force_static``: a clamp moving a free sheet carries its drag, which is no pull of
    the pocket), falls below ``force`` (G h0 R)."""

    duration: float

    force: float
    kind: ClassVar[str] = "clamp_force_below"
    met_at_duration: ClassVar[bool] = False

    def __check_init__(self):
        if not self.force > 0:
            raise ValueError(
                "stop rule clamp_force_below: the threshold must be > 0 (|force| < 0 never holds)"
            )

    def check(self, frame, t, state):
        return bool(abs(float(frame["clamp_force_static"])) < self.force), state

    def scaled(self, factor):
        return ClampForceBelow(force=self.force, duration=self.duration * factor)


class ThetaMaxBelow(AbstractStop):
    """Ends when the contact edge's polar angle falls below ``angle`` (rad) or contact is lost."""

    duration: float

    angle: float
    kind: ClassVar[str] = "theta_max_below"
    met_at_duration: ClassVar[bool] = False

    def __check_init__(self):
        if not 0 < self.angle < 3.14159265:
            raise ValueError(
                f"stop rule theta_max_below: the angle must be in (0, pi), got {self.angle}"
            )

    def check(self, frame, t, state):
        return bool(not float(frame["theta_max"]) >= self.angle), state  # NaN (no contact) ends it

    def scaled(self, factor):
        return ThetaMaxBelow(angle=self.angle, duration=self.duration * factor)


class BallSpeedAbove(AbstractStop):
    """Ends when the ball's speed exceeds ``rate`` (R/s): a ramped pull has torn it out."""

    duration: float

    rate: float
    kind: ClassVar[str] = "ball_speed_above"
    met_at_duration: ClassVar[bool] = False

    def __check_init__(self):
        if not self.rate > 0:
            raise ValueError("stop rule ball_speed_above: the speed threshold must be > 0")

    def check(self, frame, t, state):
        return bool(abs(float(frame["ball_velocity"])) > self.rate), state

    def scaled(self, factor):
        return BallSpeedAbove(rate=self.rate / factor, duration=self.duration * factor)


class Rest(AbstractStop):
    """Ends when the largest slip speed and the ball speed have stayed below ``rate`` (R/s)
    for ``hold`` seconds. The carried state is the time rest began (None while moving)."""

    duration: float

    rate: float
    hold: float
    kind: ClassVar[str] = "rest"
    met_at_duration: ClassVar[bool] = False

    def __check_init__(self):
        if not (self.rate > 0 and 0 < self.hold < self.duration):
            raise ValueError("stop rule rest: need rate > 0 and 0 < hold < duration")

    def check(self, frame, t, state):
        moving = max(float(frame["slip_max"]), abs(float(frame["ball_velocity"])))
        if not moving < self.rate:
            return False, None
        since = t if state is None else state
        return bool(t - since >= self.hold - 1e-9), since

    def scaled(self, factor):
        return Rest(
            rate=self.rate / factor, hold=self.hold * factor, duration=self.duration * factor
        )


class BallReactionBelow(AbstractStop):
    """Ends when the hold's force on the ball (+ up), net of drag, falls below ``force``
    (G h0 R), signed: a held ball standing in for one resting on a support ends the stage where
    the support would stop carrying it, also when a save interval steps past zero into a pull
    the support cannot give. Net of drag (the frame's ``ball_reaction_static``): the sheet's
    drag, which a slack span moving past the ball puts on the hold, is not a load a support at
    rest would carry."""

    duration: float

    force: float
    kind: ClassVar[str] = "ball_reaction_below"
    met_at_duration: ClassVar[bool] = False

    def __check_init__(self):
        if not self.force > 0:
            raise ValueError("stop rule ball_reaction_below: the threshold must be > 0")

    def check(self, frame, t, state):
        return bool(float(frame["ball_reaction_static"]) < self.force), state

    def scaled(self, factor):
        return BallReactionBelow(force=self.force, duration=self.duration * factor)


@dataclasses.dataclass(frozen=True)
class Stage:
    """One stage of a protocol (nondimensional lengths and forces, seconds).

    ``clamp_mode``: ``CLAMP_POSITION`` (the clamp moves at ``clamp_vz``, ``clamp_vrho``,
    R/s) or ``CLAMP_FORCE`` (the clamp lets go gradually: its force on the sheet,
    (rho, z) components, ramps from its value at the stage start, or
    ``clamp_force_start``, to ``clamp_force_end``; the edge then moves with drag) or
    ``CLAMP_BAND`` (the band: the clamp moves as in ``CLAMP_POSITION`` and carries the edge
    radially; along the wall the edge holds while the sheet's pull is below the band's grip
    and slides beyond it).
    ``ball_mode``: ``BALL_HOLD``
    (ball centre moves at ``ball_vz``) or ``BALL_FORCE`` (hold reaction ramps from the
    value at the stage start, or ``ball_force_start`` if given, to ``ball_force_end``
    over the stage's duration). ``support``: the ball also rests on a rigid support below it
    (the bottle neck), a unilateral contact: the support pushes the ball up where its centre
    is below ``Protocol.ball_z0`` and never pulls it down, so the pocket may lift the ball off.
    ``body_vz``: the axial velocity (R/s) over the stage of each held body of the model, in
    order (those not moved by the stages: 0); empty: none moves.
    """

    name: str
    stop: AbstractStop
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
    body_vz: tuple[float, ...] = ()

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
            out.append(
                dataclasses.replace(
                    s,
                    stop=s.stop.scaled(factor),
                    clamp_vz=s.clamp_vz / factor,
                    clamp_vrho=s.clamp_vrho / factor,
                    ball_vz=s.ball_vz / factor,
                    body_vz=tuple(v / factor for v in s.body_vz),
                )
            )
        return dataclasses.replace(self, stages=tuple(out))

    def keyframes(self) -> list[tuple[float, float, float]]:
        """(time, clamp_rho, clamp_z) at stage boundaries, assuming each stage runs its
        maximum duration (the extreme reach of condition stages)."""
        t, rho, z = 0.0, self.clamp_rho0, self.clamp_z0
        out = [(t, rho, z)]
        for s in self.stages:
            if s.clamp_mode == CLAMP_FORCE:
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


def ball_drag_coefficient(drag_time_s: float, ball_drag: float) -> float:
    """eta_b of the ball (G h0 R s / R): ``ball_drag`` times the sheet's drag over 4 pi R^2
    (the schema builds the run's loads with it; the release analysis reads the run back with it)."""
    return drag_time_s * 4 * math.pi * ball_drag
