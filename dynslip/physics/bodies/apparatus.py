r"""The experiment's apparatus as held bodies: the bottle the ball sits on, the tube's wall.

Sizes are the paper's where it gives them (Section 2: a 4 in OD, 4 in tall PVC tube; a bottle
with a 1 in OD neck) and stated assumptions where it does not (physics.md Section 4, "The
experiment's world"): the neck's wall 2 mm, its length 65 mm (bottles with such a neck: 50-80
mm), a conical shoulder 18.6 mm high to a body 70 mm across (typically 60-75 mm), the body 140
mm tall; the tube's wall 3 mm with a fully rounded end. Every size is an argument in mm.
Lengths returned in units of the ball's radius R, in the lab frame with the ball's centre at
the origin when it rests on the neck.

**The bottle** is one closed, smooth solid (a :class:`~.profile.Profile`, C1 at every joint:
no face of it lies inside matter, where a sheet node pushed into the glass could be hooked).
Its profile, from the top of the axis down the outside with the glass on the right:

1. the bore's flat floor, from the axis out to the bore radius $r_i = r_o - w$, at the
   shoulder's height (the bore is as deep as the neck is long; nothing of the sheet reaches
   into it, the ball sitting on the lip);
2. a hollow fillet into the bore's wall, of radius $\min(r_i, L - w/2)/2$ ($L$ the neck's
   length; unreached, so a stated rule, not a size);
3. the bore's wall up to the lip;
4. the rounded lip, a half torus of radius $w/2$ placed so that it touches the resting ball
   (distance 0): its centre at $(\rho_c, z_c)$, $\rho_c = r_o - w/2$,
   $z_c = -\sqrt{(1 + w/2)^2 - \rho_c^2}$ (with $r_o$, $w$ in R);
5. the neck's outer wall down to the shoulder, $L$ below the lip's top;
6. a hollow fillet (``neck_fillet_mm``) into
7. the conical shoulder's flank, ``shoulder_height_mm`` high, out to the body's radius;
8. a convex fillet (``shoulder_fillet_mm``) into
9. the body's cylinder, ``body_height_mm`` tall below the shoulder;
10. a convex fillet (``base_fillet_mm``) into
11. the flat base, back to the axis.

The fillets are tangent to both lines they join (the bottle is one body whose profile has no
sharp edge between its neck, shoulder, cylinder and base); a fillet too large for its lines is
refused (:func:`check_bottle_fillets`, in mm).

The tube's wall hangs from its rim: the rim (the wall's end) at height $z_{\rm rim}$ (the
clamp's height), the wall up to $z_{\rm rim} + H$. The tube is an open cylinder: its height is
geometry only and does not bound a push (the ball and the sheet's tent leave through its far
end, the ball's top passing it at $z_{\rm rim} = 1 - H$, :func:`deepest_rim`: -81.6 mm for
the paper's tube and ball).

Example::

    >>> parts = bottle(20.0)
    >>> len(parts)
    1
    >>> round(deepest_rim(20.0), 2)
    -4.08
"""

from __future__ import annotations

import functools
import math

from dynslip.physics.bodies.base import BodyGeometryError
from dynslip.physics.bodies.cylinder import Cylinder
from dynslip.physics.bodies.profile import Profile
from dynslip.physics.bodies.segments import Arc, Line

__all__ = ["bottle", "check_bottle_fillets", "tube_wall", "deepest_rim"]


def _shoulder_turn(neck_od_mm: float, shoulder_height_mm: float, body_od_mm: float) -> float:
    """The angle (radians) by which the profile turns where the neck meets the shoulder, and
    back where the shoulder meets the body: the flank's angle from the vertical."""
    return math.atan2(0.5 * (body_od_mm - neck_od_mm), shoulder_height_mm)


