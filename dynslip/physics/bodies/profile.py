r"""A body of any profile: a user's list of :class:`~.segments.Line` and
:class:`~.segments.Arc` segments (units of R), validated by
:func:`~.base.check_profile`: connected and C1 where they join, in the half plane
$\rho \ge 0$, from the axis to the axis or closed on itself, not crossing itself, listed with
the solid on the right (from the top of the axis down the outside).

Example: a capsule, a quarter ball, a cylinder of length 1 and another quarter ball, joined
C1::

    >>> import math
    >>> from dynslip.physics.bodies.segments import Arc, Line
    >>> p = Profile([Arc((0.0, 0.0), 1.0, math.pi / 2, 0.0), Line((1.0, 0.0), (1.0, -1.0)),
    ...              Arc((0.0, -1.0), 1.0, 0.0, -math.pi / 2)])
    >>> round(p.length, 12) == round(math.pi + 1.0, 12)
    True
"""

from __future__ import annotations

import equinox as eqx

from dynslip.physics.bodies.base import AbstractProfileBody, check_profile

__all__ = ["Profile"]


class Profile(AbstractProfileBody):
    """A body given by its profile's segments."""

    segments: tuple = eqx.field(static=True)

    def __init__(self, segments):
        self.segments = tuple(segments)
        check_profile(self.segments)
