"""Schema of ``kind: forming`` scenarios: the whole sheet loaded along a keyframed path.

Physical units in the file (mm, mm/s, s, N, MPa, um, g); the runner converts them to the
nondimensional core (lengths by the ball radius R, forces by G h0 R, time in s).
Heights are measured from the ball centre, upward. See docs/forming.md.

One validated model per section of the forming scenario (physics, numerics, the scenario), each
field with its bounds, unit and description, and the protocol the validated stages build. The
stages are in :mod:`dynslip.schema.stages`, the tube and the bottle in
:mod:`dynslip.schema.apparatus` (both re-exported here), the core protocol the stages build and
the run's world in :mod:`dynslip.schema.world` (:func:`build_protocol`, re-exported here).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, cast

from pydantic import PrivateAttr, model_validator

from dynslip.physics.bodies import BodyGeometryError
from dynslip.physics.bodies.apparatus import bottle, tube_wall
from dynslip.physics.solver.loadstep import FullStateLoadStep
from dynslip.physics.solver.methods import TimeStepping
from dynslip.physics.solver.newton import AbstractSegmentSolver, MotionNewton
from dynslip.schema.apparatus import BottleSpec, TubeSpec
from dynslip.schema.base import F, ScenarioBase, Strict
from dynslip.schema.bodies import BallSpec, BodySpec, ShapeSpec, ball_core, body_core, check_bodies
from dynslip.schema.friction import FRICTION_SPECS, CoulombSpec, FrictionLaw, FrictionSpec
from dynslip.schema.materials import MaterialSpec
from dynslip.schema.stages import MAX_STAGES, MAX_TIME_S, StageSpec
from dynslip.schema.stages import default_stages as _default_stages
from dynslip.schema.world import build_protocol, build_world, clamp_enters_ball

__all__ = ["FormingScenario", "FormingPhysics", "FormingNumerics", "StageSpec", "MaterialSpec",
           "FrictionSpec", "TubeSpec", "BottleSpec", "build_protocol"]

#: the most saved frames of a run (every saved frame is held in memory)
MAX_FRAMES = 1_000_000


class FormingPhysics(Strict):
    """Geometry, material, friction and the loading path (physical units)."""

    ball_radius_mm: float = F(20.0, unit="mm", gt=0, le=1e4,
                              description="ball radius R, in (0, 1e4] mm")
    ball_mass_g: float = F(2.7, unit="g", ge=0, le=1e6,
                           description="ball mass (only with gravity on), in [0, 1e6] g")
    thickness_um: float = F(150.0, unit="um", gt=0, le=1e6,
                            description="sheet thickness h0, in (0, 1e6] um")
    youngs_modulus_MPa: float = F(2.0, unit="MPa", gt=0, le=1e6, description="Young's modulus E "
                                                                             "(G = E/3), in (0, "
                                                                             "1e6] MPa")
    material: MaterialSpec = MaterialSpec()
    friction: FrictionLaw = F(CoulombSpec(),
                              description="the sheet's friction on the ball: law coulomb (the "
                                          "default; mu), slip_weakening (mu_s, mu_k, d_c_mm) or "
                                          "pressure (mu_ref, p_ref_kPa, exponent, mu_max); not "
                                          "none")
    rim_radius_mm: float = F(50.8, unit="mm", gt=0, le=1e4,
                             description="radius of the held edge (tube rim, or hands), in (0, "
                                         "1e4] mm")
    pre_stretch: float = F(1.05, ge=0.5, le=3.0,
                           description="radial stretch of the held sheet, in [0.5, 3]: method 2, "
                                       "the small stretch of the disc clamped on the rim; method "
                                       "1, the hand pre-stretch (the held disc has material "
                                       "radius rim_radius / pre_stretch). Below 1 the held disc "
                                       "is slack: more material than the rim's radius, the bound "
                                       "on what a sheet sliding over the rim could feed in "
                                       "(docs/forming.md, 'Material fed over the rim')")
    sheet_gap_mm: float = F(0.4, unit="mm", gt=0, le=1e4,
                            description="initial height of the flat sheet above the ball top, in "
                                        "(0, 1e4] mm")
    gravity: bool = F(False, description="ball weight on (off by default: a downward-opening "
                                         "membrane pocket cannot carry it; physics.md Section 4)")
    tube: TubeSpec | None = F(None, description="the tube's wall as a held body, moved with the "
                                                "band by the stages' tube_velocity_mm_s; none by "
                                                "default")
    bottle: BottleSpec | None = F(None, description="the bottle under the ball, one solid at rest "
                                                    "in the lab; none by default")
    frame: Literal["lab", "tube"] = F(
        "lab", description="the frame the run is computed and saved in: lab (the ball on its "
                           "support and the bottle at rest, the tube and its band moved by "
                           "tube_velocity_mm_s) or tube (the tube at rest, the held ball and the "
                           "bottle moved at minus it: the same path while the ball is held, "
                           "shifted; docs/experiment.md)")
    ball: BallSpec = F(BallSpec(), description="the ball's kind: a sphere of ball_radius_mm (the "
                                               "default) or a disc (a coin; R = ball_radius_mm is "
                                               "then only the length unit); schema/bodies.py")
    bodies: list[BodySpec] = F(default_factory=list, max_length=50,
                               description="held bodies (obstacles) by kind and size in mm, "
                                           "divided by ball_radius_mm (R) in the core; at most "
                                           "50; schema/bodies.py")
    band_grip_N_per_mm: float = F(0.0, unit="N/mm", ge=0, le=1e3,
                                  description="clamp: band: the band's grip, the largest pull "
                                              "along the wall per length of its circumference "
                                              "before the sheet slides under it, in [0, 1e3] N/mm")
    stages: list[StageSpec] = F(default_factory=_default_stages, max_length=MAX_STAGES,
                                description="the loading path, in order (at most 100 stages)")

    @model_validator(mode="after")
    def _geometry(self):
        if self.friction.law == "none":

            laws = ", ".join(law for law in FRICTION_SPECS.specs if law != "none")
            raise ValueError(f"friction.law = none: the ball's friction needs a law; allowed: "
                             f"{laws} (coulomb with mu: 0 for a frictionless ball)")
        if not self.stages:
            raise ValueError("stages: empty protocol (need at least one stage)")
        names = [s.name for s in self.stages]
        if len(set(names)) != len(names):
            raise ValueError(f"stages: duplicate stage names "
                             f"{sorted({n for n in names if names.count(n) > 1})}")
        if self.rim_radius_mm <= self.ball.widest_mm(self.ball_radius_mm):
            raise ValueError(f"rim_radius_mm = {self.rim_radius_mm} puts the clamp inside the "
                             f"ball (radius {self.ball.widest_mm(self.ball_radius_mm)} mm)")
        moved = self.stage_moved_names()
        allowed = ", ".join(repr(n) for n in moved) or "none: no body has motion: stage"
        for i, s in enumerate(self.stages):
            for name in s.body_velocity_mm_s:
                if name not in moved:
                    raise ValueError(
                        f"'physics.stages.{i}.body_velocity_mm_s.{name}' (stage {s.name!r}) names "
                        f"{name!r}, which is not a body with motion: stage (allowed: {allowed})")
        if self.tube is not None and not self.tube.wall_mm < self.rim_radius_mm:
            raise ValueError(f"tube.wall_mm = {self.tube.wall_mm}: the rim is thicker than the "
                             f"tube (allowed: below rim_radius_mm = {self.rim_radius_mm})")
        self._bottle_fits()
        self._bodies_fit()
        self._tube_path()
        if any(s.clamp == "band" for s in self.stages) and self.tube is None:
            raise ValueError("stages: clamp: band holds the edge on the tube's wall: it needs "
                             "physics.tube")
        z = self.sheet_start_mm
        known = True
        let_go = False
        for s in self.stages:
            if let_go and s.clamp == "move":
                raise ValueError(f"stages.{s.name}: the clamp cannot hold the edge again once it "
                                 f"has let go")
            if let_go and s.clamp == "band":
                raise ValueError(f"stages.{s.name}: the band cannot hold the edge again once the "
                                 f"clamp has let go")
            let_go = let_go or s.clamp not in ("move", "band")
            if s.clamp_to_z_mm is not None:
                if not known:
                    raise ValueError(f"stages.{s.name}: clamp_to_z_mm after a condition stage "
                                     f"(start height unknown): use clamp_velocity_mm_s with "
                                     f"duration_s")
                if abs(s.clamp_to_z_mm - z) < 1e-9:
                    raise ValueError(f"stages.{s.name}: empty stage (clamp already at {z} mm)")
                if abs(s.clamp_to_z_mm - z) / s.clamp_speed_mm_s > MAX_TIME_S:
                    raise ValueError(f"stages.{s.name}: the clamp_to_z_mm move lasts "
                                     f"{abs(s.clamp_to_z_mm - z) / s.clamp_speed_mm_s:.3g} s "
                                     f"(|dz| / clamp_speed_mm_s); allowed: at most 1e6 s")
                z = s.clamp_to_z_mm
            else:
                z += s.clamp_velocity_mm_s * s.duration_s
                if s.until.rule != "duration":
                    known = False
        return self

    @property
    def sheet_start_mm(self) -> float:
        """The flat sheet's initial height (mm, from the ball's centre): sheet_gap_mm above the
        ball's top."""
        # a validated ball is an instance of its kind's ShapeSpec (BallSpec only dispatches)
        return cast(ShapeSpec, self.ball).top_mm(self.ball_radius_mm) + self.sheet_gap_mm

    def ball_body(self):
        """The core ball body (units of R; :func:`dynslip.schema.bodies.ball_core`)."""

        return ball_core(self.ball, self.ball_radius_mm)

    def _bodies_fit(self):

        r = self.ball_radius_mm
        try:
            ball = self.ball_body()
        except BodyGeometryError as err:
            raise ValueError(f"ball (kind {self.ball.kind}): {err}") from None
        if not self.bodies:
            return

        others = []
        if self.tube is not None:

            others.append(("tube", tube_wall(r, od_mm=2 * self.rim_radius_mm,
                                             wall_mm=self.tube.wall_mm,
                                             height_mm=self.tube.height_mm,
                                             rim_z=self.tube_rim_z)))
        if self.bottle is not None:
            others += [("bottle", part) for part in self.bottle_parts()]
        check_bodies(self.bodies, ball, others, r, self.sheet_start_mm / r, self.rim_radius_mm / r)

    @property
    def tube_rim_z(self) -> float:
        """The tube's rim height (units of R): rim_gap_mm above the flat sheet's start."""
        assert self.tube is not None  # asked only of a scenario with a tube
        return (self.sheet_start_mm + self.tube.rim_gap_mm) / self.ball_radius_mm

    def tube_body(self):
        """The tube's wall as a core body (units of R;
        :func:`~dynslip.physics.bodies.apparatus.tube_wall`), hanging from its rim."""

        t = self.tube
        return tube_wall(self.ball_radius_mm, od_mm=2 * self.rim_radius_mm, wall_mm=t.wall_mm,
                         height_mm=t.height_mm, rim_z=self.tube_rim_z)

    def held_specs(self) -> list:
        """Every held body of the world, ``(name, core body, moves_with_ball, friction spec)``
        (:mod:`dynslip.schema.friction`; the tube's and the bottle's ``mu`` as Coulomb's): the
        tube's wall, the bottle's parts and each of ``physics.bodies``, in the order the solver
        holds them (:func:`~dynslip.schema.world.build_world` makes each a ``Held`` entry)."""

        t, b = self.tube, self.bottle
        out: list[tuple[str, Any, bool, FrictionSpec]] = \
            [("tube wall", self.tube_body(), False, CoulombSpec(mu=t.mu))] if t is not None else []
        if b is not None:
            parts = self.bottle_parts()
            names = ["bottle"] if len(parts) == 1 else [f"bottle {k}" for k in range(len(parts))]
            out += [(n, part, False, CoulombSpec(mu=b.mu))
                    for n, part in zip(names, parts, strict=True)]
        out += [(s.name, body_core(s, self.ball_radius_mm), s.motion == "with_ball", s.friction)
                for s in self.bodies]
        return out

    def free_names(self) -> list:
        """The names of ``physics.bodies`` free along the axis (motion: free)."""
        return [b.name for b in self.bodies if b.motion == "free"]

    def stage_moved_names(self) -> list:
        """The names of ``physics.bodies`` moved by the stages (motion: stage)."""
        return [b.name for b in self.bodies if b.motion == "stage"]

    def tube_moves(self) -> bool:
        """Whether a stage moves the tube (tube_velocity_mm_s)."""
        return any(s.tube_velocity_mm_s != 0.0 for s in self.stages)

    def apparatus_moved_names(self) -> list:
        """The apparatus's bodies the stages move: the tube's wall in the lab frame, the bottle
        in the tube's frame (where the tube moves)."""
        if not self.tube_moves():
            return []
        if self.frame == "lab":
            return ["tube wall"]
        return [name for name, *_ in self.held_specs() if name.startswith("bottle")]

    def moved_names(self) -> list:
        """Every held body moved by the stages: the apparatus's and ``physics.bodies``'."""
        return self.apparatus_moved_names() + self.stage_moved_names()

    def tube_shift_mm_s(self, stage) -> float:
        """What the frame adds to the ball's and every lab-fixed body's velocity over ``stage``
        (mm/s): 0 in the lab frame, minus the tube's velocity in the tube's."""
        return -stage.tube_velocity_mm_s if self.frame == "tube" else 0.0

    def body_velocities(self, stage) -> tuple:
        """The axial velocity (R/s) over ``stage`` of each held body, in :meth:`held_specs`
        order (0 for those not moved by the stages); empty when no body is."""
        if not self.moved_names():
            return ()
        r = self.ball_radius_mm
        apparatus = set(self.apparatus_moved_names())
        tube = stage.tube_velocity_mm_s if self.frame == "lab" else self.tube_shift_mm_s(stage)
        return tuple((tube if name in apparatus else stage.body_velocity_mm_s.get(name, 0.0)) / r
                     for name, *_ in self.held_specs())

    def _tube_path(self):
        """The tube's path: moved only where there is a tube, its rim above the table (the
        bottle's base) at each stage's end (at its longest for a condition stage), the band on
        the tube's outer wall, and the tube's frame only without ``physics.bodies``."""
        if not self.tube_moves():
            return
        i = next(i for i, s in enumerate(self.stages) if s.tube_velocity_mm_s != 0.0)
        if self.tube is None:
            raise ValueError(f"physics.stages.{i}.tube_velocity_mm_s = "
                             f"{self.stages[i].tube_velocity_mm_s}: moves the tube; allowed only "
                             f"with physics.tube")
        if self.frame == "tube" and any(s.ball == "support" for s in self.stages):
            raise ValueError("physics.frame = tube: a stage rests the ball on its support, which "
                             "is the lab's (the bottle's lip) and moves in the tube's frame; "
                             "allowed: frame: lab, or ball: hold where the tube moves and no "
                             "support stage")
        if self.frame == "tube" and self.bodies:
            raise ValueError(f"physics.frame = tube: the tube's frame moves the lab's bodies with "
                             f"the ball; allowed only without physics.bodies ({len(self.bodies)} "
                             f"given): use frame: lab")
        r = self.ball_radius_mm
        rim0 = self.tube_rim_z * r
        table = self.table_z_mm()
        shift, band = 0.0, self.sheet_start_mm
        for i, s in enumerate(self.stages):
            dur = s.duration_s
            if s.clamp_to_z_mm is not None:
                band = s.clamp_to_z_mm
            elif dur is not None:
                shift += s.tube_velocity_mm_s * dur
                band += s.clamp_velocity_mm_s * dur
            if table is not None and rim0 + shift <= table:
                raise ValueError(
                    f"physics.stages.{i}.tube_velocity_mm_s = {s.tube_velocity_mm_s} (stage "
                    f"{s.name!r}): the tube's rim would reach {rim0 + shift:.4g} mm, below the "
                    f"table (the bottle's base at {table:.4g} mm); allowed: a push that keeps the "
                    f"rim above {table:.4g} mm")
            top = rim0 + self.tube.height_mm
            if s.clamp == "band" and not rim0 <= band <= top:
                raise ValueError(
                    f"physics.stages.{i} (stage {s.name!r}): the band at {band:.4g} mm on the "
                    f"tube, past its end; allowed: on the outer wall, from the rim ({rim0:.4g} "
                    f"mm) to the top ({top:.4g} mm)")

    def table_z_mm(self) -> float | None:
        """The table's height (mm from the resting ball's centre, the lab frame): the bottle's
        base (None without a bottle)."""
        if self.bottle is None:
            return None
        import numpy as np

        z = min(float(np.min(np.asarray(part.outline())[:, 1])) for part in self.bottle_parts())
        return z * self.ball_radius_mm

    def named_bodies(self) -> list:
        """:meth:`held_specs` without the friction: ``(name, core body, moves_with_ball)``."""
        return [spec[:3] for spec in self.held_specs()]

    def bottle_parts(self) -> tuple:
        """The bottle's core bodies, one smooth solid (units of R;
        :func:`~dynslip.physics.bodies.apparatus.bottle`)."""

        b = self.bottle
        assert b is not None  # asked only of a scenario with a bottle
        return bottle(self.ball_radius_mm, b.neck_od_mm, b.neck_wall_mm, b.neck_length_mm,
                      b.shoulder_height_mm, b.body_od_mm, b.body_height_mm, b.neck_fillet_mm,
                      b.shoulder_fillet_mm, b.base_fillet_mm)

    def _bottle_fits(self):
        b = self.bottle
        if b is None:
            return
        r = self.ball_radius_mm
        if self.ball.kind != "sphere" or self.ball.radius(r) != r:
            raise ValueError(f"bottle: its neck's lip is placed under a sphere of radius "
                             f"ball_radius_mm; allowed with ball.kind = sphere of that radius "
                             f"(the ball is kind {self.ball.kind})")
        if not b.neck_od_mm / 2 < self.ball_radius_mm:
            raise ValueError(f"bottle.neck_od_mm = {b.neck_od_mm}: the bottle overlaps the ball "
                             f"(the ball sits on the neck; allowed: below the ball's diameter "
                             f"{2 * self.ball_radius_mm})")
        if not b.neck_wall_mm < b.neck_od_mm / 2:
            raise ValueError(f"bottle.neck_wall_mm = {b.neck_wall_mm}: allowed below the neck's "
                             f"radius {b.neck_od_mm / 2}")
        if not b.body_od_mm > b.neck_od_mm:
            raise ValueError(f"bottle.body_od_mm = {b.body_od_mm}: allowed above the neck's "
                             f"diameter {b.neck_od_mm}")
        if self.tube is not None and not b.body_od_mm / 2 < self.rim_radius_mm - self.tube.wall_mm:
            raise ValueError(f"bottle.body_od_mm = {b.body_od_mm}: wider than the tube's inside "
                             f"(allowed: below {2 * (self.rim_radius_mm - self.tube.wall_mm)})")

    @property
    def force_scale_N(self) -> float:
        g = self.youngs_modulus_MPa * 1e6 / 3.0
        return g * self.thickness_um * 1e-6 * self.ball_radius_mm * 1e-3


