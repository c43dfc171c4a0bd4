"""Schema of the rigid bodies of a forming scenario: ``physics.bodies``, the held obstacles, and
``physics.ball``, the moving body's kind (docs/bodies.md).

Lengths in the file are in mm; the core divides them by ``physics.ball_radius_mm`` (R, the
length unit of the core: for a ball that is not a sphere, R is only the unit). Heights are
measured from the ball's centre (its reference placement, the origin), upward.

Each kind is one :class:`ShapeSpec` subclass in :data:`BODY_KINDS` (``kind: Literal["name"]``,
its sizes in mm, :meth:`ShapeSpec.core` building its core body); ``BODY_KINDS.register(Spec)``
adds one from outside the package (tests/test_body_registry.py does so). A held body is one
flat entry ``{name, kind, <the kind's sizes>, z_mm, motion, friction}`` (its kind's spec with
:class:`HeldFields`): the sizes of another kind are refused. The ball is a kind whose spec
has ``can_be_ball`` (a sphere, the default, or a disc). ``z_mm`` places a held body: the
centre of a sphere, disc or torus, the bottom of a cylinder, the base of a cone; a profile's
points are shifted by it.
The checks that need the geometry (a profile not connected or crossing itself, bodies that
overlap each other or the ball at the start, bodies that share a face with each other, the
tube or the bottle, the flat sheet starting inside one) are made by
:func:`check_bodies` with the core's geometry (:mod:`dynslip.physics.bodies`), each as one line
naming the body's field, its value and what is allowed.
"""

from __future__ import annotations

import math
import typing
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, TypeAdapter, model_validator

from dynslip.physics.bodies import (
    BodyGeometryError,
    Cone,
    Cylinder,
    Disc,
    Profile,
    Sphere,
    Torus,
    inside,
    penetration,
    shared_face,
)
from dynslip.physics.bodies.segments import Arc, Line
from dynslip.schema.base import F, Strict
from dynslip.schema.friction import FrictionLaw, FrictionlessSpec
from dynslip.schema.registry import Registry

__all__ = ["BODY_KINDS", "BallSpec", "BodySpec", "ShapeSpec", "HeldFields", "SegmentSpec",
           "SphereSpec", "DiscSpec", "CylinderSpec", "ConeSpec", "TorusSpec", "ProfileSpec",
           "ball_core", "body_core", "check_bodies"]

Point = tuple[float, float]

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
            raise ValueError(f"{', '.join(extra)}: not a field of a {self.type} segment (its "
                             f"fields: {', '.join(need)})")
        return self

    def core(self, r: float):
        """The core segment (units of R)."""

        # _fields_of_type has checked that the fields of this segment's type are given
        if self.type == "line":
            assert self.start_mm is not None and self.end_mm is not None
            return Line((self.start_mm[0] / r, self.start_mm[1] / r),
                        (self.end_mm[0] / r, self.end_mm[1] / r))
        assert self.centre_mm is not None and self.radius_mm is not None
        assert self.start_deg is not None and self.end_deg is not None
        return Arc((self.centre_mm[0] / r, self.centre_mm[1] / r), self.radius_mm / r,
                   math.radians(self.start_deg), math.radians(self.end_deg))