def check_bottle_fillets(
    neck_od_mm: float,
    neck_wall_mm: float,
    neck_length_mm: float,
    shoulder_height_mm: float,
    body_od_mm: float,
    body_height_mm: float,
    neck_fillet_mm: float,
    shoulder_fillet_mm: float,
    base_fillet_mm: float,
) -> None:
    r"""Raise :class:`BodyGeometryError` (one line naming the size, in mm) unless each fillet
    is positive and fits its two lines with the others: a fillet of radius $r$ at a turn
    $\varphi$ takes $r\tan(\varphi/2)$ of each line it joins, and every line keeps a
    positive length (the neck's outer wall $L - w/2$, the shoulder's flank, the body
    ``body_height_mm``, the base the body's radius). Needs ``body_od_mm > neck_od_mm``."""
    turn = _shoulder_turn(neck_od_mm, shoulder_height_mm, body_od_mm)
    k = math.tan(turn / 2)  # a fillet's tangent length per radius at the shoulder's two turns
    flank = math.hypot(0.5 * (body_od_mm - neck_od_mm), shoulder_height_mm)
    neck = neck_length_mm - neck_wall_mm / 2
    rb = body_od_mm / 2
    for name, value in (("neck_fillet_mm", neck_fillet_mm),
                        ("shoulder_fillet_mm", shoulder_fillet_mm),
                        ("base_fillet_mm", base_fillet_mm)):
        if not value > 0:
            raise BodyGeometryError(f"bottle {name} = {value:g}: must be > 0 mm")
    alone = (  # each fillet on its own lines
        ("neck_fillet_mm", neck_fillet_mm, min(neck, flank) / k,
         "between the neck and the shoulder"),
        ("shoulder_fillet_mm", shoulder_fillet_mm, min(flank, body_height_mm) / k,
         "between the shoulder and the body"),
        ("base_fillet_mm", base_fillet_mm, min(rb, body_height_mm), "at the body's base"),
    )
    shared = (  # two fillets on one line: the flank, the body's wall
        ("shoulder_fillet_mm", shoulder_fillet_mm, (flank - neck_fillet_mm * k) / k,
         f"on the shoulder's flank beside neck_fillet_mm = {neck_fillet_mm:g}"),
        ("base_fillet_mm", base_fillet_mm, body_height_mm - shoulder_fillet_mm * k,
         f"on the body's wall beside shoulder_fillet_mm = {shoulder_fillet_mm:g}"),
    )
    for name, value, limit, where in alone + shared:
        if not value < limit:
            raise BodyGeometryError(
                f"bottle {name} = {value:g}: does not fit {where}; allowed: below "
                f"{max(limit, 0.0):.4g} mm"
            )


def _fillet(corner, t_in, t_out, radius):
    """The arc of ``radius`` tangent to the line arriving at ``corner`` along the unit
    direction ``t_in`` and to the line leaving it along ``t_out``: ``(arc, start, end)``, the
    arc and its tangent points on the two lines. A turn counter-clockwise is a hollow
    (positive sweep), clockwise a convex edge."""
    cross = t_in[0] * t_out[1] - t_in[1] * t_out[0]
    dot = t_in[0] * t_out[0] + t_in[1] * t_out[1]
    turn = math.atan2(abs(cross), dot)
    reach = radius * math.tan(turn / 2)
    a = (corner[0] - reach * t_in[0], corner[1] - reach * t_in[1])
    b = (corner[0] + reach * t_out[0], corner[1] + reach * t_out[1])
    side = 1.0 if cross > 0 else -1.0  # the centre to the left of t_in for a hollow
    centre = (a[0] - side * radius * t_in[1], a[1] + side * radius * t_in[0])
    start = math.atan2(a[1] - centre[1], a[0] - centre[0])
    return Arc(centre, radius, start, start + side * turn), a, b


