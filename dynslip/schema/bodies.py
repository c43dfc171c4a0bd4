"""Schema of the rigid bodies of a forming scenario: ``physics.bodies``, the held obstacles, and
``physics.ball``, the moving body's kind (docs/bodies.md).

Lengths in the file are in mm; the core divides them by ``physics.ball_radius_mm`` (R, the
length unit of the core: for a ball that is not a sphere, R is only the unit). Heights are
measured from the ball's centre (its reference placement, the origin), upward.

A body is one flat entry ``{name, kind, <the kind's sizes>, z_mm, motion, friction}``: the
sizes of another kind are refused. ``z_mm`` places the body: the centre of a sphere, disc or
torus, the bottom of a cylinder, the base of a cone; a profile's points are shifted by it.
The checks that need the geometry (a profile not connected or crossing itself, bodies that
overlap each other or the ball at the start, bodies that share a face with each other, the
tube or the bottle, the flat sheet starting inside one) are made by
:func:`check_bodies` with the core's geometry (:mod:`dynslip.physics.bodies`), each as one line
naming the body's field, its value and what is allowed.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import model_validator

from dynslip.schema.base import F, Strict
from dynslip.schema.friction import FrictionLaw, FrictionlessSpec

__all__ = ["BallSpec", "BodySpec", "SegmentSpec", "KIND_SIZES",
           "ball_core", "body_core", "check_bodies"]

Point = tuple[float, float]

#: the size fields each kind takes (required ones first; the rest have defaults)
KIND_SIZES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "sphere": (("radius_mm",), ()),
    "disc": (("radius_mm", "thickness_mm", "edge_radius_mm"), ()),
    "cylinder": (("radius_mm", "height_mm"), ("inner_radius_mm", "edge_radius_mm")),
    "cone": (("radius_mm", "apex_mm"), ()),
    "torus": (("ring_radius_mm", "minor_radius_mm"), ()),
    "profile": (("segments",), ()),
}
_ALL_SIZES = ("radius_mm", "thickness_mm", "edge_radius_mm", "height_mm", "inner_radius_mm",
              "apex_mm", "ring_radius_mm", "minor_radius_mm", "segments")

_MM = "mm, divided by ball_radius_mm (R) in the core"


class SegmentSpec(Strict):
    """One segment of a profile (mm, the profile listed with the solid on its right: from the
    top of the axis down the outside, clockwise for rho to the right and z up): a line from
    ``start_mm`` to ``end_mm``, or an arc about ``centre_mm`` of ``radius_mm`` from
    ``start_deg`` to ``end_deg`` (angles counter-clockwise from +rho about the centre; the
    sweep negative for an arc bulging out of the solid)."""

    type: Literal["line", "arc"] = F(..., description="line or arc")
    start_mm: Point | None = F(None, unit="mm", description=f"line: its start (rho, z), {_MM}")
    end_mm: Point | None = F(None, unit="mm", description=f"line: its end (rho, z), {_MM}")
    centre_mm: Point | None = F(None, unit="mm", description=f"arc: its centre (rho, z), {_MM}")
    radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                description=f"arc: its radius, in (0, 1e4] {_MM}")
    start_deg: float | None = F(None, unit="deg", ge=-720, le=720,
                                description="arc: the polar angle about its centre where it "
                                            "starts, in [-720, 720] degrees")
    end_deg: float | None = F(None, unit="deg", ge=-720, le=720,
                              description="arc: the polar angle where it ends, in [-720, 720] "
                                          "degrees (|end - start| at most 360)")

    @model_validator(mode="after")
    def _fields_of_type(self):
        need = ("start_mm", "end_mm") if self.type == "line" else (
            "centre_mm", "radius_mm", "start_deg", "end_deg")
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.type} segment needs {', '.join(missing)}")
        extra = [k for k in ("start_mm", "end_mm", "centre_mm", "radius_mm", "start_deg",
                             "end_deg") if k not in need and getattr(self, k) is not None]
        if extra:
            raise ValueError(f"{', '.join(extra)}: not a field of a {self.type} segment "
                             f"(its fields: {', '.join(need)})")
        return self

    def core(self, r: float):
        """The core segment (units of R)."""
        from dynslip.physics.bodies.segments import Arc, Line

        if self.type == "line":
            return Line((self.start_mm[0] / r, self.start_mm[1] / r),
                        (self.end_mm[0] / r, self.end_mm[1] / r))
        return Arc((self.centre_mm[0] / r, self.centre_mm[1] / r), self.radius_mm / r,
                   math.radians(self.start_deg), math.radians(self.end_deg))


class _Shape(Strict):
    """The sizes of every kind (mm); which a kind takes: :data:`KIND_SIZES`."""

    radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                description="sphere, disc, cylinder: the radius; cone: its base's "
                                            f"radius; in (0, 1e4] {_MM}")
    thickness_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                   description=f"disc: the thickness, in (0, 1e4] {_MM}")
    edge_radius_mm: float | None = F(None, unit="mm", ge=0, le=1e4,
                                     description="disc: its edge's rounding radius, in (0, "
                                                 "thickness / 2]; cylinder: its corners' (0: "
                                                 f"sharp, the default); {_MM}")
    height_mm: float | None = F(None, unit="mm", gt=0, le=1e5,
                                description=f"cylinder: its height, in (0, 1e5] {_MM}")
    inner_radius_mm: float | None = F(None, unit="mm", ge=0, le=1e4,
                                      description="cylinder: the inner radius of a tube wall (0: "
                                                  f"solid, the default), below the radius; {_MM}")
    apex_mm: float | None = F(None, unit="mm", ge=-1e5, le=1e5,
                              description="cone: the apex's height above its base (negative: "
                                          f"below), nonzero; {_MM}")
    ring_radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                     description="torus: the radius of its centre circle, above "
                                                 f"the minor radius; {_MM}")
    minor_radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                      description=f"torus: its tube's radius; {_MM}")
    segments: list[SegmentSpec] | None = F(None, max_length=200,
                                           description="profile: its segments, C1 where they "
                                                       "join, from axis to axis or closed "
                                                       "(at most 200)")
    z_mm: float = F(0.0, unit="mm", ge=-1e5, le=1e5,
                    description="placement along the axis from the ball's centre, up: the centre "
                                "of a sphere, disc or torus, the bottom of a cylinder, the base "
                                f"of a cone, the shift of a profile's points; {_MM}")

    def _check_sizes(self, kind: str, where: str):
        need, optional = KIND_SIZES[kind]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"{where}: a {kind} needs {', '.join(missing)}")
        extra = [k for k in _ALL_SIZES if k not in need + optional and getattr(self, k) is not None]
        if extra:
            raise ValueError(f"{where}: {', '.join(extra)} is not a size of a {kind} (its sizes: "
                             f"{', '.join(need + optional)})")

    def core(self, kind: str, r: float):
        """The core body (units of R); raises BodyGeometryError for an invalid solid."""
        from dynslip.physics.bodies import Cone, Cylinder, Disc, Profile, Sphere, Torus
        from dynslip.physics.bodies.segments import Arc, Line

        z = self.z_mm / r
        if kind == "sphere":
            return Sphere(self.radius_mm / r, centre_z=z)
        if kind == "disc":
            return Disc(self.radius_mm / r, self.thickness_mm / r, self.edge_radius_mm / r,
                        centre_z=z)
        if kind == "cylinder":
            return Cylinder(self.radius_mm / r, z, z + self.height_mm / r,
                            inner_radius=(self.inner_radius_mm or 0.0) / r,
                            edge_radius=(self.edge_radius_mm or 0.0) / r)
        if kind == "cone":
            return Cone(self.radius_mm / r, z, z + self.apex_mm / r)
        if kind == "torus":
            return Torus(self.ring_radius_mm / r, self.minor_radius_mm / r, centre_z=z)
        segs = []
        for s in self.segments:
            c = s.core(r)
            if isinstance(c, Line):
                c = Line((c.start[0], c.start[1] + z), (c.end[0], c.end[1] + z))
            else:
                c = Arc((c.centre[0], c.centre[1] + z), c.radius, c.start_angle, c.end_angle)
            segs.append(c)
        return Profile(segs)


class BodySpec(_Shape):
    """A held body (an obstacle): its kind and sizes (mm), its placement, its motion and the
    sheet's friction on it."""

    name: str = F(..., min_length=1, max_length=100, description="the body's name (unique)")
    kind: Literal["sphere", "disc", "cylinder", "cone", "torus", "profile"] = F(
        ..., description="sphere (radius_mm), disc (radius_mm, thickness_mm, edge_radius_mm), "
        "cylinder (radius_mm, height_mm; inner_radius_mm, edge_radius_mm), cone (radius_mm, "
        "apex_mm), torus (ring_radius_mm, minor_radius_mm), profile (segments)")
    motion: Literal["held", "with_ball", "stage", "free"] = F(
        "held", description="held: at rest; with_ball: carried with the ball (as the bottle); "
        "stage: moved by the stages (each stage's body_velocity_mm_s gives its velocity by "
        "name; 0 where not named); free: moves along the axis under the sheet's pressure and "
        "friction and force_N against its drag (numerics.solver load_step)")
    force_N: float | None = F(None, unit="N", ge=-1e4, le=1e4,
                              description="motion: free: the axial force applied to the body, + "
                                          "up (its weight, a spring's preload: give it here; "
                                          "gravity is not added), in [-1e4, 1e4] N; default 0")
    drag: float | None = F(None, gt=0, le=1e6,
                           description="motion: free: the body's drag as a multiple of the "
                                       "sheet's drag over 4 pi R^2 (as numerics.ball_drag), in "
                                       "(0, 1e6]; default 1")
    friction: FrictionLaw = F(FrictionlessSpec(),
                              description="the sheet's friction on this body, as physics.friction "
                              "(law: none, the default, coulomb, slip_weakening or pressure; "
                              "slip distances relative to the body, each body its own)")

    @model_validator(mode="after")
    def _sizes(self):
        self._check_sizes(self.kind, f"body {self.name!r}")
        if self.motion != "free":
            given = [k for k in ("force_N", "drag") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"body {self.name!r}: {given[0]} goes with motion: free (its "
                                 f"motion is {self.motion})")
        return self