class ShapeSpec(Strict):
    """A body kind: ``kind`` names it (:data:`BODY_KINDS`), the other fields are its sizes (mm).
    :meth:`core` builds its core body; a kind with ``can_be_ball`` may be ``physics.ball``
    (then :meth:`top_mm` and :meth:`widest_mm` place the flat sheet and the clamp)."""

    kind: str
    #: whether ``physics.ball`` may be of this kind (the one place that says so)
    can_be_ball: ClassVar[bool] = False
    #: sizes a held body must give that the ball may leave to their defaults
    held_needs: ClassVar[tuple[str, ...]] = ()

    @model_validator(mode="before")
    @classmethod
    def _sizes_of_kind(cls, data):
        # one line naming the size: another kind's size, or a size of this kind left out
        if not isinstance(data, dict):
            return data
        kind = typing.get_args(cls.model_fields["kind"].annotation)[0]
        own = set(cls.model_fields)
        others = [k for k in data if isinstance(k, str) and k not in own and any(
            k in s.model_fields for s in BODY_KINDS.specs.values())]
        sizes = [k for k in cls.model_fields if k not in HeldFields.model_fields and k != "kind"]
        if others:
            raise ValueError(f"{', '.join(others)} is not a size of a {kind} (its sizes: "
                             f"{', '.join(sizes)})")
        needs = [k for k, f in cls.model_fields.items()
                 if k in sizes and (f.is_required() or (issubclass(cls, HeldFields)
                                                        and k in cls.held_needs))]
        missing = [k for k in needs if data.get(k) is None]
        if missing:
            raise ValueError(f"a {kind} needs {', '.join(missing)}")
        return data

    def core(self, r: float, z: float = 0.0):
        """The core body (units of R), placed at height ``z`` (units of R); raises
        BodyGeometryError for an invalid solid."""
        raise NotImplementedError

    def top_mm(self, r: float) -> float:
        """A ball's top above its centre (mm; ``r`` = ball_radius_mm)."""
        raise NotImplementedError

    def widest_mm(self, r: float) -> float:
        """A ball's largest radius from the axis (mm)."""
        raise NotImplementedError

    def radius(self, r: float) -> float:
        """A ball's radius (mm): its largest radius from the axis."""
        return self.widest_mm(r)


#: the body kinds of the scenario file, by ``kind``: held bodies take every one, the ball those
#: with ``can_be_ball``; ``BODY_KINDS.register(Spec)`` adds one from outside
BODY_KINDS = Registry("kind")


@BODY_KINDS.add
class SphereSpec(ShapeSpec):
    """A sphere; as the ball, of ball_radius_mm by default."""

    kind: Literal["sphere"] = F("sphere", description="sphere")
    radius_mm: float | None = F(None, unit="mm", gt=0, le=1e4,
                                description=f"the radius (required of a held sphere; the ball's "
                                            f"default: ball_radius_mm); in (0, 1e4] {_MM}")
    can_be_ball: ClassVar[bool] = True
    held_needs: ClassVar[tuple[str, ...]] = ("radius_mm",)

    def radius(self, r: float) -> float:
        """The radius (mm): radius_mm, else ball_radius_mm ``r``."""
        return r if self.radius_mm is None else self.radius_mm

    def core(self, r: float, z: float = 0.0):

        return Sphere(self.radius(r) / r, centre_z=z)

    def top_mm(self, r: float) -> float:
        return self.radius(r)

    def widest_mm(self, r: float) -> float:
        return self.radius(r)


@BODY_KINDS.add
class DiscSpec(ShapeSpec):
    """A disc (a coin) with a rounded edge, centred at its placement."""

    kind: Literal["disc"] = F("disc", description="disc: a coin")
    radius_mm: float = F(..., unit="mm", gt=0, le=1e4, description=f"the radius, in (0, 1e4] {_MM}")
    thickness_mm: float = F(..., unit="mm", gt=0, le=1e4,
                            description=f"the thickness, in (0, 1e4] {_MM}")
    edge_radius_mm: float = F(..., unit="mm", ge=0, le=1e4,
                              description=f"its edge's rounding radius, in (0, thickness / 2]; "
                                          f"{_MM}")
    can_be_ball: ClassVar[bool] = True

    def core(self, r: float, z: float = 0.0):

        return Disc(self.radius_mm / r, self.thickness_mm / r, self.edge_radius_mm / r,
                    centre_z=z)

    def top_mm(self, r: float) -> float:
        return 0.5 * self.thickness_mm

    def widest_mm(self, r: float) -> float:
        return self.radius_mm