class FormingNumerics(Strict):
    """Mesh, drag, solver and regularisations (nondimensional unless a unit is given)."""

    nodes: int = F(50, ge=6, le=4000, description="nodes from the pole to the clamp, 6..4000")
    mesh_grading: float = F(1.0, ge=1.0, le=4.0,
                            description="node material radii rbar_i = rbar_edge (i/(N-1))^g: 1 is "
                                        "uniform, g > 1 grades the mesh toward the pole (where "
                                        "the push-down stretches the cap most), in [1, 4]")
    edge_grading: float = F(1.0, ge=1.0, le=4.0,
                            description="grades the mesh toward the held edge, in [1, 4]: node "
                                        "material radii rbar_i = rbar_edge v_i^g with v_i = 1 - "
                                        "(1 - i/(N-1))^e (e this, g mesh_grading; 1 is uniform): "
                                        "where the sheet wraps a tube's rim near its edge")
    drag_time_s: float = F(0.1, unit="s", gt=0, le=MAX_TIME_S,
                           description="drag time tau = eta R^2/(G h0) of the overdamped sheet; "
                                       "loading is slow when a stage lasts >> tau "
                                       "(docs/forming.md)")
    ball_drag: float = F(1.0, gt=0, le=1e6, description="ball drag as a multiple of the sheet "
                                                        "drag over the ball's area 4 pi R^2, in "
                                                        "(0, 1e6]")
    solver: Literal["load_step", "load_step_full", "kvaerno5", "kvaerno4", "kvaerno3",
                    "implicit_euler"] = F(
        "load_step", description="load_step (default): quasi-static implicit Euler load "
                                 "increments controlled by Newton's iteration count (first order "
                                 "in time: for slow paths; rtol, atol are Newton's tolerances); "
                                 "load_step_full: the same increments by Newton on the whole "
                                 "state (the reference load_step is checked against; slower, no "
                                 "free body); kvaerno5: the adaptive 5th-order reference "
                                 "(docs/speed.md says when each is right)")
    max_increment: float = F(20.0, gt=0, le=1e4,
                             description="load_step and load_step_full: largest increment in drag "
                                         "times, driven stages, in (0, 1e4] (the drag eta A / dt "
                                         "keeps Newton's matrix regular on slack sheet)")
    max_increment_free: float = F(5.0, gt=0, le=1e4,
                                  description="load_step and load_step_full: largest increment in "
                                              "drag times where the ball or the clamp moves "
                                              "under a force (let-go, release, rest), in (0, "
                                              "1e4]")
    newton_max_iter: int = F(20, ge=2, le=100,
                             description="load_step and load_step_full: Newton iterations before "
                                         "an increment is cut, 2..100")
    newton_backtrack: int = F(4, ge=0, le=20,
                              description="load_step and load_step_full: at most this many "
                                          "halvings of a Newton correction that would raise the "
                                          "residual's max norm (a backtracking safeguard that "
                                          "breaks stick/slip cycles at the contact edge; 0: plain "
                                          "Newton), 0..20")
    newton_weight: float = F(1e3, ge=0, le=1e8, unit="1",
                             description="load_step: the complementarity parameter c of the ball "
                                         "friction's weighted form, units G h0 (force per "
                                         "displacement): a node's stick/slip is decided by its "
                                         "trial force plus max(c - eta A / dt, 0) times its "
                                         "tangential displacement; the same roots as the law for "
                                         "every c, only Newton's path differs (docs/speed.md); 0: "
                                         "the law's own form, in [0, 1e8]")
    linear_solver: Literal["structured", "dense"] = F(
        "structured",
        description="Newton linear algebra of load_step_full and the diffrax solvers (load_step "
                    "picks its own by the mesh's size): structured (block-tridiagonal Jacobian by "
                    "colouring, Thomas + Schur complement, cost linear in nodes) or dense "
                    "(diffrax's default LU)",
    )
    rtol: float = F(1e-5, gt=0, lt=1, description="relative tolerance")
    atol: float = F(1e-7, gt=0, lt=1, description="absolute tolerance")
    pid_pcoeff: float = F(0.3, ge=0, le=1, description="PID controller proportional coefficient")
    pid_icoeff: float = F(0.3, gt=0, le=1, description="PID controller integral coefficient")
    penalty_stiffness: float = F(1e4, gt=0, le=1e12, unit="1",
                                 description="contact penalty stiffness k, units G h0 / R^3 per "
                                             "reference area, in (0, 1e12]")
    penalty_width: float = F(1e-3, gt=0, lt=1, description="penalty smoothing width w, units of R "
                                                           "(C^2 penalty), in (0, 1)")
    friction_smoothing: float = F(1e-3, ge=0, lt=1,
                                  description="force-space smoothing epsilon of the Coulomb law, "
                                              "units G h0 / R (exactly stuck below mu F_N - "
                                              "epsilon); 0 is the ideal law")
    contact_threshold: float = F(1e-2, gt=0, le=1e3, description="contact where the pressure "
                                                                 "exceeds this (G h0 / R), in (0, "
                                                                 "1e3]")
    support_stiffness: float = F(1e3, gt=0, le=1e8,
                                 description="ball: support: contact stiffness of the bottle neck "
                                             "on the ball, units G h0 (force G h0 R per "
                                             "penetration R; 1e3 lets the ball sink ~1e-3 R under "
                                             "a force of G h0 R)")
    max_steps: int = F(50000, ge=100, le=100_000_000,
                       description="step limit per save segment, 100..1e8")
    save_interval_s: float = F(2.0, unit="s", ge=1e-4, le=MAX_TIME_S,
                               description="time between saved frames (and condition checks), in "
                                           "[1e-4, 1e6] s; at most 1e6 frames in all")
    heal_rate_mm_s: float = F(0.002, unit="mm/s", ge=0, le=1.0,
                              description="healing criterion of slip_weakening: a node's slip "
                                          "distance resets where its slip rate is at most this "
                                          "(checked at every save); 0 is the bare force criterion "
                                          "S = 0, which a node settling onto its friction limit "
                                          "never reaches (docs/forming.md)")
    max_chord_depth: float = F(0.1, gt=0, le=1.0,
                               description="the mesh resolves the contact while no element's "
                                           "straight chord dips deeper than this into the ball "
                                           "(units R; 0.1 is about 0.9 rad of arc per element), "
                                           "checked on every saved frame (and the pole must not "
                                           "pass through the ball); a run that goes past it stops "
                                           "as failed (exit 3: no answer to trapped), in (0, 1]")
    trap_reaction_tol: float = F(1e-3, gt=0, lt=1,
                                 description="trapped needs |ball reaction| below this (units G "
                                             "h0 R) at the end")
    energy_bound: float = F(0.05, gt=0, le=1.0,
                            description="trapped is unknown (exit 3) where the energy balance's "
                                        "largest residual exceeds this fraction of the energy "
                                        "that flowed (the work of every body, or the stored "
                                        "energy released), in (0, 1]")
    runaway_mm: float = F(1000.0, unit="mm", gt=0, le=1e6,
                          description="trapped is unknown (exit 3) where the ball or a free body "
                                      "ends farther than this from where it started (ran away), "
                                      "in (0, 1e6] mm")


    def build_solver(self, heal_rate: float) -> AbstractSegmentSolver:
        """The segment solver that ``solver`` names, built with the settings of this spec that
        it runs on, and the healing rate ``heal_rate`` (R/s). Load stepping's linear algebra
        is chosen by the mesh's size (``linear_solver`` is the full-state and the diffrax
        solvers')."""
        if self.solver == "load_step_full":
            return FullStateLoadStep(
                max_steps=self.max_steps,
                newton_max_iter=self.newton_max_iter,
                newton_backtrack=self.newton_backtrack,
                linear_solver=self.linear_solver,
                heal_rate=heal_rate,
                max_increment=self.max_increment,
                max_increment_free=self.max_increment_free,
            )
        if self.solver == "load_step":
            return MotionNewton(
                max_iter=self.newton_max_iter,
                backtrack=self.newton_backtrack,
                max_increment=self.max_increment,
                max_increment_free=self.max_increment_free,
                heal_rate=heal_rate,
                max_steps=self.max_steps,
                weight=self.newton_weight,
            )
        return TimeStepping(
            scheme=self.solver,
            max_steps=self.max_steps,
            linear_solver=self.linear_solver,
            pcoeff=self.pid_pcoeff,
            icoeff=self.pid_icoeff,
            heal_rate=heal_rate,
        )


