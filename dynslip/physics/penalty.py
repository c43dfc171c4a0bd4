r"""The contact penalty: energy and pressure per reference area as functions of the
penetration d into a body, C^2 and C^1, exactly zero at a positive gap beyond the cohesive
range (so contact is detected by pressure, or by the gap within that range, never by a gap
threshold of the repulsive part alone).

**Cohesion (normal adhesion, docs/adhesion.md).** ``adhesion`` $w$ (an energy per reference area,
$G h_0$) adds a tensile well of depth $w$ over the range ``reach`` $\delta_c$ (R) of gap:

$$\phi(d) = \phi_\mathrm{rep}(d) - w\,s(d),\qquad
  s = 1 - x^3(10 - 15x + 6x^2),\ x = \mathrm{clip}(-d/\delta_c, 0, 1),$$

so $s = 1$ in contact ($d \ge 0$), $0$ beyond the range ($d \le -\delta_c$), with $s'$ and
$s''$ zero at both ends: the energy stays $C^2$ and the pressure $C^1$. The traction across a
gap $g = -d$ is the tension $p = -w\,30 x^2(1-x)^2/\delta_c$ (a traction-separation curve of
area exactly $w$, largest $15 w/(8\delta_c)$ at $g = \delta_c/2$): separating a node from
contact to beyond the range costs $w A$. At $w = 0$ the penalty is the purely repulsive one,
to the last bit.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

__all__ = ["Penalty", "cohesive_fraction", "penalty_energy", "penalty_pressure",
           "PEAK_TRACTION"]

#: the cohesive law's largest tension in units of w / reach: 30 x^2 (1 - x)^2 at x = 1/2
PEAK_TRACTION = 15.0 / 8.0


class Penalty(eqx.Module):
    """Contact penalty: stiffness ``k`` (G h0 / R^3, per reference area) and width ``w`` (R);
    the cohesive well's depth ``adhesion`` (G h0, per reference area; 0: no normal adhesion) and
    range ``reach`` (R, > 0)."""

    k: float = 1.0e4
    w: float = 1.0e-3
    adhesion: float = 0.0
    reach: float = 1.0e-3


def cohesive_fraction(reach, d):
    """$s(d)$ of the module docstring: 1 in contact, 0 beyond the gap ``reach``, a $C^2$
    quintic between (the fraction of the cohesive well a node holds)."""
    x = jnp.clip(-d / reach, 0.0, 1.0)
    return 1.0 - x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def _cohesive_slope(reach, d):
    """$ds/dd = 30 x^2 (1 - x)^2/\\delta_c \\ge 0$."""
    x = jnp.clip(-d / reach, 0.0, 1.0)
    return 30.0 * x**2 * (1.0 - x) ** 2 / reach


def _no_cohesion(pen: Penalty) -> bool:
    """Whether the well is a Python zero (a held body's or the support's penalty): nothing is
    added to the trace. A traced ``adhesion`` always adds the well (0 * s: exact)."""
    return isinstance(pen.adhesion, (int, float)) and pen.adhesion == 0.0


def penalty_energy(pen: Penalty, d):
    """Penalty energy per reference area as a function of the penetration ``d`` (C^2), the
    cohesive well included."""
    k, w = pen.k, pen.w
    dc = jnp.clip(d, 0.0, w)
    small = k * dc**3 / (6 * w)
    large = k * (d**2 / 2 - w * d / 2 + w**2 / 6)
    rep = jnp.where(d <= 0, 0.0, jnp.where(d < w, small, large))
    if _no_cohesion(pen):
        return rep
    return rep - pen.adhesion * cohesive_fraction(pen.reach, d)


def penalty_pressure(pen: Penalty, d):
    """Penalty pressure per reference area, d(phi)/d(d) (C^1): zero for d <= -reach, a tension
    (negative) in the cohesive range, the repulsive pressure in contact."""
    k, w = pen.k, pen.w
    dc = jnp.clip(d, 0.0, w)
    rep = jnp.where(d <= 0, 0.0, jnp.where(d < w, k * dc**2 / (2 * w), k * (d - w / 2)))
    if _no_cohesion(pen):
        return rep
    return rep - pen.adhesion * _cohesive_slope(pen.reach, d)
