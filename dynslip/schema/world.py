"""The world of a forming run, built once from its validated scenario (:func:`build_world`).

A :class:`World` holds every core object a run needs and every plain value that its
dataset, summary and figures read: the sheet model (mesh, material, penalty, ball and held
bodies with their laws and motion flags), the protocol, the solver's settings, the driver's
loads, the scales that convert the core's units (lengths in R, forces in G h0 R, time in s)
back to the file's, and the provenance (the resolved scenario as JSON). After it is built,
nothing downstream sees the pydantic scenario: the app runs the world, analysis and plots read
the dataset and the world.

The protocol (:func:`build_protocol`): the validated stages (:mod:`dynslip.schema.stages`,
physical units) made into the nondimensional :class:`dynslip.physics.protocols.Protocol`
(lengths by the ball radius, forces by the force scale), each stage's stop rule built by its
spec; the scenario builds it once, for its own checks (:func:`clamp_enters_ball`, the frame
count) and for the world.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import jax.numpy as jnp

from dynslip.physics.bodies import Sphere
from dynslip.physics.bodies.held import Held
from dynslip.physics.layout import traced
from dynslip.physics.protocols import (
    BALL_FORCE,
    BALL_HOLD,
    CLAMP_BAND,
    CLAMP_FORCE,
    Protocol,
    Stage,
    ball_drag_coefficient,
)
from dynslip.physics.sheet import Penalty, SheetModel, make_mesh
from dynslip.physics.solver.methods import Settings

if TYPE_CHECKING:
    from dynslip.physics.protocols import Protocol
    from dynslip.physics.sheet import SheetModel
    from dynslip.physics.solver.methods import Settings

__all__ = ["World", "Scales", "Limits", "build_world", "settings_of", "build_protocol",
           "clamp_enters_ball"]


@dataclass(frozen=True)
class Scales:
    """The units of the core: lengths in ``R_mm`` (the ball radius), forces in
    ``force_scale_N`` = G h0 R, pressures in G h0 / R, time in s."""

    R_mm: float
    G_Pa: float
    h0_m: float
    force_scale_N: float

    @property
    def attrs(self) -> dict:
        """The trajectory's ``scales`` attributes (SI: R and h0 in m, G in Pa)."""
        return {"R_m": self.R_mm * 1e-3, "G_Pa": self.G_Pa, "h0_m": self.h0_m,
                "force_scale_N": self.force_scale_N}


@dataclass(frozen=True)
class Limits:
    """What decides the run's verdict (``summary.json``): the numerics' bounds on the mesh,
    the reaction, the energy balance and a runaway, and the contact's smoothing widths."""

    max_chord_depth: float
    trap_reaction_tol: float
    energy_bound: float
    runaway_mm: float
    penalty_width: float
    contact_threshold: float
    friction_smoothing: float
    nodes: int


@dataclass(frozen=True)
class World:
    """A forming run's world in the core's units (see the module docstring).

    ``bodies``: ``(name, core body, moves_with_ball)`` of each held body in the solver's order;
    ``free``: the names of those free along the axis; ``stage_rules``: each stage's
    ``(name, stop rule)``; ``band_stages``: the indices of the stages whose band holds the
    edge; ``tube_rim_z``: the tube's rim height (R; None without a tube); ``friction``: the
    ball's law as the trajectory's and the summary's attributes state it; ``start``: the
    state and provenance of ``start_from`` once the app has resolved it (None before, or
    without one)."""

    name: str
    model: SheetModel
    protocol: Protocol
    settings: Settings
    loads: dict
    scales: Scales
    limits: Limits
    bodies: tuple
    free: tuple
    stage_rules: tuple
    band_stages: tuple
    tube_rim_z: float | None
    friction: dict
    thickness_R: float
    scenario_json: str
    start_from: str | None = None
    start: tuple | None = field(default=None, compare=False)

    @property
    def body_names(self) -> list:
        return [name for name, *_ in self.bodies]

    @property
    def stage_names(self) -> list[str]:
        return self.protocol.names

    @property
    def ball(self):
        return self.model.ball

    def until(self, stage_name: str) -> str:
        """The stop rule of the stage called ``stage_name``."""
        return next(rule for name, rule in self.stage_rules if name == stage_name)

    def simulate_kwargs(self) -> dict:
        """The keyword arguments of :func:`dynslip.physics.driver.simulate.simulate` (with the start
        state where there is one)."""
        kw = dict(self.loads, settings=self.settings)
        if self.start is not None:
            kw["start"] = self.start[0]
        return kw

    @property
    def start_info(self) -> dict | None:
        """The provenance of the start state (None without ``start_from``)."""
        return None if self.start is None else self.start[1]

    def with_start(self, start: tuple | None) -> World:
        return dataclasses.replace(self, start=start)