@BODY_KINDS.add
class CylinderSpec(ShapeSpec):
    """A cylinder standing on its bottom, solid or a tube wall, its corners sharp or rounded."""

    kind: Literal["cylinder"] = F("cylinder", description="cylinder")
    radius_mm: float = F(..., unit="mm", gt=0, le=1e4, description=f"the radius, in (0, 1e4] {_MM}")
    height_mm: float = F(..., unit="mm", gt=0, le=1e5,
                         description=f"its height, in (0, 1e5] {_MM}")
    inner_radius_mm: float | None = F(None, unit="mm", ge=0, le=1e4,
                                      description=f"the inner radius of a tube wall (0: solid, "
                                                  f"the default), below the radius; {_MM}")
    edge_radius_mm: float | None = F(None, unit="mm", ge=0, le=1e4,
                                     description=f"its corners' rounding radius (0: sharp, the "
                                                 f"default); {_MM}")

    def core(self, r: float, z: float = 0.0):

        return Cylinder(self.radius_mm / r, z, z + self.height_mm / r,
                        inner_radius=(self.inner_radius_mm or 0.0) / r,
                        edge_radius=(self.edge_radius_mm or 0.0) / r)


@BODY_KINDS.add
class ConeSpec(ShapeSpec):
    """A cone on the axis: its base at its placement, its apex above (or below) it."""

    kind: Literal["cone"] = F("cone", description="cone")
    radius_mm: float = F(..., unit="mm", gt=0, le=1e4,
                         description=f"its base's radius, in (0, 1e4] {_MM}")
    apex_mm: float = F(..., unit="mm", ge=-1e5, le=1e5,
                       description=f"the apex's height above its base (negative: below), nonzero; "
                                   f"{_MM}")

    def core(self, r: float, z: float = 0.0):

        return Cone(self.radius_mm / r, z, z + self.apex_mm / r)


@BODY_KINDS.add
class TorusSpec(ShapeSpec):
    """A torus about the axis, centred at its placement."""

    kind: Literal["torus"] = F("torus", description="torus")
    ring_radius_mm: float = F(..., unit="mm", gt=0, le=1e4,
                              description=f"the radius of its centre circle, above the minor "
                                          f"radius; {_MM}")
    minor_radius_mm: float = F(..., unit="mm", gt=0, le=1e4,
                               description=f"its tube's radius; {_MM}")

    def core(self, r: float, z: float = 0.0):

        return Torus(self.ring_radius_mm / r, self.minor_radius_mm / r, centre_z=z)


@BODY_KINDS.add
class ProfileSpec(ShapeSpec):
    """A solid of revolution drawn by its meridian's segments, shifted up by its placement."""

    kind: Literal["profile"] = F("profile", description="profile")
    segments: list[SegmentSpec] = F(..., max_length=200,
                                    description="its segments, C1 where they join, from axis to "
                                                "axis or closed (at most 200)")

    def core(self, r: float, z: float = 0.0):

        segs = []
        for s in self.segments:
            c = s.core(r)
            if isinstance(c, Line):
                c = Line((c.start[0], c.start[1] + z), (c.end[0], c.end[1] + z))
            else:
                c = Arc((c.centre[0], c.centre[1] + z), c.radius, c.start_angle, c.end_angle)
            segs.append(c)
        return Profile(segs)


class HeldFields(Strict):
    """What a held body adds to its kind's sizes: its name, placement, motion and the sheet's
    friction on it."""

    name: str = F(..., min_length=1, max_length=100, description="the body's name (unique)")
    z_mm: float = F(0.0, unit="mm", ge=-1e5, le=1e5,
                    description=f"placement along the axis from the ball's centre, up: the centre "
                                f"of a sphere, disc or torus, the bottom of a cylinder, the base "
                                f"of a cone, the shift of a profile's points; {_MM}")
    motion: Literal["held", "with_ball", "stage", "free"] = F(
        "held", description="held: at rest; with_ball: carried with the ball (as the bottle); "
                            "stage: moved by the stages (each stage's body_velocity_mm_s gives "
                            "its velocity by name; 0 where not named); free: moves along the axis "
                            "under the sheet's pressure and friction and force_N against its drag "
                            "(numerics.solver load_step)")
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
                                          "(law: none, the default, coulomb, slip_weakening or "
                                          "pressure; slip distances relative to the body, each "
                                          "body its own)")

    @model_validator(mode="after")
    def _free_only(self):
        if self.friction.ball_only:
            raise ValueError(f"body {self.name!r}: friction.law = {self.friction.law} acts on the "
                             f"ball only (a held body shares the sheet's repulsive penalty, with "
                             f"no gap to bound an adhesive range); allowed here: none, coulomb, "
                             f"slip_weakening, pressure")
        if self.motion != "free":
            given = [k for k in ("force_N", "drag") if getattr(self, k) is not None]
            if given:
                raise ValueError(f"body {self.name!r}: {given[0]} goes with motion: free (its "
                                 f"motion is {self.motion})")
        return self


