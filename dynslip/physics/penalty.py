"""The contact penalty: energy and pressure per reference area as functions of the
penetration d into a body, C^2 and C^1, exactly zero at a positive gap (so contact is detected
by pressure, never by a gap threshold)."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

__all__ = ["Penalty", "penalty_energy", "penalty_pressure"]


class Penalty(eqx.Module):
    """Contact penalty: stiffness ``k`` (G h0 / R^3, per reference area) and width ``w`` (R)."""

    k: float = 1.0e4
    w: float = 1.0e-3


def penalty_energy(pen: Penalty, d):
    """Penalty energy per reference area as a function of the penetration ``d`` (C^2)."""
    k, w = pen.k, pen.w
    dc = jnp.clip(d, 0.0, w)
    small = k * dc**3 / (6 * w)
    large = k * (d**2 / 2 - w * d / 2 + w**2 / 6)
    return jnp.where(d <= 0, 0.0, jnp.where(d < w, small, large))


def penalty_pressure(pen: Penalty, d):
    """Penalty pressure per reference area, d(phi)/d(d): zero for d <= 0 (C^1)."""
    k, w = pen.k, pen.w
    dc = jnp.clip(d, 0.0, w)
    return jnp.where(d <= 0, 0.0, jnp.where(d < w, k * dc**2 / (2 * w), k * (d - w / 2)))
