"""Rigid axisymmetric bodies by meridian profile, one kind a module: the signed distance,
normal, tangent and surface coordinate of each (:mod:`.base`), the start-of-run checks
(:mod:`.overlap`), the trapped criteria (:mod:`.trap`) and the penalty contact with every body
(:mod:`.contact`) and the mesh check against any body (:mod:`.chords`). Lengths by the ball
radius R."""

from dynslip.physics.bodies.base import (
    AbstractBody,
    AbstractProfileBody,
    BodyGeometryError,
    check_profile,
)
from dynslip.physics.bodies.chords import chord_depths
from dynslip.physics.bodies.cone import Cone
from dynslip.physics.bodies.contact import Contact, contact_energy_density, contact_forces
from dynslip.physics.bodies.cylinder import Cylinder
from dynslip.physics.bodies.disc import Disc
from dynslip.physics.bodies.overlap import inside, overlap, penetration, shared_face
from dynslip.physics.bodies.profile import Profile
from dynslip.physics.bodies.segments import Arc, Line, Projection
from dynslip.physics.bodies.sphere import Sphere
from dynslip.physics.bodies.torus import Torus
from dynslip.physics.bodies.trap import (
    AbstractTrapCriterion,
    PastEdgeMidHeight,
    PastEquator,
    PastWidest,
)

__all__ = [
    "AbstractBody",
    "AbstractProfileBody",
    "AbstractTrapCriterion",
    "Arc",
    "BodyGeometryError",
    "Cone",
    "Contact",
    "Cylinder",
    "Disc",
    "Line",
    "PastEdgeMidHeight",
    "PastEquator",
    "PastWidest",
    "Profile",
    "Projection",
    "Sphere",
    "Torus",
    "check_profile",
    "chord_depths",
    "contact_energy_density",
    "contact_forces",
    "inside",
    "overlap",
    "penetration",
    "shared_face",
]