class _Variants(Registry):
    """A registry derived from :data:`BODY_KINDS`: the kinds that ``keep`` admits, each made
    into ``cls`` + the kind (a held body's fields beside its sizes, one flat entry), built
    once per kind."""

    def __init__(self, keep, base: type[BaseModel] | None = None, default: str | None = None):
        self.tag, self.default, self.others_ignored = "kind", default, False
        self._keep, self._base = keep, base
        self._made: dict[type[BaseModel], type[BaseModel]] = {}

    @property
    def specs(self) -> dict[str, type[BaseModel]]:  # type: ignore[override]  # derived, never set
        return {tag: self._made_of(s) for tag, s in BODY_KINDS.specs.items() if self._keep(s)}

    def _made_of(self, shape: type[BaseModel]) -> type[BaseModel]:
        if self._base is None:
            return shape
        if shape not in self._made:
            self._made[shape] = type(f"Held{shape.__name__}", (shape, self._base),
                                     {"__module__": shape.__module__, "__doc__": shape.__doc__})
        return self._made[shape]


#: a held body: one flat entry ``{name, kind, <the kind's sizes>, z_mm, motion, friction}``
HELD_KINDS = _Variants(lambda s: True, base=HeldFields)
#: the ball: a kind with ``can_be_ball``, a sphere (of ball_radius_mm) by default
BALL_KINDS = _Variants(lambda s: s.can_be_ball, default="sphere")

BodySpec = Annotated[HeldFields, HELD_KINDS]


class BallSpec:
    """The ball's kind (the moving body): a sphere of ``ball_radius_mm`` by default, or a kind
    with ``can_be_ball`` (a disc: a coin). ``BallSpec(**fields)`` validates into that kind's
    spec. The length unit R stays ``ball_radius_mm``: for a ball that is not a sphere R is only
    the length unit. Its centre is the ball's height; the trapped criterion and the mesh check
    follow its kind (docs/bodies.md)."""

    def __new__(cls, **fields) -> Any:
        return TypeAdapter(cls).validate_python(fields)

    @classmethod
    def __get_pydantic_core_schema__(cls, source, handler):
        return BALL_KINDS.__get_pydantic_core_schema__(source, handler)


def ball_core(ball: ShapeSpec | None, r: float):
    """The core ball body (units of R): the unit :class:`Sphere` for the default (the closed
    forms of :mod:`dynslip.physics.sheet`, operation for operation), else its kind's body,
    centred at the origin."""

    if ball is None or (ball.kind == "sphere" and ball.radius(r) == r):
        return Sphere()
    return ball.core(r)


def body_core(spec, r: float):
    """The core body of a held body's spec (units of R), at its placement."""
    return spec.core(r, spec.z_mm / r)


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
            raise ValueError(f"bodies.{k} ({b.name!r}, kind {b.kind}): {err} (lengths in units of "
                             f"R = ball_radius_mm = {r:g} mm)") from None
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
                raise ValueError(f"{where}: overlaps body {bodies[j].name!r} by {depth * r:.4g} "
                                 f"mm; allowed: apart or touching")
            face = shared(c, cores[j])
            if face > SHARED_FACE_MAX:
                raise ValueError(f"{where}: shares a face with body {bodies[j].name!r} over "
                                 f"{face * r:.4g} mm (a face inside matter); allowed: apart or "
                                 f"touching at a point")
        ins = inside(c, sheet)
        if ins.any():
            rho = float(sheet[np.argmax(ins), 0]) * r
            raise ValueError(f"{where}: the flat sheet starts inside it (at rho = {rho:.4g} mm, z "
                             f"= {sheet_z * r:.4g} mm); allowed: the body below or above the "
                             f"sheet's start")