@functools.lru_cache(maxsize=32)
def bottle(
    ball_radius_mm: float,
    neck_od_mm: float = 25.4,
    neck_wall_mm: float = 2.0,
    neck_length_mm: float = 65.0,
    shoulder_height_mm: float = 18.6,
    body_od_mm: float = 70.0,
    body_height_mm: float = 140.0,
    neck_fillet_mm: float = 5.0,
    shoulder_fillet_mm: float = 10.0,
    base_fillet_mm: float = 5.0,
) -> tuple:
    """The bottle as one held body, a 1-tuple holding its :class:`~.profile.Profile` (module
    docstring), in units of R, the ball resting on the lip at the origin. Built once per set
    of arguments (bodies are immutable; checking a profile costs milliseconds, and a run asks
    for the bottle some ten times: the solver, the summary, the figures)."""
    R = float(ball_radius_mm)
    ro, w = neck_od_mm / 2 / R, neck_wall_mm / R
    if not 0 < w < ro:
        raise BodyGeometryError(
            f"bottle neck wall {neck_wall_mm:g} mm, must be in (0, neck radius)"
        )
    if not ro < 1.0:
        raise BodyGeometryError(
            f"bottle neck radius {neck_od_mm / 2:g} mm, must be below the ball's radius {R:g} mm"
        )
    if not body_od_mm / 2 / R > ro:
        raise BodyGeometryError(
            f"bottle body {body_od_mm:g} mm across, must be wider than the neck"
        )
    for name, value in (("neck_length_mm", neck_length_mm),
                        ("shoulder_height_mm", shoulder_height_mm),
                        ("body_height_mm", body_height_mm)):
        if not value > 0:
            raise BodyGeometryError(f"bottle {name} = {value:g}: must be > 0 mm")
    if not neck_length_mm > neck_wall_mm / 2:
        raise BodyGeometryError(
            f"bottle neck_length_mm = {neck_length_mm:g}: must exceed the lip's radius "
            f"{neck_wall_mm / 2:g} mm"
        )
    check_bottle_fillets(neck_od_mm, neck_wall_mm, neck_length_mm, shoulder_height_mm,
                         body_od_mm, body_height_mm, neck_fillet_mm, shoulder_fillet_mm,
                         base_fillet_mm)
    ri, rc = ro - w, ro - w / 2
    zc = -math.sqrt((1 + w / 2) ** 2 - rc**2)
    z_top = zc + w / 2
    z_shoulder = z_top - neck_length_mm / R  # the neck's outer wall meets the flank; the floor
    z_body = z_shoulder - shoulder_height_mm / R
    z_base = z_body - body_height_mm / R
    rb = body_od_mm / 2 / R
    down, out = (0.0, -1.0), (1.0, 0.0)
    flank = (rb - ro, z_body - z_shoulder)
    n = math.hypot(*flank)
    flank = (flank[0] / n, flank[1] / n)
    bore, b0, b1 = _fillet((ri, z_shoulder), out, (0.0, 1.0), 0.5 * min(ri, zc - z_shoulder))
    neck, n0, n1 = _fillet((ro, z_shoulder), down, flank, neck_fillet_mm / R)
    shoulder, s0, s1 = _fillet((rb, z_body), flank, down, shoulder_fillet_mm / R)
    base, e0, e1 = _fillet((rb, z_base), down, (-1.0, 0.0), base_fillet_mm / R)
    segments = (
        Line((0.0, z_shoulder), b0),
        bore,
        Line(b1, (ri, zc)),
        Arc((rc, zc), w / 2, math.pi, 0.0),  # the lip: over the top, touching the ball
        Line((ro, zc), n0),
        neck,
        Line(n1, s0),
        shoulder,
        Line(s1, e0),
        base,
        Line(e1, (0.0, z_base)),
    )
    return (Profile(segments),)


@functools.lru_cache(maxsize=32)
def tube_wall(
    ball_radius_mm: float,
    od_mm: float = 101.6,
    wall_mm: float = 3.0,
    height_mm: float = 101.6,
    rim_z: float = 0.0,
) -> Cylinder:
    """The tube's wall with a fully rounded end (a half torus of radius ``wall_mm / 2``, the
    outer wall a cylinder of radius ``od_mm / 2``), its rim (lowest point) at ``rim_z`` (units
    of R; 0: displace it by the clamp's height). Units of R. Built once per set of arguments
    (as :func:`bottle`)."""
    R = float(ball_radius_mm)
    ro, w = od_mm / 2 / R, wall_mm / R
    if not 0 < w < ro:
        raise BodyGeometryError(f"tube wall {wall_mm:g} mm, must be in (0, tube radius)")
    return Cylinder(ro, rim_z, rim_z + height_mm / R, inner_radius=ro - w, edge_radius=w / 2)


def deepest_rim(ball_radius_mm: float, height_mm: float = 101.6) -> float:
    """The rim height (units of R, below the ball's centre) below which the ball's top has
    passed the tube's far end: $1 - H/R$. Geometry only: the tube is open there and does not
    stop a push."""
    return 1.0 - height_mm / ball_radius_mm