def settings_of(nu, ball_radius_mm: float, body_names: tuple) -> Settings:
    """The driver's :class:`~dynslip.physics.solver.methods.Settings` of the numerics spec
    ``nu``: the segment solver it builds (with the healing rate in R/s), its tolerances, the
    save interval in s and the checks on each saved frame."""
    return Settings(
        solver=nu.build_solver(heal_rate=nu.heal_rate_mm_s / ball_radius_mm),
        rtol=nu.rtol,
        atol=nu.atol,
        save_interval=nu.save_interval_s,
        contact_threshold=nu.contact_threshold,
        max_chord_depth=nu.max_chord_depth,
        body_names=body_names,
    )


def build_world(sc) -> World:
    """The :class:`World` of ``sc``, a validated
    :class:`~dynslip.schema.forming.FormingScenario` (its protocol built once, by the
    scenario's validation)."""

    p, nu = sc.physics, sc.numerics
    r = p.ball_radius_mm
    fs = p.force_scale_N
    mesh = make_mesh(nu.nodes, p.rim_radius_mm / r / p.pre_stretch, nu.mesh_grading,
                     nu.edge_grading)
    # pressures in kPa per unit of G h0 / R (a pressure-dependent law's scale)
    kpa = 1e3 * fs / r**2
    moved = set(p.moved_names())
    # a free body: its applied force in G h0 R, its drag as the ball's (eta_b of its multiple)
    free: dict[str, dict[str, Any]] = {
        b.name: dict(free=True, force=jnp.asarray((b.force_N or 0.0) / fs),
                     drag=jnp.asarray(ball_drag_coefficient(nu.drag_time_s,
                                                            1.0 if b.drag is None else b.drag)))
        for b in p.bodies if b.motion == "free"
    }
    specs = p.held_specs()
    held = tuple(
        Held(body, law.build(r, nu.friction_smoothing, kpa),
             moves_with_ball=with_ball, stage=name in moved, **free.get(name, {}))
        for name, body, with_ball, law in specs
    )
    g_h0 = fs / r  # N/mm
    # the physical parameters of the material, the penalty and the ball's friction law as
    # arrays (traced): leaves of the model's pytree, inputs of the compiled step rather than
    # constants compiled into it, so that a sweep over any of them compiles once and jax.jvp
    # reaches them (the held bodies' geometry stays static)
    model = SheetModel(
        mesh,
        traced(p.material.core()),
        traced(Penalty(float(nu.penalty_stiffness), float(nu.penalty_width))),
        ball=p.ball_body(),
        bodies=held,
        band_grip=jnp.asarray(p.band_grip_N_per_mm / g_h0),
    )
    names = tuple(name for name, *_ in specs)
    loads = dict(
        friction=traced(p.friction.build(r, nu.friction_smoothing, kpa)),
        eps=nu.friction_smoothing,
        drag=nu.drag_time_s,
        ball_drag=ball_drag_coefficient(nu.drag_time_s, nu.ball_drag),
        pre_stretch=p.pre_stretch,
        z_sheet=p.sheet_start_mm / r,
        weight=-(p.ball_mass_g * 1e-3 * 9.81) / fs if p.gravity else 0.0,
        support_stiffness=nu.support_stiffness,
    )
    f = p.friction
    mu_s, mu_k, d_c_mm = f.static_kinetic()
    friction = {"friction_law": f.law, "mu": f.nominal_mu, "mu_s": mu_s, "mu_k": mu_k,
                "d_c_mm": d_c_mm}
    return World(
        name=sc.name,
        model=model,
        protocol=sc.protocol(),
        settings=settings_of(nu, r, names),
        loads=loads,
        scales=Scales(R_mm=r, G_Pa=p.youngs_modulus_MPa * 1e6 / 3.0, h0_m=p.thickness_um * 1e-6,
                      force_scale_N=fs),
        limits=Limits(max_chord_depth=nu.max_chord_depth,
                      trap_reaction_tol=nu.trap_reaction_tol, energy_bound=nu.energy_bound,
                      runaway_mm=nu.runaway_mm, penalty_width=nu.penalty_width,
                      contact_threshold=nu.contact_threshold,
                      friction_smoothing=nu.friction_smoothing, nodes=nu.nodes),
        bodies=tuple((name, body, with_ball) for name, body, with_ball, _ in specs),
        free=tuple(p.free_names()),
        stage_rules=tuple((s.name, s.until.rule) for s in p.stages),
        band_stages=tuple(k for k, s in enumerate(p.stages) if s.clamp == "band"),
        tube_rim_z=p.tube_rim_z if p.tube is not None else None,
        friction=friction,
        thickness_R=p.thickness_um * 1e-3 / r,
        scenario_json=sc.to_json(),
        start_from=sc.start_from,
    )


def clamp_enters_ball(prot, ball) -> bool:
    """Whether the keyframed clamp path comes into the ball: within the unit distance of the
    centre for the unit ball (closed form), else at a distance at most 0 from the ball's body
    along the straight segments between keyframes (sampled every 1e-3 of a segment)."""

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