class BallSpec(Strict):
    """The ball's kind (the moving body): a sphere of ``ball_radius_mm`` by default, or a
    disc (a coin). The length unit R stays ``ball_radius_mm``: for a disc R is only the length
    unit (set it to the coin's radius). Its centre is the ball's height; the trapped
    criterion and the mesh check follow its kind (docs/bodies.md)."""

    kind: Literal["sphere", "disc"] = F("sphere", description="sphere (radius_mm, default "
                                        "ball_radius_mm) or disc (radius_mm, thickness_mm, "
                                        "edge_radius_mm: a coin)")
    radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                description="the sphere's radius (default ball_radius_mm) or the "
                                            f"disc's; in (0, 1e4] {_MM}")
    thickness_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                   description=f"disc: the thickness, in (0, 1e4] {_MM}")
    edge_radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                     description="disc: its edge's rounding radius, in (0, "
                                                 f"thickness / 2]; {_MM}")

    @model_validator(mode="after")
    def _sizes(self):
        if self.kind == "disc":
            missing = [k for k in ("radius_mm", "thickness_mm", "edge_radius_mm")
                       if getattr(self, k) is None]
            if missing:
                raise ValueError(f"ball: a disc needs {', '.join(missing)}")
        else:
            extra = [k for k in ("thickness_mm", "edge_radius_mm") if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"ball: {', '.join(extra)} is not a size of a sphere (its "
                                 f"size: radius_mm)")
        return self

    def radius(self, r: float) -> float:
        """The ball's radius (mm): radius_mm, else ball_radius_mm ``r``."""
        return r if self.radius_mm is None else self.radius_mm

    def top_mm(self, r: float) -> float:
        """Height of the ball's top above its centre (mm): where the flat sheet starts above."""
        return self.radius(r) if self.kind == "sphere" else 0.5 * self.thickness_mm

    def widest_mm(self, r: float) -> float:
        """The ball's largest radius from the axis (mm)."""
        return self.radius(r)

    def core(self, r: float):
        """The core body (units of R), centred at the origin."""
        from dynslip.physics.bodies import Disc, Sphere

        if self.kind == "sphere":
            return Sphere(self.radius(r) / r)
        return Disc(self.radius_mm / r, self.thickness_mm / r, self.edge_radius_mm / r)


