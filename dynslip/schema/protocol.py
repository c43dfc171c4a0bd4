"""The core protocol of a forming scenario (:func:`build_protocol`): the validated stages
(:mod:`dynslip.schema.stages`, physical units) made into the nondimensional
:class:`dynslip.physics.protocols.Protocol` (lengths by the ball radius, forces by the force
scale), each stage's stop rule built by its spec, and the check that the keyframed clamp path
stays outside the ball (:func:`clamp_enters_ball`).
"""

from __future__ import annotations

import math

__all__ = ["build_protocol", "clamp_enters_ball"]


def clamp_enters_ball(prot, ball) -> bool:
    """Whether the keyframed clamp path comes into the ball: within the unit distance of the
    centre for the unit ball (closed form), else at a distance at most 0 from the ball's body
    along the straight segments between keyframes (sampled every 1e-3 of a segment)."""
    from dynslip.physics.bodies import Sphere

    if isinstance(ball, Sphere) and ball.radius == 1.0:
        return prot.clamp_min_distance_to_ball() <= 1.0
    import numpy as np

    kf = prot.keyframes()
    u = np.linspace(0.0, 1.0, 1001)[:, None]
    for (_, r0, z0), (_, r1, z1) in zip(kf[:-1], kf[1:], strict=True):
        x = np.array([r0, z0 - prot.ball_z0]) + u * np.array([r1 - r0, z1 - z0])
        if float(np.min(np.asarray(ball.distance(x)))) <= 0.0:
            return True
    return False


def build_protocol(sc):
    """The core :class:`dynslip.physics.protocols.Protocol` (nondimensional) of ``sc``, a
    :class:`dynslip.schema.forming.FormingScenario` (typed in words: that module imports this
    one)."""
    from dynslip.physics.protocols import (
        BALL_FORCE,
        BALL_HOLD,
        CLAMP_BAND,
        CLAMP_FORCE,
        Protocol,
        Stage,
    )

    p = sc.physics
    r = p.ball_radius_mm
    fs = p.force_scale_N
    z = p.sheet_start_mm / r
    stages = []
    prev_ball = None
    for s in p.stages:
        if s.clamp_to_z_mm is not None:
            dz = s.clamp_to_z_mm / r - z
            dur = abs(dz) * r / s.clamp_speed_mm_s
            vz = math.copysign(s.clamp_speed_mm_s / r, dz)
        else:
            dur = s.duration_s
            # the band and a moving clamp are on the tube: in the lab they move with it
            lab = p.frame == "lab" and s.clamp in ("move", "band")
            vz = (s.clamp_velocity_mm_s + (s.tube_velocity_mm_s if lab else 0.0)) / r
        z += vz * dur
        stop = s.until.build(dur, r, fs)
        ckw = {"clamp_vz": vz}
        moved = p.body_velocities(s)
        if s.clamp == "let_go":
            ckw = {"clamp_mode": CLAMP_FORCE}
        elif s.clamp == "free":
            ckw = {"clamp_mode": CLAMP_FORCE, "clamp_force_start": (0.0, 0.0)}
        elif s.clamp == "band":
            ckw = {"clamp_vz": vz, "clamp_mode": CLAMP_BAND}
        if moved:
            ckw["body_vz"] = moved
        if s.ball == "hold":
            stages.append(Stage(s.name, stop, ball_mode=BALL_HOLD,
                                ball_vz=(s.ball_velocity_mm_s + p.tube_shift_mm_s(s)) / r,
                                **ckw))
        elif s.ball == "release":
            stages.append(Stage(s.name, stop, ball_mode=BALL_FORCE, ball_force_end=0.0, **ckw))
        elif s.ball == "support":
            stages.append(
                Stage(
                    s.name,
                    stop,
                    ball_mode=BALL_FORCE,
                    ball_force_start=0.0,
                    ball_force_end=0.0,
                    support=True,
                    **ckw,
                )
            )
        elif s.ball == "pull":
            # after a pull the ramp continues from that stage's final force (a preload, then a ramp)
            start = None if prev_ball == "pull" else 0.0
            stages.append(Stage(s.name, stop, ball_mode=BALL_FORCE, ball_force_start=start,
                                ball_force_end=s.ball_force_N / fs, **ckw))
        else:
            stages.append(Stage(s.name, stop, ball_mode=BALL_FORCE, ball_force_start=0.0,
                                ball_force_end=0.0, **ckw))
        prev_ball = s.ball
    return Protocol(tuple(stages), clamp_rho0=p.rim_radius_mm / r,
                    clamp_z0=p.sheet_start_mm / r, ball_z0=0.0)