class FormingScenario(ScenarioBase):
    """Whole-sheet forming (method 2 by default): the pocket as the end state of a loading path."""

    kind: Literal["forming"] = "forming"
    start_from: str | None = F(
        None, description="start from a formed pocket: a saved trajectory.nc (its last frame) or "
                          "a forming scenario (run first into outputs/<stem>/, or reused when its "
                          "saved result matches); relative paths are taken from the working "
                          "directory, else from the scenario file's folder")
    physics: FormingPhysics = FormingPhysics()
    numerics: FormingNumerics = FormingNumerics()
    _source_dir: Path | None = PrivateAttr(default=None)

    # the core protocol, built once by the validation and kept with the physics it was built
    # from (a copy of the scenario with other physics builds its own)
    _protocol: tuple | None = PrivateAttr(default=None)

    def protocol(self):
        """The core :class:`~dynslip.physics.protocols.Protocol` of the stages
        (:func:`build_protocol`), built once per ``physics``."""
        if self._protocol is None or self._protocol[0] is not self.physics:
            self._protocol = (self.physics, build_protocol(self))
        return self._protocol[1]

    def world(self):
        """The run's :class:`~dynslip.schema.world.World`, every core object built from this
        scenario (:func:`dynslip.schema.world.build_world`)."""

        return build_world(self)

    @model_validator(mode="after")
    def _cross(self):
        # The clamp path must stay outside the ball (checked on the keyframes; condition stages at
        # their longest reach).
        try:
            prot = self.protocol()
        except ValueError as err:
            raise ValueError(f"physics.stages: {err}") from None
        if self.start_from is None and clamp_enters_ball(prot, self.physics.ball_body()):
            raise ValueError("physics.stages: the clamp path enters the ball")
        free = self.physics.free_names()
        if free and self.numerics.solver != "load_step":
            raise ValueError(f"numerics.solver = {self.numerics.solver}: the free body "
                             f"{free[0]!r} (physics.bodies, motion: free) needs load stepping; "
                             f"allowed: load_step")
        if free and self.start_from is not None:
            raise ValueError(f"start_from = {self.start_from!r}: a start state does not carry the "
                             f"free body {free[0]!r}'s height (not built); allowed: no start_from "
                             f"with a body of motion: free")
        frames = sum(s.max_duration for s in prot.stages) / self.numerics.save_interval_s
        if frames > MAX_FRAMES:  # every saved frame is held in memory
            raise ValueError(f"numerics.save_interval_s = {self.numerics.save_interval_s}: the "
                             f"loading path (at its longest) would save {frames:.3g} frames; "
                             f"allowed: at most {MAX_FRAMES:.0e}")
        return self