def ball_core(ball: BallSpec | None, r: float):
    """The core ball body (units of R): the unit :class:`Sphere` for the default (the closed
    forms of :mod:`dynslip.physics.sheet`, operation for operation), else the sphere or disc
    of the spec."""
    from dynslip.physics.bodies import Sphere

    if ball is None or (ball.kind == "sphere" and ball.radius(r) == r):
        return Sphere()
    return ball.core(r)


def body_core(spec: BodySpec, r: float):
    """The core body of a held body's spec (units of R)."""
    return spec.core(spec.kind, r)


#: the longest stretch (units of R) along which two bodies may touch and still count as touching
#: at a point: surfaces within 1e-9 R of each other near a point contact (sampled by
#: :func:`~dynslip.physics.bodies.overlap.shared_face`) stay well below it
SHARED_FACE_MAX = 1e-3


def check_bodies(bodies, ball, others, r: float, sheet_z: float, sheet_rho: float) -> None:
    """The geometry checks of ``physics.bodies`` (raises ValueError, one line): every body a
    valid solid, none overlapping another, the ball (at its start, the origin) or ``others``
    (the tube's and bottle's core bodies), none sharing a face with another or with
    ``others`` (a face inside matter, where a sheet node is hooked; touching at a point is
    allowed: :func:`~dynslip.physics.bodies.overlap.shared_face` over more than
    :data:`SHARED_FACE_MAX` R), the flat sheet at height ``sheet_z`` out to ``sheet_rho``
    (units of R) outside every body, names unique."""
    import numpy as np

    from dynslip.physics.bodies import BodyGeometryError, inside, penetration, shared_face

    def shared(a, b):
        return max(shared_face(a, b), shared_face(b, a))

    names = [b.name for b in bodies]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"bodies.name = {dup[0]!r}: duplicated; allowed: a name used once")
    cores = []
    for k, b in enumerate(bodies):
        try:
            cores.append(body_core(b, r))
        except BodyGeometryError as err:
            raise ValueError(f"bodies.{k} ({b.name!r}, kind {b.kind}): {err} (lengths in units "
                             f"of R = ball_radius_mm = {r:g} mm)") from None
    sheet = np.stack([np.linspace(0.0, sheet_rho, 4001), np.full(4001, sheet_z)], -1)
    for k, (b, c) in enumerate(zip(bodies, cores, strict=True)):
        where = f"bodies.{k} ({b.name!r}, kind {b.kind}, z_mm = {b.z_mm})"
        depth = penetration(c, ball)
        if depth > 1e-9:
            raise ValueError(f"{where}: overlaps the ball at the start by {depth * r:.4g} mm; "
                             f"allowed: apart or touching")
        for name, o in others:
            depth = penetration(c, o)
            if depth > 1e-9:
                raise ValueError(f"{where}: overlaps the {name} by {depth * r:.4g} mm; allowed: "
                                 f"apart or touching")
            face = shared(c, o)
            if face > SHARED_FACE_MAX:
                raise ValueError(f"{where}: shares a face with the {name} over {face * r:.4g} mm "
                                 f"(a face inside matter); allowed: apart or touching at a point")
        for j in range(k):
            depth = penetration(c, cores[j])
            if depth > 1e-9:
                raise ValueError(f"{where}: overlaps body {bodies[j].name!r} by "
                                 f"{depth * r:.4g} mm; allowed: apart or touching")
            face = shared(c, cores[j])
            if face > SHARED_FACE_MAX:
                raise ValueError(f"{where}: shares a face with body {bodies[j].name!r} over "
                                 f"{face * r:.4g} mm (a face inside matter); allowed: apart or "
                                 f"touching at a point")
        ins = inside(c, sheet)
        if ins.any():
            rho = float(sheet[np.argmax(ins), 0]) * r
            raise ValueError(f"{where}: the flat sheet starts inside it (at rho = {rho:.4g} mm, "
                             f"z = {sheet_z * r:.4g} mm); allowed: the body below or above the "
                             f"sheet's start")
